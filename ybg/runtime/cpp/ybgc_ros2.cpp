// The rcl side of ybgc's C++ runtime for ROS 2 (ybgc_ros2.hpp): the node
// (its context, its clock, /diagnostics), the publisher, the subscriptions,
// and the helpers of the message builders. The parameters, QoS overrides and
// statuses they use are computed in ybgc_ros2_params.cpp.
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
        rcl_(std::make_unique<Rcl>())
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

void Publisher::close()
{
    Rcl& r = *rcl_;
    if (msg_ != nullptr) {
        type_.destroy(msg_);
        msg_ = nullptr;
    }
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
        options.qos.depth = 1;
        options.qos.reliability = RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
        options.qos.durability = RMW_QOS_POLICY_DURABILITY_VOLATILE;
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
