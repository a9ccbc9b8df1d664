// The runtime library of the C++ modules ybgc generates (docs/runtime.md):
// what a module's own code uses. A module holds its spec tables (BridgeSpec),
// its gather/compute/buildMessage functions and main(), which calls run().
// The behaviour is plain code with its own tests (tests/runtime/), one
// concern a file: ybgc_runtime.cpp (run(): the loop, timing, start-up and
// shutdown), ybgc_inputs.cpp (the input ports, freshness, matching),
// ybgc_bottles.cpp (Bottles written and checked, the YARP output),
// ybgc_connections.cpp, ybgc_convert.cpp (converters), ybgc_totals.cpp
// (messages, the RPC port), ybgc_options.cpp (the command line); what they
// share is in ybgc_internal.hpp. ybgc writes these files beside each module
// it generates, or inlines them into it with --single-file.
#ifndef YBGC_RUNTIME_HPP
#define YBGC_RUNTIME_HPP

/// The version of this runtime: a module generated for another one refuses
/// to build (its #error says so).
#define YBGC_RUNTIME_VERSION "0.2.0"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <functional>
#include <initializer_list>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/Contact.h>
#include <yarp/os/Value.h>

namespace yarp {
namespace sig {
class FlexImage;
}  // namespace sig
}  // namespace yarp

namespace ybgc {

using SteadyClock = std::chrono::steady_clock;

// --- messages to the user ---------------------------------------------------

/// Name printed in front of every message ("<module>: ...").
extern const char* gModule;

/// The name this thread prints instead of gModule (nullptr: gModule): in a
/// process of several bridges (ybgc compose), every thread of a bridge (its
/// loop, its ports' callbacks, its watcher, its ROS 2 threads) says its
/// bridge's module name.
extern thread_local const char* tModule;

/// Prints "<module>: <text>" on stdout, at once (the module: tModule, else gModule).
void say(const std::string& text);

/// Prints lines as they are (totals, verbose values).
void printLines(const std::string& text);

/// A float written as Python's repr() writes it: the shortest digits that
/// read back exactly, "1.0", "0.0001", "1e-05", "1e+16", "nan", "-inf".
std::string reprFloat(double x);

/// A time of `t` seconds (finite) as integer nanoseconds, to the nanosecond:
/// the whole seconds apart from the fraction (t * 1e9 alone is a double of
/// today's epoch, whose step is 256 ns); as the Python runtime's seconds_to_ns.
std::int64_t secondsToNs(double t);

// --- mux elements -------------------------------------------------------------

/// One element of a mux: a real number, an integer, a bool or a string.
struct Element
{
    enum class Kind { Real, Integer, Boolean, Text };

    Kind kind = Kind::Real;
    double real = 0.0;          // Kind::Real
    std::int64_t integer = 0;   // Kind::Integer, Kind::Boolean (0 or 1)
    std::string text;           // Kind::Text

    static Element ofReal(double x)
    {
        Element e;
        e.real = x;
        return e;
    }
    static Element ofInteger(std::int64_t x)
    {
        Element e;
        e.kind = Kind::Integer;
        e.integer = x;
        return e;
    }
    static Element ofBool(bool x)
    {
        Element e;
        e.kind = Kind::Boolean;
        e.integer = x ? 1 : 0;
        return e;
    }
    static Element ofText(std::string x)
    {
        Element e;
        e.kind = Kind::Text;
        e.text = std::move(x);
        return e;
    }

    bool isNumber() const { return kind != Kind::Text; }

    /// The value as a double (0 for a string).
    double asReal() const
    {
        return kind == Kind::Real ? real : (kind == Kind::Text ? 0.0 : static_cast<double>(integer));
    }

    /// The value as an integer: a real is truncated (NaN gives 0, and the
    /// value saturates at the limits of int64).
    std::int64_t asInteger() const
    {
        if (kind != Kind::Real) {
            return kind == Kind::Text ? 0 : integer;
        }
        if (std::isnan(real)) {
            return 0;
        }
        if (real >= 9223372036854775807.0) {
            return std::numeric_limits<std::int64_t>::max();
        }
        if (real <= -9223372036854775808.0) {
            return std::numeric_limits<std::int64_t>::min();
        }
        return static_cast<std::int64_t>(real);
    }

