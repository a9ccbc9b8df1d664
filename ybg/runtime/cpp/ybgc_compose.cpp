// Several bridges in one process (ybgc_compose.hpp): the process's command
// line, signals, YARP network and RPC port (the process shell's parts,
// ybgc_shell.cpp); each bridge's main() run in a thread of its own as the
// Host of its bridge (ybgc_internal.hpp), whatever its kind (a stream,
// commands), started one after the other (one that cannot start is said
// and the others run); the stop (SIGINT, SIGTERM, `quit`) of every bridge at
// once, each closing its own ports, its totals printed under its name,
// within 2 s.
#include "ybgc_compose.hpp"  // ybgc:runtime-import
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/Network.h>

namespace ybgc {
namespace compose {

namespace {

/// What `help` answers on the RPC port of a composed module, one line a
/// command (as the Python runtime's compose.COMPOSED_HELP).
const std::vector<std::string> kHelp = {
    "help: this list",
    "stats: one list per bridge, its name then its own stats: per input (input SOURCE received N dropped N "
    "stale N unused N refused N), (published N skipped N failures N missed N), (rate ACHIEVED configured "
    "HZ|event-driven); a node of commands: per service (service NAME calls N answered N failed N timed_out N "
    "no_server N unfit N); a bridge that is not running: (NAME \"not running\" WHY)",
    "quit: stop every bridge (each closes its ports and prints its totals; exit 0, or 1 if a bridge could "
    "not start)",
};

/// From a stop (SIGINT, SIGTERM, `quit`): the bridges' ports closed and
/// their totals printed within kCloseBudget, their ROS 2 nodes within
/// kNodesBudget, the ROS 2 context shut down within kExitBudget; else the
/// process exits without waiting any longer.
constexpr std::chrono::milliseconds kCloseBudget(1400);
constexpr std::chrono::milliseconds kNodesBudget(1700);
constexpr std::chrono::milliseconds kExitBudget(1850);

/// "<name>: <text>", whatever this thread's bridge is.
void sayAs(const char* name, const std::string& text)
{
    printLines(std::string(name) + ": " + text + "\n");
}

class Composer;

/// One bridge of the process, the Host of its thread.
class Slot : public Host
{
public:
    enum class State { Starting, Running, Refused, Closed };

    Slot(Composer& composer, const Member& member, bool checking) :
            member(member), composer_(composer), checking_(checking)
    {
    }

    bool checking() const override { return checking_; }
    void started(Running running) override;
    void refused(const std::string& why) override;
    void closed(const std::string& totals, bool clean) override;
    void atEnd(std::function<void()> finish) override;

    const Member& member;
    // guarded by the composer's mutex
    State state = State::Starting;
    std::string why;       // why it is not running
    std::string totals;    // its exit totals, once closed
    bool clean = true;     // closed within its deadlines
    bool returned = false; // its main() returned
    std::thread thread;
    // held while the process uses its bridge (`stats`, a stop), which is
    // then not closed and destroyed meanwhile
    std::mutex liveMutex;
    bool live = false;                 // its bridge runs (guarded by liveMutex)
    Running running;                   // (guarded by liveMutex)

private:
    Composer& composer_;
    const bool checking_;
};

/// The bridges of the process, and what its RPC port answers.
class Composer : public RpcCommands
{
public:
    Composer(const char* name, const Member* members, std::size_t count, std::vector<std::string> rosArgs) :
            name_(name), rosArgs_(std::move(rosArgs))
    {
        for (std::size_t k = 0; k < count; ++k) {
            slots_.push_back(std::make_unique<Slot>(*this, members[k], false));
        }
    }

    /// Each bridge's command line and parameters checked, nothing opened:
    /// 0, or the status of the first refused (said by it).
    int check()
    {
        int status = 0;
        for (const auto& slot : slots_) {
            Slot checker(*this, slot->member, true);
            Host::setCurrent(&checker);
            tModule = slot->member.module;
            char* program = const_cast<char*>(slot->member.module);
            CommandLine words(1, &program, rosArgs_);
            status = slot->member.run(words.argc(), words.argv());
            Host::setCurrent(nullptr);
            tModule = nullptr;
            if (status != 0) {
                break;
            }
        }
        return status;
    }

