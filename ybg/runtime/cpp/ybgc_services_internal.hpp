// The internals the runtime's commands share (ybgc_services.hpp), not for
// modules: the callers of YARP RPC ports and ROS 2 services
// (ybgc_services_callers.cpp), the ROS 2 services and YARP ports served
// (ybgc_services_served.cpp), and the bridge of commands that puts them
// together on its node, in the process shell every kind of bridge runs in
// (ybgc_services_node.cpp).
#ifndef YBGC_SERVICES_INTERNAL_HPP
#define YBGC_SERVICES_INTERNAL_HPP

#include "ybgc_services.hpp"  // ybgc:runtime-import
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <rcl/client.h>
#include <rcl/service.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <yarp/os/Bottle.h>

namespace ybgc {
namespace services {

using Clock = SteadyClock;
using TimePoint = Clock::time_point;

/// `seconds` from now.
TimePoint after(double seconds);

class CommandsBridge;

// --- a YARP RPC port called: one connection at a time (ybgc_services_callers.cpp) -------------

/// The names of the client ports of one YARP port called that are open
/// (a port given up on keeps its name until its thread closes it): a new
/// port takes the first name free. Shared with the threads of the ports.
struct Names
{
    std::mutex mutex;
    std::set<std::string> taken;
    std::string base;  // <prefix>/<service>/rpc:o

    /// The first of <base>, <prefix>/<service>/rpc2:o, rpc3:o ... not taken; taken now.
    std::string take();
    void release(const std::string& name);
    std::set<std::string> open();
};

/// A request of a ROS 2 service served by the bridge, waiting for its call.
struct Job
{
    std::size_t service;       // in Commands::services
    rmw_request_id_t header;   // to send the response to
    void* request;             // owned (the service's SrvType)
    TimePoint deadline;        // arrival + the service's timeout
};

/// One client port and the thread that makes its blocking calls (open,
/// connect, write and wait for the reply), one at a time, taking them from
/// its caller's queue and answering each itself: a call goes from the ROS 2
/// thread that took its request to this one, and its response back from
/// here. The caller's watch gives a call still running at its deadline up
/// (`abandoned`) and answers it; the thread closes the port as soon as YARP
/// gives the write up (the port's timeout), so that its late reply is never
/// read as another call's, and a new link takes the calls after it. A call
/// that fails (no server, the connection lost) closes the port: the next one
/// opens it again and connects again.
struct Link
{
    // under Calls::mutex
    bool abandoned = false;  // given up by the caller's watch: close when the call returns
    bool quit = false;       // closing: no more calls
    bool finished = false;   // the thread ended (its port closed)

    std::string name;
    std::string remote;
    double timeout = 1.0;
    std::shared_ptr<Names> names;
};

/// What a YARP caller shares with the threads of its links (which may
/// outlive it, held by a write that does not return): the calls waiting, the
/// one in flight, the links.
struct Calls
{
    std::mutex mutex;
    std::condition_variable work;   // the current link waits for a call; close() for the links
    std::condition_variable watch;  // the caller's watch waits for the deadline of the call in flight
    std::deque<Job> queue;
    bool stopping = false;
    std::shared_ptr<Link> link;                 // the current connection (nullptr: none)
    std::vector<std::shared_ptr<Link>> given;  // links given up, closing by themselves
    bool inflight = false;  // `job` is being called on `link`
    Job job{};
    bool watching = false;  // the watch sleeps until `watched`
    TimePoint watched;
    int busy = 0;  // links using the bridge (a command being built, a call being answered)
};

/// One YARP RPC port called by the bridge: its calls made one after
/// another, in the order they came, by the thread of one link, each
/// answered by its deadline whatever the server does (a Link a connection).
/// Its own thread watches the deadline of the call in flight; it is woken
/// when a call starts only if it sleeps past that call's deadline, or not
/// at all.
class YarpCaller
{
public:
    YarpCaller(CommandsBridge& bridge, std::string local, std::string remote, double timeout);
    /// Is the port called registered with the name server (asked once, at a call's deadline)?
    bool serverRegistered() const;

    void start();
    /// A request to call it with: answered once the call ends.
    void submit(Job job);
    /// Closing: the calls not answered yet are answered (reason `stopped`).
    void stop();
    /// The thread ended; the port closed by `deadline` (false: a call still holds it).
    bool close(TimePoint deadline);
    /// The names of its ports still open.
    std::set<std::string> openNames() const { return names_->open(); }

private:
    /// The thread of the caller: the deadline of the call in flight.
    void watch();
    /// A new current link and its thread (under calls_->mutex).
    void startLink();
    /// The thread of a link (detached: it may outlive the bridge's wait for
    /// it); it uses `caller` only while it counts in Calls::busy.
    static void run(std::shared_ptr<Link> link, std::shared_ptr<Calls> calls, YarpCaller* caller);
    /// Answers `job`, whose call ended (`ok`: with `reply`) or did not.
    void called(Job& job, bool ok, Failure failure, const yarp::os::Bottle& command, const yarp::os::Bottle& reply);
    /// The call in flight given up with its link (under calls_->mutex): its job, to answer.
    Job giveUp();
    /// Answers a call given up at its deadline: timed out, or no server if the port's server left.
    void answerUnanswered(Job& job);
    /// Answers a call the bridge's stop ended (reason `stopped`).
    void answerStopped(Job& job);

