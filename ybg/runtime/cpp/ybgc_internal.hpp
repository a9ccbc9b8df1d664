// The internals that the C++ runtime's source files share, not for modules
// (what a module uses is ybgc_runtime.hpp): the input ports, the watcher of
// connections, the YARP output, which a stream (ybgc_runtime.cpp) puts
// together; and the process shell every kind of bridge runs in, alone or
// among others (ybgc_shell.cpp: signals, the RPC port, start and shutdown;
// ybgc_options.cpp: the command line).
#ifndef YBGC_INTERNAL_HPP
#define YBGC_INTERNAL_HPP

#include "ybgc_runtime.hpp"  // ybgc:runtime-import

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <signal.h>

#include <yarp/os/Bottle.h>
#include <yarp/os/BufferedPort.h>
#include <yarp/os/Bytes.h>
#include <yarp/os/ConnectionReader.h>
#include <yarp/os/ConnectionWriter.h>
#include <yarp/os/Contact.h>
#include <yarp/os/Contactable.h>
#include <yarp/os/PortReader.h>
#include <yarp/os/Portable.h>
#include <yarp/os/RpcServer.h>
#include <yarp/os/TypedReaderCallback.h>
#include <yarp/os/Value.h>

namespace ybgc {

// --- the input ports (ybgc_inputs.cpp) ----------------------------------------------

class Input;

/// Told of every accepted Bottle, in the input's callback thread, with
/// Shared::mutex held.
class ArrivalListener
{
public:
    virtual ~ArrivalListener() = default;
    virtual void arrived(Input& input, bool wasFresh) = 0;
};

/// What the input callbacks and the loop share; guarded by `mutex`.
struct Shared
{
    std::mutex mutex;
    std::condition_variable wake;  // stop, or an input became fresh (new stale deadline)
    bool stopping = false;
    bool dropNan = false;
    std::size_t queue = 1;  // unused Bottles kept per input (BridgeSpec::queue)
    ArrivalListener* listener = nullptr;
    std::function<void()> foreign;  // an input refused a Bottle of another port: the watcher closes its connection
    FramePorts frames = nullptr;    // makes the ports of the YARP camera image inputs (ybgc_images.cpp)
    const char* module = nullptr;   // the bridge's name, said by the threads of its ports' callbacks (tModule)
};

/// The time of an envelope stamp in the text YARP carries it as ("SEQ
/// TIME", yarp::os::Stamp::write), read as Stamp::read reads it: false when
/// it is none (no envelope, another kind of envelope, a negative sequence
/// number: an invalid Stamp).
bool stampTime(const yarp::os::Bytes& envelope, double& time);

/// An input Bottle with the name of the port that sent it: YARP's name for
/// the connection's remote end (what YARP prints as "Receiving input from"),
/// which is the sender's own name, whatever name the connection was asked
/// for; and the time of its envelope stamp, read from the connection as it
/// brought it (the envelope the port keeps for this Bottle, without
/// reading it again through a Stamp: YARP's getEnvelope() makes a
/// connection reader for it, six allocations a Bottle).
class SourcedBottle : public yarp::os::Portable
{
public:
    bool read(yarp::os::ConnectionReader& connection) override
    {
        source = connection.getRemoteContact().getName();
        const bool ok = bottle.read(connection);
        hasEnvelope = stampTime(connection.readEnvelope(), envelope);
        return ok;
    }

    bool write(yarp::os::ConnectionWriter& connection) const override { return bottle.write(connection); }

