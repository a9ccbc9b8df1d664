// The ROS 2 side of ybgc's C++ runtime: the rcl publisher and the helpers of
// the message builders (ybgc_ros2.hpp).
#include "ybgc_ros2.hpp"  // ybgc:runtime-import

#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <rcl/time.h>
#include <rcl_yaml_param_parser/parser.h>
#include <rosgraph_msgs/msg/clock.h>

#include <cstring>

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

namespace {

std::string rclError()
{
    std::string text = rcl_get_error_string().str;
    rcl_reset_error();
    return text;
}

/// A finalization's result: nothing more to do when it fails at exit.
void finished(rcl_ret_t ret)
{
    if (ret != RCL_RET_OK) {
        rcl_reset_error();
    }
}

}  // namespace

struct Publisher::Rcl
{
    rcl_allocator_t allocator = rcl_get_default_allocator();
    rcl_context_t context = rcl_get_zero_initialized_context();
    rcl_node_t node = rcl_get_zero_initialized_node();
    rcl_publisher_t publisher = rcl_get_zero_initialized_publisher();
    rcl_clock_t clock{};
    rcl_subscription_t clockSubscription = rcl_get_zero_initialized_subscription();
    bool clockSubscribed = false;
    std::thread clockThread;
    std::atomic<bool> stopping{false};
    bool contextOk = false;
    bool nodeOk = false;
    bool publisherOk = false;
    bool clockOk = false;
};

std::vector<std::string> takeRosArgs(int& argc, char* argv[])
{
    std::vector<std::string> rosArgs;
    int kept = 1;
    bool inside = false;
    for (int k = 1; k < argc; ++k) {
        if (!inside && std::strcmp(argv[k], "--ros-args") == 0) {
            inside = true;
            rosArgs.emplace_back(argv[k]);
        } else if (inside && std::strcmp(argv[k], "--") == 0) {
            inside = false;
        } else if (inside) {
            rosArgs.emplace_back(argv[k]);
        } else {
            argv[kept++] = argv[k];
        }
    }
    argc = kept;
    argv[argc] = nullptr;
    return rosArgs;
}

Publisher::Publisher(const Ros2Spec& spec, const MessageType& type, FillMessage fill,
                     std::vector<std::string> rosArgs) :
        spec_(spec), rosArgs_(std::move(rosArgs)), type_(type), fill_(std::move(fill)),
        rcl_(std::make_unique<Rcl>())
{
}

Publisher::~Publisher()
{
    close();
}

bool Publisher::open()
{
    Rcl& r = *rcl_;
    rcl_init_options_t options = rcl_get_zero_initialized_init_options();
    if (rcl_init_options_init(&options, r.allocator) != RCL_RET_OK) {
        say("cannot start ROS 2: " + rclError());
        return false;
    }
    // the domain (ROS_DOMAIN_ID) and discovery range come from the environment, as for every ROS 2 process
    std::vector<const char*> argv{spec_.node};
    for (const std::string& arg : rosArgs_) {
        argv.push_back(arg.c_str());
    }
    const rcl_ret_t init = rcl_init(static_cast<int>(argv.size()), argv.data(), &options, &r.context);
    finished(rcl_init_options_fini(&options));
    if (init != RCL_RET_OK) {
        say("cannot start ROS 2: " + rclError());
        return false;
    }
    r.contextOk = true;
    rcl_node_options_t nodeOptions = rcl_node_get_default_options();
    if (rcl_node_init(&r.node, spec_.node, "", &r.context, &nodeOptions) != RCL_RET_OK) {
        say(std::string("cannot create the ROS 2 node ") + spec_.node + ": " + rclError());
        return false;
    }
    r.nodeOk = true;
    if (rcl_clock_init(RCL_ROS_TIME, &r.clock, &r.allocator) != RCL_RET_OK) {
        say("cannot create the node's clock: " + rclError());
        return false;
    }
    r.clockOk = true;
    if (useSimTime() && !startClock()) {
        return false;
    }
    rcl_publisher_options_t pubOptions = rcl_publisher_get_default_options();
    pubOptions.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
    pubOptions.qos.depth = spec_.depth;
    pubOptions.qos.reliability = spec_.reliable ? RMW_QOS_POLICY_RELIABILITY_RELIABLE
                                                : RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
    pubOptions.qos.durability = spec_.transientLocal ? RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL
                                                     : RMW_QOS_POLICY_DURABILITY_VOLATILE;
    if (rcl_publisher_init(&r.publisher, &r.node, type_.typeSupport, spec_.topic, &pubOptions) != RCL_RET_OK) {
        say(std::string("cannot publish ") + type_.name + " on " + spec_.topic + ": " + rclError());
        return false;
    }
    r.publisherOk = true;
    msg_ = type_.create();
    if (msg_ == nullptr) {
        say(std::string("cannot allocate a message ") + type_.name);
        return false;
    }
    return true;
}

