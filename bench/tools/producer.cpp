// Benchmark producer: writes stamped Bottles of float64 on N YARP ports.
//
//   bench_producer --ports /bench/src0:o,/bench/src1:o --width 15 [--write strict|plain]
//
// Commands on stdin, one a line; each answers with one line on stdout,
// starting with "@" (YARP prints its own messages there too):
//   wait N TIMEOUT   wait until every port has at least N output connections
//                    -> "ok <min connections>" or "timeout <min connections>"
//   run COUNT RATE   COUNT ticks at RATE Hz with absolute deadlines; at each
//                    tick every port writes one Bottle (in port order)
//                    -> "done <first seq> <ticks> <late ticks> <elapsed s>"
//   quit             close the ports and exit
//
// Bottle of port p at tick s (width W >= 3), before any conversion:
//   [s, t, p, f(p,3), ..., f(p,W-1)]   with f(p,i) = p*1000 + i + 0.5
// where t is CLOCK_MONOTONIC in seconds taken just before the write (the
// latency is measured from it). The envelope carries (s, the tick's time):
// one acquisition stamp for every port of a tick, as a robot's state ports
// do (the joints sampled in one control cycle), whenever each write happens.
// Writes are strict by default (a Bottle is never dropped by the producer).
// --write plain: YARP's plain write(), as a robot's devices write their state
// ports: a Bottle is not sent on a connection still busy with the one before,
// and the producer never waits for a connection. A peer stopped and started
// again (bench/compose.py does, for the start time) can leave a connection
// whose send never completes: a strict write would wait for it, and no port
// would be written again.

#include <time.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/BufferedPort.h>
#include <yarp/os/Network.h>
#include <yarp/os/Stamp.h>

namespace {

double monotonicNow()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

void sleepUntil(const timespec& t)
{
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, nullptr) != 0) {
    }
}

void addNs(timespec& t, long long ns)
{
    long long total = static_cast<long long>(t.tv_nsec) + ns;
    t.tv_sec += static_cast<time_t>(total / 1000000000LL);
    t.tv_nsec = static_cast<long>(total % 1000000000LL);
}

bool before(const timespec& a, const timespec& b)
{
    return a.tv_sec < b.tv_sec || (a.tv_sec == b.tv_sec && a.tv_nsec < b.tv_nsec);
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

void answer(const std::string& line)
{
    std::fputs(("@" + line + "\n").c_str(), stdout);
    std::fflush(stdout);
}

} // namespace

int main(int argc, char* argv[])
{
    std::vector<std::string> names;
    int width = 15;
    bool strict = true;
    bool usage = false;
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string key = argv[i];
        const std::string value = argv[i + 1];
        if (key == "--ports") {
            names = split(value, ',');
        } else if (key == "--width") {
            width = std::atoi(value.c_str());
        } else if (key == "--write" && (value == "strict" || value == "plain")) {
            strict = value == "strict";
        } else {
            usage = true;
        }
    }
    if (usage || names.empty() || width < 3) {
        std::fprintf(stderr, "usage: bench_producer --ports A,B,... --width W (W >= 3) [--write strict|plain]\n");
        return 2;
    }
    std::signal(SIGPIPE, SIG_IGN);  // a peer that goes away must not kill this process
    yarp::os::Network yarp;
    if (!yarp::os::Network::checkNetwork(5.0)) {
        std::fprintf(stderr, "bench_producer: no YARP name server\n");
        return 1;
    }
    std::vector<std::unique_ptr<yarp::os::BufferedPort<yarp::os::Bottle>>> ports;
    for (const auto& name : names) {
        ports.emplace_back(new yarp::os::BufferedPort<yarp::os::Bottle>());
        if (!ports.back()->open(name)) {
            std::fprintf(stderr, "bench_producer: cannot open %s\n", name.c_str());
            return 1;
        }
    }
    answer("ready");

    double seq = 0.0;
    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string cmd;
        in >> cmd;
        if (cmd == "wait") {
            int want = 1;
            double timeout = 10.0;
            in >> want >> timeout;
            const double end = monotonicNow() + timeout;
            int least = 0;
            while (true) {
                least = 1 << 30;
                for (auto& p : ports) {
                    least = std::min(least, p->getOutputCount());
                }
                if (least >= want || monotonicNow() > end) {
                    break;
                }
                timespec t{0, 20 * 1000000L};
                nanosleep(&t, nullptr);
            }
            answer((least >= want ? "ok " : "timeout ") + std::to_string(least));
        } else if (cmd == "run") {
            long long count = 0;
            double rate = 100.0;
            in >> count >> rate;
            const long long period = static_cast<long long>(1e9 / rate + 0.5);
            const double first = seq + 1.0;
            long long late = 0;
            const double t0 = monotonicNow();
            timespec next{};
            clock_gettime(CLOCK_MONOTONIC, &next);
            for (long long k = 0; k < count; ++k) {
                seq += 1.0;
                // the tick's acquisition time: one stamp for every port
                const double sampled = monotonicNow();
                for (std::size_t p = 0; p < ports.size(); ++p) {
                    yarp::os::Bottle& b = ports[p]->prepare();
                    b.clear();
                    const double t = monotonicNow();
                    b.addFloat64(seq);
                    b.addFloat64(t);
                    b.addFloat64(static_cast<double>(p));
                    for (int i = 3; i < width; ++i) {
                        b.addFloat64(static_cast<double>(p) * 1000.0 + i + 0.5);
                    }
                    yarp::os::Stamp stamp(static_cast<int>(seq), sampled);
                    ports[p]->setEnvelope(stamp);
                    if (strict) {
                        ports[p]->writeStrict();
                    } else {
                        ports[p]->write();
                    }
                }
                addNs(next, period);
                timespec now{};
                clock_gettime(CLOCK_MONOTONIC, &now);
                if (before(next, now)) {
                    ++late;  // behind schedule: go on at once (no sleep)
                } else {
                    sleepUntil(next);
                }
            }
            std::ostringstream out;
            out.precision(9);
            out << "done " << static_cast<long long>(first) << " " << count << " " << late << " "
                << (monotonicNow() - t0);
            answer(out.str());
        } else if (cmd == "quit") {
            break;
        } else if (!cmd.empty()) {
            answer("error unknown command " + cmd);
        }
    }
    for (auto& p : ports) {
        p->waitForWrite();
        p->close();
    }
    return 0;
}