    yarp::os::Bottle bottle;
    std::string source;
    bool hasEnvelope = false;
    double envelope = 0.0;  // its envelope stamp's time, seconds
};

/// An admin command to the port at `where` (its contact: no name server
/// needed); false when it does not answer.
bool admin(const yarp::os::Contact& where, const std::string& command, yarp::os::Bottle& reply);

/// The port of a YARP camera image input (InputSpec::image), made by the
/// image side of the runtime (ybgc_images.cpp, beside a module that reads
/// images, which links YARP_sig): it reads frames of any pixel type, each
/// with the name of the port that sent it, and hands each to its input
/// (Input::onFrame) in YARP's callback thread.
class FramePort
{
public:
    virtual ~FramePort() = default;
    /// Opens the port `name`; `strict`: every frame reaches the input, in order.
    virtual bool open(const std::string& name, bool strict) = 0;
    /// Stops the callbacks and closes it.
    virtual void close() = 0;
    /// The port, for what every port does (its name, its connections, interrupt).
    virtual yarp::os::Contactable& port() = 0;
};

/// One input: its own port, read by YARP's callback thread, keeping only
/// the newest accepted Bottle with its arrival time and envelope. Each
/// Bottle comes with the name of the port that sent it: from a YARP port
/// input, a Bottle of any port it does not accept is refused, never used.
/// A camera image input reads frames instead, on a FramePort, through the
/// same checks of the port that sent them, freshness and matching.
class Input : public InputState, public yarp::os::TypedReaderCallback<SourcedBottle>
{
public:
    Input(Shared& shared, const InputSpec& spec, std::string local, double timeout);

    bool open();
    void interrupt();
    void close();

    /// The ports connected to its port, by YARP's names for them.
    std::vector<std::string> sources();

    /// Closes the connection from port `name` to its port (an admin `del`
    /// to its own port, which needs no name server: `name` may be a port
    /// the name server does not know).
    void drop(const std::string& name);

    using yarp::os::TypedReaderCallback<SourcedBottle>::onRead;

    void onRead(SourcedBottle& in) override;

    /// A frame read by its FramePort (YARP's callback thread), sent by port
    /// `source` (`pending`: the frames still unread behind it): taken as a
    /// Bottle is, or refused for `why` when not empty (a pixel type other
    /// than the declared one: refuseFrame); `frame` moved out when taken.
    void onFrame(const std::string& source, Frame& frame, bool hasEnvelope, double envelope, int pending,
                 const std::string& why);

    /// One message read by an InputFeed (its thread): checked against the
    /// layout (each row of it: one that does not check drops it whole), then
    /// as a Bottle.
    void deliver(Reading& reading);

    /// Its port's name and address, once open.
    yarp::os::Contact where() const;

    /// A connection of port `other`, which it does not accept: said once.
    void refuseConnection(const std::string& other);

    const std::string local;  // this module's own port
    std::string registered;   // its name in the name server (topic-@node for ROS)

private:
    /// A message read and accepted, Shared::mutex held: its values (moved
    /// out); `rows`: its rows (moved out), for an array of messages;
    /// `frame`: its frame (moved out), for a camera image.
    void take(Mux& values, bool hasEnvelope, double envelope, SteadyClock::time_point now, Rows* rows = nullptr,
              Frame* frame = nullptr);

    /// Is a Bottle or frame of port `source` one it takes? If not, it is
    /// refused (counted, said once) and its connection closed.
    bool fromAccepted(const std::string& source);

    /// Its port: of Bottles, or of frames.
    yarp::os::Contactable& port();
    const yarp::os::Contactable& port() const;

    Shared& shared_;
    yarp::os::BufferedPort<SourcedBottle> port_;
    std::unique_ptr<FramePort> frames_;  // a camera image input's port, once open
    Mux scratch_;  // only touched by the callback thread
    std::vector<const yarp::os::Value*> items_;
};

// --- connections (ybgc_connections.cpp) -----------------------------------------------

/// A connection the watcher keeps up: to an input's port from its source
/// (`input` set), or from the output to a port it connects to.
struct Link
{
    std::string source;
    std::string destination;
    Input* input = nullptr;
};

/// Every 0.5 s, connects each link whose source exists and that is not
/// connected, so that a source that starts late or is restarted is picked
/// up. An input's port reports its connections itself (no network traffic):
/// one from its source (or a port it accepts) leaves it alone; one from any
/// other port is closed (said once); the network is asked only about a
/// missing one, and once a period whether the name server still knows the
/// module's first port (registerAgain). What YARP connected is the port that
/// answered at the address the name server gave: it is said by its own name,
/// and when it is another port its Bottles are refused and its connection
/// closed; that address is then connected again only once the port there
/// answers as the source. Its own thread: the loop never waits for it. Its
/// state is shared with the thread, so that a thread held up by a peer that
/// does not answer can be left behind at exit.
class Watcher
{
public:
    /// `own`: the module's own ports, kept registered with the name server.
    Watcher(std::vector<Link> links, std::vector<yarp::os::Contact> own);

