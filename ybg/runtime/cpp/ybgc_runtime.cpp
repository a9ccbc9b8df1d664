// The C++ runtime's bridge (ybgc_runtime.hpp): run() parses the command
// line, opens the inputs, the output, the RPC port and the watcher of
// connections, loops (event-driven or at a fixed rate) until SIGINT, SIGTERM
// or `quit`, and closes everything within its deadlines. The parts it puts
// together (ybgc_internal.hpp) are in the runtime's other files.
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdint>
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

#include <yarp/conf/version.h>
#include <yarp/os/Bottle.h>
#include <yarp/os/Carriers.h>
#include <yarp/os/Contact.h>
#include <yarp/os/ContactStyle.h>
#include <yarp/os/Network.h>

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

// --- ROS 1 -------------------------------------------------------------------------------

/// YARP 3.5 leaves a closed topic@node port registered with the ROS master:
/// withdraw it (as a publisher or a subscriber), with short timeouts.
void withdrawFromRosMaster(const std::string& port, bool publisher)
{
    const std::size_t at = port.find('@');
    if (at == std::string::npos) {
        return;
    }
    const std::string topic = port.substr(0, at);
    const std::string node = port.substr(at + 1);
    yarp::os::Contact master = yarp::os::Network::queryName("/ros");
    if (!master.isValid()) {
        return;
    }
    yarp::os::ContactStyle style;
    style.quiet = true;
    style.timeout = 0.25;
    style.carrier = "xmlrpc";
    yarp::os::Bottle cmd;
    yarp::os::Bottle reply;
    cmd.addString("lookupNode");
    cmd.addString(node);
    cmd.addString(node);
    if (!yarp::os::Network::write(master, cmd, reply, style) || reply.get(0).asInt32() != 1) {
        return;
    }
    const std::string api = reply.get(2).asString();
    cmd.clear();
    reply.clear();
    cmd.addString(publisher ? "unregisterPublisher" : "unregisterSubscriber");
    cmd.addString(node);
    cmd.addString(topic);
    cmd.addString(api);
    yarp::os::Network::write(master, cmd, reply, style);
}

// --- the bridge ---------------------------------------------------------------------------

/// The module's loop: gathers inputs into muxes, converts, builds and
/// publishes messages. Event-driven, the message is built and written in
/// the callback of the input whose Bottle completes it (no thread in
/// between, so nothing is added to the latency) and the loop only wakes
/// when an input would go stale. At a fixed rate, the loop publishes at
/// absolute deadlines.
class Bridge : public ArrivalListener
{
public:
    Bridge(const BridgeSpec& spec, const Options& options, MessageSink& output, InputFeed* feed, FramePorts frames) :
            spec_(spec), options_(options), output_(output), feed_(feed),
            eventDriven_(!(options.rate > 0))
    {
        shared_.dropNan = spec.dropNan;
        shared_.queue = spec.queue;
        shared_.listener = this;
        shared_.frames = frames;
        shared_.module = spec.module;
        for (const InputSpec& in : spec.inputs) {
            const std::string mux = spec.muxes[static_cast<std::size_t>(in.mux)].name;
            const std::string index = std::to_string(in.index);
            const std::string local = in.kind == InputKind::Ros1
                ? std::string(in.source) + "@" + options.prefix + "/" + mux + "_in" + index
                : in.kind == InputKind::Ros2 ? std::string(in.source)
                : options.prefix + "/" + mux + "/in" + index + ":i";
            inputs_.push_back(std::make_unique<Input>(shared_, in, local,
                                                      options.hasTimeout ? options.timeout : in.timeout));
            std::vector<std::string>& accepted = inputs_.back()->accepted;
            accepted.emplace_back(in.source);
            for (const char* other : in.accepts) {
                accepted.emplace_back(other);
            }
            for (const auto& [port, other] : options.accept) {
                if (in.kind == InputKind::Yarp && port == in.source) {
                    accepted.push_back(other);
                }
            }
        }
        std::vector<InputState*> states;
        for (const auto& in : inputs_) {
            states.push_back(in.get());
        }
        matcher_ = std::make_unique<Matcher>(spec, std::move(states), eventDriven_);
    }

    void requestStop()
    {
        {
            std::lock_guard<std::mutex> lock(shared_.mutex);
            shared_.stopping = true;
        }
        shared_.wake.notify_all();
    }

