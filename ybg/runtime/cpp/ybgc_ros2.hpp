// The ROS 2 side of ybgc's C++ runtime (docs/ros2-native.md): a module whose
// output is a ROS 2 topic publishes through the rcl C API, with no rclcpp and
// no Python in the process. Publisher is the bridge's MessageSink: it opens
// an rcl node and a publisher with the config's QoS, stamps messages with
// the node's ROS clock, and publishes the message the module's builder fills
// through the message package's C structs (<pkg>/msg/<name>.h); Subscriptions
// read ROS 2 topics as inputs. Both honour the ROS arguments of the command
// line as an rclcpp or rclpy node does: remappings, use_sim_time and the
// qos_overrides.* parameters. The helpers below are what a builder's lines
// call: they convert a mux element to the field's C type as the Python ROS 2
// node does, and size strings and sequences with rosidl_runtime_c's
// functions. ybgc writes this file, ybgc_ros2.cpp (rcl: the publisher, the
// subscriptions, the message helpers), ybgc_ros2_node.cpp (the node: its
// context, clock, /diagnostics), ybgc_ros2_events.cpp (incompatible and
// matched peers) and ybgc_ros2_params.cpp (ROS arguments, parameters, QoS
// overrides, the statuses of /diagnostics) beside a module with a ROS 2
// node: one that publishes to ROS 2 or reads a ROS 2 topic, or of commands.
#ifndef YBGC_ROS2_HPP
#define YBGC_ROS2_HPP

#include "ybgc_runtime.hpp"  // ybgc:runtime-import

#include <builtin_interfaces/msg/duration.h>
#include <builtin_interfaces/msg/time.h>
#include <rcl/node.h>
#include <rcl/publisher.h>
#include <rcl/subscription.h>
#include <rcl/wait.h>
#include <rcl_yaml_param_parser/types.h>
#include <rmw/types.h>
#include <rosidl_runtime_c/message_type_support_struct.h>
#include <rosidl_runtime_c/primitives_sequence.h>
#include <rosidl_runtime_c/primitives_sequence_functions.h>
#include <rosidl_runtime_c/string.h>
#include <rosidl_runtime_c/string_functions.h>

#include <deque>
#include <new>
#include <type_traits>
#include <utility>

