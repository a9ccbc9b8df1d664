// The runtime of a module of commands (ybgc_services.hpp): a Bottle's
// elements checked, converted and put into fields; Bottles from fields;
// the counts; and run(): the rcl node with its services and clients, the
// YARP RPC ports served and called, the module's RPC port, SIGINT and
// SIGTERM, the exit totals.
#include "ybgc_services.hpp"  // ybgc:runtime-import

#include <diagnostic_msgs/msg/diagnostic_array.h>
#include <diagnostic_msgs/msg/diagnostic_status.h>
#include <diagnostic_msgs/msg/key_value.h>
#include <rcl/client.h>
#include <rcl/error_handling.h>
#include <rcl/graph.h>
#include <rcl/publisher.h>
#include <rcl/rcl.h>
#include <rcl/service.h>
#include <rcl/wait.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <new>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <pthread.h>
#include <signal.h>

#include <yarp/os/Bottle.h>
#include <yarp/os/ConnectionReader.h>
#include <yarp/os/ConnectionWriter.h>
#include <yarp/os/ContactStyle.h>
#include <yarp/os/Network.h>
#include <yarp/os/Port.h>
#include <yarp/os/PortReader.h>
#include <yarp/os/RpcServer.h>
#include <yarp/os/Vocab.h>

namespace ybgc {
namespace services {

// --- the elements of a Bottle -------------------------------------------------------------

Item Item::of(const yarp::os::Value& v)
{
    Item x;
    if (v.isList()) {
        x.text = "(" + v.asList()->toString() + ")";
    } else if (v.isString()) {
        x.kind = Kind::Word;
        x.text = v.asString();
    } else if (v.isVocab32()) {
        x.kind = Kind::Word;
        x.text = yarp::os::Vocab32::decode(v.asVocab32());
    } else if (v.isFloat64() || v.isFloat32()) {
        x.kind = Kind::Real;
        x.real = v.asFloat64();
    } else if (v.isInt32() || v.isInt64() || v.isInt8() || v.isInt16()) {
        x.kind = Kind::Integer;
        x.integer = v.asInt64();
    } else if (v.isBool()) {
        x.kind = Kind::Bool;
        x.flag = v.asBool();
    } else {
        x.text = v.toString();
    }
    return x;
}

std::string describe(const Item& x)
{
    switch (x.kind) {
    case Item::Kind::Word:
        return "the word " + x.text;
    case Item::Kind::Bool:
        return "a bool";
    case Item::Kind::Integer:
        return "the integer " + std::to_string(x.integer);
    case Item::Kind::Real:
        return "the number " + reprFloat(x.real);
    case Item::Kind::Other:
        break;
    }
    return "a list " + x.text;
}

Elements::Elements(const yarp::os::Bottle& bottle, std::size_t start, const std::vector<const char*>& trueWords) :
        bottle_(bottle), start_(start), trueWords_(trueWords)
{
    for (std::size_t k = start; k < bottle.size(); ++k) {
        items_.push_back(Item::of(bottle.get(k)));
    }
}

namespace {

bool oneOf(const char* type, std::initializer_list<const char*> names)
{
    for (const char* n : names) {
        if (std::strcmp(type, n) == 0) {
            return true;
        }
    }
    return false;
}

const std::initializer_list<const char*> kFloatTypes = {"float32", "float64"};
const std::initializer_list<const char*> kIntTypes = {"int8", "uint8", "int16", "uint16", "int32", "uint32",
                                                      "int64", "uint64", "byte", "char"};

}  // namespace

bool Elements::check(bool declared, const std::vector<const char*>& types, const std::vector<Converter>& converters,
                     std::string& why)
{
    if (declared) {
        if (items_.size() != types.size()) {
            why = std::to_string(items_.size()) + (items_.size() == 1 ? " element" : " elements") + ", expected "
                + std::to_string(types.size());
            return false;
        }
        for (std::size_t k = 0; k < items_.size(); ++k) {
            Item& x = items_[k];
            const char* t = types[k];
            const std::string at = "element " + std::to_string(k) + " is ";
            if (oneOf(t, kFloatTypes)) {
                if (!x.isNumber()) {
                    why = at + describe(x) + ", expected " + t;
                    return false;
                }
                if (x.kind == Item::Kind::Integer) {
                    x.kind = Item::Kind::Real;
                    x.real = static_cast<double>(x.integer);
                }
            } else if (oneOf(t, kIntTypes)) {
                if (x.kind != Item::Kind::Integer) {
                    why = at + describe(x) + ", expected " + t;
                    return false;
                }
            } else if (std::strcmp(t, "string") == 0) {
                if (x.kind != Item::Kind::Word) {
                    why = at + describe(x) + ", expected a string";
                    return false;
                }
            } else if (std::strcmp(t, "bool") == 0) {
                if (x.kind == Item::Kind::Integer && (x.integer == 0 || x.integer == 1)) {
                    x.kind = Item::Kind::Bool;
                    x.flag = x.integer == 1;
                } else if (x.kind != Item::Kind::Bool) {
                    why = at + describe(x) + ", expected a bool (0 or 1)";
                    return false;
                }
            } else {
                why = "element " + std::to_string(k) + " has the unknown type " + t;
                return false;
            }
        }
    }
    for (const Converter& c : converters) {
        const std::size_t stop = std::min(c.stop == kToEnd ? items_.size() : c.stop, items_.size());
        for (std::size_t k = c.start; k < stop; ++k) {
            Item& x = items_[k];
            if (!x.isNumber()) {
                why = "element " + std::to_string(k) + " is " + describe(x) + ", not a number (" + c.name + ")";
                return false;
            }
            const double y = (x.kind == Item::Kind::Integer ? static_cast<double>(x.integer) : x.real) * c.scale
                + c.offset;
            if (c.toFloat || x.kind == Item::Kind::Real) {
                x.kind = Item::Kind::Real;
                x.real = y;
            } else {
                x.integer = Element::ofReal(y).asInteger();  // int(y): truncated
            }
        }
    }
    return true;
}

std::string Elements::text() const
{
    if (start_ == 0) {
        return bottle_.toString();
    }
    yarp::os::Bottle rest;  // the items after the word, as Bottle::toString writes them (a list in brackets)
    for (std::size_t k = start_; k < bottle_.size(); ++k) {
        rest.add(bottle_.get(k));
    }
    return rest.toString();
}

const Item* Elements::at(std::size_t k, std::string& why) const
{
    if (k >= items_.size()) {
        why = "no element " + std::to_string(k) + " (" + std::to_string(items_.size()) + " element"
            + (items_.size() == 1 ? ")" : "s)");
        return nullptr;
    }
    return &items_[k];
}

std::string Elements::notA(std::size_t k, const char* what) const
{
    return "element " + std::to_string(k) + " is " + describe(items_[k]) + ", not " + what;
}

bool Elements::real(std::size_t k, double& out, std::string& why) const
{
    const Item* x = at(k, why);
    if (x == nullptr) {
        return false;
    }
    switch (x->kind) {
    case Item::Kind::Bool:
        out = x->flag ? 1.0 : 0.0;
        return true;
    case Item::Kind::Integer:
        out = static_cast<double>(x->integer);
        return true;
    case Item::Kind::Real:
        out = x->real;
        return true;
    default:
        why = notA(k, "a number");
        return false;
    }
}

bool Elements::integer(std::size_t k, std::int64_t& out, std::string& why) const
{
    const Item* x = at(k, why);
    if (x == nullptr) {
        return false;
    }
    switch (x->kind) {
    case Item::Kind::Bool:
        out = x->flag ? 1 : 0;
        return true;
    case Item::Kind::Integer:
        out = x->integer;
        return true;
    case Item::Kind::Real:
        if (std::isfinite(x->real) && std::trunc(x->real) == x->real && x->real >= -9223372036854775808.0
            && x->real < 9223372036854775808.0) {
            out = static_cast<std::int64_t>(x->real);
            return true;
        }
        break;
    default:
        break;
    }
    why = notA(k, "an integer");
    return false;
}

bool Elements::word(std::size_t k, std::string& out, std::string& why) const
{
    const Item* x = at(k, why);
    if (x == nullptr) {
        return false;
    }
    if (x->kind != Item::Kind::Word) {
        why = notA(k, "a word");
        return false;
    }
    out = x->text;
    return true;
}

bool Elements::boolean(std::size_t k, bool& out, std::string& why) const
{
    const Item* x = at(k, why);
    if (x == nullptr) {
        return false;
    }
    switch (x->kind) {
    case Item::Kind::Word:
        out = std::any_of(trueWords_.begin(), trueWords_.end(),
                          [x](const char* w) { return x->text == w; });
        return true;
    case Item::Kind::Bool:
        out = x->flag;
        return true;
    case Item::Kind::Integer:
        out = x->integer != 0;
        return true;
    case Item::Kind::Real:
        out = x->real != 0.0;
        return true;
    default:
        why = notA(k, "a word or a number");
        return false;
    }
}

bool Elements::set(rosidl_runtime_c__String& field, std::size_t k, std::string& why) const
{
    std::string w;
    if (!word(k, w, why)) {
        return false;
    }
    ybgc::ros2::setString(field, w);
    return true;
}

bool Elements::range(std::size_t start, std::size_t stop, std::size_t& end, std::string& why) const
{
    const std::size_t n = items_.size();
    end = stop == kToEnd ? n : stop;
    if (start > n || end > n || end < start) {
        why = "no elements [" + std::to_string(start) + ":" + (stop == kToEnd ? std::string() : std::to_string(stop))
            + "] (" + std::to_string(n) + " element" + (n == 1 ? ")" : "s)");
        return false;
    }
    return true;
}

// --- Bottles from fields -------------------------------------------------------------------

std::string text(const rosidl_runtime_c__String& s)
{
    return s.data == nullptr ? std::string() : std::string(s.data, s.size);
}

void put(yarp::os::Bottle& b, const rosidl_runtime_c__String& x, Wire /*wire*/)
{
    b.addString(text(x));
}

std::string reasonText(const std::string& reason, const std::string& reply, const std::string& why)
{
    std::string out = reason;
    for (const auto& [key, value] : {std::pair<const char*, const std::string*>{"{reply}", &reply}, {"{why}", &why}}) {
        const std::size_t at = out.find(key);
        if (at != std::string::npos) {
            out.replace(at, std::strlen(key), *value);
        }
    }
    return out;
}

// --- counts ----------------------------------------------------------------------------------

void Counts::count(Failure failure, const std::string& why)
{
    lastFailed = failure != Failure::None;
    last = why;
    switch (failure) {
    case Failure::None:
        ++answered;
        last.clear();
        break;
    case Failure::TimedOut:
        ++timedOut;
        break;
    case Failure::NoServer:
        ++noServer;
        break;
    case Failure::Unfit:
        ++unfit;
        break;
    }
}

std::string totalsLine(const char* name, const Counts& c)
{
    return std::string("service ") + name + ": calls " + std::to_string(c.calls) + ", answered "
        + std::to_string(c.answered) + ", failed " + std::to_string(c.failed()) + " (timed out "
        + std::to_string(c.timedOut) + ", no server " + std::to_string(c.noServer) + ", did not fit "
        + std::to_string(c.unfit) + ")";
}

void addStats(yarp::os::Bottle& reply, const char* name, const Counts& c)
{
    yarp::os::Bottle& item = reply.addList();
    item.addString("service");
    item.addString(name);
    for (const auto& [key, n] : {std::pair<const char*, std::uint64_t>{"calls", c.calls}, {"answered", c.answered},
                                 {"failed", c.failed()}, {"timed_out", c.timedOut}, {"no_server", c.noServer},
                                 {"unfit", c.unfit}}) {
        item.addString(key);
        item.addInt64(static_cast<std::int64_t>(n));
    }
}

ybgc::ros2::Status status(const Spec& spec, const Counts& c, const std::string& node)
{
    ybgc::ros2::Status out;
    out.name = node + ": service " + spec.name;
    if (c.lastFailed) {
        out.level = ybgc::ros2::Status::Warn;
        out.message = "its last call failed: " + c.last;
    } else {
        out.message = c.calls == 0 ? "no call yet" : "answered its last call";
    }
    for (const auto& [key, n] : {std::pair<const char*, std::uint64_t>{"calls", c.calls}, {"answered", c.answered},
                                 {"failed", c.failed()}, {"timed out", c.timedOut}, {"no server", c.noServer},
                                 {"unfit", c.unfit}}) {
        out.values.emplace_back(key, std::to_string(n));
    }
    char timeout[64];
    std::snprintf(timeout, sizeof timeout, "%g", spec.timeout);
    out.values.emplace_back("timeout (s)", timeout);
    return out;
}

const char* const kRpcHelp[3] = {
    "help: this list",
    "stats: the totals so far, one list per service: "
    "(service NAME calls N answered N failed N timed_out N no_server N unfit N)",
    "quit: stop the module (it closes its ports and exits 0, as on SIGINT)",
};

std::string firstWord(const yarp::os::Bottle& command)
{
    if (command.size() == 0) {
        return "";
    }
    const yarp::os::Value& v = command.get(0);
    if (v.isString()) {
        return v.asString();
    }
    if (v.isVocab32()) {
        return yarp::os::Vocab32::decode(v.asVocab32());
    }
    return v.toString();
}

// =============================================================================================
// running it

namespace {

using Clock = SteadyClock;
using TimePoint = Clock::time_point;

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

TimePoint after(double seconds)
{
    return Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

/// The DiagnosticArray of `all`: its statuses refilled in place; false when
/// it cannot allocate them.
bool fillArray(diagnostic_msgs__msg__DiagnosticArray& msg, const std::vector<ybgc::ros2::Status>& all,
               const std::string& hardwareId) noexcept
try {
    ybgc::ros2::resize(msg.status, all.size(), diagnostic_msgs__msg__DiagnosticStatus__Sequence__init,
                       diagnostic_msgs__msg__DiagnosticStatus__Sequence__fini);
    for (std::size_t k = 0; k < all.size(); ++k) {
        diagnostic_msgs__msg__DiagnosticStatus& out = msg.status.data[k];
        out.level = all[k].level;
        ybgc::ros2::setString(out.name, all[k].name);
        ybgc::ros2::setString(out.message, all[k].message);
        ybgc::ros2::setString(out.hardware_id, hardwareId);
        ybgc::ros2::resize(out.values, all[k].values.size(), diagnostic_msgs__msg__KeyValue__Sequence__init,
                           diagnostic_msgs__msg__KeyValue__Sequence__fini);
        for (std::size_t j = 0; j < all[k].values.size(); ++j) {
            ybgc::ros2::setString(out.values.data[j].key, all[k].values[j].first);
            ybgc::ros2::setString(out.values.data[j].value, all[k].values[j].second);
        }
    }
    return true;
} catch (const std::bad_alloc&) {
    return false;
}

/// A flag with a condition variable: set once, waited for with a deadline.
struct Latch
{
    std::mutex mutex;
    std::condition_variable cv;
    bool set = false;

    void open()
    {
        std::lock_guard<std::mutex> lock(mutex);
        set = true;
        cv.notify_all();
    }
    bool waitUntil(TimePoint deadline)
    {
        std::unique_lock<std::mutex> lock(mutex);
        return cv.wait_until(lock, deadline, [this] { return set; });
    }
};

// --- the command line --------------------------------------------------------------------------

struct Options
{
    std::string prefix;
    bool verbose = false;
};

void usage(const Commands& spec, const std::string& prog, std::FILE* out, bool full)
{
    std::fprintf(out, "usage: %s [--name P] [--verbose] [--help] [--ros-args ...]\n", prog.c_str());
    if (!full) {
        return;
    }
    std::fprintf(out, "\n");
    for (const char* line : spec.description) {
        std::fprintf(out, "%s\n", line);
    }
    std::fprintf(out,
                 "\noptions:\n"
                 "  --name P      prefix of the module's own port names, as YARP modules name it (default: %s):\n"
                 "                its RPC port P/rpc:i, the ports it calls YARP RPC ports from\n"
                 "  --prefix P    the same as --name\n"
                 "  --verbose     print every call and its answer\n"
                 "  --help        print this help and exit\n"
                 "\nROS arguments (--ros-args ... [--], as for every ROS 2 program): remappings\n"
                 "(-r FROM:=TO), parameters (-p NAME:=VALUE, --params-file FILE), --log-level. Parameters:\n"
                 "  prefix, verbose\n"
                 "                as the options above; the options win\n"
                 "  diagnostics   publish the services' counts on /diagnostics (default: true)\n"
                 "  diagnostic_updater.period\n"
                 "                seconds between two /diagnostics messages (default: 1)\n"
                 "\nGenerated by ybgc from %s.\n",
                 spec.defaultPrefix, spec.config);
}

/// -1 to go on, else the exit status (0 after --help).
int parseOptions(const Commands& spec, int argc, char* argv[], Options& opt)
{
    std::string prog = argc > 0 && argv[0][0] != '\0' ? argv[0] : spec.module;
    prog = prog.substr(prog.rfind('/') + 1);
    opt = Options();
    opt.prefix = spec.defaultPrefix;
    auto fail = [&](const std::string& text) {
        usage(spec, prog, stderr, false);
        std::fprintf(stderr, "%s: error: %s\n", prog.c_str(), text.c_str());
        return 2;
    };
    for (int k = 1; k < argc; ++k) {
        std::string arg = argv[k];
        std::string value;
        bool inlineValue = false;
        const std::size_t eq = arg.find('=');
        if (arg.rfind("--", 0) == 0 && eq != std::string::npos) {
            value = arg.substr(eq + 1);
            arg = arg.substr(0, eq);
            inlineValue = true;
        }
        if (arg == "--help" || arg == "-h") {
            usage(spec, prog, stdout, true);
            return 0;
        }
        if (arg == "--verbose") {
            if (inlineValue) {
                return fail("--verbose takes no value");
            }
            opt.verbose = true;
            continue;
        }
        if (arg != "--name" && arg != "--prefix") {
            return fail("unknown option " + arg);
        }
        if (!inlineValue) {
            if (k + 1 >= argc) {
                return fail(arg + " needs a value");
            }
            value = argv[++k];
        }
        if (arg == "--prefix" && (value.empty() || value[0] != '/')) {
            return fail("--prefix must start with /");
        }
        opt.prefix = value.empty() || value[0] != '/' ? "/" + value : value;  // `--name foo`, as YARP modules take it
    }
    while (opt.prefix.size() > 1 && opt.prefix.back() == '/') {
        opt.prefix.pop_back();
    }
    return -1;
}

// --- SIGINT and SIGTERM --------------------------------------------------------------------------

/// Blocks SIGINT and SIGTERM in every thread (made before any thread
/// starts) and waits for them in a thread of its own: the first asks the
/// module to stop; if it has not closed 1.9 s later, or a second signal
/// comes, the process exits at once (status 0: it was asked to stop).
class Signals
{
public:
    Signals()
    {
        sigemptyset(&set_);
        sigaddset(&set_, SIGINT);
        sigaddset(&set_, SIGTERM);
        pthread_sigmask(SIG_BLOCK, &set_, nullptr);
    }

    void start(std::function<void()> onStop)
    {
        thread_ = std::thread([this, onStop] { run(onStop); });
    }

    void finish()
    {
        if (!thread_.joinable()) {
            return;
        }
        finished_ = true;
        pthread_kill(thread_.native_handle(), SIGTERM);
        thread_.join();
    }

private:
    void run(const std::function<void()>& onStop)
    {
        int sig = 0;
        while (sigwait(&set_, &sig) != 0) {
        }
        if (finished_) {
            return;
        }
        onStop();
        const timespec limit = {1, 900000000};
        while (true) {
            const int r = sigtimedwait(&set_, nullptr, &limit);
            if (finished_) {
                return;
            }
            if (r < 0 && errno == EINTR) {
                continue;
            }
            say(r < 0 ? "closing takes too long; exiting without closing every port"
                      : "second signal; exiting without closing every port");
            std::_Exit(0);
        }
    }

    sigset_t set_;
    std::thread thread_;
    std::atomic<bool> finished_{false};
};

class Module;

// --- a YARP RPC port called: one connection at a time -----------------------------------------

/// The names of the client ports of one YARP port called that are open
/// (a port given up on keeps its name until its thread closes it): a new
/// port takes the first name free. Shared with the threads of the ports.
struct Names
{
    std::mutex mutex;
    std::set<std::string> taken;
    std::string base;  // <prefix>/<service>/rpc:o

    /// The first of <base>, <prefix>/<service>/rpc2:o, rpc3:o ... not taken; taken now.
    std::string take()
    {
        std::lock_guard<std::mutex> lock(mutex);
        std::string name = base;
        const bool output = base.size() > 2 && base.compare(base.size() - 2, 2, ":o") == 0;
        for (int k = 2; taken.count(name) != 0; ++k) {
            name = output ? base.substr(0, base.size() - 2) + std::to_string(k) + ":o" : base + std::to_string(k);
        }
        taken.insert(name);
        return name;
    }
    void release(const std::string& name)
    {
        std::lock_guard<std::mutex> lock(mutex);
        taken.erase(name);
    }
    std::set<std::string> open()
    {
        std::lock_guard<std::mutex> lock(mutex);
        return taken;
    }
};

/// One client port and the thread that makes its blocking calls (open,
/// connect, write and wait for the reply), one at a time. Its caller waits
/// for each call until the call's deadline, never longer: a call still
/// running then is given up (`abandoned`), and the thread closes the port
/// as soon as YARP gives the write up (the port's timeout), so that its
/// late reply is never read as another call's. A call that fails (no
/// server, the connection lost) ends the port too: the next call opens a
/// fresh one and connects again.
struct Link
{
    enum class State { Idle, Busy, Done, Ended };

    std::mutex mutex;
    std::condition_variable cv;
    State state = State::Idle;
    bool abandoned = false;  // given up by the caller: close when the call returns
    bool quit = false;       // closing: no more calls
    yarp::os::Bottle command;
    TimePoint deadline;
    // the outcome of the last call
    bool ok = false;
    Failure failure = Failure::None;
    yarp::os::Bottle reply;
    bool finished = false;  // the thread ended (its port closed)

    std::string name;
    std::string remote;
    double timeout = 1.0;
    std::shared_ptr<Names> names;

    /// The thread of the port (detached: it may outlive the module's wait for it).
    static void run(std::shared_ptr<Link> self);
};

void Link::run(std::shared_ptr<Link> self)
{
    Link& l = *self;
    yarp::os::Port port;
    port.setTimeout(static_cast<float>(l.timeout));  // YARP gives up a connection or a write after it
    bool open = false;
    bool broken = false;
    for (;;) {
        yarp::os::Bottle command;
        TimePoint deadline;
        {
            std::unique_lock<std::mutex> lock(l.mutex);
            l.cv.wait(lock, [&l] { return l.state == State::Busy || l.quit || l.abandoned; });
            if (l.state != State::Busy || l.quit || l.abandoned) {
                break;
            }
            command = l.command;
            deadline = l.deadline;
        }
        bool ok = false;
        yarp::os::Bottle reply;
        if (!open) {
            port.setInputMode(false);
            open = port.open(l.name);
            if (!open) {
                say("cannot open the port " + l.name);
            }
        }
        if (open) {
            bool connected = port.getOutputCount() > 0;
            if (!connected) {
                yarp::os::ContactStyle style;
                style.quiet = true;
                connected = yarp::os::Network::connect(l.name, l.remote, style);
            }
            ok = connected && port.write(command, reply);
        }
        broken = !ok;
        {
            std::lock_guard<std::mutex> lock(l.mutex);
            l.ok = ok;
            l.failure = ok ? Failure::None : Clock::now() >= deadline ? Failure::TimedOut : Failure::NoServer;
            l.reply = reply;
            l.state = State::Done;
            l.cv.notify_all();
            if (broken || l.abandoned) {
                break;
            }
        }
    }
    if (open) {
        port.interrupt();
        port.close();
    }
    l.names->release(l.name);
    std::lock_guard<std::mutex> lock(l.mutex);
    l.state = State::Ended;
    l.finished = true;
    l.cv.notify_all();
}

/// A request of a ROS 2 service served by the module, waiting for its call.
struct Job
{
    std::size_t service;       // in Commands::services
    rmw_request_id_t header;   // to send the response to
    void* request;             // owned (the service's SrvType)
    TimePoint deadline;        // arrival + the service's timeout
};

/// One YARP RPC port called by the module: its calls made one after
/// another, in the order they came, by one thread, each answered by its
/// deadline whatever the server does (a Link a connection).
class YarpCaller
{
public:
    YarpCaller(Module& module, std::string local, std::string remote, double timeout);
    /// Is the port called registered with the name server (asked once, at a call's deadline)?
    bool serverRegistered() const;

    void start();
    /// A request to call it with: answered by the module once the call ends.
    void submit(Job job);
    /// Closing: the calls not answered yet are answered (reason `stopped`).
    void stop();
    /// The thread ended; the port closed by `deadline` (false: a call still holds it).
    bool close(TimePoint deadline);
    /// The names of its ports still open.
    std::set<std::string> openNames() const { return names_->open(); }

private:
    void dispatch();
    /// Makes the call of `job` on the current link (a new one if none);
    /// false, with the failure, when it did not answer by the deadline.
    bool call(const yarp::os::Bottle& command, TimePoint deadline, yarp::os::Bottle& reply, Failure& failure,
              bool& stopped);

    Module& module_;
    std::string remote_;
    double timeout_;
    std::shared_ptr<Names> names_;
    std::shared_ptr<Link> link_;  // the current connection (nullptr: none)
    std::vector<std::shared_ptr<Link>> given_;  // links given up, closing by themselves

    std::mutex mutex_;
    std::condition_variable cv_;
    std::deque<Job> queue_;
    bool stopping_ = false;
    std::thread thread_;
};

// --- a ROS 2 service called --------------------------------------------------------------------

/// One ROS 2 service called by the module (a command of a YARP port it
/// serves): its rcl client, the calls waiting for their response by
/// sequence number. rcl's client is used under `mutex`; responses are taken
/// by the module's ROS 2 thread and handed to their call; one whose call
/// was given up is dropped.
class RosClient
{
public:
    RosClient(Module& module, const Service& service);

    bool open(rcl_node_t* node);
    void fini(rcl_node_t* node);
    rcl_client_t* client() { return &client_; }

    /// Calls the service with `request`: Failure::None with `response` (owned
    /// by the caller), else why not (`stopped`: the module stops).
    Failure call(const void* request, TimePoint deadline, void*& response, bool& stopped);
    /// Takes the responses that came (the ROS 2 thread).
    void take();
    void stop();

private:
    struct Pending
    {
        void* response = nullptr;
        bool done = false;
    };

    Module& module_;
    const Service& service_;
    rcl_node_t* node_ = nullptr;
    rcl_client_t client_ = rcl_get_zero_initialized_client();
    bool ok_ = false;
    std::mutex mutex_;
    std::condition_variable cv_;
    std::map<std::int64_t, Pending*> pending_;
    void* buffer_ = nullptr;  // the next response taken
    bool stopping_ = false;
};

// --- a ROS 2 service served ----------------------------------------------------------------------

/// One ROS 2 service served by the module: its rcl service (used under
/// `mutex`: requests taken by the ROS 2 thread, responses sent by the
/// threads of the YARP ports called).
class RosServer
{
public:
    RosServer(Module& module, std::size_t index, YarpCaller& caller);

    bool open(rcl_node_t* node);
    void fini(rcl_node_t* node);
    rcl_service_t* service() { return &rcl_; }
    /// Takes the requests that came (the ROS 2 thread) and hands each to its caller.
    void take();
    /// Sends a response (its sender keeps it).
    void send(rmw_request_id_t& header, void* response);

private:
    Module& module_;
    std::size_t index_;
    const Service& svc_;
    YarpCaller& caller_;
    rcl_service_t rcl_ = rcl_get_zero_initialized_service();
    bool ok_ = false;
    std::mutex mutex_;
    bool reportedSendError_ = false;
};

// --- a YARP RPC port served ------------------------------------------------------------------------

/// A YARP RPC port the module serves (its commands), or the module's own
/// RPC port (help, stats, quit), or both when they are one port. Each
/// command is answered in YARP's thread of its connection: callers on
/// several connections are answered at once.
class ServedPort : public yarp::os::PortReader
{
public:
    ServedPort(Module& module, std::string name) : name(std::move(name)), module_(module) {}

    bool open()
    {
        port_.setReader(*this);
        return port_.open(name);
    }
    /// Once no command is being answered (or after `limit`): interrupted and closed.
    void close(std::chrono::milliseconds limit);
    bool read(yarp::os::ConnectionReader& connection) override;

    const std::string name;

private:
    Module& module_;
    yarp::os::RpcServer port_;
    std::atomic<int> reading_{0};
};

// --- the module ------------------------------------------------------------------------------------

class Module
{
public:
    Module(const Commands& spec, Options options, std::vector<std::string> rosArgs) :
            spec_(spec), options_(std::move(options)), node_(spec.node, std::move(rosArgs)),
            counts_(spec.services.size()), rpcName_(options_.prefix + "/rpc:i")
    {
    }

    int run();

    void requestStop()
    {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stopping_ = true;
        }
        cv_.notify_all();
    }
    bool stopping()
    {
        std::lock_guard<std::mutex> lock(mutex_);
        return stopping_;
    }

    const Commands& spec() const { return spec_; }

    /// A call of service `s` starts: counted.
    void started(std::size_t s)
    {
        std::lock_guard<std::mutex> lock(mutex_);
        ++counts_[s].calls;
    }

    /// A call of service `s` ended: counted; a failure said (the first of
    /// the service, or each with --verbose).
    void ended(std::size_t s, Failure failure, const std::string& text)
    {
        std::uint64_t failed = 0;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            counts_[s].count(failure, text);
            failed = counts_[s].failed();
        }
        if (failure != Failure::None && (options_.verbose || failed == 1)) {
            say(std::string("service ") + spec_.services[s].spec.name + ": " + text
                + (options_.verbose ? "" : "; further failures are only counted"));
        }
    }