    void start();

    /// What wakes it at once (an input refused a Bottle: its connection is
    /// closed now); callable from any thread, also once it has stopped.
    std::function<void()> waker() const;

    /// Stops the thread; false if it did not end within `limit`.
    bool stop(std::chrono::milliseconds limit);

private:
    struct State;

    static void run(State& s);
    static void registerAgain(const State& s);
    static void checkInput(State& s, std::size_t k);
    static void check(State& s, std::size_t k);
    static bool listsInput(const std::string& port, const std::string& source);

    std::shared_ptr<State> state_;
    std::thread thread_;
};

// --- the output (ybgc_bottles.cpp) ------------------------------------------------------

/// The YARP output: each message, a Bottle built by `make`, written on a
/// BufferedPort (a ROS 1 topic's too), never waiting for a slow reader.
std::unique_ptr<MessageSink> yarpOutput(const OutputSpec& spec, MakeMessage make);

/// Writes what `port` (a BufferedPort) has prepared. A message written while
/// the previous one is still being sent is dropped for the connections that
/// are still busy; so it waits for them a little (50 ms at most), unless a
/// reader has already shown that it stalls (`patient` false: it then waits
/// no more until the port is found idle again). True when it wrote while a
/// connection was still busy: a reader missed this message.
template <class Port>
bool writePatiently(Port& port, bool& patient)
{
    bool busy = port.isWriting();
    if (busy && patient) {
        const SteadyClock::time_point deadline = SteadyClock::now() + std::chrono::milliseconds(50);
        while (port.isWriting() && SteadyClock::now() < deadline) {
            std::this_thread::sleep_for(std::chrono::microseconds(50));
        }
        busy = port.isWriting();
        patient = !busy;
    } else if (!busy) {
        patient = true;
    }
    port.write();
    return busy;
}

// --- what `stats` says of a stream (ybgc_totals.cpp) ------------------------------------

/// The rate achieved: messages published per second since the previous
/// reading (the first: since the meter was made, at start).
class RateMeter
{
public:
    explicit RateMeter(SteadyClock::time_point now) : then_(now) {}

