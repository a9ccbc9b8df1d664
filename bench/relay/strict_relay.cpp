// The second floor of the benchmark: a relay written by hand that reads its
// inputs as strictly as a generated C++ module does (docs/runtime.md,
// "Reading" and "Which Bottles a message uses"), so that the module can be
// measured against the same necessary work, done plainly (two hops:
// producer -> relay -> consumer).
//
//   strict_relay --inputs /a:o,/b:o --width 15 --output /relay/out:o [--prefix /relay]
//
// Event-driven only. Each Bottle, in its input's callback (YARP's reader thread):
// - every Bottle reaches the callback, in order (a strict BufferedPort): none
//   is replaced by a newer one before the callback runs; a reader more than
//   kBacklog unread Bottles behind skips the oldest unread ones, so that it
//   catches up rather than lags;
// - its layout is checked: exactly --width elements, each a number (an
//   integer or a float64; a float32 only before YARP 4, which gave float32
//   the tag YARP 3 gives float64); a Bottle that fails is dropped, silently;
// - its envelope stamp is read (the acquisition time, shared by the Bottles
//   of one tick on every port), and it is queued with its values and its
//   arrival time; a queue holds at most kQueue Bottles (the oldest goes).
// Then, as long as every input has a queued Bottle and delivered one less
// than kTimeout ago (freshness: no message from stale data): one Bottle of
// each input, matched in time (the reference is the newest of the inputs'
// oldest queued Bottles, and each input takes its queued Bottle nearest to
// it, the older on a tie; by envelope stamps when every queued Bottle has
// one, else by arrival times), the older queued ones discarded. Their values
// are concatenated, converted from degrees to radians (x * pi / 180) and
// written as one flat Bottle of float64, without an envelope (the module
// writes none on an untyped Bottle output). A write waits for the previous
// one (50 ms at most, and not again once a reader has shown it stalls), or
// it would be dropped for a connection still sending.
// No statistics, no reports, no reconnection watcher: only the work.
// SIGINT/SIGTERM close the ports and exit 0.

#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <yarp/conf/version.h>
#include <yarp/os/Bottle.h>
#include <yarp/os/BufferedPort.h>
#include <yarp/os/Network.h>
#include <yarp/os/Stamp.h>
#include <yarp/os/TypedReaderCallback.h>

namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr int kBacklog = 64;           // unread Bottles before the oldest are skipped
constexpr std::size_t kQueue = 64;     // queued Bottles per input
constexpr double kTimeout = 1.0;       // freshness, seconds
std::atomic<bool> gStop{false};

void onSignal(int) { gStop = true; }

double monotonicNow()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

// A number where a float64 is expected (as the module takes it).
bool isNumber(const yarp::os::Value& v)
{
    return v.isInt8() || v.isInt16() || v.isInt32() || v.isInt64() || v.isFloat64()
        || (v.isFloat32() && YARP_VERSION_MAJOR < 4);
}

struct Pending
{
    std::vector<double> values;
    bool hasStamp = false;
    double stamp = 0.0;    // envelope time
    double arrival = 0.0;  // monotonic
};

struct Relay;

struct Input : public yarp::os::TypedReaderCallback<yarp::os::Bottle>
{
    Relay* relay = nullptr;
    yarp::os::BufferedPort<yarp::os::Bottle> port;
    std::deque<Pending> queue;  // accepted, not used yet, oldest first (guarded by Relay::mutex)
    double arrival = 0.0;       // of the newest accepted Bottle

    using yarp::os::TypedReaderCallback<yarp::os::Bottle>::onRead;
    void onRead(yarp::os::Bottle& bottle) override;
};

struct Relay
{
    std::vector<std::unique_ptr<Input>> inputs;
    yarp::os::BufferedPort<yarp::os::Bottle> output;
    std::mutex mutex;
    std::size_t width = 0;
    bool patient = true;

    // Called with the mutex held: every input has a queued Bottle, all fresh.
    bool ready(double now) const
    {
        for (const auto& in : inputs) {
            if (in->queue.empty() || now - in->arrival >= kTimeout) {
                return false;
            }
        }
        return true;
    }