    /// With --verbose: a call and its answer.
    void saySuccess(std::size_t s, const yarp::os::Bottle& command, const yarp::os::Bottle& reply)
    {
        if (options_.verbose) {
            say(std::string("service ") + spec_.services[s].spec.name + ": " + command.toString() + " -> "
                + reply.toString());
        }
    }

    /// The reason of a call given up because the module stops.
    std::string stoppedText(const Service& s) const
    {
        return std::string(spec_.module) + " stopped before "
            + (s.spec.serves == Serves::Ros2 ? s.spec.port : s.spec.service) + " answered";
    }

    /// Answers the request of a job (the thread of its YARP port called):
    /// `reply` the call's reply (Failure::None), else the failure and its text.
    void answer(Job& job, Failure failure, const std::string& why, const yarp::os::Bottle* command,
                const yarp::os::Bottle* reply);

    /// The reply to a command on the port `port` (a served one or the
    /// module's own); `quit`: it asked the module to stop.
    void respond(const std::string& port, const yarp::os::Bottle& command, yarp::os::Bottle& reply, bool& quit);

    /// Calls in flight on the ports served (for the grace at closing).
    std::atomic<int> active{0};

private:
    void serveYarp(std::size_t s, const yarp::os::Bottle& command, yarp::os::Bottle& reply);
    void failedReply(std::size_t s, const std::string& text, yarp::os::Bottle& reply);
    bool openAll(std::string& what);
    void spin();
    void diagnose(double period);
    void printTotals();

