// The rcl side of ybgc's C++ runtime for ROS 2 (ybgc_ros2.hpp): the node
// (its context, its clock, /diagnostics), the publisher, the subscriptions,
// and the helpers of the message builders. The parameters, QoS overrides and
// statuses they use are computed in ybgc_ros2_params.cpp.
#include "ybgc_ros2.hpp"  // ybgc:runtime-import
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <rcl/error_handling.h>
#include <rcl/event.h>
#include <rcl/graph.h>
#include <rcl/rcl.h>
#include <rcl/time.h>
#include <rcl_yaml_param_parser/parser.h>
#include <rmw/qos_string_conversions.h>
#include <rmw/topic_endpoint_info_array.h>
#include <rosidl_runtime_c/type_hash.h>
#include <diagnostic_msgs/msg/diagnostic_array.h>
#include <diagnostic_msgs/msg/diagnostic_status.h>
#include <diagnostic_msgs/msg/key_value.h>
#include <rosgraph_msgs/msg/clock.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
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

// --- the ROS arguments ------------------------------------------------------------------

int checkRosArgs(const std::vector<std::string>& rosArgs, const char* node, std::vector<std::string>* options)
{
    std::vector<const char*> argv{node};
    for (const std::string& arg : rosArgs) {
        argv.push_back(arg.c_str());
    }
    rcl_arguments_t args = rcl_get_zero_initialized_arguments();
    const rcl_allocator_t allocator = rcl_get_default_allocator();
    if (rcl_parse_arguments(static_cast<int>(argv.size()), argv.data(), allocator, &args) != RCL_RET_OK) {
        say("bad ROS arguments: " + rclError());
        return 2;
    }
    int status = 0;
    if (rcl_arguments_get_count_unparsed_ros(&args) > 0) {
        say("bad ROS arguments: rcl does not know some of them (see `--ros-args --help` of any ROS 2 program)");
        status = 2;
    }
    rcl_params_t* params = nullptr;
    if (status == 0 && rcl_arguments_get_param_overrides(&args, &params) == RCL_RET_OK) {
        bool on = true;
        double period = 1.0;
        std::string error;
        if (!diagnosticsOptions(params, std::string("/") + node, on, period, error)
            || (options != nullptr && !parameterOptions(params, std::string("/") + node, *options, error))) {
            say(error);
            status = 2;
        }
    }
    rcl_reset_error();
    if (params != nullptr) {
        rcl_yaml_node_struct_fini(params);
    }
    finished(rcl_arguments_fini(&args));
    return status;
}

// --- the node ---------------------------------------------------------------------------

struct Node::Rcl
{
    rcl_allocator_t allocator = rcl_get_default_allocator();
    rcl_context_t context = rcl_get_zero_initialized_context();  // its own (a module of its own)
    rcl_context_t* shared = nullptr;  // else the process's (ybgc compose: one context, one node per bridge)
    rcl_context_t* ctx() { return shared != nullptr ? shared : &context; }
    rcl_node_t node = rcl_get_zero_initialized_node();
    rcl_params_t* params = nullptr;  // the command line's parameters (nullptr: none)
    std::string fqn;                 // the node's fully qualified name
    rcl_clock_t clock{};
    rcl_subscription_t clockSubscription = rcl_get_zero_initialized_subscription();
    bool clockSubscribed = false;
    std::thread clockThread;
    std::atomic<bool> stopping{false};
    bool contextOk = false;
    bool nodeOk = false;
    bool clockOk = false;
    // /diagnostics
    bool diagnostics = true;   // the parameter `diagnostics`
    double period = 1.0;       // the parameter `diagnostic_updater.period`, seconds
    rcl_publisher_t diagnosticsPublisher = rcl_get_zero_initialized_publisher();
    bool diagnosticsOk = false;
    std::thread diagnosticsThread;
    std::mutex diagnosticsMutex;
    std::condition_variable diagnosticsWake;
    bool diagnosticsStop = false;
    // the events of its publishers and subscriptions (PeerEvents)
    std::vector<PeerEvents*> peers;
    std::thread peersThread;
    std::mutex peersMutex;
    std::condition_variable peersWake;
    bool peersStop = false;
};

Node::Node(const char* name, std::vector<std::string> rosArgs) :
        name_(name), rosArgs_(std::move(rosArgs)), rcl_(std::make_unique<Rcl>())
{
}