    // Called with the mutex held, when ready().
    void publish()
    {
        bool byStamp = true;
        for (const auto& in : inputs) {
            for (const Pending& p : in->queue) {
                byStamp = byStamp && p.hasStamp;
            }
        }
        auto when = [byStamp](const Pending& p) { return byStamp ? p.stamp : p.arrival; };
        double reference = when(inputs.front()->queue.front());
        for (const auto& in : inputs) {
            reference = std::max(reference, when(in->queue.front()));
        }
        yarp::os::Bottle& out = output.prepare();
        out.clear();
        for (auto& in : inputs) {
            std::size_t best = 0;
            double gap = std::fabs(when(in->queue[0]) - reference);
            for (std::size_t k = 1; k < in->queue.size(); ++k) {
                const double g = std::fabs(when(in->queue[k]) - reference);
                if (g < gap) {
                    gap = g;
                    best = k;
                }
            }
            in->queue.erase(in->queue.begin(), in->queue.begin() + static_cast<std::ptrdiff_t>(best));
            for (double v : in->queue.front().values) {
                out.addFloat64(v * kDegToRad);
            }
            in->queue.pop_front();
        }
        if (output.isWriting()) {
            if (patient) {
                const double deadline = monotonicNow() + 0.05;
                while (output.isWriting() && monotonicNow() < deadline) {
                    std::this_thread::sleep_for(std::chrono::microseconds(50));
                }
                patient = !output.isWriting();
            }
        } else {
            patient = true;
        }
        output.write();
    }
};

void Input::onRead(yarp::os::Bottle& bottle)
{
    const double now = monotonicNow();
    if (port.getPendingReads() > kBacklog) {
        return;  // far behind: skipped unread
    }
    const std::size_t n = bottle.size();
    if (n != relay->width) {
        return;
    }
    Pending entry;
    entry.values.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const yarp::os::Value& v = bottle.get(i);
        if (!isNumber(v)) {
            return;
        }
        entry.values[i] = v.asFloat64();
    }
    yarp::os::Stamp stamp;
    entry.hasStamp = port.getEnvelope(stamp) && stamp.isValid();
    entry.stamp = entry.hasStamp ? stamp.getTime() : 0.0;
    entry.arrival = now;
    std::lock_guard<std::mutex> lock(relay->mutex);
    queue.push_back(std::move(entry));
    if (queue.size() > kQueue) {
        queue.pop_front();
    }
    arrival = now;
    while (!gStop && relay->ready(now)) {
        relay->publish();
    }
}

std::vector<std::string> split(const std::string& s, char sep)
{
    std::vector<std::string> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, sep)) {
        if (!item.empty()) {
            out.push_back(item);
        }
    }
    return out;
}

} // namespace

int main(int argc, char* argv[])
{
    std::vector<std::string> sources;
    std::string outputName = "/relay/out:o";
    std::string prefix = "/relay";
    int width = 0;
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string key = argv[i];
        if (key == "--inputs") {
            sources = split(argv[i + 1], ',');
        } else if (key == "--width") {
            width = std::atoi(argv[i + 1]);
        } else if (key == "--output") {
            outputName = argv[i + 1];
        } else if (key == "--prefix") {
            prefix = argv[i + 1];
        }
    }
    if (sources.empty() || width <= 0) {
        std::fprintf(stderr, "usage: strict_relay --inputs A,B,... --width N [--output P] [--prefix P]\n");
        return 2;
    }
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
    std::signal(SIGPIPE, SIG_IGN);  // a peer that goes away must not kill this process
    yarp::os::Network yarp;
    if (!yarp::os::Network::checkNetwork(5.0)) {
        std::fprintf(stderr, "strict_relay: no YARP name server\n");
        return 1;
    }
    Relay relay;
    relay.width = static_cast<std::size_t>(width);
    relay.output.setWriteOnly();
    if (!relay.output.open(outputName)) {
        return 1;
    }
    for (std::size_t i = 0; i < sources.size(); ++i) {
        relay.inputs.emplace_back(new Input());
        Input& in = *relay.inputs.back();
        in.relay = &relay;
        in.port.setStrict(true);
        in.port.useCallback(in);
        if (!in.port.open(prefix + "/in" + std::to_string(i) + ":i")) {
            return 1;
        }
    }
    // connect the sources (they may start later)
    std::vector<bool> connected(sources.size(), false);
    std::size_t left = sources.size();
    while (left > 0 && !gStop) {
        for (std::size_t i = 0; i < sources.size(); ++i) {
            if (!connected[i] && yarp::os::Network::exists(sources[i], true)
                && yarp::os::Network::connect(sources[i], relay.inputs[i]->port.getName(), "tcp", true)) {
                connected[i] = true;
                --left;
            }
        }
        if (left > 0) {
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
    }
    while (!gStop) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    for (auto& in : relay.inputs) {
        in->port.interrupt();
        in->port.disableCallback();
        in->port.close();
    }
    relay.output.interrupt();
    relay.output.close();
    return 0;
}