    const Commands& spec_;
    const Options options_;
    ybgc::ros2::Node node_;
    std::mutex mutex_;
    std::condition_variable cv_;
    bool stopping_ = false;
    std::vector<Counts> counts_;
    const std::string rpcName_;
    std::map<std::string, std::unique_ptr<YarpCaller>> callers_;  // by the YARP port called
    std::vector<std::unique_ptr<RosServer>> servers_;
    std::map<std::size_t, std::unique_ptr<RosClient>> clients_;   // by service
    std::vector<std::unique_ptr<ServedPort>> served_;
    std::thread spinner_;
    std::atomic<bool> spinning_{false};
    rcl_publisher_t diagnostics_ = rcl_get_zero_initialized_publisher();  // /diagnostics
    bool diagnosticsOk_ = false;
    std::thread diagnose_;
};

// --- YarpCaller --------------------------------------------------------------------------------------

YarpCaller::YarpCaller(Module& module, std::string local, std::string remote, double timeout) :
        module_(module), remote_(std::move(remote)), timeout_(timeout), names_(std::make_shared<Names>())
{
    names_->base = std::move(local);
}

void YarpCaller::start()
{
    thread_ = std::thread([this] { dispatch(); });
}

void YarpCaller::submit(Job job)
{
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!stopping_) {
            queue_.push_back(job);
            cv_.notify_all();
            return;
        }
    }
    const Service& s = module_.spec().services[job.service];
    module_.answer(job, Failure::TimedOut, module_.stoppedText(s), nullptr, nullptr);
}