    /// Starts the bridges one after the other, each once the one before it
    /// runs or is refused.
    void startAll()
    {
        for (const auto& slot : slots_) {
            Slot* s = slot.get();
            {
                std::lock_guard<std::mutex> lock(mutex_);
                if (stopping_) {
                    s->why = "stopped before it started";
                    s->state = Slot::State::Refused;
                    continue;
                }
            }
            s->thread = std::thread([this, s] { runSlot(*s); });
            std::unique_lock<std::mutex> lock(mutex_);
            wake_.wait(lock, [this, s] { return s->state != Slot::State::Starting || stopping_; });
        }
        std::string notRunning;
        std::size_t running = 0;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            for (const auto& slot : slots_) {
                if (slot->state == Slot::State::Refused) {
                    notRunning += (notRunning.empty() ? "" : ", ") + std::string(slot->member.module);
                } else {
                    ++running;
                }
            }
        }
        say(std::to_string(running) + (running == 1 ? " bridge running" : " bridges running")
            + (notRunning.empty() ? std::string() : "; not running: " + notRunning));
    }

    /// Asks every bridge to stop (any thread; a signal's, the RPC port's).
    void stop() override
    {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            if (!stopping_) {
                stopping_ = true;
                stoppedAt_ = SteadyClock::now();
            }
        }
        wake_.notify_all();
        for (const auto& slot : slots_) {
            stopSlot(*slot);
        }
    }

    void waitStop()
    {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [this] { return stopping_; });
    }

    /// Every bridge stopped and closed (all at once: each closes its own),
    /// their totals printed in order under their names, the ROS 2 context
    /// shut down; the exit status (1 when a bridge could not start). A bridge
    /// that does not close within the budget: the process exits without it.
    int shutDown(RpcPort& rpc)
    {
        stop();
        rpc.close(std::chrono::milliseconds(500));
        SteadyClock::time_point stoppedAt;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stoppedAt = stoppedAt_;
        }
        bool done = false;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            done = wake_.wait_until(lock, stoppedAt + kCloseBudget, [this] { return allClosed(); });
        }
        int status = 0;
        bool stuck = !done;
        std::string out;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            for (const auto& slot : slots_) {
                const char* module = slot->member.module;
                if (slot->state == Slot::State::Refused) {
                    status = 1;
                    out += std::string(module) + ": not started (" + slot->why + ")\n";
                } else if (slot->state == Slot::State::Closed) {
                    out += slot->totals;
                    stuck = stuck || !slot->clean;
                } else {
                    out += std::string(module) + ": did not stop in time\n";
                }
            }
        }
        printLines(out);
        if (stuck) {
            std::fflush(stdout);
            std::_Exit(status);
        }
        {
            // each bridge's thread ends once its nodes are destroyed
            std::unique_lock<std::mutex> lock(mutex_);
            if (!wake_.wait_until(lock, stoppedAt + kNodesBudget, [this] { return allReturned(); })) {
                std::fflush(stdout);
                std::_Exit(status);
            }
        }
        for (const auto& slot : slots_) {
            if (slot->thread.joinable()) {
                slot->thread.join();
            }
        }
        finish(stoppedAt + kExitBudget, status);
        return status;
    }

    /// `stats` on the process's RPC port: one list per bridge, its name
    /// then its own lists (or why it is not running).
    void ownStats(yarp::os::Bottle& reply) override
    {
        reply.addVocab32("many");
        for (const auto& slot : slots_) {
            yarp::os::Bottle& item = reply.addList();
            item.addString(slot->member.module);
            {
                std::lock_guard<std::mutex> live(slot->liveMutex);
                if (slot->live) {
                    slot->running.stats(item);
                    continue;
                }
            }
            std::lock_guard<std::mutex> lock(mutex_);
            item.addString("not running");
            item.addString(slot->state == Slot::State::Refused ? slot->why
                           : slot->state == Slot::State::Closed ? std::string("stopped")
                                                                 : std::string("starting"));
        }
    }

    std::vector<std::string> help() const override { return kHelp; }

    const char* name() const { return name_; }

    // what the slots tell, from their bridges' threads
    void started(Slot& slot, Running running)
    {
        {
            std::lock_guard<std::mutex> live(slot.liveMutex);
            slot.running = std::move(running);
            slot.live = true;
        }
        bool stopping = false;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            slot.state = Slot::State::Running;
            stopping = stopping_;
        }
        wake_.notify_all();
        if (stopping) {
            stopSlot(slot);  // a stop came while it was starting
        }
    }

    void refused(Slot& slot, const std::string& why)
    {
        sayAs(name_, "bridge " + std::string(slot.member.module) + " (" + slot.member.at + ") cannot start: " + why
                         + "; the other bridges run");
        {
            std::lock_guard<std::mutex> lock(mutex_);
            slot.why = why;
            slot.state = Slot::State::Refused;
        }
        wake_.notify_all();
    }

    void closed(Slot& slot, const std::string& totals, bool clean)
    {
        {
            std::lock_guard<std::mutex> live(slot.liveMutex);
            slot.live = false;  // no `stats` or stop reaches it any more: its bridge goes
        }
        {
            std::lock_guard<std::mutex> lock(mutex_);
            slot.totals = totals;
            slot.clean = clean;
            slot.state = Slot::State::Closed;
        }
        wake_.notify_all();
    }

    void atEnd(std::function<void()> finish)
    {
        std::lock_guard<std::mutex> lock(mutex_);
        finishers_.push_back(std::move(finish));
    }