Node::~Node()
{
    close();
}

namespace {

/// rcl_init of `context` with the ROS arguments `rosArgs` (for a program
/// named `name`); false, said, when it fails.
bool initContext(rcl_context_t& context, const std::string& name, const std::vector<std::string>& rosArgs)
{
    rcl_init_options_t options = rcl_get_zero_initialized_init_options();
    if (rcl_init_options_init(&options, rcl_get_default_allocator()) != RCL_RET_OK) {
        say("cannot start ROS 2: " + rclError());
        return false;
    }
    // the domain (ROS_DOMAIN_ID) and discovery range come from the environment, as for every ROS 2 process
    std::vector<const char*> argv{name.c_str()};
    for (const std::string& arg : rosArgs) {
        argv.push_back(arg.c_str());
    }
    const rcl_ret_t init = rcl_init(static_cast<int>(argv.size()), argv.data(), &options, &context);
    finished(rcl_init_options_fini(&options));
    if (init != RCL_RET_OK) {
        say("cannot start ROS 2: " + rclError());
        return false;
    }
    return true;
}

/// The one rcl context of a process of several bridges (ybgc compose), and
/// so its one DDS participant: made by the first node that opens, with the
/// process's ROS arguments (every bridge is given them), shut down once
/// every bridge has closed. Never destroyed (the process may exit while a
/// thread still uses it).
struct ProcessContext
{
    std::mutex mutex;
    rcl_context_t context = rcl_get_zero_initialized_context();
    bool ok = false;
};

ProcessContext& processContext()
{
    static ProcessContext* const process = new ProcessContext;
    return *process;
}

/// The process's context for a node of the bridge `host` runs (made the
/// first time); nullptr, said, when ROS 2 cannot start.
rcl_context_t* sharedContext(Host& host, const std::string& name, const std::vector<std::string>& rosArgs)
{
    ProcessContext& p = processContext();
    std::lock_guard<std::mutex> lock(p.mutex);
    if (!p.ok) {
        if (!initContext(p.context, name, rosArgs)) {
            return nullptr;
        }
        p.ok = true;
        host.atEnd([] {
            ProcessContext& p = processContext();
            std::lock_guard<std::mutex> lock(p.mutex);
            if (p.ok) {
                finished(rcl_shutdown(&p.context));
                finished(rcl_context_fini(&p.context));
                p.ok = false;
            }
        });
    }
    return &p.context;
}

}  // namespace

bool Node::open()
{
    Rcl& r = *rcl_;
    if (Host* host = Host::current()) {
        r.shared = sharedContext(*host, name_, rosArgs_);
        if (r.shared == nullptr) {
            return false;
        }
    } else {
        if (!initContext(r.context, name_, rosArgs_)) {
            return false;
        }
        r.contextOk = true;
    }
    rcl_node_options_t nodeOptions = rcl_node_get_default_options();
    if (rcl_node_init(&r.node, name_.c_str(), "", r.ctx(), &nodeOptions) != RCL_RET_OK) {
        say("cannot create the ROS 2 node " + name_ + ": " + rclError());
        return false;
    }
    r.nodeOk = true;
    r.fqn = rcl_node_get_fully_qualified_name(&r.node);
    if (rcl_arguments_get_param_overrides(&r.ctx()->global_arguments, &r.params) != RCL_RET_OK) {
        rcl_reset_error();
        r.params = nullptr;
    }
    if (rcl_clock_init(RCL_ROS_TIME, &r.clock, &r.allocator) != RCL_RET_OK) {
        say("cannot create the node's clock: " + rclError());
        return false;
    }
    r.clockOk = true;
    return diagnosticsParameters() && (!useSimTime() || startClock());
}

/// The parameters of /diagnostics, as the Python node checks them.
bool Node::diagnosticsParameters()
{
    std::string error;
    if (!diagnosticsOptions(rcl_->params, rcl_->fqn, rcl_->diagnostics, rcl_->period, error)) {
        say(error);
        return false;
    }
    return true;
}

bool Node::diagnostics(double& period) const
{
    period = rcl_->period;
    return rcl_->diagnostics;
}

