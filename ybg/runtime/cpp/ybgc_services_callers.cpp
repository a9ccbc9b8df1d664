// The callers of the runtime's commands (ybgc_services_internal.hpp): a YARP
// RPC port called, its calls one after another on one connection, each
// answered by its deadline whatever the server does; a ROS 2 service
// called, each response matched to its request.
#include "ybgc_services_internal.hpp"  // ybgc:runtime-import

#include <rcl/error_handling.h>
#include <rcl/graph.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/ContactStyle.h>
#include <yarp/os/Network.h>
#include <yarp/os/Port.h>

namespace ybgc {
namespace services {

using ros2::finished;
using ros2::rclError;

TimePoint after(double seconds)
{
    return Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

// --- Names ---------------------------------------------------------------------------------------------

std::string Names::take()
{
    std::lock_guard<std::mutex> lock(mutex);
    std::string name = base;
    const bool output = base.size() > 2 && base.compare(base.size() - 2, 2, ":o") == 0;
    for (int k = 2; taken.count(name) != 0; ++k) {
        name = output ? base.substr(0, base.size() - 2) + std::to_string(k) + ":o" : base + std::to_string(k);
    }
    taken.insert(name);
    return name;
}

void Names::release(const std::string& name)
{
    std::lock_guard<std::mutex> lock(mutex);
    taken.erase(name);
}

std::set<std::string> Names::open()
{
    std::lock_guard<std::mutex> lock(mutex);
    return taken;
}

// --- YarpCaller and its links --------------------------------------------------------------------

YarpCaller::YarpCaller(CommandsBridge& bridge, std::string local, std::string remote, double timeout) :
        bridge_(bridge),
        remote_(std::move(remote)),
        timeout_(timeout),
        names_(std::make_shared<Names>()),
        calls_(std::make_shared<Calls>())
{
    names_->base = std::move(local);
}

void YarpCaller::start()
{
    thread_ = bridgeThread([this] { watch(); });
}

void YarpCaller::submit(Job job)
{
    {
        std::lock_guard<std::mutex> lock(calls_->mutex);
        if (!calls_->stopping) {
            calls_->queue.push_back(job);
            if (calls_->link == nullptr) {
                startLink();
            }
            calls_->work.notify_all();
            return;
        }
    }
    answerStopped(job);
}

void YarpCaller::stop()
{
    {
        std::lock_guard<std::mutex> lock(calls_->mutex);
        calls_->stopping = true;
    }
    calls_->watch.notify_all();  // the call in flight is answered now
    calls_->work.notify_all();
}

void YarpCaller::startLink()
{
    Calls& c = *calls_;
    // the links given up that have closed their ports are forgotten
    c.given.erase(std::remove_if(c.given.begin(), c.given.end(),
                                 [](const std::shared_ptr<Link>& l) { return l->finished; }),
                  c.given.end());
    auto link = std::make_shared<Link>();
    link->name = names_->take();
    link->remote = remote_;
    link->timeout = timeout_;
    link->names = names_;
    c.link = link;
    bridgeThread([link, calls = calls_, caller = this] { run(link, calls, caller); }).detach();
}

void YarpCaller::run(std::shared_ptr<Link> self, std::shared_ptr<Calls> calls, YarpCaller* caller)
{
    Link& l = *self;
    Calls& c = *calls;
    yarp::os::Port port;
    port.setTimeout(static_cast<float>(l.timeout));  // YARP gives up a connection or a write after it
    bool open = false;
    for (;;) {
        Job job;
        bool late = false;
        {
            std::unique_lock<std::mutex> lock(c.mutex);
            c.work.wait(lock, [&c, &l] { return !c.queue.empty() || c.stopping || l.abandoned || l.quit; });
            if (c.stopping || l.abandoned || l.quit) {
                break;  // the calls waiting are answered by the watch
            }
            job = c.queue.front();
            c.queue.pop_front();
            ++c.busy;
            late = Clock::now() >= job.deadline;
            if (!late) {
                c.inflight = true;
                c.job = job;
                // the watch is woken only when it would sleep past this deadline
                if (!c.watching || job.deadline < c.watched) {
                    c.watch.notify_all();
                }
            }
        }
        const Service& s = caller->bridge_.spec().services[job.service];
        if (late) {
            caller->bridge_.answer(job, Failure::TimedOut, s.spec.reasons.waited, nullptr, nullptr);
            std::lock_guard<std::mutex> lock(c.mutex);
            --c.busy;
            c.work.notify_all();
            continue;
        }
        yarp::os::Bottle command;
        s.functions.command(job.request, command);
        bool ok = false;
        yarp::os::Bottle reply;
        if (!open) {
            port.setInputMode(false);
            open = port.open(l.name);
            if (!open) {
                say("cannot open the port " + l.name);
            }
        }
        if (open) {
            bool connected = port.getOutputCount() > 0;
            if (!connected) {
                yarp::os::ContactStyle style;
                style.quiet = true;
                connected = yarp::os::Network::connect(l.name, l.remote, style);
            }
            ok = connected && port.write(command, reply);
        }
        {
            std::lock_guard<std::mutex> lock(c.mutex);
            if (l.abandoned) {
                --c.busy;  // answered by the watch, which gave this link up
                c.work.notify_all();
                break;
            }
            c.inflight = false;
        }
        const Failure failure = ok ? Failure::None : Clock::now() >= job.deadline ? Failure::TimedOut : Failure::NoServer;
        caller->called(job, ok, failure, command, reply);
        {
            std::lock_guard<std::mutex> lock(c.mutex);
            --c.busy;
            c.work.notify_all();
        }
        if (!ok && open) {
            // no server or the connection lost: the next call opens the port again
            port.interrupt();
            port.close();
            open = false;
        }
    }
    if (open) {
        port.interrupt();
        port.close();
    }
    l.names->release(l.name);
    std::lock_guard<std::mutex> lock(c.mutex);
    l.finished = true;
    c.work.notify_all();
}

void YarpCaller::called(Job& job, bool ok, Failure failure, const yarp::os::Bottle& command,
                        const yarp::os::Bottle& reply)
{
    const Service& s = bridge_.spec().services[job.service];
    if (ok) {
        bridge_.answer(job, Failure::None, "", &command, &reply);
    } else {
        bridge_.answer(job, failure, failure == Failure::TimedOut ? s.spec.reasons.timedOut : s.spec.reasons.noServer,
                       &command, nullptr);
    }
}

void YarpCaller::watch()
{
    Calls& c = *calls_;
    std::unique_lock<std::mutex> lock(c.mutex);
    while (!c.stopping) {
        if (!c.inflight) {
            c.watching = false;
            c.watch.wait(lock, [&c] { return c.inflight || c.stopping; });
            continue;
        }
        if (Clock::now() < c.job.deadline) {
            // asleep until this call's deadline, though it may end and others
            // start meanwhile: the link wakes it for an earlier deadline only
            c.watching = true;
            c.watched = c.job.deadline;
            c.watch.wait_until(lock, c.watched);
            continue;
        }
        // no answer by the deadline: the link is given up, the calls after it go on a new one
        Job job = giveUp();
        if (!c.queue.empty()) {
            startLink();
        }
        c.work.notify_all();
        ++c.busy;
        lock.unlock();
        answerUnanswered(job);
        lock.lock();
        --c.busy;
        c.work.notify_all();
    }
    // stopping: the call in flight (given up) and those waiting are answered
    std::vector<Job> stopped;
    Job late{};
    bool pastDeadline = false;
    if (c.inflight) {
        Job job = giveUp();
        pastDeadline = Clock::now() >= job.deadline;
        if (pastDeadline) {
            late = job;
        } else {
            stopped.push_back(job);
        }
    }
    for (; !c.queue.empty(); c.queue.pop_front()) {
        stopped.push_back(c.queue.front());
    }
    c.work.notify_all();
    lock.unlock();
    if (pastDeadline) {
        answerUnanswered(late);
    }
    for (Job& job : stopped) {
        answerStopped(job);
    }
}

Job YarpCaller::giveUp()
{
    Calls& c = *calls_;
    c.inflight = false;
    c.link->abandoned = true;
    c.given.push_back(c.link);
    c.link = nullptr;
    return c.job;
}

void YarpCaller::answerUnanswered(Job& job)
{
    // a server that left the name server while the call waited (it quit) is no server,
    // whether or not its leaving broke the connection before the deadline (the Python
    // runtime says the same); one that is still registered did not answer in time
    const Failure failure = serverRegistered() ? Failure::TimedOut : Failure::NoServer;
    called(job, false, failure, yarp::os::Bottle(), yarp::os::Bottle());
}

void YarpCaller::answerStopped(Job& job)
{
    const Service& s = bridge_.spec().services[job.service];
    bridge_.answer(job, Failure::TimedOut, bridge_.stoppedText(s), nullptr, nullptr);
}

bool YarpCaller::serverRegistered() const
{
    return yarp::os::Network::queryName(remote_).isValid();
}

bool YarpCaller::close(TimePoint deadline)
{
    if (thread_.joinable()) {
        thread_.join();  // never waits for YARP: it answers each call by its deadline
    }
    Calls& c = *calls_;
    std::unique_lock<std::mutex> lock(c.mutex);
    std::vector<std::shared_ptr<Link>> links = c.given;
    if (c.link != nullptr) {
        links.push_back(c.link);
    }
    for (const std::shared_ptr<Link>& l : links) {
        l->quit = true;
    }
    c.work.notify_all();
    return c.work.wait_until(lock, deadline, [&c, &links] {
        return c.busy == 0
            && std::all_of(links.begin(), links.end(), [](const std::shared_ptr<Link>& l) { return l->finished; });
    });
}

// --- RosClient ----------------------------------------------------------------------------------------

RosClient::RosClient(const Service& service) : service_(service) {}

bool RosClient::open(rcl_node_t* node)
{
    node_ = node;
    rcl_client_options_t options = rcl_client_get_default_options();
    if (rcl_client_init(&client_, node, service_.type.typeSupport, service_.spec.service, &options) != RCL_RET_OK) {
        say(std::string("cannot call the ROS 2 service ") + service_.spec.service + ": " + rclError());
        return false;
    }
    ok_ = true;
    buffer_ = service_.type.createResponse();
    if (buffer_ == nullptr) {
        say(std::string("cannot allocate a response of ") + service_.type.name);
        return false;
    }
    return true;
}

void RosClient::fini(rcl_node_t* node)
{
    if (ok_) {
        finished(rcl_client_fini(&client_, node));
        ok_ = false;
    }
    if (buffer_ != nullptr) {
        service_.type.destroyResponse(buffer_);
        buffer_ = nullptr;
    }
}

Failure RosClient::call(const void* request, TimePoint deadline, void*& response, bool& stopped)
{
    // a server: waited for up to the deadline
    for (;;) {
        bool available = false;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            if (stopping_) {
                stopped = true;
                return Failure::TimedOut;
            }
            if (rcl_service_server_is_available(node_, &client_, &available) != RCL_RET_OK) {
                rcl_reset_error();
                available = false;
            }
        }
        if (available) {
            break;
        }
        if (Clock::now() >= deadline) {
            return Failure::NoServer;
        }
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait_until(lock, std::min(deadline, Clock::now() + std::chrono::milliseconds(10)),
                       [this] { return stopping_; });
    }
    Pending pending;
    std::unique_lock<std::mutex> lock(mutex_);
    std::int64_t sequence = 0;
    if (rcl_send_request(&client_, request, &sequence) != RCL_RET_OK) {
        rcl_reset_error();
        return Failure::NoServer;
    }
    pending_[sequence] = &pending;
    cv_.wait_until(lock, deadline, [this, &pending] { return pending.done || stopping_; });
    pending_.erase(sequence);  // a response that comes later is dropped
    if (pending.done) {
        response = pending.response;
        return Failure::None;
    }
    stopped = stopping_ && Clock::now() < deadline;
    return Failure::TimedOut;
}

void RosClient::take()
{
    std::lock_guard<std::mutex> lock(mutex_);
    for (;;) {
        if (buffer_ == nullptr) {
            buffer_ = service_.type.createResponse();
            if (buffer_ == nullptr) {
                return;
            }
        }
        rmw_request_id_t header;
        if (rcl_take_response(&client_, &header, buffer_) != RCL_RET_OK) {
            rcl_reset_error();
            return;
        }
        const auto it = pending_.find(header.sequence_number);
        if (it == pending_.end()) {
            continue;  // its call was given up: dropped (the buffer is taken into again)
        }
        it->second->response = buffer_;
        it->second->done = true;
        buffer_ = nullptr;
        pending_.erase(it);
        cv_.notify_all();
    }
}

void RosClient::stop()
{
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stopping_ = true;
    }
    cv_.notify_all();
}

}  // namespace services
}  // namespace ybgc