    /// The value as text, as Python's repr() prints it.
    std::string repr() const
    {
        switch (kind) {
        case Kind::Real:
            return reprFloat(real);
        case Kind::Integer:
            return std::to_string(integer);
        case Kind::Boolean:
            return integer != 0 ? "True" : "False";
        case Kind::Text:
            break;
        }
        std::string out = "'";
        for (char c : text) {
            if (c == '\'' || c == '\\') {
                out += '\\';
            }
            out += c;
        }
        return out + "'";
    }

    /// The value as the text of a string field.
    std::string str() const
    {
        return kind == Kind::Text ? text : repr();
    }
};

/// A mux: the elements of its inputs, in input order, then converted.
using Mux = std::vector<Element>;

/// A mux of rows: one row for each element of an array of messages (a ROS 2
/// input with `each`), each row converted alike.
using Rows = std::vector<Mux>;

/// A camera frame: a YARP image of any pixel type, never changed once read
/// (shared by the messages that use it, not copied). The mux of a camera
/// image input holds its frame; the image side of the runtime
/// (ybgc_images.hpp, beside a module that reads or writes images) reads,
/// fills and writes them.
using Frame = std::shared_ptr<const yarp::sig::FlexImage>;

/// "Up to the end" for a range of mux elements.
constexpr std::size_t kToEnd = std::numeric_limits<std::size_t>::max();

/// A converter: y = x * scale + offset on the elements [start, stop) of a mux.
/// A string element is left as it is; an integer stays an integer (truncated)
/// unless toFloat.
void convert(Mux& mux, double scale, double offset, bool toFloat, std::size_t start, std::size_t stop);

/// Prints every element of a mux: "[<mux>] <index>: <value>".
void printMux(const char* name, const Mux& mux);
/// Prints every row of a mux of rows: "[<mux>] <index>: [<value>, ...]".
void printMux(const char* name, const Rows& rows);

// --- orientation and geometry converters, element-wise expressions ------------
// The same operations in the same order as ybg/runtime/geometry.py, so that
// C++ and Python modules give the same bits (the module is built with
// -ffp-contract=off). Quaternions are x y z w, as ROS orders them.

/// A geometry converter (docs/config.md, "Converters").
enum class Geometry
{
    EulerToQuat,      ///< 3 Euler angles about fixed axes -> quaternion (4)
    QuatToEuler,      ///< quaternion -> 3 Euler angles about fixed axes
    AxisAngleToQuat,  ///< iCub's ax ay az theta (radians) -> quaternion
    QuatToAxisAngle,  ///< quaternion -> unit axis and angle in [0, pi]
    MatrixToQuat,     ///< 3x3 rotation matrix, row-major (9) -> quaternion
    TransformToPose,  ///< 4x4 homogeneous transform, row-major (16) -> x y z, quaternion (7)
    QuatNormalize,    ///< quaternion -> quaternion / its norm
};

/// Elements a geometry converter takes and gives.
std::size_t geometryWidthIn(Geometry g);
std::size_t geometryWidthOut(Geometry g);

/// A geometry converter on plain values (``in`` has geometryWidthIn(g)
/// values). ``axes``: the Euler axis order about fixed axes, "xyz" (ROS's
/// rpy: R = Rz(yaw) Ry(pitch) Rx(roll)) or another order of x, y, z;
/// ``degrees``: Euler angles in degrees. A result that is not finite is all NaN.
std::vector<double> geometry(Geometry g, const std::vector<double>& in, const char* axes = "xyz",
                             bool degrees = false);

/// Applies a geometry converter to the elements [start, start + width in) of
/// a mux: they are replaced by its results (float64). A mux too short for
/// the range is left as it is.
void convertGeometry(Mux& mux, Geometry g, std::size_t start, const char* axes, bool degrees);

/// An element-wise expression: each number x of [start, stop) becomes
/// f(x), a float64; strings are left as they are.
void convertEach(Mux& mux, double (*f)(double), std::size_t start, std::size_t stop);

/// The functions of expressions that C++ does not have as such:
/// min and max as std::min and std::max, clamp(x, lo, hi) = min(max(x, lo), hi).
double minOf(double a, double b);
double maxOf(double a, double b);
double clamp(double x, double lo, double hi);

// --- writing Bottles ------------------------------------------------------------

/// How a value travels in the output Bottle (the Bottle tag).
/// `Number`: an undeclared port's element, as it came (an integer as int32,
/// or int64 beyond int32's range; a real as float64).
enum class Wire { Int8, Int16, Int32, Int64, Float32, Float64, String, Number };

/// Appends an integer with the given tag (truncated to its width).
void putInteger(yarp::os::Bottle& b, std::int64_t x, Wire wire);
/// Appends one element with the given tag.
void put(yarp::os::Bottle& b, const Element& e, Wire wire);
/// Appends the elements [start, stop) of a mux, each with the given tag.
void putRange(yarp::os::Bottle& b, const Mux& mux, std::size_t start, std::size_t stop, Wire wire);
/// Appends a time as a nested list (sec, nsec) with the given tags.
void putTime(yarp::os::Bottle& b, std::int64_t ns, Wire secWire, Wire nsecWire);
/// Appends each row of a mux of rows as a nested list, each element with the given tag.
void putRows(yarp::os::Bottle& b, const Rows& rows, Wire wire);

// --- the bridge's description (filled in by namespace bridge) --------------------

/// `count` consecutive elements of one type in an input Bottle
/// ("float64", "int32", "bool", "string" ...).
struct Group
{
    const char* type;
    int count;
};

/// Where one element (or one array of elements) is in a ROS 1 message read
/// as a Bottle: `name` is the field's path, `at` the index at each level.
struct FieldPath
{
    const char* name;
    std::vector<int> at;
};

/// Where an input is read: a YARP port, a ROS 1 topic through YARP, or a
/// ROS 2 topic (its values delivered by an InputFeed: ybgc_ros2.hpp).
enum class InputKind { Yarp, Ros1, Ros2 };

/// One input of a mux.
struct InputSpec
{
    int mux;                        // index of its mux in BridgeSpec::muxes
    int index;                      // its position in the mux
    const char* source;             // the YARP port, or the ROS topic, read
    InputKind kind;
    double timeout;                 // freshness timeout, seconds
    bool declared;                  // false: any number of numbers, each a float64
    std::vector<Group> layout;      // the declared elements
    std::vector<FieldPath> fields;  // ROS 1 topic: the fields read (empty: every leaf)
    int reads = -1;                 // undeclared port cut by the message (W511): the values
                                    // it reads; a wider Bottle is said once (-1: no cut)
    std::vector<const char*> accepts = {};  // YARP port: other ports whose Bottles it takes too
    /// A camera image input: its frames' encoding ("rgb8", "mono16", "32FC1" ...; "any": each
    /// frame's own, a ROS 2 sensor_msgs/Image topic); a YARP port's frame of another pixel type is
    /// refused (refuseFrame). nullptr: Bottles (or a ROS 2 message's values).
    const char* image = nullptr;
};

struct MuxSpec
{
    const char* name;
};

enum class OutputKind { Yarp, Ros1, Ros2 };

struct OutputSpec
{
    OutputKind kind;
    const char* port;        // the port opened (topic@node for ROS 1; the topic for ROS 2)
    const char* msgType;     // ROS type promised on the port ("" for none)
    const char* connectTo;   // a port to keep connected to ("" for none)
    /// ROS 1 only, for a message holding an array of messages (which YARP's
    /// Bottle translation cannot express): the message is sent serialized,
    /// ros1Bytes(message, ros1Shape), as the one blob of a Bottle ("": the
    /// Bottle itself, translated by YARP).
    const char* ros1Shape = "";
};

/// The ROS 1 serialization of a message built as a Bottle laid out like its
/// definition: each item by its tag (int8..int64, float32, float64 little
/// endian; a string with its length), each nested list by the next letter of
/// ``shape`` (depth first): 's' a sequence, written with its length, 'f' a
/// nested message, a time or a fixed-size array, written without. False when
/// the Bottle and the shape disagree.
bool ros1Bytes(const yarp::os::Bottle& msg, const char* shape, std::string& out);

struct BridgeSpec
{
    const char* module;
    const char* config;
    std::vector<const char*> description;
    const char* defaultPrefix;
    std::vector<MuxSpec> muxes;
    std::vector<InputSpec> inputs;
    std::vector<int> needed;  // the muxes the message reads (their inputs gate publishing)
    OutputSpec output;
    double rate;              // Hz; 0 = event-driven
    bool triggerAll;          // event-driven: every needed input has new data (else any)
    std::size_t queue;        // unused Bottles kept per input (1: the newest, read non-strictly)
    bool hold;                // on_stale = hold (else skip)
    bool dropNan;             // on_nan = drop (else pass)
    bool newOnly = false;     // publish = new: a cycle of a fixed rate publishes new data only
};

// --- reading and checking input Bottles -------------------------------------------

/// The accepted values of one input that a message uses.
struct Latest
{
    Mux values;
    Rows rows;  // an input read from an array of messages: its rows (values empty)
    Frame frame;  // a camera image input: its frame (values empty)
    bool hasEnvelope = false;
    double envelope = 0.0;  // envelope time stamp, seconds
};

/// An accepted Bottle that no message has used yet.
struct Pending
{
    Latest data;
    SteadyClock::time_point arrival;
};

/// Unread Bottles a port may hold before the oldest are skipped unread (a
/// reader that fell this far behind catches up instead of lagging).
constexpr int kBacklog = 64;

/// The values a message uses, of every input in BridgeSpec::inputs order;
/// read while the inputs are locked (a message is built with the lock held).
class Inputs
{
public:
    const Latest& operator[](std::size_t k) const { return *latest_[k]; }
    std::size_t size() const { return latest_.size(); }
    void add(const Latest& latest) { latest_.push_back(&latest); }

private:
    std::vector<const Latest*> latest_;
};

/// Appends the values of one input to a mux.
void append(Mux& mux, const Latest& input);
/// Appends the rows of one input to a mux of rows.
void append(Rows& rows, const Latest& input);
/// The frame of a camera image input, as its mux's (shared, not copied).
inline void append(Frame& frame, const Latest& input)
{
    frame = input.frame;
}

/// Checks an input Bottle against the input's layout. On success `out`
/// holds its values; else `why` says what is wrong. `in` is scratch space.
bool parseBottle(const yarp::os::Bottle& b, const InputSpec& spec, bool dropNan, Mux& out, std::string& why,
                 std::vector<const yarp::os::Value*>& in);

/// Checks the values read from a message of another middleware (a ROS 2
/// topic: numbers, a time as seconds) against the input's layout, as
/// parseBottle checks a Bottle: undeclared, every value a number, each made
/// a float64; declared, the declared number of values, a real for a float
/// type, an integer for an integer type, a bool or 0/1 for a bool. The
/// values are converted in place; else `why` says what is wrong.
bool checkValues(Mux& values, const InputSpec& spec, bool dropNan, std::string& why);

// --- what is kept of each input, and which Bottles a message uses --------------

enum class Freshness { Waiting, Fresh, Stale };

/// What the bridge keeps of one input: the Bottles no message used yet, the
/// values messages use, its freshness and its totals. Guarded by the
/// bridge's lock (the totals are atomic: they are printed without it).
struct InputState
{
    InputState(const InputSpec& spec, double timeout) : spec(spec), timeout(timeout) {}
    InputState(const InputState&) = delete;
    InputState& operator=(const InputState&) = delete;
    virtual ~InputState() = default;