    /// The totals as they stand, read under the lock (the RPC port's `stats`).
    Totals totals()
    {
        std::lock_guard<std::mutex> lock(shared_.mutex);
        Totals out;
        const SteadyClock::time_point now = SteadyClock::now();
        for (const auto& in : inputs_) {
            Totals::PerInput t{in->spec.source, in->received, in->dropped, in->stalePeriods, in->unused};
            t.refused = in->refused;
            t.foreign = in->foreign;
            t.state = in->state;
            t.age = in->state == Freshness::Waiting ? -1.0 : std::chrono::duration<double>(now - in->arrival).count();
            t.timeout = in->timeout;
            out.inputs.push_back(std::move(t));
        }
        out.module = spec_.module;
        out.output = spec_.output.port;
        out.rate = eventDriven_ ? 0.0 : options_.rate;
        out.published = published_;
        out.skipped = skippedCycles_;
        out.failures = buildFailures_;
        out.missed = output_.missed();
        out.ros2 = ros2Events();
        return out;
    }

    /// The incompatible peers of its ROS 2 publishers, then subscriptions.
    std::vector<Totals::Ros2Endpoint> ros2Events() const
    {
        std::vector<Totals::Ros2Endpoint> out;
        output_.ros2Events(out);
        if (feed_ != nullptr) {
            feed_->ros2Events(out);
        }
        return out;
    }

    /// Opens everything, loops until stopped, closes; the exit status.
    int run()
    {
        const int status = open(true);
        if (status == 0) {
            serve();
        }
        // Closing waits for the peers; one that does not answer (a stalled
        // reader) would hold it: after a deadline the names are unregistered
        // and the process ends without waiting any longer.
        const Closed closed = close();
        printLines(totalsText(""));
        if (!closed.ports || !closed.watcher) {
            if (!closed.ports) {
                say("a peer did not answer while the ports closed; their names were unregistered");
            }
            std::fflush(stdout);
            std::_Exit(status);
        }
        return status;
    }

    /// The same in a process of several bridges (ybgc compose): no RPC port
    /// of its own (the process has one); `host` hears that it runs, or why
    /// it cannot start, and its totals once closed. The exit status.
    int run(Host& host)
    {
        if (open(false) != 0) {
            const Closed closed = close();  // what it opened
            host.refused(failure_);
            if (!closed.ports || !closed.watcher) {
                hold();
            }
            return 1;
        }
        host.started({[this] { return totals(); }, [this] { requestStop(); }, eventDriven_ ? 0.0 : options_.rate});
        serve();
        const Closed closed = close();
        if (!closed.ports) {
            say("a peer did not answer while the ports closed; their names were unregistered");
        }
        host.closed(totalsText(std::string(spec_.module) + ": "), closed.ports && closed.watcher);
        if (!closed.ports || !closed.watcher) {
            hold();
        }
        return 0;
    }

    /// An input accepted a Bottle (its callback thread, Shared::mutex held).
    void arrived(Input& /*input*/, bool wasFresh) override
    {
        if (!wasFresh) {
            shared_.wake.notify_all();  // the loop sleeps until the next stale deadline
        }
        if (!eventDriven_ || !publishing_ || shared_.stopping) {
            return;
        }
        while (!shared_.stopping && matcher_->ready(SteadyClock::now(), true)) {
            publish();
        }
    }

private:
    /// What closing ended with: the ports closed (else their names were
    /// unregistered), the watcher stopped, each within its deadline.
    struct Closed
    {
        bool ports;
        bool watcher;
    };

    /// Says why it cannot run, and keeps it (failure_).
    void fail(const std::string& why)
    {
        say(why);
        failure_ = why;
    }