void YarpCaller::stop()
{
    std::shared_ptr<Link> link;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stopping_ = true;
        link = link_;
    }
    cv_.notify_all();
    if (link != nullptr) {
        std::lock_guard<std::mutex> lock(link->mutex);
        link->cv.notify_all();  // the call waiting on it ends now
    }
}

void YarpCaller::dispatch()
{
    for (;;) {
        Job job;
        bool stopping = false;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            cv_.wait(lock, [this] { return !queue_.empty() || stopping_; });
            if (queue_.empty()) {
                break;  // stopping, every call answered
            }
            job = queue_.front();
            queue_.pop_front();
            stopping = stopping_;
        }
        const Service& s = module_.spec().services[job.service];
        if (stopping) {
            module_.answer(job, Failure::TimedOut, module_.stoppedText(s), nullptr, nullptr);
            continue;
        }
        if (Clock::now() >= job.deadline) {
            module_.answer(job, Failure::TimedOut, s.spec.reasons.waited, nullptr, nullptr);
            continue;
        }
        yarp::os::Bottle command;
        s.functions.command(job.request, command);
        yarp::os::Bottle reply;
        Failure failure = Failure::None;
        bool stopped = false;
        if (call(command, job.deadline, reply, failure, stopped)) {
            module_.answer(job, Failure::None, "", &command, &reply);
        } else if (stopped) {
            module_.answer(job, Failure::TimedOut, module_.stoppedText(s), &command, nullptr);
        } else {
            module_.answer(job, failure,
                           failure == Failure::TimedOut ? s.spec.reasons.timedOut : s.spec.reasons.noServer, &command,
                           nullptr);
        }
    }
}