    CommandsBridge& bridge_;
    std::string remote_;
    double timeout_;
    std::shared_ptr<Names> names_;
    std::shared_ptr<Calls> calls_;
    std::thread thread_;
};

// --- a ROS 2 service called (ybgc_services_callers.cpp) -----------------------------------------

/// One ROS 2 service called by the bridge (a command of a YARP port it
/// serves): its rcl client, the calls waiting for their response by
/// sequence number. rcl's client is used under `mutex`; responses are taken
/// by the bridge's ROS 2 thread and handed to their call; one whose call
/// was given up is dropped.
class RosClient
{
public:
    explicit RosClient(const Service& service);

    bool open(rcl_node_t* node);
    void fini(rcl_node_t* node);
    rcl_client_t* client() { return &client_; }

    /// Calls the service with `request`: Failure::None with `response` (owned
    /// by the caller), else why not (`stopped`: the bridge stops).
    Failure call(const void* request, TimePoint deadline, void*& response, bool& stopped);
    /// Takes the responses that came (the ROS 2 thread).
    void take();
    void stop();

private:
    struct Pending
    {
        void* response = nullptr;
        bool done = false;
    };

    const Service& service_;
    rcl_node_t* node_ = nullptr;
    rcl_client_t client_ = rcl_get_zero_initialized_client();
    bool ok_ = false;
    std::mutex mutex_;
    std::condition_variable cv_;
    std::map<std::int64_t, Pending*> pending_;
    void* buffer_ = nullptr;  // the next response taken
    bool stopping_ = false;
};

// --- a ROS 2 service served (ybgc_services_served.cpp) ---------------------------------------------

/// One ROS 2 service served by the bridge: its rcl service (used under
/// `mutex`: requests taken by the ROS 2 thread, responses sent by the
/// threads of the YARP ports called).
class RosServer
{
public:
    RosServer(CommandsBridge& bridge, std::size_t index, YarpCaller& caller);

    bool open(rcl_node_t* node);
    void fini(rcl_node_t* node);
    rcl_service_t* service() { return &rcl_; }
    /// Takes the requests that came (the ROS 2 thread) and hands each to its caller.
    void take();
    /// Sends a response (its sender keeps it).
    void send(rmw_request_id_t& header, void* response);

private:
    CommandsBridge& bridge_;
    std::size_t index_;
    const Service& svc_;
    YarpCaller& caller_;
    rcl_service_t rcl_ = rcl_get_zero_initialized_service();
    bool ok_ = false;
    std::mutex mutex_;
    bool reportedSendError_ = false;
};

// --- the bridge of commands (ybgc_services_node.cpp, ybgc_services_served.cpp) ---------------------

/// A module's commands as a bridge of the process shell: its node (its
/// services served and called, their ROS 2 thread, its /diagnostics), the
/// YARP ports it calls and serves, its counts. Its own RPC port is the
/// shell's, unless it serves a port of that name (which then answers
/// `stats` and `quit` too); in a process of several bridges, the process's.
class CommandsBridge : public Bridge
{
public:
    CommandsBridge(const Commands& spec, const Options& options, std::vector<std::string> rosArgs);

    bool open() override;
    void serve() override;
    void stop() override;
    Closed close() override;
    std::string totalsText(const std::string& prefix) override;
    void stats(yarp::os::Bottle& out) override;
    void ownStats(yarp::os::Bottle& reply) override;
    std::vector<std::string> help() const override;
    void unknown(const std::string& word, yarp::os::Bottle& reply) const override;
    bool serves(const std::string& name) const override;

    const Commands& spec() const { return spec_; }

    /// A call of service `s` starts: counted.
    void started(std::size_t s);
    /// A call of service `s` ended: counted; a failure said (the first of
    /// the service, or each with --verbose).
    void ended(std::size_t s, Failure failure, const std::string& text);
    /// With --verbose: a call and its answer.
    void saySuccess(std::size_t s, const yarp::os::Bottle& command, const yarp::os::Bottle& reply);
    /// The reason of a call given up because the bridge stops.
    std::string stoppedText(const Service& s) const;

    /// Answers the request of a job (the thread of its YARP port called):
    /// `reply` the call's reply (Failure::None), else the failure and its text.
    void answer(Job& job, Failure failure, const std::string& why, const yarp::os::Bottle* command,
                const yarp::os::Bottle* reply);

    /// The reply to a command on the port `port` it serves; `quit`: it
    /// asked the module to stop (its own RPC port).
    void respond(const std::string& port, const yarp::os::Bottle& command, yarp::os::Bottle& reply, bool& quit);

    /// Calls in flight on the ports served (for the grace at closing).
    std::atomic<int> active{0};

private:
    void serveYarp(std::size_t s, const yarp::os::Bottle& command, yarp::os::Bottle& reply);
    void failedReply(std::size_t s, const std::string& text, yarp::os::Bottle& reply);
    /// The reason of a command no service names.
    std::string unknownText(const std::string& word) const;
    bool openAll();
    void spin();

    const Commands& spec_;
    const Options options_;
    ybgc::ros2::Node node_;
    bool nodeOpen_ = false;
    std::mutex mutex_;
    std::condition_variable cv_;
    bool stopping_ = false;
    std::vector<Counts> counts_;
    std::map<std::string, std::unique_ptr<YarpCaller>> callers_;  // by the YARP port called
    std::vector<std::unique_ptr<RosServer>> servers_;
    std::map<std::size_t, std::unique_ptr<RosClient>> clients_;   // by service
    std::vector<std::unique_ptr<RpcPort>> served_;
    std::thread spinner_;
    std::atomic<bool> spinning_{false};
};

}  // namespace services
}  // namespace ybgc

#endif  // YBGC_SERVICES_INTERNAL_HPP
