// Benchmark consumer: records the receive time of every Bottle arriving on a
// YARP port, with the sequence numbers and send times the producer put in it.
//
//   bench_consumer --port /bench/sink:i --width 15 [--scale deg]
//                  [--source /a:o]... [--stall-every S --stall-for D] [--no-record]
//
// The port is a plain yarp::os::Port (one per source when there are several)
// whose reader runs in the connection's own thread, so nothing is buffered or dropped here: a Bottle is recorded as
// soon as it is read off the socket. With --stall-every/--stall-for the reader
// sleeps D seconds every S seconds, which stops reading the socket (the
// sender sees a consumer that stalls).
//
// A Bottle is read as blocks of W values (one per producer port, see
// producer.cpp): block k holds [seq, t, port, fillers...], all multiplied by
// pi/180 with --scale deg (what a deg_to_rad bridge does). The fillers are
// checked; a Bottle that does not match is counted as bad.
//
// Commands on stdin (one answer line each on stdout, starting with "@"):
//   count           -> "count <records> <bad>"
//   reset           -> "reset" (forget the records)
//   dump PATH       -> "dumped <records>": raw float64, 11 per record:
//                      recv, blocks, bad, then (seq, t) of the first 4 blocks
//   quit
// Sources given with --source are connected (retried until they exist);
// "connected" is printed once all are.

#include <execinfo.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/ConnectionReader.h>
#include <yarp/os/Network.h>
#include <yarp/os/Port.h>
#include <yarp/os/PortReader.h>

namespace {

constexpr int kFields = 11;
constexpr int kMaxBlocks = 4;

double monotonicNow()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

/// On a crash, the stack on stderr (the harness shows the log), then the
/// default action.
void onCrash(int sig)
{
    void* frames[64];
    const int n = backtrace(frames, 64);
    const char text[] = "bench_consumer: crashed, stack:\n";
    ssize_t ignored = write(2, text, sizeof text - 1);
    (void)ignored;
    backtrace_symbols_fd(frames, n, 2);
    std::signal(sig, SIG_DFL);
    raise(sig);
}

void answer(const std::string& line)
{
    std::fputs(("@" + line + "\n").c_str(), stdout);
    std::fflush(stdout);
}

class Recorder : public yarp::os::PortReader
{
public:
    int width = 15;
    double scale = 1.0;
    bool record = true;
    double stallEvery = 0.0;
    double stallFor = 0.0;

    std::mutex mutex;
    std::vector<double> data;
    long long count = 0;
    long long bad = 0;
    double nextStall = 0.0;

