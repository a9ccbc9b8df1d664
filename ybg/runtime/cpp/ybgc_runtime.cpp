// A stream (ybgc_runtime.hpp): its inputs, its output and the watcher of
// connections, opened; its loop (event-driven or at a fixed rate) until it
// is stopped; everything closed within its deadlines; its totals. It runs in
// the process shell (ybgc_shell.cpp) as every kind of bridge does: run()
// gives the shell its options and makes it. The parts it puts together
// (ybgc_internal.hpp) are in the runtime's other files.
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <atomic>
#include <chrono>
#include <condition_variable>
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


#include <yarp/conf/version.h>
#include <yarp/os/Bottle.h>
#include <yarp/os/Carriers.h>
#include <yarp/os/Contact.h>
#include <yarp/os/ContactStyle.h>
#include <yarp/os/Network.h>

namespace ybgc {

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

/// A stream: gathers inputs into muxes, converts, builds and publishes
/// messages. Event-driven, the message is built and written in the callback
/// of the input whose Bottle completes it (no thread in between, so nothing
/// is added to the latency) and the loop only wakes when an input would go
/// stale. At a fixed rate, the loop publishes at absolute deadlines.
class Stream : public Bridge, public ArrivalListener
{
public:
    Stream(const BridgeSpec& spec, const Options& options, MessageSink& output, InputFeed* feed, FramePorts frames) :
            spec_(spec), options_(options), output_(output), feed_(feed),
            eventDriven_(!(options.rate > 0)), meter_(SteadyClock::now())
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

    void stop() override
    {
        {
            std::lock_guard<std::mutex> lock(shared_.mutex);
            shared_.stopping = true;
        }
        shared_.wake.notify_all();
    }

    /// The totals as they stand, read under the lock (`stats`, /diagnostics).
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

    void stats(yarp::os::Bottle& out) override
    {
        const Totals now = totals();
        double achieved = 0.0;
        {
            std::lock_guard<std::mutex> lock(meterMutex_);
            achieved = meter_.read(SteadyClock::now(), now.published);
        }
        statsItems(out, now, achieved, now.rate);
    }

    std::vector<std::string> help() const override { return kStreamHelp; }

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

    /// Opens the inputs, the output and the inputs read outside YARP; makes
    /// the watcher of connections: false when one cannot open (said;
    /// failure() says why).
    bool open() override
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
        return status == 0;
    }

    /// Once open: publishes until stopped.
    void serve() override
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

    /// Closes what is open: the watcher, the inputs read outside YARP, the
    /// ports and the output.
    Closed close() override
    {
        const bool watcherStopped = watcher_->stop(std::chrono::milliseconds(300));
        if (feedOpen_) {
            feed_->close();  // before the output, whose node it may share
        }
        const bool closed = closeAll(opened_, outputOpen_, std::chrono::milliseconds(800));
        return {closed, watcherStopped};
    }

private:
    /// Closes the ports in a thread of their own; false if that did not end
    /// within `limit`: the ports' names are then unregistered.
    bool closeAll(std::size_t opened, bool outputOpen, std::chrono::milliseconds limit)
    {
        const bool closed = finishBy(SteadyClock::now() + limit, [this, opened, outputOpen] {
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
            return true;
        });
        if (closed) {
            return true;
        }
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
    std::string totalsText(const std::string& prefix) override
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
    std::unique_ptr<Watcher> watcher_;
    std::mutex meterMutex_;
    RateMeter meter_;           // `stats`: the rate since the previous one
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

/// Does the bridge read or write ROS 1 topics?
bool usesRos1(const BridgeSpec& spec)
{
    bool ros1 = spec.output.kind == OutputKind::Ros1;
    for (const InputSpec& input : spec.inputs) {
        ros1 = ros1 || input.kind == InputKind::Ros1;
    }
    return ros1;
}

}  // namespace

int run(const BridgeSpec& spec, int argc, char* argv[], MessageSink& output, InputFeed* feed, FramePorts frames)
{
    Start start;
    start.options = streamOptions(spec);
    start.check = [&spec](const Options& options) {
        if (options.rate <= 0 && spec.inputs.empty()) {
            std::fprintf(stderr, "%s: an event-driven bridge needs at least one input; give --rate\n", spec.module);
            return 2;
        }
        return -1;
    };
    start.usable = [&spec] {
        std::string why;
        return usesRos1(spec) && !ros1Available(why) ? "cannot use ROS 1 topics: " + why : std::string();
    };
    start.make = [&spec, &output, feed, frames](const Options& options) -> std::unique_ptr<Bridge> {
        return std::make_unique<Stream>(spec, options, output, feed, frames);
    };
    return runBridge(start, argc, argv);
}

}  // namespace ybgc
