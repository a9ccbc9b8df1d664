// What the C++ runtime says (ybgc_runtime.hpp, ybgc_internal.hpp): the
// messages printed, each mux printed with --verbose, and what a stream's RPC
// port answers (help, stats: its totals).
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <string>
#include <vector>
#include <utility>

#include <yarp/os/Bottle.h>

namespace ybgc {

const char* gModule = "";
thread_local const char* tModule = nullptr;

std::mutex& printMutex()
{
    static std::mutex m;
    return m;
}

/// Prints "<module>: <text>" on stdout, at once.
void say(const std::string& text)
{
    std::lock_guard<std::mutex> lock(printMutex());
    std::fprintf(stdout, "%s: %s\n", tModule != nullptr ? tModule : gModule, text.c_str());
    std::fflush(stdout);
}

/// Prints lines as they are (totals, verbose values).
void printLines(const std::string& text)
{
    std::lock_guard<std::mutex> lock(printMutex());
    std::fputs(text.c_str(), stdout);
    std::fflush(stdout);
}

/// Prints every element of a mux: "[<mux>] <index>: <value>".
void printMux(const char* name, const Mux& mux)
{
    std::string out;
    for (std::size_t k = 0; k < mux.size(); ++k) {
        out += "[" + std::string(name) + "] " + std::to_string(k) + ": " + mux[k].repr() + "\n";
    }
    printLines(out);
}

void printMux(const char* name, const Rows& rows)
{
    std::string out;
    for (std::size_t k = 0; k < rows.size(); ++k) {
        out += "[" + std::string(name) + "] " + std::to_string(k) + ": [";
        for (std::size_t j = 0; j < rows[k].size(); ++j) {
            out += (j > 0 ? ", " : "") + rows[k][j].repr();
        }
        out += "]\n";
    }
    printLines(out);
}

// --- a stream's RPC port (the convention of YARP modules) -------------------------------------

const std::vector<std::string> kStreamHelp = {
    "help: this list",
    "stats: the totals so far: per input (input SOURCE received N dropped N stale N unused N refused N), "
    "(published N skipped N failures N missed N), (rate ACHIEVED configured HZ|event-driven), and per ROS 2 publisher "
    "and subscription (ros2 publisher|subscription TOPIC incompatible_qos N incompatible_type N)",
    "quit: stop the module (it closes its ports and exits 0, as on SIGINT)",
};

/// A rate achieved as `stats` gives it: messages per second, two decimals.
std::string rateText(double rate)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.2f", rate);
    return buf;
}

double RateMeter::read(SteadyClock::time_point now, std::uint64_t published)
{
    const double seconds = std::chrono::duration<double>(now - then_).count();
    const double rate = seconds > 0 ? static_cast<double>(published - before_) / seconds : 0.0;
    then_ = now;
    before_ = published;
    return rate;
}

void statsItems(yarp::os::Bottle& out, const Totals& totals, double achieved, double rate)
{
    for (const Totals::PerInput& in : totals.inputs) {
        yarp::os::Bottle& item = out.addList();
        item.addString("input");
        item.addString(in.source);
        for (const auto& [key, n] : {std::pair<const char*, std::uint64_t>{"received", in.received},
                                     {"dropped", in.dropped}, {"stale", in.stale}, {"unused", in.unused},
                                     {"refused", in.refused}}) {
            item.addString(key);
            item.addInt64(static_cast<std::int64_t>(n));
        }
    }
    yarp::os::Bottle& counts = out.addList();
    for (const auto& [key, n] : {std::pair<const char*, std::uint64_t>{"published", totals.published},
                                 {"skipped", totals.skipped}, {"failures", totals.failures},
                                 {"missed", totals.missed}}) {
        counts.addString(key);
        counts.addInt64(static_cast<std::int64_t>(n));
    }
    // the rates as text, with the digits that mean something (a float64
    // prints with 21 digits)
    yarp::os::Bottle& line = out.addList();
    line.addString("rate");
    line.addString(rateText(achieved));
    line.addString("configured");
    line.addString(rate > 0 ? reprFloat(rate) : std::string("event-driven"));
    // the incompatible peers of its ROS 2 publishers and subscriptions
    for (const Totals::Ros2Endpoint& e : totals.ros2) {
        yarp::os::Bottle& item = out.addList();
        item.addString("ros2");
        item.addString(e.kind);
        item.addString(e.topic);
        item.addString("incompatible_qos");
        item.addInt64(static_cast<std::int64_t>(e.qos));
        item.addString("incompatible_type");
        item.addInt64(static_cast<std::int64_t>(e.type));
    }
}

std::string ros2TotalsLine(const Totals::Ros2Endpoint& e)
{
    return "ros2 " + e.kind + " " + e.topic + ": incompatible QoS " + std::to_string(e.qos) + ", incompatible type "
        + std::to_string(e.type);
}

std::string missedLine(std::uint64_t missed)
{
    return "readers missed " + std::to_string(missed)
        + " messages (each written while a reader was still taking the one before)";
}

}  // namespace ybgc