/// The parameter use_sim_time of the command line (`-p use_sim_time:=true`,
/// for every node or this one).
bool Publisher::useSimTime()
{
    rcl_params_t* params = nullptr;
    if (rcl_arguments_get_param_overrides(&rcl_->context.global_arguments, &params) != RCL_RET_OK
        || params == nullptr) {
        rcl_reset_error();
        return false;
    }
    bool on = false;
    const std::string node = std::string("/") + spec_.node;
    for (const char* name : {"/**", node.c_str()}) {
        const rcl_variant_t* value = rcl_yaml_node_struct_get(name, "use_sim_time", params);
        if (value != nullptr && value->bool_value != nullptr) {
            on = *value->bool_value;
        }
    }
    rcl_yaml_node_struct_fini(params);
    return on;
}

/// Simulated time: the node's clock follows /clock (best effort, the last
/// one kept, as rclpy's and rclcpp's clocks subscribe), read by a thread of
/// its own; it reads 0 until the first /clock message.
bool Publisher::startClock()
{
    Rcl& r = *rcl_;
    rcl_subscription_options_t options = rcl_subscription_get_default_options();
    options.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
    options.qos.depth = 1;
    options.qos.reliability = RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
    if (rcl_subscription_init(&r.clockSubscription, &r.node, ROSIDL_GET_MSG_TYPE_SUPPORT(rosgraph_msgs, msg, Clock),
                              "/clock", &options) != RCL_RET_OK) {
        say("cannot subscribe to /clock (use_sim_time): " + rclError());
        return false;
    }
    r.clockSubscribed = true;
    if (rcl_enable_ros_time_override(&r.clock) != RCL_RET_OK) {
        say("cannot use the simulated time: " + rclError());
        return false;
    }
    r.clockThread = std::thread([this] { followClock(); });
    say("use_sim_time: stamps from /clock");
    return true;
}

void Publisher::followClock()
{
    Rcl& r = *rcl_;
    rcl_wait_set_t waitSet = rcl_get_zero_initialized_wait_set();
    if (rcl_wait_set_init(&waitSet, 1, 0, 0, 0, 0, 0, &r.context, r.allocator) != RCL_RET_OK) {
        say("cannot wait for /clock: " + rclError());
        return;
    }
    rosgraph_msgs__msg__Clock clock;
    rosgraph_msgs__msg__Clock__init(&clock);
    while (!r.stopping) {
        finished(rcl_wait_set_clear(&waitSet));
        finished(rcl_wait_set_add_subscription(&waitSet, &r.clockSubscription, nullptr));
        const rcl_ret_t woke = rcl_wait(&waitSet, RCL_MS_TO_NS(100));
        if (woke == RCL_RET_TIMEOUT) {
            continue;
        }
        if (woke != RCL_RET_OK) {
            rcl_reset_error();
            continue;
        }
        while (rcl_take(&r.clockSubscription, &clock, nullptr, nullptr) == RCL_RET_OK) {
            finished(rcl_set_ros_time_override(&r.clock, RCL_S_TO_NS(static_cast<std::int64_t>(clock.clock.sec))
                                                             + clock.clock.nanosec));
        }
        rcl_reset_error();
    }
    rosgraph_msgs__msg__Clock__fini(&clock);
    finished(rcl_wait_set_fini(&waitSet));
}

