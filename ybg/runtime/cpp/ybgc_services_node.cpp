// The bridge of commands (ybgc_services_internal.hpp) in the process shell
// every kind of bridge runs in (ybgc_shell.cpp): its node with its services
// and clients and their ROS 2 thread, the YARP ports it calls and serves,
// /diagnostics over its counts; stopped and closed within its deadlines,
// every call in flight answered; `stats`, `help` and its exit totals.
#include "ybgc_services_internal.hpp"  // ybgc:runtime-import

#include <rcl/error_handling.h>
#include <rcl/wait.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/Network.h>

namespace ybgc {
namespace services {

using ros2::finished;
using ros2::rclError;
using ros2::waitOn;

CommandsBridge::CommandsBridge(const Commands& spec, const Options& options, std::vector<std::string> rosArgs) :
        spec_(spec), options_(options), node_(spec.node, std::move(rosArgs)), counts_(spec.services.size())
{
}

// --- counts and what is said -----------------------------------------------------------------------

void CommandsBridge::started(std::size_t s)
{
    std::lock_guard<std::mutex> lock(mutex_);
    ++counts_[s].calls;
}

void CommandsBridge::ended(std::size_t s, Failure failure, const std::string& text)
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

void CommandsBridge::saySuccess(std::size_t s, const yarp::os::Bottle& command, const yarp::os::Bottle& reply)
{
    if (options_.verbose) {
        say(std::string("service ") + spec_.services[s].spec.name + ": " + command.toString() + " -> "
            + reply.toString());
    }
}

std::string CommandsBridge::stoppedText(const Service& s) const
{
    return std::string(spec_.module) + " stopped before "
        + (s.spec.serves == Serves::Ros2 ? s.spec.port : s.spec.service) + " answered";
}

std::string CommandsBridge::totalsText(const std::string& prefix)
{
    std::string out = prefix + "totals:\n";
    std::lock_guard<std::mutex> lock(mutex_);
    for (std::size_t s = 0; s < spec_.services.size(); ++s) {
        out += prefix + totalsLine(spec_.services[s].spec.name, counts_[s]) + "\n";
    }
    return out;
}

void CommandsBridge::stats(yarp::os::Bottle& out)
{
    std::lock_guard<std::mutex> lock(mutex_);
    for (std::size_t s = 0; s < spec_.services.size(); ++s) {
        addStats(out, spec_.services[s].spec.name, counts_[s]);
    }
}

void CommandsBridge::ownStats(yarp::os::Bottle& reply)
{
    stats(reply);  // no vocab many before them: `yarp rpc` would print a lone list's items one by one
}

std::vector<std::string> CommandsBridge::help() const
{
    return {std::begin(kRpcHelp), std::end(kRpcHelp)};
}

bool CommandsBridge::serves(const std::string& name) const
{
    return std::any_of(spec_.ports.begin(), spec_.ports.end(), [&name](const PortHelp& p) { return name == p.port; });
}

// --- open, serve, stop, close ------------------------------------------------------------------------

bool CommandsBridge::open()
{
    nodeOpen_ = node_.open();
    if (!nodeOpen_) {
        failure_ = "cannot open its ROS 2 node";  // the node said why
        return false;
    }
    if (!openAll()) {
        return false;
    }
    for (auto& [port, caller] : callers_) {
        caller->start();
    }
    spinning_ = true;
    spinner_ = bridgeThread([this] { spin(); });
    // the services' counts on /diagnostics (parameters `diagnostics`, `diagnostic_updater.period`)
    node_.publishStatuses([this] {
        std::vector<ros2::Status> all;
        const std::string node = node_.name();
        std::lock_guard<std::mutex> lock(mutex_);
        for (std::size_t s = 0; s < spec_.services.size(); ++s) {
            all.push_back(status(spec_.services[s].spec, counts_[s], node));
        }
        return all;
    }, spec_.module);
    return true;
}

/// Its callers, services, clients and served ports; false (said, failure()
/// says why) when one cannot open.
bool CommandsBridge::openAll()
{
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
    servers_.resize(spec_.services.size());
    for (std::size_t k = 0; k < spec_.services.size(); ++k) {
        const Service& s = spec_.services[k];
        if (s.spec.serves == Serves::Ros2) {
            servers_[k] = std::make_unique<RosServer>(*this, k, *callers_.at(s.spec.port));
            if (!servers_[k]->open(node)) {
                failure_ = std::string("cannot serve the ROS 2 service ") + s.spec.service;  // said
                return false;
            }
        } else {
            clients_[k] = std::make_unique<RosClient>(s);
            if (!clients_[k]->open(node)) {
                failure_ = std::string("cannot call the ROS 2 service ") + s.spec.service;  // said
                return false;
            }
        }
    }
    // the YARP ports served (one of them may be its own RPC port)
    for (const PortHelp& p : spec_.ports) {
        const std::string name = p.port;
        served_.push_back(std::make_unique<RpcPort>(
            name, [this, name](const yarp::os::Bottle& command, yarp::os::Bottle& reply) {
                bool quit = false;
                respond(name, command, reply, quit);
                return quit;
            }, [this] { stop(); }));
        if (!served_.back()->open()) {
            served_.pop_back();
            fail("cannot open the port " + name);
            return false;
        }
    }
    return true;
}

void CommandsBridge::serve()
{
    for (const Service& s : spec_.services) {
        say(s.spec.description);
    }
    if (!ownPort.empty()) {
        say("its RPC port: " + ownPort + " (help, stats, quit)");
    }
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return stopping_; });
}

void CommandsBridge::stop()
{
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stopping_ = true;
    }
    cv_.notify_all();
}

Closed CommandsBridge::close()
{
    stop();
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
    // cannot hold the bridge beyond its deadline (its names are then unregistered)
    auto closedPorts = std::make_shared<std::set<std::string>>();
    auto closedMutex = std::make_shared<std::mutex>();
    const bool closed = finishBy(Clock::now() + std::chrono::milliseconds(1000), [this, closedPorts, closedMutex] {
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
        return all;
    });
    spinning_ = false;
    if (spinner_.joinable()) {
        spinner_.join();
    }
    if (!closed) {
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
        return {false, true};
    }
    rcl_node_t* node = node_.node();
    for (auto& s : servers_) {
        if (s != nullptr) {
            s->fini(node);
        }
    }
    for (auto& [k, c] : clients_) {
        c->fini(node);
    }
    if (nodeOpen_) {
        node_.close();
    }
    return {};
}

/// The ROS 2 thread: the requests of the services served and the responses
/// of the services called, taken through one wait set (woken every 50 ms to
/// see whether the module stops).
void CommandsBridge::spin()
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
        if (!waitOn(waitSet, 50)) {
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

}  // namespace services
}  // namespace ybgc
