// Commands (docs/services.md): the C++ runtime of a module of [service]
// sections, between YARP RPC ports and ROS 2 services, both ways, through
// rcl (no rclcpp, no Python in the process).
//
// - A ROS 2 service served by the module (Serves::Ros2): each request
//   becomes a command Bottle (the module's buildCommand), sent to a YARP RPC
//   port; its reply fills the response (the module's fillResponse). The
//   calls to one YARP port are made one after another, in the order they
//   came, each within its own deadline (its arrival + its timeout): a call
//   that waited its whole timeout for the ones before it fails without being
//   sent. A blocking connect or write runs in a thread of its own; the call
//   is answered at its deadline whatever the server does, and a connection
//   given up on is closed, never read again.
// - A YARP RPC port served by the module (Serves::Yarp): a command whose
//   first word names a service fills the request from its arguments (the
//   module's fillRequest), calls the ROS 2 service (a response is matched to
//   its request by its sequence number, a late one dropped) and replies the
//   Bottle of the module's buildReply; `help` lists the commands.
//
// Never hang, never lie: every call ends within its timeout with the answer
// of success or the failure answer (the module's, given the reason): no
// server, no answer in time, a reply or command that does not fit. Counted
// per service, in `stats` on the module's RPC port and in the exit totals.
// The texts a caller reads are the compiler's (ybg/lower/services.py),
// printed into the module; the behaviour is the rclpy node's
// (ybg/runtime/services.py). ybgc writes this file and ybgc_services*.cpp
// beside a module of commands, with the runtime's ROS 2 side (ybgc_ros2*);
// the bridge of commands runs in the process shell every kind of bridge runs
// in, alone or among others (ybgc compose).
#ifndef YBGC_SERVICES_HPP
#define YBGC_SERVICES_HPP

#include "ybgc_ros2.hpp"  // ybgc:runtime-import

#include <rosidl_runtime_c/service_type_support_struct.h>

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/Value.h>

namespace ybgc {

/// The command's first item as a word ("" for none; a vocab as its word, a
/// number as its text).
std::string firstWord(const yarp::os::Bottle& command);

namespace services {

// --- the elements of a Bottle: a reply, or a command's arguments -------------------------

/// One item of a Bottle as a field takes it: an integer, a real, a bool, a
/// word (a string, or a vocab as its word) or anything else (a nested list,
/// a blob: never a field's value).
struct Item
{
    enum class Kind { Integer, Real, Bool, Word, Other };

    Kind kind = Kind::Other;
    std::int64_t integer = 0;  // Kind::Integer
    double real = 0.0;         // Kind::Real
    bool flag = false;         // Kind::Bool
    std::string text;          // Kind::Word: the word; Kind::Other: the item as text

    static Item of(const yarp::os::Value& v);
    bool isNumber() const { return kind == Kind::Integer || kind == Kind::Real; }
};

/// What an item is, as a reason says it: "the word ok", "the integer 3",
/// "the number 1.5", "a bool", "a list (1 2)".
std::string describe(const Item& x);

/// A converter of a service's elements: y = x * scale + offset on [start, stop).
struct Converter
{
    const char* name;
    double scale;
    double offset;
    bool toFloat;
    std::size_t start;
    std::size_t stop;  // kToEnd: to the last element
};

/// The elements of a Bottle from `start` (a reply: 0; a command's
/// arguments: 1, after its word), checked against a declaration and
/// converted (check()); what a module's functions fill fields from. Each
/// setter says why (false, `why`) when an element cannot fill its field.
class Elements
{
public:
    /// `trueWords`: the words a bool field takes for true (kept by reference).
    Elements(const yarp::os::Bottle& bottle, std::size_t start, const std::vector<const char*>& trueWords);

    /// Checks the items against the declared element types (`declared`
    /// false: each taken as it comes) and applies the converters in order;
    /// false, with why, when they do not fit.
    bool check(bool declared, const std::vector<const char*>& types, const std::vector<Converter>& converters,
               std::string& why);

    std::size_t size() const { return items_.size(); }
    const Item& operator[](std::size_t k) const { return items_[k]; }

    /// The Bottle as text (Bottle::toString): a reply whole, a command's
    /// arguments after its word.
    std::string text() const;

    /// Element k as each kind of field takes it: a number (a bool as 0 or
    /// 1), an integer (a real only when it is whole), a word, a bool (a word
    /// is true when it is one of the true words, a number when it is not 0).
    bool real(std::size_t k, double& out, std::string& why) const;
    bool integer(std::size_t k, std::int64_t& out, std::string& why) const;
    bool word(std::size_t k, std::string& out, std::string& why) const;
    bool boolean(std::size_t k, bool& out, std::string& why) const;