bool YarpCaller::call(const yarp::os::Bottle& command, TimePoint deadline, yarp::os::Bottle& reply,
                      Failure& failure, bool& stopped)
{
    std::shared_ptr<Link> link;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        // the links given up that have closed their ports are forgotten
        given_.erase(std::remove_if(given_.begin(), given_.end(),
                                    [](const std::shared_ptr<Link>& l) {
                                        std::lock_guard<std::mutex> guard(l->mutex);
                                        return l->finished;
                                    }),
                     given_.end());
        if (link_ == nullptr) {
            link_ = std::make_shared<Link>();
            link_->name = names_->take();
            link_->remote = remote_;
            link_->timeout = timeout_;
            link_->names = names_;
            std::thread(Link::run, link_).detach();
        }
        link = link_;
    }
    std::unique_lock<std::mutex> lock(link->mutex);
    link->command = command;
    link->deadline = deadline;
    link->state = Link::State::Busy;
    link->cv.notify_all();
    const bool done = link->cv.wait_until(lock, deadline, [this, &link] {
        if (link->state == Link::State::Done || link->state == Link::State::Ended) {
            return true;
        }
        std::lock_guard<std::mutex> guard(mutex_);
        return stopping_;
    });
    if (done && link->state == Link::State::Done) {
        link->state = Link::State::Idle;
        failure = link->failure;
        const bool ok = link->ok;
        if (ok) {
            reply = link->reply;
        }
        lock.unlock();
        if (!ok) {
            std::lock_guard<std::mutex> guard(mutex_);
            link_ = nullptr;  // its thread closes the port
        }
        return ok;
    }
    // no answer by the deadline (or the module stops): the link is given up
    link->abandoned = true;
    link->cv.notify_all();
    const bool ended = link->state == Link::State::Ended;
    lock.unlock();
    {
        std::lock_guard<std::mutex> guard(mutex_);
        stopped = stopping_ && Clock::now() < deadline;
        link_ = nullptr;
        if (!ended) {
            given_.push_back(link);
        }
    }
    // a server that left the name server while the call waited (it quit) is no server,
    // whether or not its leaving broke the connection before the deadline (the Python
    // runtime says the same); one that is still registered did not answer in time
    failure = !stopped && !serverRegistered() ? Failure::NoServer : Failure::TimedOut;
    return false;
}

bool YarpCaller::serverRegistered() const
{
    return yarp::os::Network::queryName(remote_).isValid();
}