namespace ybgc {
namespace ros2 {

/// rcl's error text, reset.
std::string rclError();

/// A finalization's result: nothing more to do when it fails at exit (the error reset).
void finished(rcl_ret_t ret);

/// Waits on `waitSet` for up to `ms` milliseconds: true when something is
/// ready; false on a timeout or an error (reset: after an error 10 ms pass
/// first, so that a loop of waits is never a busy one).
bool waitOn(rcl_wait_set_t& waitSet, std::int64_t ms);

// --- values of each field's C type, as the Python node converts them ------------

/// A mux element as a field of type T: a real as float(x), an integer as
/// int(x) (a real truncated), a bool as bool(x).
template <class T>
T as(const Element& e)
{
    if constexpr (std::is_same_v<T, bool>) {
        return e.kind == Element::Kind::Real ? e.real != 0.0 : e.integer != 0;
    } else if constexpr (std::is_floating_point_v<T>) {
        return static_cast<T>(e.asReal());
    } else {
        return static_cast<T>(e.asInteger());
    }
}

/// One scalar field from one mux element.
template <class T>
void set(T& field, const Element& e)
{
    field = as<T>(e);
}

/// A string field from one mux element (a number as Python's str() writes it).
void set(rosidl_runtime_c__String& field, const Element& e);

/// A number field from a constant or a number of the module (the counter,
/// the seconds): an integer field wraps like its type.
template <class T, class V>
void assign(T& field, V x)
{
    field = static_cast<T>(x);
}

/// A string field.
void setString(rosidl_runtime_c__String& field, const std::string& text);

/// A builtin_interfaces/Time from nanoseconds since the epoch.
void setTime(builtin_interfaces__msg__Time& field, std::int64_t ns);

// --- sequences and fixed arrays -------------------------------------------------------

/// Sizes a sequence to n elements (kept when it has them already); false when
/// it cannot allocate.
#define YBGC_ROS2_RESIZE(NAME) \
    inline bool resize(rosidl_runtime_c__##NAME##__Sequence& s, std::size_t n) \
    { \
        if (s.size == n && (n == 0 || s.data != nullptr)) { \
            return true; \
        } \
        rosidl_runtime_c__##NAME##__Sequence__fini(&s); \
        return rosidl_runtime_c__##NAME##__Sequence__init(&s, n); \
    }
YBGC_ROS2_RESIZE(float)
YBGC_ROS2_RESIZE(double)
YBGC_ROS2_RESIZE(char)
YBGC_ROS2_RESIZE(boolean)
YBGC_ROS2_RESIZE(octet)
YBGC_ROS2_RESIZE(uint8)
YBGC_ROS2_RESIZE(int8)
YBGC_ROS2_RESIZE(uint16)
YBGC_ROS2_RESIZE(int16)
YBGC_ROS2_RESIZE(uint32)
YBGC_ROS2_RESIZE(int32)
YBGC_ROS2_RESIZE(uint64)
YBGC_ROS2_RESIZE(int64)
YBGC_ROS2_RESIZE(String)
#undef YBGC_ROS2_RESIZE

/// Sizes a sequence of messages to n elements (kept when it has them
/// already: the config fixes their number, so the elements and the fields
/// the config leaves unset stay from one message to the next) with its
/// package's functions, pkg__msg__Name__Sequence__init and __fini: a new
/// element has the defaults of its definition. Throws std::bad_alloc when it
/// cannot allocate.
template <class Seq>
void resize(Seq& seq, std::size_t n, bool (*init)(Seq*, std::size_t), void (*fini)(Seq*))
{
    if (seq.size == n && (n == 0 || seq.data != nullptr)) {
        return;
    }
    fini(&seq);
    if (!init(&seq, n)) {
        throw std::bad_alloc();
    }
}

/// The elements [start, stop) of a mux (stop kToEnd: to its end) into a
/// sequence, each converted to the sequence's element type; `bound` (0: none)
/// the most a bounded sequence holds. False when they do not fit.
template <class Seq>
bool setRange(Seq& seq, const Mux& mux, std::size_t start, std::size_t stop, std::size_t bound = 0)
{
    const std::size_t end = stop == kToEnd ? mux.size() : stop;
    if (start > end || end > mux.size() || (bound != 0 && end - start > bound) || !resize(seq, end - start)) {
        return false;
    }
    for (std::size_t k = start; k < end; ++k) {
        set(seq.data[k - start], mux[k]);
    }
    return true;
}

/// The same into a fixed-size array: exactly N elements.
template <class T, std::size_t N>
bool setRange(T (&array)[N], const Mux& mux, std::size_t start, std::size_t stop, std::size_t /*bound*/ = 0)
{
    const std::size_t end = stop == kToEnd ? mux.size() : stop;
    if (start > end || end > mux.size() || end - start != N) {
        return false;
    }
    for (std::size_t k = start; k < end; ++k) {
        set(array[k - start], mux[k]);
    }
    return true;
}

/// Constant values (the lowering checked their number) into a sequence or a
/// fixed-size array.
template <class V, class Seq>
void setValues(Seq& seq, std::initializer_list<V> values)
{
    resize(seq, values.size());
    std::size_t k = 0;
    for (const V& v : values) {
        seq.data[k++] = static_cast<std::remove_reference_t<decltype(seq.data[0])>>(v);
    }
}
template <class V, class T, std::size_t N>
void setValues(T (&array)[N], std::initializer_list<V> values)
{
    std::size_t k = 0;
    for (const V& v : values) {
        array[k++] = static_cast<T>(v);
    }
}

/// Constant strings into a sequence of strings or a fixed-size array of them.
void setStrings(rosidl_runtime_c__String__Sequence& seq, std::initializer_list<std::string> values);
template <std::size_t N>
void setStrings(rosidl_runtime_c__String (&array)[N], std::initializer_list<std::string> values)
{
    std::size_t k = 0;
    for (const std::string& v : values) {
        setString(array[k++], v);
    }
}

// --- the node's parameters and QoS -------------------------------------------------------

/// Does the node name of a parameter file or of `-p` (`/**`, `/*`,
/// `/robot/*`, `bridge`) name the node whose fully qualified name is `fqn`?
/// As rclcpp matches them: `**` any run of characters, `*` any run without
/// a `/`, and a name without a leading `/` is taken from the root.
bool nodeMatches(const std::string& pattern, const std::string& fqn);

/// The value of parameter `name` for the node `fqn` among the parameters of
/// the command line (`--ros-args -p NAME:=VALUE`, `--params-file F`), the
/// last given that names the node; nullptr when none does.
const rcl_variant_t* parameter(const rcl_params_t* params, const std::string& fqn, const std::string& name);

/// The QoS of a publisher ("publisher") or a subscription ("subscription")
/// of `topic` (its resolved name) with the read-only parameters
/// qos_overrides.<topic>.<entity>.<policy> of the node `fqn` applied, as
/// rclcpp's and rclpy's QoSOverridingOptions apply them: `history`
/// (keep_last, keep_all), `depth` (an integer), `reliability` (reliable,
/// best_effort), `durability` (volatile, transient_local). False, with the
/// parameter and what it accepts in `error`, for a value ROS 2 refuses.
bool overrideQos(const rcl_params_t* params, const std::string& fqn, const std::string& topic, const char* entity,
                 rmw_qos_profile_t& qos, std::string& error);

/// A QoS as the start-up lines say it: "reliable, volatile, depth 10".
std::string describeQos(const rmw_qos_profile_t& qos);

/// The parameters of /diagnostics for the node `fqn`: `diagnostics` (true or
/// false) into `on`, `diagnostic_updater.period` (a positive number of
/// seconds) into `period`, each left as it is when not given; false, with
/// the reason in `error`, for a value the Python node refuses too.
bool diagnosticsOptions(const rcl_params_t* params, const std::string& fqn, bool& on, double& period,
                        std::string& error);

/// The module's options given as the Python node takes them, as ROS
/// parameters (`-p rate:=50`, a launch file's `parameters`): `rate`,
/// `timeout` (0: the config's), `prefix`, `verbose`, appended to `options`
/// as the command-line options they stand for (`--rate=50`); false, with
/// the reason in `error`, for a value the Python node refuses too.
bool parameterOptions(const rcl_params_t* params, const std::string& fqn, std::vector<std::string>& options,
                      std::string& error);

/// Checks the command line's ROS arguments before anything opens, as the
/// Python node checks its parameters: 0, or 2 (said) when rcl refuses them
/// or a parameter of the module has a value it refuses. `options`: the
/// options its parameters give (parameterOptions).
int checkRosArgs(const std::vector<std::string>& rosArgs, const char* node,
                 std::vector<std::string>* options = nullptr);

// --- /diagnostics ------------------------------------------------------------------------

/// One status of a diagnostic_msgs/DiagnosticArray, as plain data.
struct Status
{
    enum Level : std::uint8_t { Ok = 0, Warn = 1, Error = 2 };
    std::uint8_t level = Ok;
    std::string name;
    std::string message;
    std::vector<std::pair<std::string, std::string>> values;
};

/// The statuses a node publishes on /diagnostics, read when called (under
/// its bridge's lock: never call it holding the lock).
using StatusSource = std::function<std::vector<Status>()>;

/// The statuses of the bridge's totals, as the Python node writes them
/// (docs/runtime.md, "Diagnostics"): one a input, `<node>: input <source>`,
/// OK while fresh, WARN once stale, ERROR before its first message; then the
/// output, `<node>: output <topic or port>`, the rate `achieved` against the
/// configured one (WARN below 90 % of it, diagnostic_updater's tolerance).
std::vector<Status> statuses(const Totals& totals, const std::string& node, double achieved);

/// The rate achieved over the last `window` periods: messages published a
/// second between the oldest and the newest of the last window + 1 samples.
class RateWindow
{
public:
    explicit RateWindow(std::size_t window = 5) : window_(window) {}
    /// Adds the sample (`seconds` of a steady clock, `published` so far); the rate.
    double add(double seconds, std::uint64_t published);

private:
    std::size_t window_;
    std::deque<std::pair<double, std::uint64_t>> samples_;
};

class Node;

/// The incompatible-QoS and incompatible-type events of one rcl publisher
/// or subscription (`kind`) of `topic` (as the config names it): counted (the
/// bridge's `stats`, exit totals and /diagnostics), the first of each kind
/// said with the peer's QoS (the first peer in the graph whose reliability
/// or durability does not match its own) or type hash, in the Python node's
/// words; and the matched peers, said when they change: a publisher's
/// subscriptions ("TOPIC: N subscribers"), a subscription's publishers
/// ("TOPIC: N publishers"), as the Python node (a message published before
/// both sides have matched is not delivered). An event kind the rmw
/// does not support is left out. Taken by its Node's thread (Node::takeEvents),
/// every 100 ms.
class PeerEvents
{
public:
    PeerEvents(const char* kind, std::string topic, std::string typeName);
    ~PeerEvents();
    PeerEvents(const PeerEvents&) = delete;
    PeerEvents& operator=(const PeerEvents&) = delete;

    /// Its events on `publisher` (`subscription`) of `node`, taken by `node`
    /// until stop().
    void watch(Node& node, const rcl_publisher_t* publisher);
    void watch(Node& node, const rcl_subscription_t* subscription);
    /// No longer taken, its events finished: before its publisher or
    /// subscription is. The counts stay.
    void stop();
    /// Takes the events that came (the Node's thread).
    void take();
    Totals::Ros2Endpoint counts() const;

private:
    struct Rcl;
    void init(Node& node);
    std::string qosText(int policy);
    std::string typeText();
    std::string kind_;
    std::string topic_;
    std::string typeName_;
    std::unique_ptr<Rcl> rcl_;
};

/// One rcl context and node opened with the command line's ROS arguments
/// (`--ros-args ...`: remappings, parameters), the node's parameters, and
/// its ROS clock: with the parameter use_sim_time true, the simulated time
/// of /clock (subscribed best effort, the last one kept, as rclcpp's and
/// rclpy's clocks subscribe, by a thread of its own; 0 until the first
/// /clock message), else the system clock.
class Node
{
public:
    Node(const char* name, std::vector<std::string> rosArgs);
    ~Node();
    Node(const Node&) = delete;
    Node& operator=(const Node&) = delete;

    /// Opens it; false, said, when it cannot.
    bool open();
    void close();
    /// The node's clock, nanoseconds since the epoch.
    std::int64_t nowNs();
    /// The QoS of a publisher or subscription of `topic` (as the config
    /// names it) with the node's qos_overrides; false, with the reason in
    /// `error`, for an override ROS 2 refuses. `resolved`: the topic's
    /// name after the remappings, which the overrides name.
    bool qos(const char* topic, const char* entity, rmw_qos_profile_t& qos, std::string& resolved,
             std::string& error);
    rcl_context_t* context();
    rcl_node_t* node();
    std::string name() const;
    /// Publishes the statuses of `source` on /diagnostics (a
    /// diagnostic_msgs/DiagnosticArray, depth 1, reliable, as
    /// diagnostic_updater does) every `diagnostic_updater.period` seconds
    /// (parameter, default 1) of the steady clock, stamped with the node's
    /// clock, `hardware_id` the module's name `hardwareId`, until closed;
    /// nothing with the parameter `diagnostics:=false`. The parameters were
    /// checked by open().
    void publishStatuses(StatusSource source, std::string hardwareId);
    /// The same of a stream's `totals`: its inputs and its output (statuses()),
    /// the rate achieved over the last 5 periods.
    void publishDiagnostics(TotalsSource totals);
    /// Takes the events of `peers` every 100 ms, by a thread of its own,
    /// until unwatch(peers) or close().
    void watch(PeerEvents* peers);
    /// No longer takes them (returns once it does not).
    void unwatch(PeerEvents* peers);

private:
    struct Rcl;
    void takeEvents();
    bool useSimTime();
    bool startClock();
    void followClock();
    bool diagnosticsParameters();
    void diagnose(const StatusSource& source, const std::string& hardwareId);
    std::string name_;
    std::vector<std::string> rosArgs_;
    std::unique_ptr<Rcl> rcl_;
};

// --- the publisher --------------------------------------------------------------------

/// The ROS 2 output of a bridge: its topic, node and the config's QoS
/// (the qos_overrides parameters of the command line apply on top of it).
struct Ros2Spec
{
    const char* topic;
    const char* node;         // the node's name
    bool reliable;            // reliability = reliable (else best_effort)
    bool transientLocal;      // durability = transient_local (else volatile)
    std::size_t depth;        // history: keep the last `depth`
};

/// The QoS the config gives a publisher (the qos_overrides apply on top of it).
rmw_qos_profile_t configQos(const Ros2Spec& spec);

/// The message type the generated module publishes: its type support and
/// the C functions that create and destroy one message (with its defaults).
struct MessageType
{
    const char* name;  // pkg/msg/Name
    const rosidl_message_type_support_t* typeSupport;
    void* (*create)();
    void (*destroy)(void*);
};

/// The MessageType of the C struct Msg, from its C functions.
template <class Msg, Msg* (*Create)(), void (*Destroy)(Msg*)>
MessageType messageType(const char* name, const rosidl_message_type_support_t* typeSupport)
{
    return {name, typeSupport, []() -> void* { return Create(); },
            [](void* msg) { Destroy(static_cast<Msg*>(msg)); }};
}

/// Fills one message from the newest input values; false (with the mux
/// sizes in `failure`) when a mux does not fit the message.
using FillMessage = std::function<bool(void* msg, const Inputs&, const Context&, std::string& failure)>;

/// Publishes through rcl: a Node and a publisher, opened by the bridge once
/// its inputs are open; messages are stamped with the node's clock. One
/// message is kept and filled again for each publish (the fields the config
/// leaves unset keep the defaults of the message's definition). `rosArgs`:
/// the command line's ROS arguments (`--ros-args ...`), given to rcl.
class Publisher : public MessageSink
{
public:
    Publisher(const Ros2Spec& spec, const MessageType& type, FillMessage fill,
              std::vector<std::string> rosArgs = {});
    ~Publisher() override;

    bool open() override;
    std::string describe() const override;
    std::int64_t nowNs() override;
    bool publish(const Inputs& in, const Context& ctx, std::string& failure) override;
    void close() override;
    void watch(TotalsSource totals) override;
    void ros2Events(std::vector<Totals::Ros2Endpoint>& out) const override;
    Node& node() { return node_; }
    /// The message published last (its C struct; nullptr before open()).
    const void* message() const { return msg_; }

private:
    struct Rcl;
    const Ros2Spec& spec_;
    const MessageType& type_;
    FillMessage fill_;
    Node node_;
    std::unique_ptr<Rcl> rcl_;
    std::string describe_;
    void* msg_ = nullptr;
    bool reportedPublishError_ = false;
    PeerEvents peers_;
};

/// The module's builder `fill` of a message of C struct Msg, as a FillMessage.
template <class Msg>
FillMessage filling(bool (*fill)(const Inputs&, const Context&, Msg&, std::string&))
{
    return [fill](void* msg, const Inputs& in, const Context& ctx, std::string& failure) {
        return fill(in, ctx, *static_cast<Msg*>(msg), failure);
    };
}

struct Topics;

/// Parses the command line and runs the bridge with its ROS 2 output (a
/// message of `type`, filled by `fill`) until SIGINT or SIGTERM, reading the
/// ROS 2 `topics` too (nullptr: none) on the same node; the exit status.
int run(const BridgeSpec& spec, const Ros2Spec& ros2, const MessageType& type, const Topics* topics, int argc,
        char* argv[], FillMessage fill);

/// The same, `fill` the module's builder for a message of type `Msg` (the C
/// struct of its definition).
template <class Msg>
int run(const BridgeSpec& spec, const Ros2Spec& ros2, const MessageType& type, int argc, char* argv[],
        bool (*fill)(const Inputs&, const Context&, Msg&, std::string&))
{
    return run(spec, ros2, type, nullptr, argc, argv, filling(fill));
}

// --- ROS 2 topics as inputs -------------------------------------------------------------

/// The values of one field of a message taken from a topic, appended to a
/// mux as the Python ROS 2 node reads them: a number as it is (a float a
/// real, an integer an integer, a bool a bool), a time or a duration as
/// seconds (sec + nanosec / 1e9), a sequence element by element.
template <class T>
void read(Mux& out, const T& field)
{
    if constexpr (std::is_same_v<T, bool>) {
        out.push_back(Element::ofBool(field));
    } else if constexpr (std::is_floating_point_v<T>) {
        out.push_back(Element::ofReal(static_cast<double>(field)));
    } else if constexpr (std::is_integral_v<T>) {
        out.push_back(Element::ofInteger(static_cast<std::int64_t>(field)));
    } else {  // a sequence: rosidl_runtime_c's {data, size, capacity}
        for (std::size_t k = 0; k < field.size; ++k) {
            read(out, field.data[k]);
        }
    }
}

/// A fixed-size array, element by element.
template <class T, std::size_t N>
void read(Mux& out, const T (&array)[N])
{
    for (const T& x : array) {
        read(out, x);
    }
}

/// Calls `f` on each element of an array of messages (a sequence or a
/// fixed-size array), in order.
template <class Seq, class F>
void forEach(const Seq& seq, F f)
{
    for (std::size_t k = 0; k < seq.size; ++k) {
        f(seq.data[k]);
    }
}
template <class T, std::size_t N, class F>
void forEach(const T (&array)[N], F f)
{
    for (const T& x : array) {
        f(x);
    }
}

void read(Mux& out, const builtin_interfaces__msg__Time& field);
void read(Mux& out, const builtin_interfaces__msg__Duration& field);

/// Has the message a header.stamp?
template <class Msg, class = void>
struct HasStamp : std::false_type
{
};
template <class Msg>
struct HasStamp<Msg, std::void_t<decltype(std::declval<const Msg&>().header.stamp.nanosec)>> : std::true_type
{
};

/// The envelope of a message: its header.stamp in seconds, when it has a
/// header and the stamp is not zero (as the Python node takes it).
template <class Msg>
bool envelopeOf(const Msg& msg, double& seconds)
{
    if constexpr (HasStamp<Msg>::value) {
        const builtin_interfaces__msg__Time& stamp = msg.header.stamp;
        if (stamp.sec == 0 && stamp.nanosec == 0) {
            return false;
        }
        seconds = static_cast<double>(stamp.sec) + static_cast<double>(stamp.nanosec) * 1e-9;
        return true;
    } else {
        (void)msg;
        (void)seconds;
        return false;
    }
}

/// One ROS 2 topic a bridge input reads: the input's index in
/// BridgeSpec::inputs, the message type, and the module's reader of its
/// fields (with the message's envelope).
/// The QoS a topic input subscribes with: its mux's, else best effort,
/// volatile and the last message kept, which matches every publisher.
struct InputQos
{
    bool reliable = false;        // reliability = reliable (else best_effort)
    bool transientLocal = false;  // durability = transient_local (else volatile)
    std::size_t depth = 1;        // history: keep the last `depth`
};

struct Topic
{
    std::size_t input;
    const char* name;  // the topic
    MessageType type;
    void (*read)(const void* msg, Reading& out);
    InputQos qos;
};

/// The Topic of input `input` (topic `name`), a message of C struct Msg read
/// by `Read`, the module's reader of the fields the config lists: into the
/// input's values, `void (const Msg&, Mux&)`, or one row for each element of
/// an array of messages, `void (const Msg&, Rows&)`; or the runtime's reader
/// of a whole message, `void (const Msg&, Reading&)` (a camera image:
/// ybgc_images.hpp).
template <class Msg, Msg* (*Create)(), void (*Destroy)(Msg*), auto Read>
Topic topic(std::size_t input, const char* name, const char* typeName,
            const rosidl_message_type_support_t* typeSupport, InputQos qos = {})
{
    return {input, name, messageType<Msg, Create, Destroy>(typeName, typeSupport),
            [](const void* msg, Reading& out) {
                const Msg& m = *static_cast<const Msg*>(msg);
                if constexpr (std::is_invocable_v<decltype(Read), const Msg&, Reading&>) {
                    Read(m, out);
                } else if constexpr (std::is_invocable_v<decltype(Read), const Msg&, Rows&>) {
                    out.isRows = true;
                    Read(m, out.rows);
                } else {
                    Read(m, out.values);
                }
                out.hasEnvelope = envelopeOf(m, out.envelope);
            },
            qos};
}

/// The ROS 2 topics a bridge reads, and the name of the node that reads
/// them when the output is a YARP port (a ROS 2 output's node reads them
/// otherwise).
struct Topics
{
    const char* node;
    std::vector<Topic> topics;
};

/// The bridge's ROS 2 inputs: one rcl subscription a topic, with the QoS of
/// the Python node's inputs (keep the last 1, best effort, which matches
/// reliable and best-effort publishers alike, volatile) and the node's
/// qos_overrides.<topic>.subscription.* on top, all taken through one rcl
/// wait set by a thread of their own; each message's values go to the
/// bridge as a Bottle's do. On a Node of their own (a YARP output: `rosArgs`
/// given to rcl, and the node's clock stamps the messages, the simulated
/// time with use_sim_time), or on the node of `publisher` (a ROS 2 output).
class Subscriptions : public InputFeed
{
public:
    Subscriptions(const Topics& topics, std::vector<std::string> rosArgs, Publisher* publisher = nullptr);
    ~Subscriptions() override;

    bool open(Deliver deliver) override;
    void close() override;
    bool nowNs(std::int64_t& ns) override;
    void watch(TotalsSource totals) override;
    void ros2Events(std::vector<Totals::Ros2Endpoint>& out) const override;

private:
    struct Rcl;
    void follow();
    const Topics& topics_;
    std::unique_ptr<Node> ownNode_;  // with a YARP output
    Node* node_;
    std::unique_ptr<Rcl> rcl_;
    Deliver deliver_;
};

/// Runs a bridge whose output is a YARP port and whose inputs include ROS 2
/// topics until SIGINT or SIGTERM; the exit status.
int run(const BridgeSpec& spec, const Topics& topics, int argc, char* argv[], MakeMessage make);

/// Runs a bridge that reads ROS 2 topics (besides YARP ports) and publishes
/// to ROS 2, on one node.
template <class Msg>
int run(const BridgeSpec& spec, const Ros2Spec& ros2, const MessageType& type, const Topics& topics, int argc,
        char* argv[], bool (*fill)(const Inputs&, const Context&, Msg&, std::string&))
{
    return run(spec, ros2, type, &topics, argc, argv, filling(fill));
}

}  // namespace ros2
}  // namespace ybgc

#endif  // YBGC_ROS2_HPP