    /// Fresh now: its last Bottle arrived less than `timeout` ago.
    bool isFresh(SteadyClock::time_point now) const
    {
        return state != Freshness::Waiting && std::chrono::duration<double>(now - arrival).count() < timeout;
    }

    const InputSpec& spec;
    const double timeout;               // freshness timeout, seconds
    std::deque<Pending> queue;          // accepted, not used yet (oldest first)
    Latest latest;                      // what messages use (hasLatest: there is one)
    bool hasLatest = false;
    Mux spare;                          // the room of values no longer used, for the next Bottle (accept)
    SteadyClock::time_point arrival;    // of the newest accepted Bottle
    std::atomic<std::uint64_t> received{0};
    std::atomic<std::uint64_t> dropped{0};
    std::atomic<std::uint64_t> unused{0};        // accepted (or skipped unread), never in a message
    std::atomic<std::uint64_t> stalePeriods{0};
    std::atomic<std::uint64_t> refused{0};       // Bottles of another port than those it accepts, and unfit frames
    std::atomic<std::uint64_t> unfit{0};         // camera frames refused for what they are (of `refused`)
    std::string unfitReason;                     // why the first of them was refused (said once)
    std::vector<std::string> accepted;           // the ports whose Bottles it takes: its source, those accepted
    std::vector<std::string> foreign;            // the other ports that sent to it, in order (each said once)
    Freshness state = Freshness::Waiting;
    bool reportedWaiting = false;
    bool reportedDrop = false;
    bool reportedCut = false;
};

/// A Bottle the input accepted, its values moved out of `values` (which
/// gets the room of values no longer used, InputState::spare): queued
/// (at most `queue` kept: the oldest is then unused), the input fresh (said
/// when it was stale; a Bottle wider than InputSpec::reads is said once).
/// True when the input was fresh before it.
bool accept(InputState& in, Mux& values, bool hasEnvelope, double envelope, SteadyClock::time_point arrival,
            std::size_t queue);

/// A Bottle the input refused (`why`): counted, said the first time only.
void refuse(InputState& in, const std::string& why);

/// A camera frame of the input's own port refused for what it is (`why`: a
/// pixel type other than the declared one, an encoding YARP has no pixel type
/// for): counted as refused, never used; said the first time only.
void refuseFrame(InputState& in, const std::string& why);

/// What the exit totals say of an input's refused messages ("" for none):
/// of which ports, and how many frames refused for what they are (the
/// first reason), as the Python runtime says it.
std::string refusedText(const InputState& in);

/// Does the input take the Bottles of port `name` (its source, or one it accepts)?
bool accepts(const InputState& in, const std::string& name);

/// A Bottle (`bottle`), or a connection, of port `other`, which the input
/// does not accept: never used; the Bottle counted; said once per port with
/// both names. True the first time `other` is seen.
bool refuseForeign(InputState& in, const std::string& other, bool bottle);

/// What is said, once per port, when another port than an input's own (or
/// those it accepts) is connected to it.
std::string foreignText(const std::string& source, const std::string& other);

/// What is said, once, when a Bottle of an undeclared port brings more values
/// (`width`) than the message reads (`reads`, InputSpec::reads).
std::string cutText(const std::string& source, std::size_t width, std::size_t reads);

/// Which Bottles each message uses and when an input goes stale
/// (docs/runtime.md, "Which Bottles a message uses", "Freshness"): plain
/// logic on the inputs' state, with no port; the caller holds the lock.
class Matcher
{
public:
    /// `inputs` in BridgeSpec::inputs order; `eventDriven`: no fixed rate.
    Matcher(const BridgeSpec& spec, std::vector<InputState*> inputs, bool eventDriven);