void Node::publishDiagnostics(TotalsSource totals)
{
    Rcl& r = *rcl_;
    if (!r.diagnostics || r.diagnosticsOk) {
        return;
    }
    rcl_publisher_options_t options = rcl_publisher_get_default_options();
    options.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
    options.qos.depth = 1;
    options.qos.reliability = RMW_QOS_POLICY_RELIABILITY_RELIABLE;
    options.qos.durability = RMW_QOS_POLICY_DURABILITY_VOLATILE;
    if (rcl_publisher_init(&r.diagnosticsPublisher, &r.node,
                           ROSIDL_GET_MSG_TYPE_SUPPORT(diagnostic_msgs, msg, DiagnosticArray), "/diagnostics",
                           &options) != RCL_RET_OK) {
        say("cannot publish /diagnostics: " + rclError() + "; the module runs without it");
        return;
    }
    r.diagnosticsOk = true;
    r.diagnosticsThread = std::thread([this, totals = std::move(totals), who = tModule] {
        tModule = who;  // in a process of several bridges, its bridge's name
        diagnose(totals);
    });
}

namespace {

/// The DiagnosticArray of `all`: its statuses refilled in place; false when
/// it cannot allocate them.
bool fill(diagnostic_msgs__msg__DiagnosticArray& msg, const std::vector<Status>& all,
          const std::string& hardwareId) noexcept
try {
    resize(msg.status, all.size(), diagnostic_msgs__msg__DiagnosticStatus__Sequence__init,
           diagnostic_msgs__msg__DiagnosticStatus__Sequence__fini);
    for (std::size_t k = 0; k < all.size(); ++k) {
        diagnostic_msgs__msg__DiagnosticStatus& out = msg.status.data[k];
        out.level = all[k].level;
        setString(out.name, all[k].name);
        setString(out.message, all[k].message);
        setString(out.hardware_id, hardwareId);
        resize(out.values, all[k].values.size(), diagnostic_msgs__msg__KeyValue__Sequence__init,
               diagnostic_msgs__msg__KeyValue__Sequence__fini);
        for (std::size_t j = 0; j < all[k].values.size(); ++j) {
            setString(out.values.data[j].key, all[k].values[j].first);
            setString(out.values.data[j].value, all[k].values[j].second);
        }
    }
    return true;
} catch (const std::bad_alloc&) {
    return false;
}

}  // namespace

/// Every period: the totals, read under the bridge's lock, published.
void Node::diagnose(TotalsSource totals)
{
    Rcl& r = *rcl_;
    diagnostic_msgs__msg__DiagnosticArray msg;
    if (!diagnostic_msgs__msg__DiagnosticArray__init(&msg)) {
        say("cannot allocate a diagnostic_msgs/DiagnosticArray; no /diagnostics");
        return;
    }
    RateWindow window;
    const auto start = SteadyClock::now();
    auto seconds = [start] { return std::chrono::duration<double>(SteadyClock::now() - start).count(); };
    window.add(seconds(), totals().published);
    const auto period = std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(r.period));
    auto next = start + period;
    bool reported = false;
    const std::string node = rcl_node_get_name(&r.node);
    for (;;) {
        {
            std::unique_lock<std::mutex> lock(r.diagnosticsMutex);
            if (r.diagnosticsWake.wait_until(lock, next, [&r] { return r.diagnosticsStop; })) {
                break;
            }
        }
        next += period;
        const Totals now = totals();
        const double achieved = window.add(seconds(), now.published);
        setTime(msg.header.stamp, nowNs());
        if (!fill(msg, statuses(now, node, achieved), now.module)
            || rcl_publish(&r.diagnosticsPublisher, &msg, nullptr) != RCL_RET_OK) {
            if (!reported) {
                reported = true;
                say("cannot publish /diagnostics: " + rclError() + "; further errors are not said");
            } else {
                rcl_reset_error();
            }
        }
    }
    diagnostic_msgs__msg__DiagnosticArray__fini(&msg);
}

void Node::watch(PeerEvents* peers)
{
    Rcl& r = *rcl_;
    std::lock_guard<std::mutex> lock(r.peersMutex);
    r.peers.push_back(peers);
    if (!r.peersThread.joinable()) {
        r.peersStop = false;
        r.peersThread = std::thread([this, who = tModule] {
            tModule = who;
            takeEvents();
        });
    }
}