    double read(SteadyClock::time_point now, std::uint64_t published);

private:
    SteadyClock::time_point then_;
    std::uint64_t before_ = 0;
};

/// What `stats` answers of a bridge, appended to `out` (after its vocab
/// `many`): one list per input (input SOURCE received N dropped N stale N
/// unused N refused N), (published N skipped N failures N missed N), (rate ACHIEVED
/// configured HZ|event-driven); `rate`: the configured rate, 0 event-driven.
void statsItems(yarp::os::Bottle& out, const Totals& totals, double achieved, double rate);

/// What `help` answers on a stream's RPC port, one line a command.
extern const std::vector<std::string> kStreamHelp;

/// The exit totals' line of a ROS 2 publisher or subscription that had
/// incompatible peers (without its indent), as the Python runtime's.
std::string ros2TotalsLine(const Totals::Ros2Endpoint& e);
/// The exit totals' line of the messages YARP readers missed, when any
/// (the Python runtime's core.MISSED_LINE).
std::string missedLine(std::uint64_t missed);

// --- the process shell (ybgc_shell.cpp) ---------------------------------------------------
// What every kind of bridge (a stream, commands) runs in, alone or among others
// (ybgc compose): its command line, SIGINT and SIGTERM, the YARP network, its RPC
// port, its start and its shutdown within deadlines, its exit totals.

/// A thread of this thread's bridge: what it says is headed by the bridge's
/// name (tModule), in a process of several bridges too.
template <class F>
std::thread bridgeThread(F&& f)
{
    return std::thread([f = std::forward<F>(f), who = tModule]() mutable {
        tModule = who;
        f();
    });
}

/// Runs `work` in a thread of this bridge; true when it ended by
/// `deadline` and said so (returned true), else false: a thread still at
/// work is left to end by itself (a peer that does not answer holds it; the
/// process may exit without it).
bool finishBy(SteadyClock::time_point deadline, std::function<bool()> work);

/// A thread left closing a port still uses its bridge: the calling thread
/// never returns (the process exits without it).
[[noreturn]] void hold();

/// The command's first item as a word ("" for none; a vocab as its word, a
/// number as its text).
std::string firstWord(const yarp::os::Bottle& command);

/// A YARP RPC port served (a yarp::os::RpcServer): each command answered by
/// `answer` in YARP's own thread of its connection (callers on several
/// connections are answered at once), never in a bridge's loop or inputs;
/// a command whose answer asked to quit (answer's result) runs `quit` once
/// its reply is on its way. What its thread says is headed by the name of
/// the bridge that made it.
class RpcPort : public yarp::os::PortReader
{
public:
    using Answer = std::function<bool(const yarp::os::Bottle& command, yarp::os::Bottle& reply)>;

    RpcPort(std::string name, Answer answer, std::function<void()> quit);

    bool open();

    /// Closed once no command is being answered (or after `limit`) and the
    /// reply of a `quit` is on its way: YARP sends a reply when read() has
    /// returned, so a port closed at once could drop it (the caller would
    /// not know the module heard it).
    void close(std::chrono::milliseconds limit);

    bool read(yarp::os::ConnectionReader& connection) override;

    const std::string name;

private:
    Answer answer_;
    std::function<void()> quit_;
    const char* module_;  // the bridge whose lines its thread says (tModule)
    std::atomic<int> reading_{0};
    std::atomic<bool> answered_{false};  // a command came while it was closing
    std::atomic<bool> quitAsked_{false};
    yarp::os::RpcServer port_;
};

/// What closing a bridge ended with: its ports closed (else a peer held one
/// and their names were unregistered), its threads ended, each within its
/// deadline. Either false: the process exits without waiting for them.
struct Closed
{
    bool ports = true;
    bool threads = true;
    bool clean() const { return ports && threads; }
};

/// What a module's own RPC port answers, as YARP modules do (`yarp rpc
/// <prefix>/rpc:i`): `help`, `stats`, `quit` (also `exit`, `bye`: the
/// RFModule convention); a bridge's, or a process of several bridges'.
class RpcCommands
{
public:
    virtual ~RpcCommands() = default;
    /// `stats`: its lists, after the vocab `many` (a bridge of commands: its lists alone).
    virtual void ownStats(yarp::os::Bottle& reply) = 0;
    /// What `help` answers, a line a command.
    virtual std::vector<std::string> help() const = 0;
    /// The answer to a word it does not know.
    virtual void unknown(const std::string& word, yarp::os::Bottle& reply) const;
    /// Asks it to stop, from any thread (a signal's, an RPC port's, the process's).
    virtual void stop() = 0;