    /// Says each freshness transition once; returns the next time an input
    /// would go stale (or SteadyClock::time_point::max()).
    SteadyClock::time_point checkFreshness(SteadyClock::time_point now);

    /// Every needed input fresh (on_stale = skip) or delivered once (hold);
    /// event-driven (or at a fixed rate with publish = new), also the
    /// trigger: every (all) or one (any) needed input has a Bottle that no
    /// message used yet.
    bool ready(SteadyClock::time_point now, bool eventDriven) const;

    /// Moves the Bottles the next message uses from the queues.
    void take();

    /// The values messages use, of every input in BridgeSpec::inputs order.
    const Inputs& latest() const { return latest_; }

private:
    static double when(const Pending& p, bool byEnvelope);
    static std::size_t nearest(const InputState& in, double reference, bool byEnvelope);
    static void use(InputState& in, std::size_t k);

    const BridgeSpec& spec_;
    std::vector<InputState*> inputs_;
    std::vector<InputState*> needed_;
    std::vector<InputState*> sampled_;  // newest Bottle each message: all at a fixed rate, else those not needed
    const bool eventDriven_;
    Inputs latest_;
};

// --- the loop ---------------------------------------------------------------------------------

/// What the message builder sees besides the muxes.
struct Context
{
    std::uint64_t counter = 0;    // messages published before this one
    std::int64_t wallNs = 0;      // the clock, nanoseconds since the epoch (a ROS 2 node's: simulated with use_sim_time)
    double seconds = 0.0;         // the same, in seconds
    bool verbose = false;         // --verbose: print every mux
    const Inputs* inputs = nullptr;

