// The reference relay of the benchmark: the least a bridge between YARP ports
// has to do, written by hand, for the generated modules to be measured
// against (two hops: producer -> relay -> consumer).
//
//   relay --inputs /a:o,/b:o --output /relay/out:o [--prefix /relay] [--rate HZ]
//
// It reads every input on a BufferedPort (newest Bottle only) with a callback,
// concatenates the inputs' float64 values, converts them from degrees to
// radians (x * pi / 180) and writes one flat Bottle of float64.
// - event-driven (default, --rate 0): the work is done in the callback of the
//   input that completes the set, as soon as every input has a new Bottle
//   since the last write (no other thread, no queue);
// - --rate HZ: a loop with absolute deadlines writes the newest values of
//   every input that delivered in the last second.
// No layout checks, no freshness reports, no statistics: only the work.
// SIGINT/SIGTERM close the ports and exit 0.

#include <time.h>

#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/BufferedPort.h>
#include <yarp/os/Network.h>
#include <yarp/os/TypedReaderCallback.h>

namespace {

constexpr double kDegToRad = M_PI / 180.0;
std::atomic<bool> gStop{false};

void onSignal(int) { gStop = true; }

double monotonicNow()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

struct Relay;

struct Input : public yarp::os::TypedReaderCallback<yarp::os::Bottle>
{
    Relay* relay = nullptr;
    std::size_t index = 0;
    yarp::os::BufferedPort<yarp::os::Bottle> port;
    std::vector<double> values;  // newest values (guarded by Relay::mutex)
    bool fresh = false;          // new since the last write
    double arrival = 0.0;

    using yarp::os::TypedReaderCallback<yarp::os::Bottle>::onRead;
    void onRead(yarp::os::Bottle& bottle) override;
};

struct Relay
{
    std::vector<std::unique_ptr<Input>> inputs;
    yarp::os::BufferedPort<yarp::os::Bottle> output;
    std::mutex mutex;
    bool eventDriven = true;

    // Called with the mutex held.
    void write()
    {
        yarp::os::Bottle& out = output.prepare();
        out.clear();
        for (auto& in : inputs) {
            for (double v : in->values) {
                out.addFloat64(v * kDegToRad);
            }
            in->fresh = false;
        }
        output.write();
    }
};

void Input::onRead(yarp::os::Bottle& bottle)
{
    std::lock_guard<std::mutex> lock(relay->mutex);
    values.resize(bottle.size());
    for (std::size_t i = 0; i < bottle.size(); ++i) {
        values[i] = bottle.get(i).asFloat64();
    }
    fresh = true;
    arrival = monotonicNow();
    if (!relay->eventDriven) {
        return;
    }
    for (auto& in : relay->inputs) {
        if (!in->fresh) {
            return;
        }
    }
    relay->write();
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
    double rate = 0.0;
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string key = argv[i];
        if (key == "--inputs") {
            sources = split(argv[i + 1], ',');
        } else if (key == "--output") {
            outputName = argv[i + 1];
        } else if (key == "--prefix") {
            prefix = argv[i + 1];
        } else if (key == "--rate") {
            rate = std::atof(argv[i + 1]);
        }
    }
    if (sources.empty()) {
        std::fprintf(stderr, "usage: relay --inputs A,B,... [--output P] [--prefix P] [--rate HZ]\n");
        return 2;
    }
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
    std::signal(SIGPIPE, SIG_IGN);  // a peer that goes away must not kill this process
    yarp::os::Network yarp;
    if (!yarp::os::Network::checkNetwork(5.0)) {
        std::fprintf(stderr, "relay: no YARP name server\n");
        return 1;
    }
    Relay relay;
    relay.eventDriven = rate <= 0.0;
    if (!relay.output.open(outputName)) {
        return 1;
    }
    for (std::size_t i = 0; i < sources.size(); ++i) {
        relay.inputs.emplace_back(new Input());
        Input& in = *relay.inputs.back();
        in.relay = &relay;
        in.index = i;
        in.port.setStrict(false);
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

    if (relay.eventDriven) {
        while (!gStop) {
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
    } else {
        const long long period = static_cast<long long>(1e9 / rate + 0.5);
        timespec next{};
        clock_gettime(CLOCK_MONOTONIC, &next);
        while (!gStop) {
            long long ns = static_cast<long long>(next.tv_nsec) + period;
            next.tv_sec += static_cast<time_t>(ns / 1000000000LL);
            next.tv_nsec = static_cast<long>(ns % 1000000000LL);
            timespec clock{};
            clock_gettime(CLOCK_MONOTONIC, &clock);
            const double behind = static_cast<double>(clock.tv_sec - next.tv_sec)
                + static_cast<double>(clock.tv_nsec - next.tv_nsec) * 1e-9;
            if (behind * rate > 1.0) {
                next = clock;  // overran by more than a period: skip, do not burst
            }
            clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
            std::lock_guard<std::mutex> lock(relay.mutex);
            const double now = monotonicNow();
            bool ready = true;
            for (auto& in : relay.inputs) {
                ready = ready && in->arrival > 0.0 && now - in->arrival < 1.0;
            }
            if (ready) {
                relay.write();
            }
        }
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