    /// Element k into a field of a number or bool type.
    template <class T>
    bool set(T& field, std::size_t k, std::string& why) const
    {
        static_assert(std::is_arithmetic_v<T>, "a field of a number or bool type");
        if constexpr (std::is_same_v<T, bool>) {
            return boolean(k, field, why);
        } else if constexpr (std::is_floating_point_v<T>) {
            double x = 0.0;
            if (!real(k, x, why)) {
                return false;
            }
            if (sizeof(T) < sizeof(double) && std::isfinite(x) && std::fabs(x) > static_cast<double>(FLT_MAX)) {
                why = "element " + std::to_string(k) + " is the number " + reprFloat(x) + ", beyond a float32";
                return false;
            }
            field = static_cast<T>(x);
            return true;
        } else {
            std::int64_t x = 0;
            if (!integer(k, x, why)) {
                return false;
            }
            if (!fits<T>(x)) {
                why = "element " + std::to_string(k) + " is the integer " + std::to_string(x)
                    + ", beyond the field's range";
                return false;
            }
            field = static_cast<T>(x);
            return true;
        }
    }

    /// Element k (a word) into a string field.
    bool set(rosidl_runtime_c__String& field, std::size_t k, std::string& why) const;

    /// The elements [start, stop) (stop kToEnd: to the last) into a
    /// sequence: `bound` (0: none) the most a bounded one holds; `field` its
    /// name, for why.
    template <class Seq>
    bool setRange(Seq& seq, std::size_t start, std::size_t stop, std::size_t bound, const char* field,
                  std::string& why) const
    {
        std::size_t end = 0;
        if (!range(start, stop, end, why)) {
            return false;
        }
        const std::size_t n = end - start;
        if (bound != 0 && n > bound) {
            why = std::string("field ") + field + " holds at most " + std::to_string(bound) + " values, got "
                + std::to_string(n);
            return false;
        }
        return fill(seq, start, end, why);
    }

    /// The same into a fixed-size array: exactly N elements.
    template <class T, std::size_t N>
    bool setRange(T (&array)[N], std::size_t start, std::size_t stop, std::size_t /*bound*/, const char* field,
                  std::string& why) const
    {
        std::size_t end = 0;
        if (!range(start, stop, end, why)) {
            return false;
        }
        if (end - start != N) {
            why = std::string("field ") + field + " holds exactly " + std::to_string(N) + " values, got "
                + std::to_string(end - start);
            return false;
        }
        for (std::size_t k = start; k < end; ++k) {
            if (!set(array[k - start], k, why)) {
                return false;
            }
        }
        return true;
    }

private:
    template <class T>
    static bool fits(std::int64_t x)
    {
        if constexpr (std::is_signed_v<T>) {
            return x >= static_cast<std::int64_t>(std::numeric_limits<T>::min())
                && x <= static_cast<std::int64_t>(std::numeric_limits<T>::max());
        } else {
            return x >= 0 && static_cast<std::uint64_t>(x) <= static_cast<std::uint64_t>(std::numeric_limits<T>::max());
        }
    }

    /// [start, stop) within the elements: `end` its end; false, with why, when it is not.
    bool range(std::size_t start, std::size_t stop, std::size_t& end, std::string& why) const;

    /// The elements [start, end) into a sequence, sized to them.
    template <class Seq>
    bool fill(Seq& seq, std::size_t start, std::size_t end, std::string& why) const
    {
        if (!ybgc::ros2::resize(seq, end - start)) {
            why = "cannot allocate " + std::to_string(end - start) + " values";
            return false;
        }
        for (std::size_t k = start; k < end; ++k) {
            if (!set(seq.data[k - start], k, why)) {
                return false;
            }
        }
        return true;
    }

    /// An element that is no number (a word, a list) where a number is wanted.
    std::string notA(std::size_t k, const char* what) const;
    const Item* at(std::size_t k, std::string& why) const;

