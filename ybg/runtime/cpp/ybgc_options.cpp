// The C++ runtime's command line (ybgc_internal.hpp), for every kind of
// bridge: the options and their checks, those read from a YARP config file
// (--from, --context) with YARP's ResourceFinder, the ROS arguments taken out
// of it; and a stream's --help.
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include <yarp/os/ResourceFinder.h>

namespace ybgc {

/// The YARP config file read from a ResourceFinder context given alone (--context CTX).
const char* const kDefaultConfigFile = "config.ini";

std::string formatNumber(double x)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
}

namespace {

/// The rest of a stream's --help: its options and ROS arguments.
void streamHelp(const BridgeSpec& spec, std::FILE* out)
{
    std::fprintf(out,
                 "\noptions:\n"
                 "  --name P      prefix of the module's own port names, as YARP modules name it (default: %s)\n"
                 "  --prefix P    the same as --name\n"
                 "  --rate HZ     fixed output rate in Hz, 0 for event-driven (default: %s)\n"
                 "  --timeout S   freshness timeout of every input in seconds (default: the config's)\n"
                 "  --verbose     print every value after conversion, for every mux\n"
                 "  --accept [PORT=]OTHER\n"
                 "                the input of YARP port PORT also takes the Bottles of port OTHER (a replay\n"
                 "                under another name); OTHER alone: the module's one YARP port input; any\n"
                 "                other port's Bottles are refused. May be given several times\n"
                 "  --from FILE   read these options (name, prefix, rate, timeout, verbose) from a YARP\n"
                 "                config file, found by YARP's ResourceFinder; the command line wins\n"
                 "  --context CTX the ResourceFinder's context to look for the file in (alone: %s)\n"
                 "  --help        print this help and exit\n",
                 spec.defaultPrefix, spec.rate > 0 ? formatNumber(spec.rate).c_str() : "event-driven",
                 kDefaultConfigFile);
    bool ros2 = spec.output.kind == OutputKind::Ros2;
    for (const InputSpec& in : spec.inputs) {
        ros2 = ros2 || in.kind == InputKind::Ros2;
    }
    if (ros2) {
        std::fprintf(out,
                     "\nROS arguments (--ros-args ... [--], as for every ROS 2 program): remappings\n"
                     "(-r FROM:=TO), parameters (-p NAME:=VALUE, --params-file FILE), --log-level. Parameters:\n"
                     "  rate, timeout, prefix, verbose, accept\n"
                     "                as the options above (timeout 0: the config's); the options win\n"
                     "  use_sim_time  the node's clock is the simulated time of /clock (default: false)\n"
                     "  diagnostics   publish the bridge's state on /diagnostics (default: true)\n"
                     "  diagnostic_updater.period\n"
                     "                seconds between two /diagnostics messages (default: 1)\n"
                     "  qos_overrides./TOPIC.publisher.POLICY (.subscription. for inputs)\n"
                     "                history, depth, reliability, durability over the config's\n");
    }
}

bool parseNumber(const std::string& text, double& out)
{
    if (text.empty()) {
        return false;
    }
    char* end = nullptr;
    errno = 0;
    out = std::strtod(text.c_str(), &end);
    return errno == 0 && end == text.c_str() + text.size() && std::isfinite(out);
}

/// Adds `--accept` `value` to `accept`: `PORT=OTHER` (the input of YARP port
/// PORT, one of `ports`, also takes the Bottles of port OTHER), or `OTHER`
/// for a module of one YARP port input; false (`why` says it) for anything else.
bool parseAccept(const std::vector<std::string>& ports, const std::string& value,
                 std::vector<std::pair<std::string, std::string>>& accept, std::string& why)
{
    std::string read;
    for (const std::string& port : ports) {
        read += (read.empty() ? "" : ", ") + port;
    }
    if (read.empty()) {
        read = "no YARP port";
    }
    const std::size_t split = value.find('=');
    std::string port;
    std::string other = value;
    if (split == std::string::npos) {
        if (ports.size() != 1) {
            why = "--accept " + value + ": say which input takes it, --accept PORT=" + value + " (the module reads "
                + read + ")";
            return false;
        }
        port = ports.front();
    } else {
        port = value.substr(0, split);
        other = value.substr(split + 1);
    }
    if (std::find(ports.begin(), ports.end(), port) == ports.end()) {
        why = "--accept " + value + ": " + port + " is not a YARP port the module reads (it reads " + read + ")";
        return false;
    }
    if (other.size() < 2 || other[0] != '/'
        || std::any_of(other.begin(), other.end(), [](unsigned char c) { return std::isspace(c) != 0; })) {
        why = "--accept " + value + ": '" + other + "' is not a YARP port name";
        return false;
    }
    accept.emplace_back(port, other);
    return true;
}

/// Parses `args` into `opt` (from the config's defaults): -1 to go on, 0
/// after --help, else `why` says what is wrong.
int parseArgs(const OptionsSpec& spec, const std::string& prog, const std::vector<std::string>& args, Options& opt,
              std::string& why)
{
    opt = Options();
    opt.prefix = spec.defaultPrefix;
    opt.rate = spec.rate;
    for (std::size_t k = 0; k < args.size(); ++k) {
        std::string arg = args[k];
        std::string value;
        bool inlineValue = false;
        const std::size_t eq = arg.find('=');
        if (arg.rfind("--", 0) == 0 && eq != std::string::npos) {
            value = arg.substr(eq + 1);
            arg = arg.substr(0, eq);
            inlineValue = true;
        }
        if (arg == "--help" || arg == "-h") {
            printUsage(spec, prog, stdout, true);
            return 0;
        }
        if (arg == "--verbose") {
            if (inlineValue) {
                why = "--verbose takes no value";
                return 2;
            }
            opt.verbose = true;
            continue;
        }
        const bool streams = arg == "--rate" || arg == "--timeout" || arg == "--from" || arg == "--context"
            || arg == "--accept";
        if (arg != "--prefix" && arg != "--name" && !(streams && spec.stream)) {
            why = "unknown option " + arg;
            return 2;
        }
        if (!inlineValue) {
            if (k + 1 >= args.size()) {
                why = arg + " needs a value";
                return 2;
            }
            value = args[++k];
        }
        if (arg == "--prefix") {
            if (value.empty() || value[0] != '/') {
                why = "--prefix must start with /";
                return 2;
            }
            opt.prefix = value;
        } else if (arg == "--name") {
            opt.prefix = value.empty() || value[0] != '/' ? "/" + value : value;  // `--name foo`, as YARP modules take it
        } else if (arg == "--from") {
            opt.from = value;
        } else if (arg == "--context") {
            opt.context = value;
        } else if (arg == "--accept") {
            if (!parseAccept(spec.ports, value, opt.accept, why)) {
                return 2;
            }
        } else if (arg == "--rate") {
            if (!parseNumber(value, opt.rate) || opt.rate < 0) {
                why = "--rate must be 0 (event-driven) or positive";
                return 2;
            }
        } else {
            if (!parseNumber(value, opt.timeout) || opt.timeout <= 0) {
                why = "--timeout must be positive";
                return 2;
            }
            opt.hasTimeout = true;
        }
    }
    return -1;
}

/// The options in the YARP config file `--from path` / `--context context`
/// (alone: its kDefaultConfigFile), found by YARP's ResourceFinder as every
/// YARP module finds its own, appended to `out` as command-line arguments;
/// false (`why` says it) when there is no such file.
bool readConfigFile(const OptionsSpec& spec, const std::string& path, const std::string& context,
                    std::vector<std::string>& out, std::string& why)
{
    yarp::os::ResourceFinder finder;
    finder.setQuiet(true);
    finder.setDefaultConfigFile(kDefaultConfigFile);
    std::vector<std::string> args{spec.module};
    if (!context.empty()) {
        args.insert(args.end(), {"--context", context});
    }
    if (!path.empty()) {
        args.insert(args.end(), {"--from", path});
    }
    std::vector<char*> argv;
    for (std::string& arg : args) {
        argv.push_back(&arg[0]);
    }
    const bool configured = finder.configure(static_cast<int>(argv.size()), argv.data());
    const std::string found = configured ? finder.findFile("from") : std::string();
    if (found.empty()) {
        why = "YARP's ResourceFinder finds no config file " + (path.empty() ? std::string(kDefaultConfigFile) : path)
            + (context.empty() ? std::string() : " in the context " + context);
        return false;
    }
    for (const char* key : {"name", "prefix", "rate", "timeout"}) {
        if (finder.check(key)) {
            out.push_back(std::string("--") + key);
            out.push_back(finder.find(key).toString());
        }
    }
    if (finder.check("verbose")) {
        std::string flag = finder.find("verbose").toString();
        std::transform(flag.begin(), flag.end(), flag.begin(), [](unsigned char c) { return std::tolower(c); });
        if (flag == "" || flag == "true" || flag == "1") {
            out.push_back("--verbose");
        } else if (flag != "false" && flag != "0") {
            why = found + ": verbose must be true or false";
            return false;
        }
    }
    return true;
}

}  // namespace