    /// The newest envelope stamp of the given inputs, in nanoseconds (the
    /// clock if none of them has one).
    std::int64_t envelopeNs(std::initializer_list<int> which) const
    {
        bool found = false;
        double newest = 0.0;
        for (int i : which) {
            const Latest& in = (*inputs)[static_cast<std::size_t>(i)];
            if (in.hasEnvelope && (!found || in.envelope > newest)) {
                newest = in.envelope;
                found = true;
            }
        }
        return found && std::isfinite(newest) ? secondsToNs(newest) : wallNs;
    }
};

/// The totals as they stand, read under the bridge's lock: what `stats`
/// answers on the RPC port and a ROS 2 node publishes on /diagnostics.
struct Totals
{
    struct PerInput
    {
        std::string source;
        std::uint64_t received, dropped, stale, unused;
        std::uint64_t refused = 0;  // Bottles of other ports
        std::vector<std::string> foreign = {};  // those ports
        Freshness state = Freshness::Waiting;
        double age = -1.0;      // seconds since its newest accepted Bottle (< 0: none yet)
        double timeout = 0.0;   // its freshness timeout, seconds
    };
    std::vector<PerInput> inputs;
    /// The incompatible peers of one ROS 2 publisher or subscription (ybgc_ros2.hpp).
    struct Ros2Endpoint
    {
        std::string kind;         // "publisher" or "subscription"
        std::string topic;        // as the config names it
        std::uint64_t qos = 0;    // peers of an incompatible QoS
        std::uint64_t type = 0;   // peers of its type's name and another definition
    };
    std::vector<Ros2Endpoint> ros2;  // its publishers, then its subscriptions
    std::string module;         // the module's name
    std::string output;         // the output's topic or port
    double rate = 0.0;          // the configured rate, Hz (0: event-driven)
    std::uint64_t published = 0;
    std::uint64_t skipped = 0;
    std::uint64_t failures = 0;
    std::uint64_t missed = 0;   // messages a YARP reader missed (MessageSink::missed())
};

/// The bridge's totals, read when called (under its lock: never call it
/// holding the lock).
using TotalsSource = std::function<Totals()>;

/// Builds one message into `msg` from the newest input values; false (with
/// the mux sizes in `failure`) when a mux is too short for the message.
using MakeMessage = std::function<bool(const Inputs&, const Context&, yarp::os::Bottle& msg, std::string& failure)>;

/// Where the bridge publishes: a YARP port (a Bottle built by MakeMessage),
/// or another middleware (ybgc_ros2.hpp: a ROS 2 topic through rcl).
class MessageSink
{
public:
    virtual ~MessageSink() = default;
    /// Opens it (after the inputs); false, said, when it cannot.
    virtual bool open() = 0;
    /// What it publishes and where, for the start-up line.
    virtual std::string describe() const = 0;
    /// The time messages are stamped with, nanoseconds since the epoch.
    virtual std::int64_t nowNs() = 0;
    /// Builds one message from the newest input values and publishes it;
    /// false, with the reason in `failure` (tooShort() of the mux sizes when a
    /// mux is too short for it), when it cannot be built.
    virtual bool publish(const Inputs& in, const Context& ctx, std::string& failure) = 0;
    virtual void close() = 0;
    /// Its name in the YARP name server ("" for none).
    virtual std::string registered() const { return ""; }
    /// Its YARP port's contact, to register again with a restarted name
    /// server (an invalid Contact for none).
    virtual yarp::os::Contact where() const { return yarp::os::Contact(); }
    /// Called once it is open and the bridge runs, with the bridge's totals:
    /// a sink with a ROS 2 node publishes them on /diagnostics until closed.
    virtual void watch(TotalsSource /*totals*/) {}
    /// Appends the incompatible peers of its ROS 2 publishers (none: nothing).
    virtual void ros2Events(std::vector<Totals::Ros2Endpoint>& /*out*/) const {}
    /// The messages a reader of its YARP port missed: written while the
    /// reader's connection was still sending the one before, which YARP
    /// then skips for that connection (0 for a sink of no YARP port).
    virtual std::uint64_t missed() const { return 0; }
};

/// Why a message cannot be built when a mux is shorter than it (`sizes`: each
/// mux's size, as the module's makeMessage() gives them).
std::string tooShort(const std::string& sizes);

/// What was read of one message of an input read outside YARP.
struct Reading
{
    Mux values;
    Rows rows;             // read from an array of messages: one row an element
    bool isRows = false;
    Frame frame;           // a camera image (InputSpec::image)
    std::string refused;   // not empty: why the message is refused (an image YARP has no pixel type for)
    bool hasEnvelope = false;
    double envelope = 0.0;  // seconds
};

/// Hands one message's Reading to the bridge (its contents are moved out):
/// `input` its index in BridgeSpec::inputs.
using Deliver = std::function<void(std::size_t input, Reading& reading)>;

/// The inputs of a bridge that are read by another middleware
/// (InputKind::Ros2: ybgc_ros2.hpp's Subscriptions): opened after the
/// output, closed before it; each message read goes through `deliver`, from
/// a thread of the feed's own, into the same checks, freshness and matching
/// as a Bottle.
class InputFeed
{
public:
    virtual ~InputFeed() = default;
    /// Opens it; false, said, when it cannot.
    virtual bool open(Deliver deliver) = 0;
    /// Stops delivering (returns once no delivery runs) and closes it.
    virtual void close() = 0;
    /// Its clock, nanoseconds since the epoch, when the messages are stamped
    /// by it rather than by the output's (a ROS 2 node's, which keeps the
    /// simulated time with use_sim_time); false when they are not.
    virtual bool nowNs(std::int64_t& /*ns*/) { return false; }
    /// As MessageSink::watch: a feed with a ROS 2 node of its own publishes
    /// the totals on /diagnostics until closed.
    virtual void watch(TotalsSource /*totals*/) {}
    /// Appends the incompatible peers of its ROS 2 subscriptions (none: nothing).
    virtual void ros2Events(std::vector<Totals::Ros2Endpoint>& /*out*/) const {}
};

class FramePort;
class Input;

/// Makes the port of a YARP camera image input (InputSpec::image): given by
/// a module that reads images (ybgc_images.hpp), whose frames it hands to the
/// input as Bottles are handed; nullptr in every other module.
using FramePorts = std::unique_ptr<FramePort> (*)(Input& input);

/// Parses the command line and runs the bridge until SIGINT or SIGTERM; the
/// exit status. `feed`: its inputs that are not YARP ports (none: nullptr).
int run(const BridgeSpec& spec, int argc, char* argv[], MakeMessage make, InputFeed* feed = nullptr);

/// The same with the messages published through `sink`; `frames`: the ports
/// of its YARP camera image inputs.
int run(const BridgeSpec& spec, int argc, char* argv[], MessageSink& sink, InputFeed* feed = nullptr,
        FramePorts frames = nullptr);

}  // namespace ybgc

#endif  // YBGC_RUNTIME_HPP