bool YarpCaller::close(TimePoint deadline)
{
    if (thread_.joinable()) {
        thread_.join();  // never waits for YARP: its calls wait until their deadlines at most
    }
    std::vector<std::shared_ptr<Link>> links;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        links = given_;
        if (link_ != nullptr) {
            links.push_back(link_);
        }
    }
    bool closed = true;
    for (const std::shared_ptr<Link>& l : links) {
        std::unique_lock<std::mutex> lock(l->mutex);
        l->quit = true;
        l->cv.notify_all();
        closed = l->cv.wait_until(lock, deadline, [&l] { return l->finished; }) && closed;
    }
    return closed;
}

// --- RosClient ----------------------------------------------------------------------------------------

RosClient::RosClient(Module& module, const Service& service) : module_(module), service_(service) {}

bool RosClient::open(rcl_node_t* node)
{
    node_ = node;
    rcl_client_options_t options = rcl_client_get_default_options();
    if (rcl_client_init(&client_, node, service_.type.typeSupport, service_.spec.service, &options) != RCL_RET_OK) {
        say(std::string("cannot call the ROS 2 service ") + service_.spec.service + ": " + rclError());
        return false;
    }
    ok_ = true;
    buffer_ = service_.type.createResponse();
    if (buffer_ == nullptr) {
        say(std::string("cannot allocate a response of ") + service_.type.name);
        return false;
    }
    return true;
}

void RosClient::fini(rcl_node_t* node)
{
    if (ok_) {
        finished(rcl_client_fini(&client_, node));
        ok_ = false;
    }
    if (buffer_ != nullptr) {
        service_.type.destroyResponse(buffer_);
        buffer_ = nullptr;
    }
}

Failure RosClient::call(const void* request, TimePoint deadline, void*& response, bool& stopped)
{
    // a server: waited for up to the deadline
    for (;;) {
        bool available = false;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            if (stopping_) {
                stopped = true;
                return Failure::TimedOut;
            }
            if (rcl_service_server_is_available(node_, &client_, &available) != RCL_RET_OK) {
                rcl_reset_error();
                available = false;
            }
        }
        if (available) {
            break;
        }
        if (Clock::now() >= deadline) {
            return Failure::NoServer;
        }
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait_until(lock, std::min(deadline, Clock::now() + std::chrono::milliseconds(10)),
                       [this] { return stopping_; });
    }
    Pending pending;
    std::unique_lock<std::mutex> lock(mutex_);
    std::int64_t sequence = 0;
    if (rcl_send_request(&client_, request, &sequence) != RCL_RET_OK) {
        rcl_reset_error();
        return Failure::NoServer;
    }
    pending_[sequence] = &pending;
    cv_.wait_until(lock, deadline, [this, &pending] { return pending.done || stopping_; });
    pending_.erase(sequence);  // a response that comes later is dropped
    if (pending.done) {
        response = pending.response;
        return Failure::None;
    }
    stopped = stopping_ && Clock::now() < deadline;
    return Failure::TimedOut;
}

void RosClient::take()
{
    std::lock_guard<std::mutex> lock(mutex_);
    for (;;) {
        if (buffer_ == nullptr) {
            buffer_ = service_.type.createResponse();
            if (buffer_ == nullptr) {
                return;
            }
        }
        rmw_request_id_t header;
        if (rcl_take_response(&client_, &header, buffer_) != RCL_RET_OK) {
            rcl_reset_error();
            return;
        }
        const auto it = pending_.find(header.sequence_number);
        if (it == pending_.end()) {
            continue;  // its call was given up: dropped (the buffer is taken into again)
        }
        it->second->response = buffer_;
        it->second->done = true;
        buffer_ = nullptr;
        pending_.erase(it);
        cv_.notify_all();
    }
}

void RosClient::stop()
{
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stopping_ = true;
    }
    cv_.notify_all();
}

// --- RosServer ----------------------------------------------------------------------------------------

RosServer::RosServer(Module& module, std::size_t index, YarpCaller& caller) :
        module_(module), index_(index), svc_(module.spec().services[index]), caller_(caller)
{
}

bool RosServer::open(rcl_node_t* node)
{
    rcl_service_options_t options = rcl_service_get_default_options();
    if (rcl_service_init(&rcl_, node, svc_.type.typeSupport, svc_.spec.service, &options)
        != RCL_RET_OK) {
        say(std::string("cannot serve the ROS 2 service ") + svc_.spec.service + ": " + rclError());
        return false;
    }
    ok_ = true;
    return true;
}

void RosServer::fini(rcl_node_t* node)
{
    std::lock_guard<std::mutex> lock(mutex_);
    if (ok_) {
        finished(rcl_service_fini(&rcl_, node));
        ok_ = false;
    }
}

void RosServer::take()
{
    for (;;) {
        void* request = svc_.type.createRequest();
        if (request == nullptr) {
            return;
        }
        rmw_request_id_t header;
        rcl_ret_t taken = RCL_RET_ERROR;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            taken = ok_ ? rcl_take_request(&rcl_, &header, request) : RCL_RET_ERROR;
        }
        if (taken != RCL_RET_OK) {
            rcl_reset_error();
            svc_.type.destroyRequest(request);
            return;
        }
        module_.started(index_);
        caller_.submit(Job{index_, header, request, after(svc_.spec.timeout)});
    }
}

void RosServer::send(rmw_request_id_t& header, void* response)
{
    std::lock_guard<std::mutex> lock(mutex_);
    if (!ok_) {
        return;
    }
    if (rcl_send_response(&rcl_, &header, response) != RCL_RET_OK) {
        const std::string error = rclError();
        if (!reportedSendError_) {
            reportedSendError_ = true;
            say(std::string("cannot send a response of ") + svc_.spec.service + ": " + error
                + "; further errors are not said");
        }
    }
}

// --- ServedPort ------------------------------------------------------------------------------------------

bool ServedPort::read(yarp::os::ConnectionReader& connection)
{
    ++reading_;
    yarp::os::Bottle command;
    if (!command.read(connection)) {
        --reading_;
        return false;
    }
    yarp::os::Bottle reply;
    bool quit = false;
    module_.respond(name, command, reply, quit);
    yarp::os::ConnectionWriter* writer = connection.getWriter();
    if (writer != nullptr) {
        reply.write(*writer);
    }
    --reading_;
    if (quit) {
        module_.requestStop();  // closing waits for the reply to go (close())
    }
    return true;
}

void ServedPort::close(std::chrono::milliseconds limit)
{
    const TimePoint deadline = Clock::now() + limit;
    while (reading_ > 0 && Clock::now() < deadline) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));  // read() returned: its reply is sent
    port_.interrupt();
    port_.close();
}

// --- Module -------------------------------------------------------------------------------------------------

void Module::answer(Job& job, Failure failure, const std::string& why, const yarp::os::Bottle* command,
                    const yarp::os::Bottle* reply)
{
    const Service& s = spec_.services[job.service];
    void* response = s.type.createResponse();
    std::string text = why;
    if (response == nullptr) {
        say(std::string("cannot allocate a response of ") + s.type.name);
    } else {
        if (failure == Failure::None && reply != nullptr) {
            Elements e(*reply, 0, s.spec.trueWords);
            std::string unfit;
            if (e.check(s.spec.declared, s.spec.types, s.spec.converters, unfit)
                && s.functions.response(e, response, unfit)) {
                servers_[job.service]->send(job.header, response);
                ended(job.service, Failure::None, "");
                saySuccess(job.service, *command, *reply);
                s.type.destroyResponse(response);
                s.type.destroyRequest(job.request);
                return;
            }
            // a fresh response for the failure answer
            s.type.destroyResponse(response);
            response = s.type.createResponse();
            failure = Failure::Unfit;
            text = reasonText(s.spec.reasons.unfitReply, reply->toString(), unfit);
        }
        if (response != nullptr) {
            s.functions.failedResponse(text, response);
            servers_[job.service]->send(job.header, response);
            s.type.destroyResponse(response);
        }
    }
    ended(job.service, failure == Failure::None ? Failure::TimedOut : failure, text);
    s.type.destroyRequest(job.request);
}

