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

// --- Link ----------------------------------------------------------------------------------------------

void Link::run(std::shared_ptr<Link> self)
{
    Link& l = *self;
    yarp::os::Port port;
    port.setTimeout(static_cast<float>(l.timeout));  // YARP gives up a connection or a write after it
    bool open = false;
    bool broken = false;
    for (;;) {
        yarp::os::Bottle command;
        TimePoint deadline;
        {
            std::unique_lock<std::mutex> lock(l.mutex);
            l.cv.wait(lock, [&l] { return l.state == State::Busy || l.quit || l.abandoned; });
            if (l.state != State::Busy || l.quit || l.abandoned) {
                break;
            }
            command = l.command;
            deadline = l.deadline;
        }
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
        broken = !ok;
        {
            std::lock_guard<std::mutex> lock(l.mutex);
            l.ok = ok;
            l.failure = ok ? Failure::None : Clock::now() >= deadline ? Failure::TimedOut : Failure::NoServer;
            l.reply = reply;
            l.state = State::Done;
            l.cv.notify_all();
            if (broken || l.abandoned) {
                break;
            }
        }
    }
    if (open) {
        port.interrupt();
        port.close();
    }
    l.names->release(l.name);
    std::lock_guard<std::mutex> lock(l.mutex);
    l.state = State::Ended;
    l.finished = true;
    l.cv.notify_all();
}

// --- YarpCaller --------------------------------------------------------------------------------------

YarpCaller::YarpCaller(CommandsBridge& bridge, std::string local, std::string remote, double timeout) :
        bridge_(bridge), remote_(std::move(remote)), timeout_(timeout), names_(std::make_shared<Names>())
{
    names_->base = std::move(local);
}

void YarpCaller::start()
{
    thread_ = bridgeThread([this] { dispatch(); });
}

void YarpCaller::submit(Job job)
{
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!stopping_) {
            queue_.push_back(job);
            cv_.notify_all();
            return;
        }
    }
    const Service& s = bridge_.spec().services[job.service];
    bridge_.answer(job, Failure::TimedOut, bridge_.stoppedText(s), nullptr, nullptr);
}

void YarpCaller::stop()
{
    std::shared_ptr<Link> link;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stopping_ = true;
        link = link_;
    }
    cv_.notify_all();
    if (link != nullptr) {
        std::lock_guard<std::mutex> lock(link->mutex);
        link->cv.notify_all();  // the call waiting on it ends now
    }
}

void YarpCaller::dispatch()
{
    for (;;) {
        Job job;
        bool stopping = false;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            cv_.wait(lock, [this] { return !queue_.empty() || stopping_; });
            if (queue_.empty()) {
                break;  // stopping, every call answered
            }
            job = queue_.front();
            queue_.pop_front();
            stopping = stopping_;
        }
        const Service& s = bridge_.spec().services[job.service];
        if (stopping) {
            bridge_.answer(job, Failure::TimedOut, bridge_.stoppedText(s), nullptr, nullptr);
            continue;
        }
        if (Clock::now() >= job.deadline) {
            bridge_.answer(job, Failure::TimedOut, s.spec.reasons.waited, nullptr, nullptr);
            continue;
        }
        yarp::os::Bottle command;
        s.functions.command(job.request, command);
        yarp::os::Bottle reply;
        Failure failure = Failure::None;
        bool stopped = false;
        if (call(command, job.deadline, reply, failure, stopped)) {
            bridge_.answer(job, Failure::None, "", &command, &reply);
        } else if (stopped) {
            bridge_.answer(job, Failure::TimedOut, bridge_.stoppedText(s), &command, nullptr);
        } else {
            bridge_.answer(job, failure,
                           failure == Failure::TimedOut ? s.spec.reasons.timedOut : s.spec.reasons.noServer, &command,
                           nullptr);
        }
    }
}

bool YarpCaller::call(const yarp::os::Bottle& command, TimePoint deadline, yarp::os::Bottle& reply,
                      Failure& failure, bool& stopped)
{
    std::shared_ptr<Link> link;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        // the links given up that have closed their ports are forgotten
        given_.erase(std::remove_if(given_.begin(), given_.end(),
                                    [](const std::shared_ptr<Link>& l) {
                                        std::lock_guard<std::mutex> guard(l->mutex);
                                        return l->finished;
                                    }),
                     given_.end());
        if (link_ == nullptr) {
            link_ = std::make_shared<Link>();
            link_->name = names_->take();
            link_->remote = remote_;
            link_->timeout = timeout_;
            link_->names = names_;
            bridgeThread([link = link_] { Link::run(link); }).detach();
        }
        link = link_;
    }
    std::unique_lock<std::mutex> lock(link->mutex);
    link->command = command;
    link->deadline = deadline;
    link->state = Link::State::Busy;
    link->cv.notify_all();
    const bool done = link->cv.wait_until(lock, deadline, [this, &link] {
        if (link->state == Link::State::Done || link->state == Link::State::Ended) {
            return true;
        }
        std::lock_guard<std::mutex> guard(mutex_);
        return stopping_;
    });
    if (done && link->state == Link::State::Done) {
        link->state = Link::State::Idle;
        failure = link->failure;
        const bool ok = link->ok;
        if (ok) {
            reply = link->reply;
        }
        lock.unlock();
        if (!ok) {
            std::lock_guard<std::mutex> guard(mutex_);
            link_ = nullptr;  // its thread closes the port
        }
        return ok;
    }
    // no answer by the deadline (or the module stops): the link is given up
    link->abandoned = true;
    link->cv.notify_all();
    const bool ended = link->state == Link::State::Ended;
    lock.unlock();
    {
        std::lock_guard<std::mutex> guard(mutex_);
        stopped = stopping_ && Clock::now() < deadline;
        link_ = nullptr;
        if (!ended) {
            given_.push_back(link);
        }
    }
    // a server that left the name server while the call waited (it quit) is no server,
    // whether or not its leaving broke the connection before the deadline (the Python
    // runtime says the same); one that is still registered did not answer in time
    failure = !stopped && !serverRegistered() ? Failure::NoServer : Failure::TimedOut;
    return false;
}

bool YarpCaller::serverRegistered() const
{
    return yarp::os::Network::queryName(remote_).isValid();
}

bool YarpCaller::close(TimePoint deadline)
{
    if (thread_.joinable()) {
        thread_.join();  // never waits for YARP: its calls wait until their deadlines at most
    }
    std::vector<std::shared_ptr<Link>> links;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        links = given_;
        if (link_ != nullptr) {
            links.push_back(link_);
        }
    }
    bool closed = true;
    for (const std::shared_ptr<Link>& l : links) {
        std::unique_lock<std::mutex> lock(l->mutex);
        l->quit = true;
        l->cv.notify_all();
        closed = l->cv.wait_until(lock, deadline, [&l] { return l->finished; }) && closed;
    }
    return closed;
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