private:
    /// Asks the slot's bridge to stop, if it runs.
    static void stopSlot(Slot& slot)
    {
        std::lock_guard<std::mutex> live(slot.liveMutex);
        if (slot.live) {
            slot.running.stop();
        }
    }

    /// A bridge's thread: its module's main(), hosted by its slot.
    void runSlot(Slot& slot)
    {
        Host::setCurrent(&slot);
        tModule = slot.member.module;
        char* program = const_cast<char*>(slot.member.module);
        CommandLine words(1, &program, rosArgs_);
        const int status = slot.member.run(words.argc(), words.argv());
        bool refusedNow = false;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            slot.returned = true;
            refusedNow = slot.state == Slot::State::Starting;
        }
        if (refusedNow) {  // it ended before it ran, telling nothing (a bad option)
            refused(slot, "it stopped at start with exit status " + std::to_string(status));
        }
        wake_.notify_all();
    }

    /// Every bridge is closed, or was refused and closed what it opened (mutex_ held).
    bool allClosed() const
    {
        for (const auto& slot : slots_) {
            const bool closed = slot->state == Slot::State::Closed
                || (slot->state == Slot::State::Refused && (slot->returned || !slot->thread.joinable()));
            if (!closed) {
                return false;
            }
        }
        return true;
    }

    /// Every bridge that was started has returned (mutex_ held).
    bool allReturned() const
    {
        for (const auto& slot : slots_) {
            if (slot->thread.joinable() && !slot->returned) {
                return false;
            }
        }
        return true;
    }

    /// What must be done before the process exits (the ROS 2 context shut
    /// down), the last given first, by `deadline`: else the process exits
    /// with `status` without waiting any longer.
    void finish(SteadyClock::time_point deadline, int status)
    {
        std::vector<std::function<void()>> finishers;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            finishers.swap(finishers_);
        }
        if (finishers.empty()) {
            return;
        }
        const bool done = finishBy(deadline, [finishers = std::move(finishers)] {
            for (auto it = finishers.rbegin(); it != finishers.rend(); ++it) {
                (*it)();
            }
            return true;
        });
        if (!done) {
            std::fflush(stdout);
            std::_Exit(status);
        }
    }

    const char* name_;
    const std::vector<std::string> rosArgs_;
    std::vector<std::unique_ptr<Slot>> slots_;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stopping_ = false;
    SteadyClock::time_point stoppedAt_;
    std::vector<std::function<void()>> finishers_;
};