void Module::respond(const std::string& port, const yarp::os::Bottle& command, yarp::os::Bottle& reply, bool& quit)
{
    const std::string word = firstWord(command);
    std::size_t first = spec_.services.size();  // the port's first command
    for (std::size_t s = 0; s < spec_.services.size(); ++s) {
        const Spec& sp = spec_.services[s].spec;
        if (sp.serves != Serves::Yarp || port != sp.port) {
            continue;
        }
        if (first == spec_.services.size()) {
            first = s;
        }
        if (word == sp.name) {
            ++active;
            serveYarp(s, command, reply);
            --active;
            return;
        }
    }
    const bool own = port == rpcName_;
    if (word == "help") {
        // a served port: its commands (stats and quit unlisted where it is the module's own too)
        reply.addVocab32("many");
        const auto help = std::find_if(spec_.ports.begin(), spec_.ports.end(),
                                       [&port](const PortHelp& p) { return port == p.port; });
        if (help != spec_.ports.end()) {
            for (const char* line : help->help) {
                reply.addString(line);
            }
        } else {
            for (const char* line : kRpcHelp) {
                reply.addString(line);
            }
        }
        return;
    }
    if (own && word == "stats") {
        std::lock_guard<std::mutex> lock(mutex_);
        for (std::size_t s = 0; s < spec_.services.size(); ++s) {
            addStats(reply, spec_.services[s].spec.name, counts_[s]);
        }
        return;
    }
    if (own && (word == "quit" || word == "exit" || word == "bye")) {
        say("asked to quit on the RPC port");
        quit = true;
        reply.addVocab32("bye");
        return;
    }
    std::string text = spec_.unknownCommand;
    const std::size_t at = text.find("{word}");
    if (at != std::string::npos) {
        text.replace(at, 6, word);
    }
    if (first < spec_.services.size()) {
        // a served port: the failure reply (of its first command), and why
        const Service& s = spec_.services[first];
        void* response = s.type.createResponse();
        if (response != nullptr) {
            s.functions.failedReply(response, text, reply);
            s.type.destroyResponse(response);
            return;
        }
    }
    reply.addVocab32("fail");
    reply.addString(text);
}

void Module::failedReply(std::size_t s, const std::string& text, yarp::os::Bottle& reply)
{
    const Service& sv = spec_.services[s];
    void* response = sv.type.createResponse();
    if (response == nullptr) {
        reply.addVocab32("fail");
        reply.addString(text);
        return;
    }
    sv.functions.failedReply(response, text, reply);
    sv.type.destroyResponse(response);
}

void Module::serveYarp(std::size_t s, const yarp::os::Bottle& command, yarp::os::Bottle& reply)
{
    const Service& sv = spec_.services[s];
    const TimePoint deadline = after(sv.spec.timeout);
    started(s);
    Elements args(command, 1, sv.spec.trueWords);
    std::string why;
    void* request = sv.type.createRequest();
    if (request == nullptr) {
        const std::string text = reasonText(sv.spec.reasons.badArguments, "", "cannot allocate a request");
        ended(s, Failure::Unfit, text);
        failedReply(s, text, reply);
        return;
    }
    if (!args.check(sv.spec.declared, sv.spec.types, sv.spec.converters, why)
        || !sv.functions.request(args, request, why)) {
        sv.type.destroyRequest(request);
        const std::string text = reasonText(sv.spec.reasons.badArguments, "", why);
        ended(s, Failure::Unfit, text);
        failedReply(s, text, reply);
        return;
    }
    void* response = nullptr;
    bool stopped = false;
    const Failure failure = clients_.at(s)->call(request, deadline, response, stopped);
    sv.type.destroyRequest(request);
    if (failure != Failure::None) {
        const std::string text = stopped ? stoppedText(sv)
            : failure == Failure::NoServer ? sv.spec.reasons.noServer : sv.spec.reasons.timedOut;
        ended(s, failure, text);
        failedReply(s, text, reply);
        return;
    }
    sv.functions.reply(response, reply);
    sv.type.destroyResponse(response);
    ended(s, Failure::None, "");
    saySuccess(s, command, reply);
}

bool Module::openAll(std::string& what)
{
    if (!node_.open()) {
        what.clear();  // said
        return false;
    }
    rcl_node_t* node = node_.node();
    // the YARP ports called: a client port each (of the first service that calls it), its timeout the longest
    std::map<std::string, double> timeouts;
    std::map<std::string, std::string> locals;
    for (const Service& s : spec_.services) {
        if (s.spec.serves == Serves::Ros2) {
            timeouts[s.spec.port] = std::max(timeouts[s.spec.port], s.spec.timeout);
            locals.emplace(s.spec.port, options_.prefix + "/" + s.spec.name + "/rpc:o");
        }
    }
    for (const auto& [port, local] : locals) {
        callers_[port] = std::make_unique<YarpCaller>(*this, local, port, timeouts[port]);
    }
    for (std::size_t k = 0; k < spec_.services.size(); ++k) {
        const Service& s = spec_.services[k];
        if (s.spec.serves == Serves::Ros2) {
            servers_.resize(spec_.services.size());
            servers_[k] = std::make_unique<RosServer>(*this, k, *callers_.at(s.spec.port));
            if (!servers_[k]->open(node)) {
                return false;
            }
        } else {
            clients_[k] = std::make_unique<RosClient>(*this, s);
            if (!clients_[k]->open(node)) {
                return false;
            }
        }
    }
    servers_.resize(spec_.services.size());
    // the YARP ports served, and the module's own (one of them, or a port of its own)
    std::vector<std::string> names;
    for (const PortHelp& p : spec_.ports) {
        names.emplace_back(p.port);
    }
    if (std::find(names.begin(), names.end(), rpcName_) == names.end()) {
        names.push_back(rpcName_);
    }
    for (const std::string& name : names) {
        served_.push_back(std::make_unique<ServedPort>(*this, name));
        if (!served_.back()->open()) {
            served_.pop_back();
            what = "the port " + name;
            return false;
        }
    }
    for (auto& [port, caller] : callers_) {
        caller->start();
    }
    spinning_ = true;
    spinner_ = std::thread([this] { spin(); });
    // the services' counts on /diagnostics (parameters `diagnostics`, `diagnostic_updater.period`)
    double period = 1.0;
    if (node_.diagnostics(period)) {
        rcl_publisher_options_t options = rcl_publisher_get_default_options();
        options.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
        options.qos.depth = 1;
        options.qos.reliability = RMW_QOS_POLICY_RELIABILITY_RELIABLE;
        options.qos.durability = RMW_QOS_POLICY_DURABILITY_VOLATILE;
        if (rcl_publisher_init(&diagnostics_, node, ROSIDL_GET_MSG_TYPE_SUPPORT(diagnostic_msgs, msg, DiagnosticArray),
                               "/diagnostics", &options)
            != RCL_RET_OK) {
            say("cannot publish /diagnostics: " + rclError() + "; the module runs without it");
        } else {
            diagnosticsOk_ = true;
            diagnose_ = std::thread([this, period] { diagnose(period); });
        }
    }
    return true;
}