void printUsage(const OptionsSpec& spec, const std::string& prog, std::FILE* out, bool full)
{
    std::fprintf(out, "usage: %s %s\n", prog.c_str(), spec.usage);
    if (!full) {
        return;
    }
    std::fprintf(out, "\n");
    if (spec.description != nullptr) {
        for (const char* line : *spec.description) {
            std::fprintf(out, "%s\n", line);
        }
    }
    if (spec.help) {
        spec.help(out);
    }
    std::fprintf(out, "\nGenerated by ybgc from %s.\n", spec.config);
}

int parseOptions(const OptionsSpec& spec, int argc, char* argv[], Options& opt)
{
    std::string prog = argc > 0 && argv[0][0] != '\0' ? argv[0] : spec.module;
    prog = prog.substr(prog.rfind('/') + 1);
    auto fail = [&](const std::string& text) {
        printUsage(spec, prog, stderr, false);
        std::fprintf(stderr, "%s: error: %s\n", prog.c_str(), text.c_str());
        return 2;
    };
    std::vector<std::string> args(argv + (argc > 0 ? 1 : 0), argv + argc);
    std::string why;
    int status = parseArgs(spec, prog, args, opt, why);
    if (status < 0 && (!opt.from.empty() || !opt.context.empty())) {
        std::vector<std::string> withFile;
        if (!readConfigFile(spec, opt.from, opt.context, withFile, why)) {
            return fail(why);
        }
        withFile.insert(withFile.end(), args.begin(), args.end());
        status = parseArgs(spec, prog, withFile, opt, why);
    }
    if (status >= 0) {
        return status == 0 ? 0 : fail(why);
    }
    while (opt.prefix.size() > 1 && opt.prefix.back() == '/') {
        opt.prefix.pop_back();
    }
    return -1;
}