void Node::unwatch(PeerEvents* peers)
{
    Rcl& r = *rcl_;
    std::lock_guard<std::mutex> lock(r.peersMutex);  // not while it takes them
    r.peers.erase(std::remove(r.peers.begin(), r.peers.end(), peers), r.peers.end());
}

/// Every 100 ms: the events of each publisher and subscription watched.
void Node::takeEvents()
{
    Rcl& r = *rcl_;
    std::unique_lock<std::mutex> lock(r.peersMutex);
    while (!r.peersWake.wait_for(lock, std::chrono::milliseconds(100), [&r] { return r.peersStop; })) {
        for (PeerEvents* peers : r.peers) {
            peers->take();
        }
    }
}

/// The parameter use_sim_time of the command line (`-p use_sim_time:=true`,
/// for every node or this one).
bool Node::useSimTime()
{
    const rcl_variant_t* value = parameter(rcl_->params, rcl_->fqn, "use_sim_time");
    return value != nullptr && value->bool_value != nullptr && *value->bool_value;
}

/// Simulated time: the clock follows /clock, read by a thread of its own.
bool Node::startClock()
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
    r.clockThread = std::thread([this, who = tModule] {
        tModule = who;
        followClock();
    });
    say("use_sim_time: stamps from /clock");
    return true;
}