    /// `stats` and `quit` answered (`quit` set: it stops once the reply is
    /// on its way); false for any other word.
    bool answerOwn(const std::string& word, yarp::os::Bottle& reply, bool& quit);
    /// A command on its RPC port: `help`, `stats`, `quit`, else unknown();
    /// true when it asked to quit.
    bool answerRpc(const yarp::os::Bottle& command, yarp::os::Bottle& reply);
};

/// A bridge of one kind (a stream: ybgc_runtime.cpp; commands:
/// ybgc_services_node.cpp) as the process shell runs it: alone, a module
/// with its own signals, YARP network and RPC port; or among others in a
/// process of several (Host), which has them.
class Bridge : public RpcCommands
{
public:
    /// Opens what it uses; false when something cannot open (said; failure() says why).
    virtual bool open() = 0;
    /// Says what it does, then runs until stop().
    virtual void serve() = 0;
    /// Closes what open() opened, within its deadlines.
    virtual Closed close() = 0;
    /// Its exit totals, each line headed by `prefix`.
    virtual std::string totalsText(const std::string& prefix) = 0;
    /// What `stats` answers of it, appended to `out`: its lists.
    virtual void stats(yarp::os::Bottle& out) = 0;
    void ownStats(yarp::os::Bottle& reply) override;
    /// Does it serve the port `name` itself (commands: a port it serves
    /// named as its own RPC port, which then answers `stats` and `quit` too)?
    virtual bool serves(const std::string& /*name*/) const { return false; }

    /// Says why it cannot run, and keeps it (failure()).
    void fail(const std::string& why);
    /// Why it cannot run ("": it can).
    const std::string& failure() const { return failure_; }

    /// Its own RPC port's name, set by the shell before open() (a module of
    /// its own: <prefix>/rpc:i); "" in a process of several bridges, whose RPC
    /// port is the process's.
    std::string ownPort;

protected:
    std::string failure_;
};

/// Blocks SIGINT and SIGTERM in every thread (construct it before any
/// thread starts) and waits for them in a thread of its own: the first one
/// asks the process to stop; if it is not closed 1.9 s later, or a second
/// signal comes, the process exits at once, status 1.
class SignalWatch
{
public:
    SignalWatch();
    void start(std::function<void()> onStop);
    /// Everything is closed: end the thread.
    void finish();

private:
    void run(const std::function<void()>& onStop);

    sigset_t set_;
    std::thread thread_;
    std::atomic<bool> finished_{false};
};

// --- a bridge in a process of several (ybgc compose: ybgc_compose.cpp) -----------------

/// What the process of several bridges holds of one of them once it runs.
struct Running
{
    std::function<void(yarp::os::Bottle&)> stats;  // its lists of `stats` (under its lock)
    std::function<void()> stop;                     // asks it to stop, from any thread
};

/// The process that runs a bridge among others (ybgc compose), set in the
/// thread that runs the bridge (Host::current()): the shell then uses the
/// process's YARP network, signals and RPC port instead of opening its
/// own, and tells it how the bridge starts and ends; a ROS 2 node opens on
/// the process's one rcl context (ybgc_ros2_node.cpp).
class Host
{
public:
    virtual ~Host() = default;
    /// The host of this thread's bridge (nullptr: a module of its own).
    static Host* current();
    static void setCurrent(Host* host);