    /// Opens the inputs, the output, the inputs read outside YARP and, with
    /// `rpc`, the RPC port; makes the watcher of connections: 0, or 1 when
    /// one cannot open (said; failure_ says why).
    int open(bool rpc)
    {
        int status = 0;
        for (; opened_ < inputs_.size(); ++opened_) {
            if (!inputs_[opened_]->open()) {
                fail("cannot open the port " + inputs_[opened_]->local);
                status = 1;
                break;
            }
        }
        if (status == 0) {
            outputOpen_ = output_.open();
            if (!outputOpen_) {
                output_.close();
                fail(std::string("cannot open the output ") + spec_.output.port);
                status = 1;
            }
        }
        if (status == 0 && feed_ != nullptr) {
            feedOpen_ = feed_->open([this](std::size_t k, Reading& reading) { inputs_[k]->deliver(reading); });
            if (!feedOpen_) {
                feed_->close();
                failure_ = "cannot read its ROS 2 topics";  // the feed said why
                status = 1;
            }
        }
        if (rpc) {
            rpc_ = std::make_unique<RpcPort>(
                options_.prefix + "/rpc:i", [this] { return totals(); }, [this] { requestStop(); },
                eventDriven_ ? 0.0 : options_.rate);
            rpcOpen_ = status == 0 && rpc_->open();
            if (status == 0 && !rpcOpen_) {
                fail("cannot open the RPC port " + rpc_->name);
                status = 1;
            }
        }
        std::vector<Link> links;
        for (const auto& in : inputs_) {
            if (in->spec.kind == InputKind::Yarp) {
                links.push_back({in->spec.source, in->local, in.get()});
            }
        }
        if (spec_.output.connectTo[0] != '\0') {
            links.push_back({spec_.output.port, spec_.output.connectTo, nullptr});
        }
        std::vector<yarp::os::Contact> own;
        for (const auto& in : inputs_) {
            if (in->spec.kind == InputKind::Yarp) {
                own.push_back(in->where());
            }
        }
        if (spec_.output.kind == OutputKind::Yarp) {
            own.push_back(output_.where());
        }
        watcher_ = std::make_unique<Watcher>(std::move(links), std::move(own));
        {
            std::lock_guard<std::mutex> lock(shared_.mutex);
            shared_.foreign = watcher_->waker();
        }
        return status;
    }

    /// Once open: publishes until stopped.
    void serve()
    {
        // a ROS 2 node among them reports the totals (its /diagnostics)
        output_.watch([this] { return totals(); });
        if (feed_ != nullptr) {
            feed_->watch([this] { return totals(); });
        }
        say("publishing " + output_.describe() + ", "
            + (eventDriven_ ? std::string("event-driven") : formatNumber(options_.rate) + " Hz"));
        watcher_->start();
        if (eventDriven_) {
            loopEventDriven();
        } else {
            loopFixedRate();
        }
    }

    /// Closes what is open: the RPC port, the watcher, the inputs read
    /// outside YARP, the ports and the output.
    Closed close()
    {
        if (rpcOpen_) {
            rpc_->close();
        }
        const bool watcherStopped = watcher_->stop(std::chrono::milliseconds(300));
        if (feedOpen_) {
            feed_->close();  // before the output, whose node it may share
        }
        const bool closed = closeAll(opened_, outputOpen_, std::chrono::milliseconds(800));
        return {closed, watcherStopped};
    }

    /// A thread left closing a port (or the watcher) still uses this bridge:
    /// its thread never returns; the process exits without it.
    [[noreturn]] static void hold()
    {
        std::fflush(stdout);
        for (;;) {
            std::this_thread::sleep_for(std::chrono::hours(1));
        }
    }

    /// Closes the ports in a thread of their own; false if that did not end
    /// within `limit`: the ports' names are then unregistered.
    bool closeAll(std::size_t opened, bool outputOpen, std::chrono::milliseconds limit)
    {
        struct Done
        {
            std::mutex mutex;
            std::condition_variable cv;
            bool done = false;
        };
        auto state = std::make_shared<Done>();
        std::thread closer([this, opened, outputOpen, state, who = tModule] {
            tModule = who;
            for (std::size_t k = 0; k < opened; ++k) {
                inputs_[k]->interrupt();
            }
            {
                // one port after the other in the process: YARP ports closed by
                // several threads at once (the bridges of a composed process)
                // stall for a second each; one after the other, milliseconds
                static std::mutex closing;
                std::lock_guard<std::mutex> lock(closing);
                for (std::size_t k = 0; k < opened; ++k) {
                    inputs_[k]->close();
                }
            }
            if (outputOpen) {
                output_.close();
            }
            withdrawRos(opened, outputOpen);
            std::lock_guard<std::mutex> lock(state->mutex);
            state->done = true;
            state->cv.notify_all();
        });
        std::unique_lock<std::mutex> lock(state->mutex);
        if (state->cv.wait_for(lock, limit, [&state] { return state->done; })) {
            lock.unlock();
            closer.join();
            return true;
        }
        lock.unlock();
        closer.detach();  // the process ends without it
        for (std::size_t k = 0; k < opened; ++k) {
            if (!inputs_[k]->registered.empty()) {
                yarp::os::Network::unregisterName(inputs_[k]->registered);
            }
        }
        if (outputOpen && !output_.registered().empty()) {
            yarp::os::Network::unregisterName(output_.registered());
        }
        withdrawRos(opened, outputOpen);
        return false;
    }

