// The rcl node of ybgc's C++ runtime (ybgc_ros2.hpp), which every kind of
// bridge with a ROS 2 side opens (a stream's publisher or subscriptions, a
// bridge of commands): its context (its own, or the process's one in a
// process of several bridges), its ROS arguments checked, its parameters,
// its ROS clock (simulated with use_sim_time), /diagnostics over a source of
// statuses, and the thread that takes its peers' events.
#include "ybgc_ros2.hpp"  // ybgc:runtime-import
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <rcl/time.h>
#include <rcl_yaml_param_parser/parser.h>
#include <diagnostic_msgs/msg/diagnostic_array.h>
#include <diagnostic_msgs/msg/diagnostic_status.h>
#include <diagnostic_msgs/msg/key_value.h>
#include <rosgraph_msgs/msg/clock.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace ybgc {
namespace ros2 {

std::string rclError()
{
    std::string text = rcl_get_error_string().str;
    rcl_reset_error();
    return text;
}

void finished(rcl_ret_t ret)
{
    if (ret != RCL_RET_OK) {
        rcl_reset_error();
    }
}

bool waitOn(rcl_wait_set_t& waitSet, std::int64_t ms)
{
    const rcl_ret_t woke = rcl_wait(&waitSet, RCL_MS_TO_NS(ms));
    if (woke == RCL_RET_OK) {
        return true;
    }
    rcl_reset_error();
    if (woke != RCL_RET_TIMEOUT) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));  // no busy loop on an error
    }
    return false;
}

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

void Node::publishDiagnostics(TotalsSource totals)
{
    if (!rcl_->diagnostics) {
        return;
    }
    // the rate achieved over the last 5 periods, from a first sample now
    auto window = std::make_shared<RateWindow>();
    const auto start = SteadyClock::now();
    auto seconds = [start] { return std::chrono::duration<double>(SteadyClock::now() - start).count(); };
    const Totals first = totals();
    window->add(seconds(), first.published);
    publishStatuses([totals = std::move(totals), window, seconds, node = name()] {
        const Totals now = totals();
        return statuses(now, node, window->add(seconds(), now.published));
    }, first.module);
}

void Node::publishStatuses(StatusSource source, std::string hardwareId)
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
    r.diagnosticsThread = bridgeThread([this, source = std::move(source), hardwareId = std::move(hardwareId)] {
        diagnose(source, hardwareId);
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

/// Every period: the statuses, read under the bridge's lock, published.
void Node::diagnose(const StatusSource& source, const std::string& hardwareId)
{
    Rcl& r = *rcl_;
    diagnostic_msgs__msg__DiagnosticArray msg;
    if (!diagnostic_msgs__msg__DiagnosticArray__init(&msg)) {
        say("cannot allocate a diagnostic_msgs/DiagnosticArray; no /diagnostics");
        return;
    }
    const auto period = std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(r.period));
    auto next = SteadyClock::now() + period;
    bool reported = false;
    for (;;) {
        {
            std::unique_lock<std::mutex> lock(r.diagnosticsMutex);
            if (r.diagnosticsWake.wait_until(lock, next, [&r] { return r.diagnosticsStop; })) {
                break;
            }
        }
        next += period;
        const std::vector<Status> all = source();
        setTime(msg.header.stamp, nowNs());
        if (!fill(msg, all, hardwareId) || rcl_publish(&r.diagnosticsPublisher, &msg, nullptr) != RCL_RET_OK) {
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
        r.peersThread = bridgeThread([this] { takeEvents(); });
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
    r.clockThread = bridgeThread([this] { followClock(); });
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
        if (!waitOn(waitSet, 100)) {
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

}  // namespace ros2
}  // namespace ybgc