std::string Publisher::describe() const
{
    return std::string(type_.name) + " on the ROS 2 topic " + spec_.topic + " (node " + spec_.node + ", "
        + (spec_.reliable ? "reliable" : "best_effort") + ", "
        + (spec_.transientLocal ? "transient_local" : "volatile") + ", depth " + std::to_string(spec_.depth) + ")";
}

std::int64_t Publisher::nowNs()
{
    rcl_time_point_value_t now = 0;
    if (rcl_->clockOk && rcl_clock_get_now(&rcl_->clock, &now) == RCL_RET_OK) {
        return now;
    }
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::system_clock::now().time_since_epoch()).count();
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

void Publisher::close()
{
    Rcl& r = *rcl_;
    r.stopping = true;
    if (r.clockThread.joinable()) {
        r.clockThread.join();
    }
    if (r.clockSubscribed) {
        finished(rcl_subscription_fini(&r.clockSubscription, &r.node));
        r.clockSubscribed = false;
    }
    if (msg_ != nullptr) {
        type_.destroy(msg_);
        msg_ = nullptr;
    }
    if (r.publisherOk) {
        finished(rcl_publisher_fini(&r.publisher, &r.node));
        r.publisherOk = false;
    }
    if (r.clockOk) {
        finished(rcl_clock_fini(&r.clock));
        r.clockOk = false;
    }
    if (r.nodeOk) {
        finished(rcl_node_fini(&r.node));
        r.nodeOk = false;
    }
    if (r.contextOk) {
        finished(rcl_shutdown(&r.context));
        finished(rcl_context_fini(&r.context));
        r.contextOk = false;
    }
    rcl_reset_error();
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
    rcl_context_t ownContext = rcl_get_zero_initialized_context();
    rcl_node_t ownNode = rcl_get_zero_initialized_node();
    rcl_context_t* context = nullptr;  // its own, or the publisher's
    rcl_node_t* node = nullptr;
    std::vector<rcl_subscription_t> subscriptions;  // one a topic, in Topics order
    std::vector<void*> messages;                    // one taken message a topic
    std::size_t subscribed = 0;
    std::thread thread;
    std::atomic<bool> stopping{false};
    bool contextOk = false;
    bool nodeOk = false;
};

Subscriptions::Subscriptions(const Topics& topics, std::vector<std::string> rosArgs, Publisher* publisher) :
        topics_(topics), rosArgs_(std::move(rosArgs)), publisher_(publisher), rcl_(std::make_unique<Rcl>())
{
}

Subscriptions::~Subscriptions()
{
    close();
}