    /// The ROS 1 ports, withdrawn from the ROS master.
    void withdrawRos(std::size_t opened, bool outputOpen)
    {
        for (std::size_t k = 0; k < opened; ++k) {
            if (inputs_[k]->spec.kind == InputKind::Ros1) {
                withdrawFromRosMaster(inputs_[k]->local, false);
            }
        }
        if (outputOpen && spec_.output.kind == OutputKind::Ros1) {
            withdrawFromRosMaster(spec_.output.port, true);
        }
    }

    /// Builds and writes one message from the values taken; Shared::mutex
    /// held, so no input changes meanwhile (and nothing is copied).
    void publish()
    {
        matcher_->take();
        Context ctx;
        ctx.counter = published_;
        if (feed_ == nullptr || !feed_->nowNs(ctx.wallNs)) {
            ctx.wallNs = output_.nowNs();
        }
        ctx.seconds = static_cast<double>(ctx.wallNs) / 1e9;
        ctx.verbose = options_.verbose;
        ctx.inputs = &matcher_->latest();
        std::string failure;
        if (!output_.publish(matcher_->latest(), ctx, failure)) {
            if (++buildFailures_ == 1) {
                say("cannot build the message: " + failure + "; further failures are only counted");
            }
            return;
        }
        ++published_;
    }

    void loopEventDriven()
    {
        std::unique_lock<std::mutex> lock(shared_.mutex);
        publishing_ = true;
        // Bottles that came before the output was open
        while (matcher_->ready(SteadyClock::now(), true)) {
            publish();
        }
        while (!shared_.stopping) {
            const SteadyClock::time_point deadline = matcher_->checkFreshness(SteadyClock::now());
            if (deadline == SteadyClock::time_point::max()) {
                shared_.wake.wait(lock);
            } else {
                shared_.wake.wait_until(lock, deadline);
            }
        }
        publishing_ = false;
    }

    void loopFixedRate()
    {
        const double period = 1.0 / options_.rate;
        const SteadyClock::time_point start = SteadyClock::now();
        std::uint64_t cycle = 0;  // cycle k is due at start + k * period: absolute, never drifting
        auto dueTime = [&](std::uint64_t k) {
            return start + std::chrono::duration_cast<SteadyClock::duration>(
                               std::chrono::duration<double>(static_cast<double>(k) * period));
        };
        std::unique_lock<std::mutex> lock(shared_.mutex);
        while (true) {
            const SteadyClock::time_point due = dueTime(cycle);
            shared_.wake.wait_until(lock, due, [&] { return shared_.stopping || SteadyClock::now() >= due; });
            if (shared_.stopping) {
                return;
            }
            const SteadyClock::time_point now = SteadyClock::now();
            const double late = std::chrono::duration<double>(now - due).count();
            if (late > period) {
                // overran by more than a whole period: skip, never catch up in a burst
                const auto missed = static_cast<std::uint64_t>(late / period);
                skippedCycles_ += missed;
                cycle += missed;
            }
            ++cycle;
            matcher_->checkFreshness(now);
            if (!matcher_->ready(now, false)) {
                continue;
            }
            publish();
        }
    }

    /// The exit totals, each line headed by `prefix`.
    std::string totalsText(const std::string& prefix) const
    {
        std::string out = prefix + "totals:\n";
        for (const auto& in : inputs_) {
            out += prefix + "  input " + std::string(in->spec.source) + ": received " + std::to_string(in->received)
                + ", dropped " + std::to_string(in->dropped) + ", stale periods "
                + std::to_string(in->stalePeriods) + ", unused " + std::to_string(in->unused);
            out += refusedText(*in) + "\n";
        }
        out += prefix + "  published " + std::to_string(published_) + " messages, skipped "
            + std::to_string(skippedCycles_) + " cycles, build failures " + std::to_string(buildFailures_) + "\n";
        if (const std::uint64_t missed = output_.missed(); missed != 0) {
            out += prefix + "  " + missedLine(missed) + "\n";
        }
        for (const Totals::Ros2Endpoint& e : ros2Events()) {
            if (e.qos != 0 || e.type != 0) {
                out += prefix + "  " + ros2TotalsLine(e) + "\n";
            }
        }
        return out;
    }

    const BridgeSpec& spec_;
    const Options options_;
    Shared shared_;
    std::vector<std::unique_ptr<Input>> inputs_;
    std::unique_ptr<Matcher> matcher_;  // which Bottles each message uses
    MessageSink& output_;
    InputFeed* feed_;  // the inputs read outside YARP (nullptr: none)
    const bool eventDriven_;
    std::size_t opened_ = 0;    // the inputs opened
    bool outputOpen_ = false;
    bool feedOpen_ = false;
    std::unique_ptr<RpcPort> rpc_;  // a module of its own: its RPC port
    bool rpcOpen_ = false;
    std::unique_ptr<Watcher> watcher_;
    std::string failure_;       // why it cannot run
    bool publishing_ = false;  // guarded by Shared::mutex
    std::atomic<std::uint64_t> published_{0};
    std::atomic<std::uint64_t> skippedCycles_{0};
    std::atomic<std::uint64_t> buildFailures_{0};
};