void Node::followClock()
{
    Rcl& r = *rcl_;
    rcl_wait_set_t waitSet = rcl_get_zero_initialized_wait_set();
    if (rcl_wait_set_init(&waitSet, 1, 0, 0, 0, 0, 0, r.ctx(), r.allocator) != RCL_RET_OK) {
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

std::int64_t Node::nowNs()
{
    rcl_time_point_value_t now = 0;
    if (rcl_->clockOk && rcl_clock_get_now(&rcl_->clock, &now) == RCL_RET_OK) {
        return now;
    }
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::system_clock::now().time_since_epoch()).count();
}

bool Node::qos(const char* topic, const char* entity, rmw_qos_profile_t& qos, std::string& resolved,
               std::string& error)
{
    // the overrides name the topic as the node resolves it (remapped, expanded), as rclpy's do
    char* name = nullptr;
    if (rcl_node_resolve_name(&rcl_->node, topic, rcl_->allocator, false, false, &name) != RCL_RET_OK) {
        error = "cannot resolve the topic name: " + rclError();
        return false;
    }
    resolved = name;
    rcl_->allocator.deallocate(name, rcl_->allocator.state);
    return overrideQos(rcl_->params, rcl_->fqn, resolved, entity, qos, error);
}

rcl_context_t* Node::context()
{
    return rcl_->ctx();
}

rcl_node_t* Node::node()
{
    return &rcl_->node;
}

std::string Node::name() const
{
    const char* name = rcl_->nodeOk ? rcl_node_get_name(&rcl_->node) : nullptr;
    return name != nullptr ? name : name_;
}

void Node::close()
{
    Rcl& r = *rcl_;
    {
        std::lock_guard<std::mutex> lock(r.peersMutex);
        r.peersStop = true;
        r.peers.clear();
    }
    r.peersWake.notify_all();
    if (r.peersThread.joinable()) {
        r.peersThread.join();
    }
    {
        std::lock_guard<std::mutex> lock(r.diagnosticsMutex);
        r.diagnosticsStop = true;
    }
    r.diagnosticsWake.notify_all();
    if (r.diagnosticsThread.joinable()) {
        r.diagnosticsThread.join();
    }
    if (r.diagnosticsOk) {
        finished(rcl_publisher_fini(&r.diagnosticsPublisher, &r.node));
        r.diagnosticsOk = false;
    }
    r.stopping = true;
    if (r.clockThread.joinable()) {
        r.clockThread.join();
    }
    if (r.clockSubscribed) {
        finished(rcl_subscription_fini(&r.clockSubscription, &r.node));
        r.clockSubscribed = false;
    }
    if (r.clockOk) {
        finished(rcl_clock_fini(&r.clock));
        r.clockOk = false;
    }
    if (r.params != nullptr) {
        rcl_yaml_node_struct_fini(r.params);
        r.params = nullptr;
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

// --- incompatible peers ----------------------------------------------------------------

namespace {

/// What the Python node's words say of a policy's value (rmw's names).
std::string policyText(const char* name)
{
    return name != nullptr ? name : "unknown";
}

/// A QoS's reliability and durability, as the Python node says them.
std::string qosWords(const rmw_qos_profile_t& qos)
{
    return policyText(rmw_qos_reliability_policy_to_str(qos.reliability)) + ", "
        + policyText(rmw_qos_durability_policy_to_str(qos.durability));
}

/// Whether a publisher of QoS `pub` gives nothing to a subscription of QoS
/// `sub` by their reliability or durability.
bool conflicts(const rmw_qos_profile_t& pub, const rmw_qos_profile_t& sub)
{
    return (pub.reliability == RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT
            && sub.reliability == RMW_QOS_POLICY_RELIABILITY_RELIABLE)
        || (pub.durability == RMW_QOS_POLICY_DURABILITY_VOLATILE
            && sub.durability == RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL);
}

/// The endpoints of the graph on `topic`: its publishers or its subscriptions.
class Endpoints
{
public:
    Endpoints(const rcl_node_t* node, const char* topic, bool publishers)
    {
        const rcl_ret_t ret = publishers
            ? rcl_get_publishers_info_by_topic(node, &allocator_, topic, false, &array_)
            : rcl_get_subscriptions_info_by_topic(node, &allocator_, topic, false, &array_);
        if (ret != RCL_RET_OK) {
            rcl_reset_error();
        }
    }
    ~Endpoints() { finished(rmw_topic_endpoint_info_array_fini(&array_, &allocator_)); }
    Endpoints(const Endpoints&) = delete;
    Endpoints& operator=(const Endpoints&) = delete;
    const rmw_topic_endpoint_info_t* begin() const { return array_.info_array; }
    const rmw_topic_endpoint_info_t* end() const { return array_.info_array + (array_.info_array ? array_.size : 0); }

private:
    rcutils_allocator_t allocator_ = rcutils_get_default_allocator();
    rmw_topic_endpoint_info_array_t array_ = rmw_get_zero_initialized_topic_endpoint_info_array();
};

/// A type hash as REP-2011 writes it (RIHS01_...).
std::string hashText(const rosidl_type_hash_t& hash)
{
    char* text = nullptr;
    const rcutils_allocator_t allocator = rcutils_get_default_allocator();
    if (rosidl_stringify_type_hash(&hash, allocator, &text) != RCUTILS_RET_OK || text == nullptr) {
        rcutils_reset_error();
        return "unknown";
    }
    std::string out = text;
    allocator.deallocate(text, allocator.state);
    return out;
}

/// What the Python node says (core.py; ybg/lower/ros2_events.py holds both
/// to its texts): the first peer of an incompatible QoS, of another
/// definition of the type; their {names} filled by filled().
const char* const kIncompatibleQosText =
    "ROS 2 {kind} {topic}: a {peer} of an incompatible QoS ({policy}; the {peer}'s: {theirs}; this {kind}'s: "
    "{ours}): no messages between them; further incompatible QoS events of it are only counted";
/// What a publisher says each time its matched subscriptions change ({s}: ""
/// for one, "s" otherwise), as the Python node.
const char* const kSubscribersText = "{topic}: {n} subscriber{s}";
/// ... and a subscription each time its matched publishers change.
const char* const kPublishersText = "{topic}: {n} publisher{s}";
const char* const kIncompatibleTypeText =
    "ROS 2 {kind} {topic}: a {peer} of another definition of {type} (its type hash {theirs}; this {kind}'s: "
    "{ours}): no messages between them; further incompatible type events of it are only counted";

/// `text` with each {name} of `values` replaced by its value (as Python's str.format).
std::string filled(const char* text, std::initializer_list<std::pair<const char*, std::string>> values)
{
    std::string out = text;
    for (const auto& [name, value] : values) {
        const std::string key = std::string("{") + name + "}";
        for (std::size_t at = out.find(key); at != std::string::npos; at = out.find(key, at + value.size())) {
            out.replace(at, key.size(), value);
        }
    }
    return out;
}

/// A count of events from the middleware's `total` (its lifetime count),
/// when `change` says some came; true for the first.
bool counted(std::atomic<std::uint64_t>& n, std::int32_t total, std::int32_t change)
{
    const std::uint64_t before = n.load();
    if (change <= 0 && total <= 0) {
        return false;
    }
    if (change <= 0 && static_cast<std::uint64_t>(total) <= before) {
        return false;
    }
    n = std::max<std::uint64_t>(static_cast<std::uint64_t>(std::max(total, 0)), before + 1);
    return before == 0;
}

}  // namespace

struct PeerEvents::Rcl
{
    Node* node = nullptr;
    const rcl_publisher_t* publisher = nullptr;
    const rcl_subscription_t* subscription = nullptr;
    rcl_event_t qosEvent = rcl_get_zero_initialized_event();
    rcl_event_t typeEvent = rcl_get_zero_initialized_event();
    rcl_event_t matchedEvent = rcl_get_zero_initialized_event();
    bool qosOk = false;
    bool typeOk = false;
    bool matchedOk = false;
    std::atomic<std::uint64_t> qos{0};
    std::atomic<std::uint64_t> type{0};
};

PeerEvents::PeerEvents(const char* kind, std::string topic, std::string typeName) :
        kind_(kind), topic_(std::move(topic)), typeName_(std::move(typeName)), rcl_(std::make_unique<Rcl>())
{
}

PeerEvents::~PeerEvents()
{
    stop();
}

void PeerEvents::watch(Node& node, const rcl_publisher_t* publisher)
{
    Rcl& r = *rcl_;
    r.publisher = publisher;
    // an event kind the rmw does not support (RCL_RET_UNSUPPORTED) is left out
    r.qosOk = rcl_publisher_event_init(&r.qosEvent, publisher, RCL_PUBLISHER_OFFERED_INCOMPATIBLE_QOS)
        == RCL_RET_OK;
    r.typeOk = rcl_publisher_event_init(&r.typeEvent, publisher, RCL_PUBLISHER_INCOMPATIBLE_TYPE) == RCL_RET_OK;
    r.matchedOk = rcl_publisher_event_init(&r.matchedEvent, publisher, RCL_PUBLISHER_MATCHED) == RCL_RET_OK;
    init(node);
}

void PeerEvents::watch(Node& node, const rcl_subscription_t* subscription)
{
    Rcl& r = *rcl_;
    r.subscription = subscription;
    r.qosOk = rcl_subscription_event_init(&r.qosEvent, subscription, RCL_SUBSCRIPTION_REQUESTED_INCOMPATIBLE_QOS)
        == RCL_RET_OK;
    r.typeOk = rcl_subscription_event_init(&r.typeEvent, subscription, RCL_SUBSCRIPTION_INCOMPATIBLE_TYPE)
        == RCL_RET_OK;
    r.matchedOk = rcl_subscription_event_init(&r.matchedEvent, subscription, RCL_SUBSCRIPTION_MATCHED)
        == RCL_RET_OK;
    init(node);
}

void PeerEvents::init(Node& node)
{
    Rcl& r = *rcl_;
    rcl_reset_error();
    r.node = &node;
    if (r.qosOk || r.typeOk || r.matchedOk) {
        node.watch(this);
    }
}

void PeerEvents::stop()
{
    Rcl& r = *rcl_;
    if (r.node != nullptr) {
        r.node->unwatch(this);
        r.node = nullptr;
    }
    if (r.qosOk) {
        finished(rcl_event_fini(&r.qosEvent));
        r.qosOk = false;
    }
    if (r.typeOk) {
        finished(rcl_event_fini(&r.typeEvent));
        r.typeOk = false;
    }
    if (r.matchedOk) {
        finished(rcl_event_fini(&r.matchedEvent));
        r.matchedOk = false;
    }
}

void PeerEvents::take()
{
    Rcl& r = *rcl_;
    if (r.qosOk) {
        rmw_qos_incompatible_event_status_t status{};
        if (rcl_take_event(&r.qosEvent, &status) == RCL_RET_OK) {
            if (counted(r.qos, status.total_count, status.total_count_change)) {
                say(qosText(status.last_policy_kind));
            }
        } else {
            rcl_reset_error();
        }
    }
    if (r.typeOk) {
        rmw_incompatible_type_status_t status{};
        if (rcl_take_event(&r.typeEvent, &status) == RCL_RET_OK) {
            if (counted(r.type, status.total_count, status.total_count_change)) {
                say(typeText());
            }
        } else {
            rcl_reset_error();
        }
    }
    if (r.matchedOk) {
        rmw_matched_status_t status{};
        if (rcl_take_event(&r.matchedEvent, &status) == RCL_RET_OK) {
            if (status.current_count_change != 0) {
                const std::size_t n = status.current_count;
                say(filled(r.publisher != nullptr ? kSubscribersText : kPublishersText,
                           {{"topic", topic_}, {"n", std::to_string(n)}, {"s", n == 1 ? "" : "s"}}));
            }
        } else {
            rcl_reset_error();
        }
    }
}

std::string PeerEvents::qosText(int policy)
{
    Rcl& r = *rcl_;
    const bool publishes = r.publisher != nullptr;
    const rmw_qos_profile_t* ours = publishes ? rcl_publisher_get_actual_qos(r.publisher)
                                              : rcl_subscription_get_actual_qos(r.subscription);
    const char* topic = publishes ? rcl_publisher_get_topic_name(r.publisher)
                                  : rcl_subscription_get_topic_name(r.subscription);
    std::string theirs = "unknown (not in the graph yet)";
    if (ours != nullptr && topic != nullptr) {
        Endpoints peers(r.node->node(), topic, !publishes);
        const rmw_topic_endpoint_info_t* pick = nullptr;
        for (const rmw_topic_endpoint_info_t& e : peers) {
            if (publishes ? conflicts(*ours, e.qos_profile) : conflicts(e.qos_profile, *ours)) {
                pick = &e;
                break;
            }
        }
        if (pick == nullptr && peers.begin() != peers.end()) {
            pick = peers.begin();
        }
        if (pick != nullptr) {
            theirs = qosWords(pick->qos_profile);
        }
    }
    const char* name = rmw_qos_policy_kind_to_str(static_cast<rmw_qos_policy_kind_t>(policy));
    return filled(kIncompatibleQosText, {{"kind", kind_}, {"topic", topic_},
                                         {"peer", publishes ? "subscription" : "publisher"},
                                         {"policy", name != nullptr ? name : "policy " + std::to_string(policy)},
                                         {"theirs", theirs}, {"ours", ours != nullptr ? qosWords(*ours) : "unknown"}});
}

std::string PeerEvents::typeText()
{
    Rcl& r = *rcl_;
    const bool publishes = r.publisher != nullptr;
    const char* topic = publishes ? rcl_publisher_get_topic_name(r.publisher)
                                  : rcl_subscription_get_topic_name(r.subscription);
    std::string theirs = "unknown";
    std::string ours = "unknown";
    if (topic != nullptr) {
        const rcl_node_t* node = r.node->node();
        Endpoints own(node, topic, publishes);
        for (const rmw_topic_endpoint_info_t& e : own) {
            if (e.node_name != nullptr && e.node_namespace != nullptr
                && std::strcmp(e.node_name, rcl_node_get_name(node)) == 0
                && std::strcmp(e.node_namespace, rcl_node_get_namespace(node)) == 0) {
                ours = hashText(e.topic_type_hash);
                break;
            }
        }
        Endpoints peers(node, topic, !publishes);
        for (const rmw_topic_endpoint_info_t& e : peers) {
            const std::string hash = hashText(e.topic_type_hash);
            if (hash != ours) {
                theirs = hash;
                break;
            }
        }
    }
    return filled(kIncompatibleTypeText, {{"kind", kind_}, {"topic", topic_},
                                          {"peer", publishes ? "subscription" : "publisher"}, {"type", typeName_},
                                          {"theirs", theirs}, {"ours", ours}});
}

Totals::Ros2Endpoint PeerEvents::counts() const
{
    return {kind_, topic_, rcl_->qos.load(), rcl_->type.load()};
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
    r.thread = std::thread([this, who = tModule] {
        tModule = who;
        follow();
    });
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
    std::vector<std::string> rosArgs = takeRosArgs(argc, argv);
    std::vector<std::string> options;
    if (const int status = checkRosArgs(rosArgs, topics.node, &options)) {
        return status;
    }
    CommandLine line(argc, argv, options);
    Subscriptions subscriptions(topics, std::move(rosArgs));
    return ybgc::run(spec, line.argc(), line.argv(), std::move(make), &subscriptions);
}

}  // namespace ros2
}  // namespace ybgc