    /// Only its command line and parameters are checked, nothing opens:
    /// the shell returns 0 once they are.
    virtual bool checking() const = 0;
    /// It runs (its ports and nodes open) until `running.stop`.
    virtual void started(Running running) = 0;
    /// It cannot start (`why`: the reason, said already); what it opened is closed.
    virtual void refused(const std::string& why) = 0;
    /// It stopped and closed its ports: `totals`, the lines of its exit
    /// totals (each headed by its name); `clean` false when a peer held a
    /// port (the names were unregistered: the process exits without waiting
    /// for it, and this thread never returns).
    virtual void closed(const std::string& totals, bool clean) = 0;
    /// Runs `finish` once every bridge has closed, before the process exits
    /// (the ROS 2 context of the process, shut down); the last given first.
    virtual void atEnd(std::function<void()> finish) = 0;
};

// --- the command line (ybgc_options.cpp) ------------------------------------------------

struct Options
{
    std::string prefix;
    std::string from;     // --from FILE
    std::string context;  // --context CTX
    double rate = 0.0;
    bool hasTimeout = false;
    double timeout = 0.0;
    bool verbose = false;
    std::vector<std::pair<std::string, std::string>> accept;  // --accept: (input's source, other port)
};

/// What a kind of bridge takes on its command line: --name (--prefix),
/// --verbose and --help; a stream also --rate, --timeout, --accept, --from
/// and --context.
struct OptionsSpec
{
    const char* module;         // the program's name when argv[0] has none; its YARP config file's
    const char* config;         // the config it was generated from (--help)
    const char* defaultPrefix;  // --name's default
    bool stream = false;        // it takes a stream's options too
    double rate = 0.0;          // --rate's default (a stream: its config's)
    std::vector<std::string> ports;  // --accept: the YARP ports it reads
    const char* usage = "";     // its usage line, after the program's name
    const std::vector<const char*>* description = nullptr;  // what it does (--help)
    /// Prints the rest of its --help: its options and ROS arguments.
    std::function<void(std::FILE* out)> help;
};

/// Its usage line for the program `prog` and, `full`, its --help.
void printUsage(const OptionsSpec& spec, const std::string& prog, std::FILE* out, bool full);

/// A number as the start-up line and --help say it (printf's %g).
std::string formatNumber(double x);

/// Parses argv into `opt`: -1 to go on, else the exit status (0 after
/// --help, 2 for a bad option, said with the usage line). `--from` /
/// `--context` (a stream): the options in that YARP config file come
/// first, so that the command line wins over the file and the file over the
/// config.
int parseOptions(const OptionsSpec& spec, int argc, char* argv[], Options& opt);

/// What a stream takes on its command line, and its --help.
OptionsSpec streamOptions(const BridgeSpec& spec);

/// Moves the ROS arguments of a command line (from `--ros-args` to `--` or
/// the end, as ROS 2 spells them) out of `argv`, into the result.
std::vector<std::string> takeRosArgs(int& argc, char* argv[]);

/// A command line with `before` inserted after the program's name: the
/// options the ROS parameters give, which the command line's own follow
/// (and so win over).
class CommandLine
{
public:
    CommandLine(int argc, char* argv[], const std::vector<std::string>& before);
    int argc() const { return static_cast<int>(words_.size()); }
    char** argv() { return argv_.data(); }

private:
    std::vector<std::string> words_;
    std::vector<char*> argv_;
};

/// The command line of a bridge with a ROS 2 node (ybgc_ros2_params.cpp,
/// beside a module with one): its ROS arguments taken out (`rosArgs`, given
/// to rcl) and checked for the node `node` before anything opens, and the
/// options its parameters give put before the command line's own (argc(),
/// argv()); `status` 0 to go on, else the exit status (2, said under the
/// name of `module`). A bridge of commands (`stream` false) takes the
/// parameters `prefix` and `verbose` alone.
class RosCommandLine
{
public:
    RosCommandLine(int argc, char* argv[], const char* module, const char* node, bool stream = true);
    int argc() const { return line_->argc(); }
    char** argv() { return line_->argv(); }

    int status = 0;
    std::vector<std::string> rosArgs;

private:
    std::unique_ptr<CommandLine> line_;
};

/// How the shell starts a bridge of one kind (runBridge).
struct Start
{
    OptionsSpec options;
    /// Once its options are parsed: -1 to go on, else the exit status (said).
    std::function<int(const Options&)> check;
    /// Once YARP is up, before it opens: "" or why it cannot run.
    std::function<std::string()> usable;
    /// The bridge of these options.
    std::function<std::unique_ptr<Bridge>(const Options&)> make;
};

/// Parses the command line and runs the bridge until SIGINT, SIGTERM or
/// `quit` (a module of its own), or as its host says (a process of several
/// bridges); the exit status: 0 when stopped, 1 when it cannot reach YARP or
/// something cannot open, 2 for a bad option.
int runBridge(const Start& start, int argc, char* argv[]);

}  // namespace ybgc

#endif  // YBGC_INTERNAL_HPP
