// The process shell of the C++ runtime (ybgc_internal.hpp): what every kind of
// bridge (a stream, commands) runs in. Alone, a module: its command line
// (ybgc_options.cpp), SIGINT and SIGTERM, the YARP network, its RPC port
// (`help`, `stats`, `quit`), its exit totals, and a shutdown within its
// deadlines; among others (ybgc compose, ybgc_compose.cpp), the process's
// host is told how it starts and ends instead. One implementation for every
// kind, so that they behave alike: a close that stalls exits 1 in each.
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <pthread.h>
#include <signal.h>

#include <yarp/os/Bottle.h>
#include <yarp/os/ConnectionReader.h>
#include <yarp/os/ConnectionWriter.h>
#include <yarp/os/Network.h>
#include <yarp/os/Vocab.h>

namespace ybgc {

// --- SIGINT and SIGTERM ----------------------------------------------------------------

SignalWatch::SignalWatch()
{
    sigemptyset(&set_);
    sigaddset(&set_, SIGINT);
    sigaddset(&set_, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &set_, nullptr);
}

void SignalWatch::start(std::function<void()> onStop)
{
    thread_ = std::thread([this, onStop] { run(onStop); });
}

void SignalWatch::finish()
{
    if (!thread_.joinable()) {
        return;
    }
    finished_ = true;
    pthread_kill(thread_.native_handle(), SIGTERM);
    thread_.join();
}

void SignalWatch::run(const std::function<void()>& onStop)
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
        std::_Exit(1);
    }
}

// --- threads and deadlines -----------------------------------------------------------------

bool finishBy(SteadyClock::time_point deadline, std::function<bool()> work)
{
    struct Done
    {
        std::mutex mutex;
        std::condition_variable cv;
        bool done = false;
        bool ok = false;
    };
    auto state = std::make_shared<Done>();
    std::thread worker = bridgeThread([work = std::move(work), state] {
        const bool ok = work();
        std::lock_guard<std::mutex> lock(state->mutex);
        state->done = true;
        state->ok = ok;
        state->cv.notify_all();
    });
    std::unique_lock<std::mutex> lock(state->mutex);
    if (state->cv.wait_until(lock, deadline, [&state] { return state->done; })) {
        const bool ok = state->ok;
        lock.unlock();
        worker.join();
        return ok;
    }
    lock.unlock();
    worker.detach();  // the process ends without it
    return false;
}

void hold()
{
    std::fflush(stdout);
    for (;;) {
        std::this_thread::sleep_for(std::chrono::hours(1));
    }
}

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

// --- an RPC port ---------------------------------------------------------------------------

RpcPort::RpcPort(std::string name, Answer answer, std::function<void()> quit) :
        name(std::move(name)), answer_(std::move(answer)), quit_(std::move(quit)), module_(tModule)
{
}

bool RpcPort::open()
{
    port_.setReader(*this);
    return port_.open(name);
}

void RpcPort::close(std::chrono::milliseconds limit)
{
    const SteadyClock::time_point deadline = SteadyClock::now() + limit;
    bool waited = false;
    while (reading_ > 0 && SteadyClock::now() < deadline) {
        waited = true;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (waited || quitAsked_) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));  // read() returned: the reply is sent
    }
    port_.interrupt();
    port_.close();
}

bool RpcPort::read(yarp::os::ConnectionReader& connection)
{
    tModule = module_;  // what this thread says is said under its bridge's name
    ++reading_;
    yarp::os::Bottle command;
    if (!command.read(connection)) {
        --reading_;
        return false;
    }
    yarp::os::Bottle reply;
    const bool quit = answer_(command, reply);
    if (quit) {
        quitAsked_ = true;
    }
    yarp::os::ConnectionWriter* writer = connection.getWriter();
    if (writer != nullptr) {
        reply.write(*writer);
    }
    --reading_;
    if (quit) {
        quit_();  // closing waits for the reply to go (close())
    }
    return true;
}

// --- a bridge's own RPC port ----------------------------------------------------------------

void Bridge::ownStats(yarp::os::Bottle& reply)
{
    reply.addVocab32("many");
    stats(reply);
}

void RpcCommands::unknown(const std::string& word, yarp::os::Bottle& reply) const
{
    reply.addString("unknown command '" + word + "'; the commands: help, stats, quit");
}

bool RpcCommands::answerOwn(const std::string& word, yarp::os::Bottle& reply, bool& quit)
{
    if (word == "stats") {
        ownStats(reply);
        return true;
    }
    if (word == "quit" || word == "exit" || word == "bye") {
        say("asked to quit on the RPC port");
        quit = true;
        reply.addVocab32("bye");
        return true;
    }
    return false;
}