    bool read(yarp::os::ConnectionReader& connection) override
    {
        yarp::os::Bottle b;
        if (!b.read(connection)) {
            return false;
        }
        const double recv = monotonicNow();
        double rec[kFields] = {recv, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
        const int size = static_cast<int>(b.size());
        bool isBad = size == 0 || size % width != 0;
        const int blocks = isBad ? 0 : size / width;
        rec[1] = blocks;
        for (int k = 0; k < blocks && !isBad; ++k) {
            const int base = k * width;
            const double seq = b.get(base).asFloat64() / scale;
            const double t = b.get(base + 1).asFloat64() / scale;
            const double port = std::round(b.get(base + 2).asFloat64() / scale);
            for (int i = 3; i < width; ++i) {
                const double want = (port * 1000.0 + i + 0.5) * scale;
                const double got = b.get(base + i).asFloat64();
                if (std::fabs(got - want) > 1e-9 * std::fabs(want)) {
                    isBad = true;
                    break;
                }
            }
            if (k < kMaxBlocks) {
                rec[3 + 2 * k] = std::round(seq);
                rec[4 + 2 * k] = t;
            }
        }
        rec[2] = isBad ? 1 : 0;
        {
            std::lock_guard<std::mutex> lock(mutex);
            ++count;
            if (isBad) {
                ++bad;
            }
            if (record) {
                data.insert(data.end(), rec, rec + kFields);
            }
        }
        if (stallEvery > 0.0 && stallFor > 0.0) {
            if (nextStall == 0.0) {
                nextStall = recv + stallEvery;
            } else if (recv >= nextStall) {
                std::this_thread::sleep_for(std::chrono::duration<double>(stallFor));
                nextStall = monotonicNow() + stallEvery;
            }
        }
        return true;
    }
};

} // namespace

int main(int argc, char* argv[])
{
    std::string portName = "/bench/sink:i";
    std::vector<std::string> sources;
    Recorder recorder;
    for (int i = 1; i < argc; ++i) {
        const std::string key = argv[i];
        const bool hasValue = i + 1 < argc;
        if (key == "--no-record") {
            recorder.record = false;
        } else if (key == "--port" && hasValue) {
            portName = argv[++i];
        } else if (key == "--width" && hasValue) {
            recorder.width = std::atoi(argv[++i]);
        } else if (key == "--scale" && hasValue) {
            const std::string s = argv[++i];
            recorder.scale = s == "deg" ? M_PI / 180.0 : std::atof(s.c_str());
        } else if (key == "--source" && hasValue) {
            sources.emplace_back(argv[++i]);
        } else if (key == "--stall-every" && hasValue) {
            recorder.stallEvery = std::atof(argv[++i]);
        } else if (key == "--stall-for" && hasValue) {
            recorder.stallFor = std::atof(argv[++i]);
        } else {
            std::fprintf(stderr, "bench_consumer: unknown argument %s\n", key.c_str());
            return 2;
        }
    }
    if (recorder.width < 3) {
        std::fprintf(stderr, "bench_consumer: --width must be >= 3\n");
        return 2;
    }
    recorder.data.reserve(static_cast<std::size_t>(kFields) * 200000);
    std::signal(SIGPIPE, SIG_IGN);  // a peer that goes away must not kill this process
    std::signal(SIGSEGV, onCrash);
    std::signal(SIGABRT, onCrash);
    yarp::os::Network yarp;
    if (!yarp::os::Network::checkNetwork(5.0)) {
        std::fprintf(stderr, "bench_consumer: no YARP name server\n");
        return 1;
    }
    // One Port per source: a Port fed by several connections at once has its
    // reader called from each connection's thread at the same time, and with
    // enveloped Bottles arriving on two connections together YARP 3.5 crashed
    // in it (heap corruption, in the benchmark's long runs). With several
    // sources: <port>/0, <port>/1, ...
    std::vector<std::string> names;
    if (sources.size() <= 1) {
        names.push_back(portName);
    } else {
        for (std::size_t i = 0; i < sources.size(); ++i) {
            names.push_back(portName + "/" + std::to_string(i));
        }
    }
    std::vector<std::unique_ptr<yarp::os::Port>> ports;
    for (const auto& name : names) {
        ports.emplace_back(new yarp::os::Port());
        ports.back()->setReader(recorder);
        if (!ports.back()->open(name)) {
            std::fprintf(stderr, "bench_consumer: cannot open %s\n", name.c_str());
            return 1;
        }
    }
    answer("ready");

    std::atomic<bool> quitting{false};
    std::thread connector([&] {
        std::vector<bool> done(sources.size(), false);
        std::size_t left = sources.size();
        while (left > 0 && !quitting) {
            for (std::size_t i = 0; i < sources.size(); ++i) {
                if (!done[i] && yarp::os::Network::exists(sources[i], true)
                    && yarp::os::Network::connect(sources[i], names[std::min(i, names.size() - 1)], "tcp",
                                                  true)) {
                    done[i] = true;
                    --left;
                }
            }
            if (left > 0) {
                std::this_thread::sleep_for(std::chrono::milliseconds(100));
            }
        }
        if (left == 0) {
            answer("connected");
        }
    });

    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string cmd;
        in >> cmd;
        if (cmd == "count") {
            std::lock_guard<std::mutex> lock(recorder.mutex);
            answer("count " + std::to_string(recorder.count) + " " + std::to_string(recorder.bad));
        } else if (cmd == "reset") {
            std::lock_guard<std::mutex> lock(recorder.mutex);
            recorder.data.clear();
            recorder.count = 0;
            recorder.bad = 0;
            answer("reset");
        } else if (cmd == "dump") {
            std::string path;
            in >> path;
            std::vector<double> copy;
            {
                std::lock_guard<std::mutex> lock(recorder.mutex);
                copy = recorder.data;
            }
            FILE* f = std::fopen(path.c_str(), "wb");
            if (f == nullptr) {
                answer("error cannot write " + path);
                continue;
            }
            std::fwrite(copy.data(), sizeof(double), copy.size(), f);
            std::fclose(f);
            answer("dumped " + std::to_string(copy.size() / kFields));
        } else if (cmd == "quit") {
            break;
        } else if (!cmd.empty()) {
            answer("error unknown command " + cmd);
        }
    }
    quitting = true;
    connector.join();
    for (auto& port : ports) {
        port->interrupt();
        port->close();
    }
    return 0;
}