void Slot::started(Running running)
{
    composer_.started(*this, std::move(running));
}

void Slot::refused(const std::string& why)
{
    composer_.refused(*this, why);
}

void Slot::closed(const std::string& totals, bool clean)
{
    composer_.closed(*this, totals, clean);
}

void Slot::atEnd(std::function<void()> finish)
{
    composer_.atEnd(std::move(finish));
}

/// --help: the bridges, and how each takes its parameters.
void help(const char* name, const std::string& prog, const Member* members, std::size_t count)
{
    std::string out = "usage: " + prog + " [--help] [--ros-args ...]\n\n" + name + ": " + std::to_string(count)
        + " bridges in one process (ybgc compose):\n";
    for (std::size_t k = 0; k < count; ++k) {
        out += "  " + std::string(members[k].module) + ", from " + members[k].config + "\n";
    }
    out += "\nEach bridge runs with its config's options; one with a ROS 2 side is a node of its own\n"
           "name with the parameters of its node alone (rate, timeout, prefix, verbose, diagnostics,\n"
           "diagnostic_updater.period, qos_overrides.*, use_sim_time), given for one node as\n"
           "  --ros-args -p NODE:NAME:=VALUE   or in a --params-file keyed by node name\n"
           "(-p NAME:=VALUE gives every node the value). `yarp rpc /" + std::string(name) + "/rpc:i` answers\n"
           "help, stats and quit.\n";
    std::fputs(out.c_str(), stdout);
}

}  // namespace

int run(const char* name, const Member* members, std::size_t count, int argc, char* argv[])
{
    gModule = name;
    std::string prog = argc > 0 && argv[0][0] != '\0' ? argv[0] : name;
    prog = prog.substr(prog.rfind('/') + 1);
    // the ROS arguments (from --ros-args to -- or the end) go to every bridge; nothing else is taken
    std::vector<std::string> rosArgs = takeRosArgs(argc, argv);
    std::string others;
    for (int k = 1; k < argc; ++k) {
        if (std::strcmp(argv[k], "--help") == 0 || std::strcmp(argv[k], "-h") == 0) {
            help(name, prog, members, count);
            return 0;
        }
        others += (others.empty() ? "" : " ") + std::string(argv[k]);
    }
    if (!others.empty()) {
        std::fprintf(stderr, "usage: %s [--help] [--ros-args ...]\n%s: error: unrecognized arguments: %s\n",
                     prog.c_str(), prog.c_str(), others.c_str());
        return 2;
    }
    SignalWatch signals;  // before any thread starts
    std::signal(SIGPIPE, SIG_IGN);
    Composer composer(name, members, count, std::move(rosArgs));
    if (const int status = composer.check()) {
        return status;
    }
    yarp::os::Network network;
    if (!yarp::os::Network::checkNetwork(3.0)) {
        say("cannot reach the YARP name server (is yarpserver running?)");
        return 1;
    }
    RpcPort rpc(
        "/" + std::string(name) + "/rpc:i",
        [&composer](const yarp::os::Bottle& command, yarp::os::Bottle& reply) {
            return composer.answerRpc(command, reply);
        },
        [&composer] { composer.stop(); });
    if (!rpc.open()) {
        say("cannot open the RPC port " + rpc.name);
        return 1;
    }
    signals.start([&composer] { composer.stop(); });
    composer.startAll();
    composer.waitStop();
    const int status = composer.shutDown(rpc);
    signals.finish();
    return status;
}

}  // namespace compose
}  // namespace ybgc