bool RpcCommands::answerRpc(const yarp::os::Bottle& command, yarp::os::Bottle& reply)
{
    const std::string word = firstWord(command);
    bool quit = false;
    if (word == "help") {
        reply.addVocab32("many");
        for (const std::string& line : help()) {
            reply.addString(line);
        }
    } else if (!answerOwn(word, reply, quit)) {
        unknown(word, reply);
    }
    return quit;
}

void Bridge::fail(const std::string& why)
{
    say(why);
    failure_ = why;
}

namespace {

/// The host of the bridge run by this thread (Host::current()).
thread_local Host* tHost = nullptr;

/// A module of its own: opens the bridge and its RPC port, runs it until it
/// is stopped, closes it and prints its totals; the exit status. Closing
/// waits for the peers; one that does not answer (a stalled reader) would
/// hold it: after a deadline the names are unregistered and the process
/// ends without waiting any longer.
int alone(Bridge& bridge)
{
    int status = bridge.open() ? 0 : 1;
    std::unique_ptr<RpcPort> rpc;
    if (status == 0 && !bridge.serves(bridge.ownPort)) {
        rpc = std::make_unique<RpcPort>(
            bridge.ownPort, [&bridge](const yarp::os::Bottle& command, yarp::os::Bottle& reply) {
                return bridge.answerRpc(command, reply);
            }, [&bridge] { bridge.stop(); });
        if (!rpc->open()) {
            bridge.fail("cannot open the RPC port " + rpc->name);
            status = 1;
        }
    }
    if (status == 0) {
        bridge.serve();
    }
    if (rpc != nullptr) {
        rpc->close(std::chrono::milliseconds(500));
    }
    const Closed closed = bridge.close();
    printLines(bridge.totalsText(""));
    if (!closed.clean()) {
        if (!closed.ports) {
            say("a peer did not answer while the ports closed; their names were unregistered");
        }
        std::fflush(stdout);
        std::_Exit(status);
    }
    return status;
}

/// In a process of several bridges (ybgc compose): no RPC port, signals or
/// YARP network of its own (the process has them); `host` hears that it
/// runs, or why it cannot start, and its totals once closed.
int hosted(Host& host, const Start& start, const Options& options)
{
    if (start.usable) {
        const std::string why = start.usable();
        if (!why.empty()) {
            say(why);
            host.refused(why);
            return 1;
        }
    }
    const std::unique_ptr<Bridge> bridge = start.make(options);
    if (!bridge->open()) {
        const Closed closed = bridge->close();  // what it opened
        host.refused(bridge->failure());
        if (!closed.clean()) {
            hold();
        }
        return 1;
    }
    Bridge* b = bridge.get();
    host.started({[b](yarp::os::Bottle& out) { b->stats(out); }, [b] { b->stop(); }});
    bridge->serve();
    const Closed closed = bridge->close();
    if (!closed.ports) {
        say("a peer did not answer while the ports closed; their names were unregistered");
    }
    host.closed(bridge->totalsText(std::string(start.options.module) + ": "), closed.clean());
    if (!closed.clean()) {
        hold();
    }
    return 0;
}

}  // namespace

Host* Host::current()
{
    return tHost;
}

void Host::setCurrent(Host* host)
{
    tHost = host;
}

int runBridge(const Start& start, int argc, char* argv[])
{
    Host* host = Host::current();
    if (host == nullptr) {
        gModule = start.options.module;
    }
    Options options;
    int status = parseOptions(start.options, argc, argv, options);
    if (status >= 0) {
        return status;
    }
    if (start.check && (status = start.check(options)) >= 0) {
        return status;
    }
    if (host != nullptr) {
        return host->checking() ? 0 : hosted(*host, start, options);
    }
    SignalWatch signals;  // before YARP or rcl starts any thread
    std::signal(SIGPIPE, SIG_IGN);
    yarp::os::Network network;
    if (!yarp::os::Network::checkNetwork(3.0)) {
        say("cannot reach the YARP name server (is yarpserver running?)");
        return 1;
    }
    if (start.usable) {
        const std::string why = start.usable();
        if (!why.empty()) {
            say(why);
            return 1;
        }
    }
    const std::unique_ptr<Bridge> bridge = start.make(options);
    bridge->ownPort = options.prefix + "/rpc:i";
    Bridge* b = bridge.get();
    signals.start([b] { b->stop(); });
    const int result = alone(*bridge);
    signals.finish();
    return result;
}

}  // namespace ybgc