bool Subscriptions::open(Deliver deliver)
{
    Rcl& r = *rcl_;
    deliver_ = std::move(deliver);
    if (publisher_ != nullptr) {
        r.context = &publisher_->rcl_->context;
        r.node = &publisher_->rcl_->node;
    } else {
        rcl_init_options_t options = rcl_get_zero_initialized_init_options();
        if (rcl_init_options_init(&options, r.allocator) != RCL_RET_OK) {
            say("cannot start ROS 2: " + rclError());
            return false;
        }
        std::vector<const char*> argv{topics_.node};
        for (const std::string& arg : rosArgs_) {
            argv.push_back(arg.c_str());
        }
        const rcl_ret_t init = rcl_init(static_cast<int>(argv.size()), argv.data(), &options, &r.ownContext);
        finished(rcl_init_options_fini(&options));
        if (init != RCL_RET_OK) {
            say("cannot start ROS 2: " + rclError());
            return false;
        }
        r.contextOk = true;
        rcl_node_options_t nodeOptions = rcl_node_get_default_options();
        if (rcl_node_init(&r.ownNode, topics_.node, "", &r.ownContext, &nodeOptions) != RCL_RET_OK) {
            say(std::string("cannot create the ROS 2 node ") + topics_.node + ": " + rclError());
            return false;
        }
        r.nodeOk = true;
        r.context = &r.ownContext;
        r.node = &r.ownNode;
    }
    r.subscriptions.assign(topics_.topics.size(), rcl_get_zero_initialized_subscription());
    for (const Topic& t : topics_.topics) {
        rcl_subscription_options_t options = rcl_subscription_get_default_options();
        options.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
        options.qos.depth = 1;
        options.qos.reliability = RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
        options.qos.durability = RMW_QOS_POLICY_DURABILITY_VOLATILE;
        const std::size_t k = r.subscribed;
        if (rcl_subscription_init(&r.subscriptions[k], r.node, t.type.typeSupport, t.name, &options)
            != RCL_RET_OK) {
            say(std::string("cannot subscribe to ") + t.name + " (" + t.type.name + "): " + rclError());
            return false;
        }
        ++r.subscribed;
        r.messages.push_back(t.type.create());
        if (r.messages.back() == nullptr) {
            say(std::string("cannot allocate a message ") + t.type.name);
            return false;
        }
    }
    std::string names;
    for (const Topic& t : topics_.topics) {
        names += (names.empty() ? "" : ", ") + std::string(t.name) + " (" + t.type.name + ")";
    }
    say("reading the ROS 2 topics " + names + " on the node " + rcl_node_get_name(r.node)
        + " (best_effort, volatile, depth 1)");
    r.thread = std::thread([this] { follow(); });
    return true;
}

/// Takes the messages of every topic as they come, through one wait set
/// (woken every 100 ms to see whether the bridge stops).
void Subscriptions::follow()
{
    Rcl& r = *rcl_;
    rcl_wait_set_t waitSet = rcl_get_zero_initialized_wait_set();
    if (rcl_wait_set_init(&waitSet, r.subscribed, 0, 0, 0, 0, 0, r.context, r.allocator) != RCL_RET_OK) {
        say("cannot wait for the ROS 2 topics: " + rclError());
        return;
    }
    Reading reading;
    while (!r.stopping) {
        finished(rcl_wait_set_clear(&waitSet));
        for (std::size_t k = 0; k < r.subscribed; ++k) {
            finished(rcl_wait_set_add_subscription(&waitSet, &r.subscriptions[k], nullptr));
        }
        const rcl_ret_t woke = rcl_wait(&waitSet, RCL_MS_TO_NS(100));
        if (woke != RCL_RET_OK) {
            rcl_reset_error();
            if (woke != RCL_RET_TIMEOUT) {
                std::this_thread::sleep_for(std::chrono::milliseconds(10));  // no busy loop on an error
            }
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
        finished(rcl_subscription_fini(&r.subscriptions[k], r.node));
    }
    r.subscribed = 0;
    for (std::size_t k = 0; k < r.messages.size(); ++k) {
        if (r.messages[k] != nullptr) {
            topics_.topics[k].type.destroy(r.messages[k]);
        }
    }
    r.messages.clear();
    if (r.nodeOk) {
        finished(rcl_node_fini(&r.ownNode));
        r.nodeOk = false;
    }
    if (r.contextOk) {
        finished(rcl_shutdown(&r.ownContext));
        finished(rcl_context_fini(&r.ownContext));
        r.contextOk = false;
    }
    rcl_reset_error();
}

int run(const BridgeSpec& spec, const Topics& topics, int argc, char* argv[], MakeMessage make)
{
    std::vector<std::string> rosArgs = takeRosArgs(argc, argv);
    Subscriptions subscriptions(topics, std::move(rosArgs));
    return ybgc::run(spec, argc, argv, std::move(make), &subscriptions);
}

}  // namespace ros2
}  // namespace ybgc