    const yarp::os::Bottle& bottle_;
    std::size_t start_;
    const std::vector<const char*>& trueWords_;
    std::vector<Item> items_;
};

// --- Bottles from a message's fields ------------------------------------------------------

/// One field's value on the wire type `wire` (Wire::Int32, Int64, Float64,
/// String): an integer wraps to the width of its wire type, a bool is the
/// int32 0 or 1.
template <class T>
void put(yarp::os::Bottle& b, const T& x, Wire wire)
{
    static_assert(std::is_arithmetic_v<T>, "a field of a number or bool type");
    switch (wire) {
    case Wire::Float64:
        b.addFloat64(static_cast<double>(x));
        break;
    case Wire::Int64:
        b.addInt64(static_cast<std::int64_t>(x));
        break;
    case Wire::String:
        b.addString(std::is_floating_point_v<T> ? reprFloat(static_cast<double>(x)) : std::to_string(x));
        break;
    default:
        b.addInt32(static_cast<std::int32_t>(static_cast<std::int64_t>(x)));
        break;
    }
}

/// A string field.
void put(yarp::os::Bottle& b, const rosidl_runtime_c__String& x, Wire wire);

/// An array field, one item per element: a sequence, or a fixed-size array.
template <class Seq>
void putEach(yarp::os::Bottle& b, const Seq& seq, Wire wire)
{
    for (std::size_t k = 0; k < seq.size; ++k) {
        put(b, seq.data[k], wire);
    }
}
template <class T, std::size_t N>
void putEach(yarp::os::Bottle& b, const T (&array)[N], Wire wire)
{
    for (const T& x : array) {
        put(b, x, wire);
    }
}

/// A number field through a converter, as a float64: x * scale + offset,
/// the multiplication left out when scale is 1 and the addition when
/// offset is 0 (as the rclpy node writes the expression).
template <class T>
void putConverted(yarp::os::Bottle& b, const T& x, double scale, double offset)
{
    double y = static_cast<double>(x);
    if (scale != 1.0) {
        y = y * scale;
    }
    if (offset != 0.0) {
        y = y + offset;
    }
    b.addFloat64(y);
}

/// An array field through a converter, each element float(x) * scale + offset.
template <class Seq>
void putEachConverted(yarp::os::Bottle& b, const Seq& seq, double scale, double offset)
{
    for (std::size_t k = 0; k < seq.size; ++k) {
        b.addFloat64(static_cast<double>(seq.data[k]) * scale + offset);
    }
}
template <class T, std::size_t N>
void putEachConverted(yarp::os::Bottle& b, const T (&array)[N], double scale, double offset)
{
    for (const T& x : array) {
        b.addFloat64(static_cast<double>(x) * scale + offset);
    }
}

/// A string field's text.
std::string text(const rosidl_runtime_c__String& s);

/// A reason of ybg.lower.services with what is known at run time: `{reply}`
/// and `{why}` replaced.
std::string reasonText(const std::string& reason, const std::string& reply, const std::string& why);

// --- what a module declares -----------------------------------------------------------

/// A service's type: its type support and the C functions that create and
/// destroy a request and a response (with their definition's defaults).
struct SrvType
{
    const char* name;  // pkg/srv/Name
    const rosidl_service_type_support_t* typeSupport;
    void* (*createRequest)();
    void (*destroyRequest)(void*);
    void* (*createResponse)();
    void (*destroyResponse)(void*);
};

/// The SrvType of the C structs Req and Res, from their C functions.
template <class Req, Req* (*CreateReq)(), void (*DestroyReq)(Req*), class Res, Res* (*CreateRes)(),
          void (*DestroyRes)(Res*)>
SrvType srvType(const char* name, const rosidl_service_type_support_t* typeSupport)
{
    return {name, typeSupport, []() -> void* { return CreateReq(); },
            [](void* r) { DestroyReq(static_cast<Req*>(r)); }, []() -> void* { return CreateRes(); },
            [](void* r) { DestroyRes(static_cast<Res*>(r)); }};
}

/// Which side the module serves.
enum class Serves { Ros2, Yarp };

/// The reasons of a failed call (ybg.lower.services.reasons), `{reply}`
/// and `{why}` left to the runtime.
struct Reasons
{
    const char* noServer;
    const char* timedOut;
    const char* waited;        // serves ros2: a call that waited its whole timeout for the ones before it
    const char* unfitReply;    // "{reply}", "{why}"
    const char* badArguments;  // serves yarp: "{why}"
};

/// One [service] section: what it serves and calls.
struct Spec
{
    const char* name;     // the section's name: the command word (serves yarp)
    Serves serves;
    const char* service;  // the ROS 2 service served (Serves::Ros2) or called
    const char* port;     // the YARP RPC port called (Serves::Ros2) or served
    double timeout;       // seconds, from a call's arrival
    bool declared;        // the reply's (serves ros2) or arguments' (serves yarp) elements are declared
    std::vector<const char*> types;  // their types, one an element
    std::vector<Converter> converters;
    std::vector<const char*> trueWords;
    Reasons reasons;
    const char* description;  // the start-up line
};

/// The module's functions of one service, on its C structs (void*: the
/// request and response of its SrvType).
struct Functions
{
    // serves ros2: the command Bottle of a request; the response from the
    // reply's elements (false, with why, when one does not fit); the failure
    // answer (a fresh response) given the reason
    void (*command)(const void* request, yarp::os::Bottle& command) = nullptr;
    bool (*response)(const Elements& reply, void* response, std::string& why) = nullptr;
    void (*failedResponse)(const std::string& reason, void* response) = nullptr;
    // serves yarp: the request from the arguments' elements (false, with
    // why, when one does not fit); the reply Bottle of a response; the
    // failure reply (`response` a fresh one) given the reason
    bool (*request)(const Elements& args, void* request, std::string& why) = nullptr;
    void (*reply)(const void* response, yarp::os::Bottle& reply) = nullptr;
    void (*failedReply)(const void* response, const std::string& reason, yarp::os::Bottle& reply) = nullptr;
};

/// The functions of a ROS 2 service served by the module, on its C structs.
template <class Req, class Res, void (*Command)(const Req&, yarp::os::Bottle&),
          bool (*Fill)(const Elements&, Res&, std::string&), void (*Failure)(const std::string&, Res&)>
Functions servesRos2()
{
    Functions f;
    f.command = [](const void* r, yarp::os::Bottle& b) { Command(*static_cast<const Req*>(r), b); };
    f.response = [](const Elements& e, void* r, std::string& why) { return Fill(e, *static_cast<Res*>(r), why); };
    f.failedResponse = [](const std::string& reason, void* r) { Failure(reason, *static_cast<Res*>(r)); };
    return f;
}

/// The functions of a command on a YARP port served by the module.
template <class Req, class Res, bool (*Fill)(const Elements&, Req&, std::string&),
          void (*Reply)(const Res&, yarp::os::Bottle&), void (*Failure)(const Res&, const std::string&, yarp::os::Bottle&)>
Functions servesYarp()
{
    Functions f;
    f.request = [](const Elements& e, void* r, std::string& why) { return Fill(e, *static_cast<Req*>(r), why); };
    f.reply = [](const void* r, yarp::os::Bottle& b) { Reply(*static_cast<const Res*>(r), b); };
    f.failedReply = [](const void* r, const std::string& reason, yarp::os::Bottle& b) {
        Failure(*static_cast<const Res*>(r), reason, b);
    };
    return f;
}

/// One service of the module: its section, its type, its functions.
struct Service
{
    Spec spec;
    SrvType type;
    Functions functions;
};

/// A YARP RPC port the module serves, and what `help` answers there (after
/// the vocab `many`).
struct PortHelp
{
    const char* port;
    std::vector<const char*> help;
};

/// The module: its services, the ports it serves.
struct Commands
{
    const char* module;
    const char* config;
    const char* node;           // the ROS 2 node's name
    const char* defaultPrefix;  // of its own ports: its RPC port <prefix>/rpc:i, its clients <prefix>/<service>/rpc:o
    std::vector<const char*> description;  // --help
    std::vector<Service> services;
    std::vector<PortHelp> ports;
    const char* unknownCommand;  // the reason of a command no service names ("{word}": its word)
};

// --- counts ------------------------------------------------------------------------------

/// Why a call failed, as it is counted.
enum class Failure { None, TimedOut, NoServer, Unfit };

/// What one service did (read and changed under the module's lock).
struct Counts
{
    std::uint64_t calls = 0;
    std::uint64_t answered = 0;
    std::uint64_t timedOut = 0;
    std::uint64_t noServer = 0;
    std::uint64_t unfit = 0;
    bool lastFailed = false;  // its last call failed: why in `last`
    std::string last;

