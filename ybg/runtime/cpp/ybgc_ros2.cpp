// The publisher and the subscriptions of ybgc's C++ runtime for ROS 2
// (ybgc_ros2.hpp), on the node of ybgc_ros2_node.cpp, and the helpers of the
// message builders; the run() of a stream with a ROS 2 side. The parameters,
// QoS overrides and statuses they use are computed in ybgc_ros2_params.cpp,
// their peers' events taken in ybgc_ros2_events.cpp.
#include "ybgc_ros2.hpp"  // ybgc:runtime-import
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <rcl/error_handling.h>
#include <rcl/rcl.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace ybgc {
namespace ros2 {

void setString(rosidl_runtime_c__String& field, const std::string& text)
{
    // The message is filled again for each publish: a text that fits the
    // field's buffer (capacity counts the terminating NUL) is copied into it,
    // without the free and malloc of rosidl's assign.
    if (field.data != nullptr && field.capacity > text.size()) {
        std::memcpy(field.data, text.data(), text.size());
        field.data[text.size()] = '\0';
        field.size = text.size();
        return;
    }
    rosidl_runtime_c__String__assignn(&field, text.data(), text.size());
}

void set(rosidl_runtime_c__String& field, const Element& e)
{
    setString(field, e.str());
}

void setTime(builtin_interfaces__msg__Time& field, std::int64_t ns)
{
    // as rclpy's Time.to_msg(): divmod by 1e9
    std::int64_t sec = ns / 1000000000;
    std::int64_t nsec = ns % 1000000000;
    if (nsec < 0) {
        nsec += 1000000000;
        sec -= 1;
    }
    field.sec = static_cast<std::int32_t>(sec);
    field.nanosec = static_cast<std::uint32_t>(nsec);
}

void setStrings(rosidl_runtime_c__String__Sequence& seq, std::initializer_list<std::string> values)
{
    resize(seq, values.size());
    std::size_t k = 0;
    for (const std::string& v : values) {
        setString(seq.data[k++], v);
    }
}

// --- the publisher --------------------------------------------------------------------

rmw_qos_profile_t configQos(const Ros2Spec& spec)
{
    rmw_qos_profile_t qos = rmw_qos_profile_default;
    qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
    qos.depth = spec.depth;
    qos.reliability = spec.reliable ? RMW_QOS_POLICY_RELIABILITY_RELIABLE : RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
    qos.durability = spec.transientLocal ? RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL
                                         : RMW_QOS_POLICY_DURABILITY_VOLATILE;
    return qos;
}

struct Publisher::Rcl
{
    rcl_publisher_t publisher = rcl_get_zero_initialized_publisher();
    bool publisherOk = false;
};

Publisher::Publisher(const Ros2Spec& spec, const MessageType& type, FillMessage fill,
                     std::vector<std::string> rosArgs) :
        spec_(spec), type_(type), fill_(std::move(fill)), node_(spec.node, std::move(rosArgs)),
        rcl_(std::make_unique<Rcl>()), peers_("publisher", spec.topic, type.name)
{
    describe_ = std::string(type_.name) + " on the ROS 2 topic " + spec_.topic + " (node " + spec_.node + ", "
        + describeQos(configQos(spec_)) + ")";
}

Publisher::~Publisher()
{
    close();
}

bool Publisher::open()
{
    Rcl& r = *rcl_;
    if (!node_.open()) {
        return false;
    }
    rcl_publisher_options_t options = rcl_publisher_get_default_options();
    options.qos = configQos(spec_);
    std::string topic;
    std::string error;
    if (!node_.qos(spec_.topic, "publisher", options.qos, topic, error)) {
        say(std::string("cannot publish ") + type_.name + " on " + spec_.topic + ": " + error);
        return false;
    }
    if (rcl_publisher_init(&r.publisher, node_.node(), type_.typeSupport, spec_.topic, &options) != RCL_RET_OK) {
        say(std::string("cannot publish ") + type_.name + " on " + spec_.topic + ": " + rclError());
        return false;
    }
    r.publisherOk = true;
    peers_.watch(node_, &r.publisher);
    describe_ = std::string(type_.name) + " on the ROS 2 topic " + topic + " (node " + node_.name() + ", "
        + describeQos(options.qos) + ")";
    msg_ = type_.create();
    if (msg_ == nullptr) {
        say(std::string("cannot allocate a message ") + type_.name);
        return false;
    }
    return true;
}

std::string Publisher::describe() const
{
    return describe_;
}

std::int64_t Publisher::nowNs()
{
    return node_.nowNs();
}

bool Publisher::publish(const Inputs& in, const Context& ctx, std::string& failure)
{
    if (!fill_(msg_, in, ctx, failure)) {
        failure = tooShort(failure);
        return false;
    }
    if (rcl_publish(&rcl_->publisher, msg_, nullptr) != RCL_RET_OK) {
        if (!reportedPublishError_) {
            reportedPublishError_ = true;
            say("cannot publish on " + std::string(spec_.topic) + ": " + rclError() + "; further errors are not said");
        } else {
            rcl_reset_error();
        }
    }
    return true;
}

void Publisher::watch(TotalsSource totals)
{
    node_.publishDiagnostics(std::move(totals));
}

void Publisher::ros2Events(std::vector<Totals::Ros2Endpoint>& out) const
{
    out.push_back(peers_.counts());
}

void Publisher::close()
{
    Rcl& r = *rcl_;
    if (msg_ != nullptr) {
        type_.destroy(msg_);
        msg_ = nullptr;
    }
    peers_.stop();
    if (r.publisherOk) {
        finished(rcl_publisher_fini(&r.publisher, node_.node()));
        r.publisherOk = false;
    }
    node_.close();
}

// --- ROS 2 topics as inputs -------------------------------------------------------------

void read(Mux& out, const builtin_interfaces__msg__Time& field)
{
    out.push_back(Element::ofReal(static_cast<double>(field.sec) + static_cast<double>(field.nanosec) / 1e9));
}

void read(Mux& out, const builtin_interfaces__msg__Duration& field)
{
    out.push_back(Element::ofReal(static_cast<double>(field.sec) + static_cast<double>(field.nanosec) / 1e9));
}

struct Subscriptions::Rcl
{
    rcl_allocator_t allocator = rcl_get_default_allocator();
    std::vector<rcl_subscription_t> subscriptions;  // one a topic, in Topics order
    std::vector<std::unique_ptr<PeerEvents>> peers;  // one a topic, in Topics order
    std::vector<void*> messages;                    // one taken message a topic
    std::size_t subscribed = 0;
    std::thread thread;
    std::atomic<bool> stopping{false};
};

Subscriptions::Subscriptions(const Topics& topics, std::vector<std::string> rosArgs, Publisher* publisher) :
        topics_(topics),
        ownNode_(publisher == nullptr ? std::make_unique<Node>(topics.node, std::move(rosArgs)) : nullptr),
        node_(publisher == nullptr ? ownNode_.get() : &publisher->node()), rcl_(std::make_unique<Rcl>())
{
    for (const Topic& t : topics_.topics) {
        rcl_->peers.push_back(std::make_unique<PeerEvents>("subscription", t.name, t.type.name));
    }
}

Subscriptions::~Subscriptions()
{
    close();
}

bool Subscriptions::open(Deliver deliver)
{
    Rcl& r = *rcl_;
    deliver_ = std::move(deliver);
    if (ownNode_ != nullptr && !ownNode_->open()) {
        return false;
    }
    r.subscriptions.assign(topics_.topics.size(), rcl_get_zero_initialized_subscription());
    std::string names;
    for (const Topic& t : topics_.topics) {
        rcl_subscription_options_t options = rcl_subscription_get_default_options();
        options.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
        options.qos.depth = t.qos.depth;
        options.qos.reliability = t.qos.reliable ? RMW_QOS_POLICY_RELIABILITY_RELIABLE
                                                 : RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
        options.qos.durability = t.qos.transientLocal ? RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL
                                                      : RMW_QOS_POLICY_DURABILITY_VOLATILE;
        std::string resolved;
        std::string error;
        if (!node_->qos(t.name, "subscription", options.qos, resolved, error)) {
            say(std::string("cannot subscribe to ") + t.name + " (" + t.type.name + "): " + error);
            return false;
        }
        const std::size_t k = r.subscribed;
        if (rcl_subscription_init(&r.subscriptions[k], node_->node(), t.type.typeSupport, t.name, &options)
            != RCL_RET_OK) {
            say(std::string("cannot subscribe to ") + t.name + " (" + t.type.name + "): " + rclError());
            return false;
        }
        ++r.subscribed;
        r.peers[k]->watch(*node_, &r.subscriptions[k]);
        r.messages.push_back(t.type.create());
        if (r.messages.back() == nullptr) {
            say(std::string("cannot allocate a message ") + t.type.name);
            return false;
        }
        names += (names.empty() ? "" : ", ") + resolved + " (" + t.type.name + "; " + describeQos(options.qos) + ")";
    }
    say("reading the ROS 2 topics " + names + " on the node " + node_->name());
    r.thread = bridgeThread([this] { follow(); });
    return true;
}

void Subscriptions::watch(TotalsSource totals)
{
    if (ownNode_ != nullptr) {
        ownNode_->publishDiagnostics(std::move(totals));  // else the publisher's node does
    }
}

void Subscriptions::ros2Events(std::vector<Totals::Ros2Endpoint>& out) const
{
    for (const auto& peers : rcl_->peers) {
        out.push_back(peers->counts());
    }
}

bool Subscriptions::nowNs(std::int64_t& ns)
{
    if (ownNode_ == nullptr) {
        return false;  // the publisher's node stamps the messages
    }
    ns = ownNode_->nowNs();
    return true;
}

/// Takes the messages of every topic as they come, through one wait set
/// (woken every 100 ms to see whether the bridge stops).
void Subscriptions::follow()
{
    Rcl& r = *rcl_;
    rcl_wait_set_t waitSet = rcl_get_zero_initialized_wait_set();
    if (rcl_wait_set_init(&waitSet, r.subscribed, 0, 0, 0, 0, 0, node_->context(), r.allocator) != RCL_RET_OK) {
        say("cannot wait for the ROS 2 topics: " + rclError());
        return;
    }
    Reading reading;
    while (!r.stopping) {
        finished(rcl_wait_set_clear(&waitSet));
        for (std::size_t k = 0; k < r.subscribed; ++k) {
            finished(rcl_wait_set_add_subscription(&waitSet, &r.subscriptions[k], nullptr));
        }
        if (!waitOn(waitSet, 100)) {
            continue;
        }
        for (std::size_t k = 0; k < r.subscribed && !r.stopping; ++k) {
            if (waitSet.subscriptions[k] == nullptr) {
                continue;
            }
            const Topic& t = topics_.topics[k];
            while (!r.stopping && rcl_take(&r.subscriptions[k], r.messages[k], nullptr, nullptr) == RCL_RET_OK) {
                reading.values.clear();
                reading.rows.clear();
                reading.frame.reset();
                reading.refused.clear();
                reading.envelope = 0.0;
                t.read(r.messages[k], reading);
                deliver_(t.input, reading);
            }
            rcl_reset_error();
        }
    }
    finished(rcl_wait_set_fini(&waitSet));
}

void Subscriptions::close()
{
    Rcl& r = *rcl_;
    r.stopping = true;
    if (r.thread.joinable()) {
        r.thread.join();
    }
    for (std::size_t k = 0; k < r.subscribed; ++k) {
        r.peers[k]->stop();
        finished(rcl_subscription_fini(&r.subscriptions[k], node_->node()));
    }
    r.subscribed = 0;
    for (std::size_t k = 0; k < r.messages.size(); ++k) {
        if (r.messages[k] != nullptr) {
            topics_.topics[k].type.destroy(r.messages[k]);
        }
    }
    r.messages.clear();
    if (ownNode_ != nullptr) {
        ownNode_->close();
    }
    rcl_reset_error();
}

int run(const BridgeSpec& spec, const Topics& topics, int argc, char* argv[], MakeMessage make)
{
    RosCommandLine line(argc, argv, spec.module, topics.node);
    if (line.status != 0) {
        return line.status;
    }
    Subscriptions subscriptions(topics, std::move(line.rosArgs));
    return ybgc::run(spec, line.argc(), line.argv(), std::move(make), &subscriptions);
}

int run(const BridgeSpec& spec, const Ros2Spec& ros2, const MessageType& type, const Topics* topics, int argc,
        char* argv[], FillMessage fill)
{
    RosCommandLine line(argc, argv, spec.module, ros2.node);
    if (line.status != 0) {
        return line.status;
    }
    Publisher publisher(ros2, type, std::move(fill), std::move(line.rosArgs));
    std::unique_ptr<Subscriptions> subscriptions;
    if (topics != nullptr) {
        subscriptions = std::make_unique<Subscriptions>(*topics, std::vector<std::string>{}, &publisher);
    }
    return ybgc::run(spec, line.argc(), line.argv(), publisher, subscriptions.get());
}

}  // namespace ros2
}  // namespace ybgc
