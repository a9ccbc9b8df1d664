// The YARP side of the service benchmark: an RPC server that answers every
// command at once with `ok` (the YARP RPC port the module and the relay
// call), and an RPC client timing its calls (the YARP round trip alone).
//
//   rpc_peer server --port /bench/rpc:i
//   rpc_peer client --target /bench/rpc:i [--clients 1] [--calls 1000]
//                   [--warmup 50] [--name /bench/rpc_client] [--out FILE]
//
// The server reads each command on a yarp::os::RpcServer (read with a
// reply) and replies the one-word Bottle `ok`; it counts the commands and
// prints "commands N" at exit (SIGINT/SIGTERM, exit 0). Each client is a
// thread with a yarp::os::RpcClient of its own sending `home all` and
// waiting for the reply; the time of a call is that of write(command,
// reply) (CLOCK_MONOTONIC). The client prints one line: "calls N failed F
// seconds S per_second R"; --out writes every counted call's time in ns.
#include "common.hpp"

#include <atomic>
#include <chrono>
#include <csignal>
#include <memory>
#include <thread>

#include <yarp/os/Bottle.h>
#include <yarp/os/Network.h>
#include <yarp/os/RpcClient.h>
#include <yarp/os/RpcServer.h>

namespace {
std::atomic<bool> gStop{false};
void onSignal(int) { gStop = true; }

int server(const std::map<std::string, std::string>& o)
{
    yarp::os::RpcServer port;
    if (!port.open(bench::get(o, "port", "/bench/rpc:i"))) {
        return 1;
    }
    std::printf("ready\n");
    std::fflush(stdout);
    long n = 0;
    std::thread stopper([&port] {
        while (!gStop) {
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
        port.interrupt();
    });
    yarp::os::Bottle command;
    yarp::os::Bottle reply;
    reply.addString("ok");
    while (!gStop) {
        if (!port.read(command, true)) {
            continue;
        }
        ++n;
        port.reply(reply);
    }
    stopper.join();
    port.close();
    std::printf("commands %ld\n", n);
    return 0;
}

int client(const std::map<std::string, std::string>& o)
{
    const std::string target = bench::get(o, "target", "/bench/rpc:i");
    const std::string name = bench::get(o, "name", "/bench/rpc_client");
    const int clients = std::atoi(bench::get(o, "clients", "1").c_str());
    const long calls = std::atol(bench::get(o, "calls", "1000").c_str());
    const long warmup = std::atol(bench::get(o, "warmup", "50").c_str());
    const std::string out = bench::get(o, "out", "");
    std::vector<std::unique_ptr<yarp::os::RpcClient>> ports;
    for (int i = 0; i < clients; ++i) {
        ports.emplace_back(new yarp::os::RpcClient());
        if (!ports.back()->open(name + "/" + std::to_string(i))
            || !yarp::os::Network::connect(ports.back()->getName(), target, "tcp", true)) {
            std::fprintf(stderr, "rpc_peer: cannot connect to %s\n", target.c_str());
            return 1;
        }
    }
    std::vector<std::vector<std::int64_t>> times(clients);
    std::vector<long> failed(clients, 0);
    auto run = [&](int i, long n, bool keep) {
        yarp::os::Bottle command;
        command.addString("home");
        command.addString("all");
        yarp::os::Bottle reply;
        for (long k = 0; k < n; ++k) {
            reply.clear();
            const std::int64_t t0 = bench::nowNs();
            const bool ok = ports[i]->write(command, reply);
            const std::int64_t t = bench::nowNs() - t0;
            if (!ok || reply.get(0).toString() != "ok") {
                ++failed[i];
            } else if (keep) {
                times[i].push_back(t);
            }
        }
    };
    for (int phase = 0; phase < 2; ++phase) {
        if (phase == 1) {
            std::fill(failed.begin(), failed.end(), 0);
        }
        const std::int64_t t0 = bench::nowNs();
        std::vector<std::thread> threads;
        for (int i = 0; i < clients; ++i) {
            threads.emplace_back(run, i, phase == 0 ? warmup : calls, phase == 1);
        }
        for (auto& t : threads) {
            t.join();
        }
        if (phase == 1) {
            const double seconds = static_cast<double>(bench::nowNs() - t0) * 1e-9;
            long f = 0;
            std::vector<std::int64_t> all;
            for (int i = 0; i < clients; ++i) {
                f += failed[i];
                all.insert(all.end(), times[i].begin(), times[i].end());
            }
            std::printf("calls %ld failed %ld seconds %.6f per_second %.2f\n", clients * calls, f, seconds,
                        seconds > 0 ? static_cast<double>(clients * calls) / seconds : 0.0);
            std::fflush(stdout);
            if (!out.empty() && !bench::writeLatencies(out, all)) {
                return 1;
            }
        }
    }
    for (auto& p : ports) {
        p->close();
    }
    return 0;
}
}  // namespace

int main(int argc, char* argv[])
{
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
    std::signal(SIGPIPE, SIG_IGN);
    const std::string mode = argc > 1 ? argv[1] : "";
    const auto o = bench::options(argc, argv);
    yarp::os::Network yarp;
    if (!yarp::os::Network::checkNetwork(5.0)) {
        std::fprintf(stderr, "rpc_peer: no YARP name server\n");
        return 1;
    }
    if (mode == "server") {
        return server(o);
    }
    if (mode == "client") {
        return client(o);
    }
    std::fprintf(stderr, "usage: rpc_peer server|client [options]\n");
    return 2;
}