/// Does this YARP carry ROS 1 topics? It needs the tcpros and xmlrpc carriers
/// (built in up to YARP 3.9, YARP's separate yarp-ros plugins in 3.10 to 3.12,
/// gone in YARP 4) and a name server started with `--ros`. Otherwise a ROS 1
/// port opens as a plain YARP port and the module would publish into nothing.
bool ros1Available(std::string& why)
{
    const yarp::os::Bottle carriers = yarp::os::Carriers::listCarriers();
    for (const char* need : {"tcpros", "xmlrpc"}) {
        bool found = false;
        for (std::size_t k = 0; k < carriers.size() && !found; ++k) {
            found = carriers.get(k).asString() == need;
        }
        if (!found) {
            why = std::string("YARP ") + YARP_VERSION + " has no `" + need + "` carrier: ROS 1 topics need "
                + (YARP_VERSION_MAJOR >= 4 ? "YARP 3.5 to 3.12 (YARP 4 has no ROS 1); with YARP 4 set `via = ros2` and "
                                             "generate the ROS 2 node (ybgc CONFIG --backend ros2)"
                                           : "YARP's yarp-ros plugins (tcpros, xmlrpc) with YARP 3.10 and later");
            return false;
        }
    }
    if (!yarp::os::Network::queryName("/ros").isValid()) {
        why = "the YARP name server does not speak ROS: start it as `yarpserver --ros` with ROS_MASTER_URI "
              "set to the ROS master";
        return false;
    }
    return true;
}

/// Parses the command line and runs the bridge until SIGINT or SIGTERM.
int run(const BridgeSpec& spec, int argc, char* argv[], MakeMessage make, InputFeed* feed)
{
    const std::unique_ptr<MessageSink> output = yarpOutput(spec.output, std::move(make));
    return run(spec, argc, argv, *output, feed);
}

namespace {

/// The host of the bridge run by this thread (Host::current()).
thread_local Host* tHost = nullptr;

/// Does the bridge read or write ROS 1 topics?
bool usesRos1(const BridgeSpec& spec)
{
    bool ros1 = spec.output.kind == OutputKind::Ros1;
    for (const InputSpec& input : spec.inputs) {
        ros1 = ros1 || input.kind == InputKind::Ros1;
    }
    return ros1;
}

/// The bridge in a process of several (ybgc compose): the process holds
/// the YARP network and the signals, and hears from it (Host).
int runHosted(Host& host, const BridgeSpec& spec, const Options& options, MessageSink& output, InputFeed* feed,
              FramePorts frames)
{
    std::string why;
    if (usesRos1(spec) && !ros1Available(why)) {
        say("cannot use ROS 1 topics: " + why);
        host.refused("cannot use ROS 1 topics: " + why);
        return 1;
    }
    Bridge bridge(spec, options, output, feed, frames);
    return bridge.run(host);
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

int run(const BridgeSpec& spec, int argc, char* argv[], MessageSink& output, InputFeed* feed, FramePorts frames)
{
    Host* host = Host::current();
    if (host == nullptr) {
        gModule = spec.module;
    }
    Options options;
    const int status = parseOptions(spec, argc, argv, options);
    if (status >= 0) {
        return status;
    }
    if (options.rate <= 0 && spec.inputs.empty()) {
        std::fprintf(stderr, "%s: an event-driven bridge needs at least one input; give --rate\n", spec.module);
        return 2;
    }
    if (host != nullptr) {
        return host->checking() ? 0 : runHosted(*host, spec, options, output, feed, frames);
    }
    SignalWatch signals;  // before YARP starts any thread
    std::signal(SIGPIPE, SIG_IGN);
    yarp::os::Network network;
    if (!yarp::os::Network::checkNetwork(3.0)) {
        say("cannot reach the YARP name server (is yarpserver running?)");
        return 1;
    }
    std::string why;
    if (usesRos1(spec) && !ros1Available(why)) {
        say("cannot use ROS 1 topics: " + why);
        return 1;
    }
    Bridge bridge(spec, options, output, feed, frames);
    signals.start([&bridge] { bridge.requestStop(); });
    const int result = bridge.run();
    signals.finish();
    return result;
}

}  // namespace ybgc