/// Every period of the steady clock: one status a service on /diagnostics,
/// stamped with the node's clock, until the module stops.
void Module::diagnose(double period)
{
    diagnostic_msgs__msg__DiagnosticArray msg;
    if (!diagnostic_msgs__msg__DiagnosticArray__init(&msg)) {
        say("cannot allocate a diagnostic_msgs/DiagnosticArray; no /diagnostics");
        return;
    }
    const auto step = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(period));
    TimePoint next = Clock::now() + step;
    const std::string node = node_.name();
    bool reported = false;
    for (;;) {
        std::vector<ybgc::ros2::Status> all;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            if (cv_.wait_until(lock, next, [this] { return stopping_; })) {
                break;
            }
            for (std::size_t s = 0; s < spec_.services.size(); ++s) {
                all.push_back(status(spec_.services[s].spec, counts_[s], node));
            }
        }
        next += step;
        ybgc::ros2::setTime(msg.header.stamp, node_.nowNs());
        if (!fillArray(msg, all, spec_.module) || rcl_publish(&diagnostics_, &msg, nullptr) != RCL_RET_OK) {
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

/// The ROS 2 thread: the requests of the services served and the responses
/// of the services called, taken through one wait set (woken every 50 ms to
/// see whether the module stops).
void Module::spin()
{
    std::vector<RosServer*> servers;
    for (const auto& s : servers_) {
        if (s != nullptr) {
            servers.push_back(s.get());
        }
    }
    std::vector<RosClient*> clients;
    for (const auto& [k, c] : clients_) {
        clients.push_back(c.get());
    }
    rcl_wait_set_t waitSet = rcl_get_zero_initialized_wait_set();
    if (rcl_wait_set_init(&waitSet, 0, 0, 0, clients.size(), servers.size(), 0, node_.context(),
                          rcl_get_default_allocator())
        != RCL_RET_OK) {
        say("cannot wait for the ROS 2 services: " + rclError());
        return;
    }
    while (spinning_) {
        finished(rcl_wait_set_clear(&waitSet));
        for (RosServer* s : servers) {
            finished(rcl_wait_set_add_service(&waitSet, s->service(), nullptr));
        }
        for (RosClient* c : clients) {
            finished(rcl_wait_set_add_client(&waitSet, c->client(), nullptr));
        }
        const rcl_ret_t woke = rcl_wait(&waitSet, RCL_MS_TO_NS(50));
        if (woke != RCL_RET_OK) {
            rcl_reset_error();
            if (woke != RCL_RET_TIMEOUT) {
                std::this_thread::sleep_for(std::chrono::milliseconds(10));  // no busy loop on an error
            }
            continue;
        }
        for (std::size_t k = 0; k < servers.size(); ++k) {
            if (waitSet.services[k] != nullptr) {
                servers[k]->take();
            }
        }
        for (std::size_t k = 0; k < clients.size(); ++k) {
            if (waitSet.clients[k] != nullptr) {
                clients[k]->take();
            }
        }
    }
    finished(rcl_wait_set_fini(&waitSet));
}

void Module::printTotals()
{
    std::string out = "totals:\n";
    std::lock_guard<std::mutex> lock(mutex_);
    for (std::size_t s = 0; s < spec_.services.size(); ++s) {
        out += totalsLine(spec_.services[s].spec.name, counts_[s]) + "\n";
    }
    printLines(out);
}

int Module::run()
{
    std::string what;
    int status = 0;
    if (!openAll(what)) {
        if (!what.empty()) {
            say("cannot open " + what);
        }
        status = 1;
    } else {
        for (const Service& s : spec_.services) {
            say(s.spec.description);
        }
        say("its RPC port: " + rpcName_ + " (help, stats, quit)");
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait(lock, [this] { return stopping_; });
    }
    requestStop();
    // the calls in flight answered (reason `stopped`) within 0.5 s
    for (auto& [port, caller] : callers_) {
        caller->stop();
    }
    for (auto& [k, client] : clients_) {
        client->stop();
    }
    const TimePoint grace = Clock::now() + std::chrono::milliseconds(500);
    while (active > 0 && Clock::now() < grace) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    // the ports closed in a thread of their own: a peer that does not answer
    // cannot hold the module beyond its deadline (its names are then unregistered)
    auto done = std::make_shared<Latch>();
    auto closedPorts = std::make_shared<std::set<std::string>>();
    auto closedMutex = std::make_shared<std::mutex>();
    std::thread closer([this, done, closedPorts, closedMutex] {
        const TimePoint deadline = Clock::now() + std::chrono::milliseconds(700);
        for (auto& p : served_) {
            p->close(std::chrono::milliseconds(300));
            std::lock_guard<std::mutex> lock(*closedMutex);
            closedPorts->insert(p->name);
        }
        bool all = true;
        for (auto& [port, caller] : callers_) {
            all = caller->close(deadline) && all;
        }
        if (all) {
            done->open();
        }
    });
    const bool closed = done->waitUntil(Clock::now() + std::chrono::milliseconds(1000));
    spinning_ = false;
    if (spinner_.joinable()) {
        spinner_.join();
    }
    if (diagnose_.joinable()) {
        diagnose_.join();  // woken by the stop
    }
    printTotals();
    if (!closed) {
        closer.detach();  // the process ends without it
        std::lock_guard<std::mutex> lock(*closedMutex);
        for (auto& p : served_) {
            if (closedPorts->count(p->name) == 0) {
                yarp::os::Network::unregisterName(p->name);
            }
        }
        for (auto& [port, caller] : callers_) {
            for (const std::string& name : caller->openNames()) {
                yarp::os::Network::unregisterName(name);
            }
        }
        std::fflush(stdout);
        std::_Exit(status);
    }
    closer.join();
    rcl_node_t* node = node_.node();
    if (diagnosticsOk_) {
        finished(rcl_publisher_fini(&diagnostics_, node));
    }
    for (auto& s : servers_) {
        if (s != nullptr) {
            s->fini(node);
        }
    }
    for (auto& [k, c] : clients_) {
        c->fini(node);
    }
    node_.close();
    return status;
}

}  // namespace

int run(const Commands& spec, int argc, char* argv[])
{
    gModule = spec.module;
    std::vector<std::string> rosArgs = ybgc::ros2::takeRosArgs(argc, argv);
    std::vector<std::string> fromParameters;
    if (const int status = ybgc::ros2::checkRosArgs(rosArgs, spec.node, &fromParameters)) {
        return status;
    }
    // the parameters a module of commands takes (prefix, verbose), before the command line's own options
    std::vector<std::string> words{argc > 0 ? argv[0] : spec.module};
    for (const std::string& option : fromParameters) {
        if (option.rfind("--prefix=", 0) == 0 || option == "--verbose") {
            words.push_back(option);
        }
    }
    for (int k = 1; k < argc; ++k) {
        words.emplace_back(argv[k]);
    }
    std::vector<char*> args;
    for (std::string& w : words) {
        args.push_back(w.data());
    }
    args.push_back(nullptr);
    Options options;
    const int status = parseOptions(spec, static_cast<int>(words.size()), args.data(), options);
    if (status >= 0) {
        return status;
    }
    Signals signals;  // before YARP or rcl starts any thread
    std::signal(SIGPIPE, SIG_IGN);
    yarp::os::Network network;
    if (!yarp::os::Network::checkNetwork(3.0)) {
        say("cannot reach the YARP name server (is yarpserver running?)");
        return 1;
    }
    Module module(spec, options, std::move(rosArgs));
    signals.start([&module] { module.requestStop(); });
    const int result = module.run();
    signals.finish();
    return result;
}

}  // namespace services
}  // namespace ybgc