OptionsSpec streamOptions(const BridgeSpec& spec)
{
    OptionsSpec out;
    out.module = spec.module;
    out.defaultPrefix = spec.defaultPrefix;
    out.stream = true;
    out.rate = spec.rate;
    for (const InputSpec& in : spec.inputs) {
        if (in.kind == InputKind::Yarp && std::find(out.ports.begin(), out.ports.end(), in.source) == out.ports.end()) {
            out.ports.emplace_back(in.source);
        }
    }
    out.config = spec.config;
    out.usage = "[--name P] [--rate HZ] [--timeout S] [--verbose] [--accept [PORT=]OTHER] [--from FILE]\n"
                "       [--context CTX] [--help]";
    out.description = &spec.description;
    out.help = [&spec](std::FILE* to) { streamHelp(spec, to); };
    return out;
}

// --- the ROS arguments -------------------------------------------------------------------

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
    argc = std::min(argc, kept);
    argv[argc] = nullptr;
    return rosArgs;
}

CommandLine::CommandLine(int argc, char* argv[], const std::vector<std::string>& before)
{
    words_.emplace_back(argc > 0 ? argv[0] : "");
    words_.insert(words_.end(), before.begin(), before.end());
    for (int k = 1; k < argc; ++k) {
        words_.emplace_back(argv[k]);
    }
    for (std::string& w : words_) {
        argv_.push_back(w.data());
    }
    argv_.push_back(nullptr);
}

}  // namespace ybgc
