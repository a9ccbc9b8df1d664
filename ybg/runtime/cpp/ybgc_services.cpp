// The runtime of a module of commands (ybgc_services.hpp): a Bottle's
// elements checked, converted and put into fields; Bottles from fields; the
// counts, `stats`, the exit totals and the statuses of /diagnostics; and
// run(), which runs the bridge of commands (ybgc_services_node.cpp) in the
// process shell every kind of bridge runs in (ybgc_shell.cpp).
#include "ybgc_services.hpp"  // ybgc:runtime-import
#include "ybgc_services_internal.hpp"  // ybgc:runtime-import

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <yarp/os/Bottle.h>
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

// --- running it --------------------------------------------------------------------------------

namespace {

/// The rest of the --help of a module of commands: its options and ROS arguments.
void commandsHelp(const Commands& spec, std::FILE* out)
{
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
                 "                seconds between two /diagnostics messages (default: 1)\n",
                 spec.defaultPrefix);
}

}  // namespace

int run(const Commands& spec, int argc, char* argv[])
{
    RosCommandLine line(argc, argv, spec.module, spec.node, false);
    if (line.status != 0) {
        return line.status;
    }
    Start start;
    start.options.module = spec.module;
    start.options.config = spec.config;
    start.options.defaultPrefix = spec.defaultPrefix;
    start.options.usage = "[--name P] [--verbose] [--help] [--ros-args ...]";
    start.options.description = &spec.description;
    start.options.help = [&spec](std::FILE* out) { commandsHelp(spec, out); };
    start.make = [&spec, &line](const Options& options) -> std::unique_ptr<Bridge> {
        return std::make_unique<CommandsBridge>(spec, options, line.rosArgs);
    };
    return runBridge(start, line.argc(), line.argv());
}

}  // namespace services
}  // namespace ybgc