    std::uint64_t failed() const { return timedOut + noServer + unfit; }
    /// One call ended: answered (Failure::None) or failed, `why`.
    void count(Failure failure, const std::string& why = "");
};

/// A service's line of the exit totals (ybg.lower.services.TOTALS_LINE).
std::string totalsLine(const char* name, const Counts& c);

/// A service's list of `stats`: (service NAME calls N answered N failed N
/// timed_out N no_server N unfit N).
void addStats(yarp::os::Bottle& reply, const char* name, const Counts& c);

/// The status of a service on /diagnostics, as the rclpy node says it:
/// `<node>: service <name>`, OK until a call fails ("no call yet",
/// "answered its last call"), WARN while its last call failed ("its last
/// call failed: <why>"); its counts and its timeout as values.
ybgc::ros2::Status status(const Spec& spec, const Counts& c, const std::string& node);

/// What `help` answers on the module's RPC port (when no served port is it).
extern const char* const kRpcHelp[3];

/// The command's first item as a word ("" for none; a number as its text):
/// the process shell's (ybgc_shell.cpp).
using ybgc::firstWord;

// --- running it ----------------------------------------------------------------------------

/// Parses the command line (--name, --verbose, --help, the ROS arguments
/// after --ros-args) and runs the module until SIGINT, SIGTERM or `quit`;
/// the exit status (0 when stopped, 1 when something could not open, 2 for
/// a bad option).
int run(const Commands& spec, int argc, char* argv[]);

}  // namespace services
}  // namespace ybgc

#endif  // YBGC_SERVICES_HPP
