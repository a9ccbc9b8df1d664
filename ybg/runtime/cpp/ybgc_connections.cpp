// The C++ runtime's connections (ybgc_internal.hpp): the watcher that keeps
// each input connected to its source (and the output to the port it
// connects to), closes the connections of other ports, and registers the
// module's ports again with a restarted name server.
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/Contact.h>
#include <yarp/os/ContactStyle.h>
#include <yarp/os/Network.h>

namespace ybgc {

/// Does the port at `where` answer as the port `name` (an admin `prop get`,
/// which a port answers with its process only for its own name)?
bool answersAs(const yarp::os::Contact& where, const std::string& name)
{
    yarp::os::Bottle reply;
    return admin(where, "prop get " + name, reply) && reply.check("process");
}

struct Watcher::State
{
    std::vector<Link> links;
    std::vector<yarp::os::Contact> own;
    std::vector<bool> connected;
    std::vector<bool> made;  // connected by this watcher
    std::vector<yarp::os::Contact> blocked;  // where another port answered to the source's name
    std::mutex mutex;
    std::condition_variable wake;
    bool done = false;
    bool poked = false;
    bool finished = false;
};

Watcher::Watcher(std::vector<Link> links, std::vector<yarp::os::Contact> own) : state_(std::make_shared<State>())
{
    state_->connected.assign(links.size(), false);
    state_->made.assign(links.size(), false);
    state_->blocked.assign(links.size(), yarp::os::Contact());
    state_->links = std::move(links);
    state_->own = std::move(own);
}

void Watcher::start()
{
    std::shared_ptr<State> state = state_;
    thread_ = std::thread([state, who = tModule] {
        tModule = who;  // in a process of several bridges, its bridge's name
        run(*state);
    });
}

std::function<void()> Watcher::waker() const
{
    std::shared_ptr<State> state = state_;
    return [state] {
        std::lock_guard<std::mutex> lock(state->mutex);
        state->poked = true;
        state->wake.notify_all();
    };
}

bool Watcher::stop(std::chrono::milliseconds limit)
{
    if (!thread_.joinable()) {
        return true;
    }
    std::unique_lock<std::mutex> lock(state_->mutex);
    state_->done = true;
    state_->wake.notify_all();
    const bool ended = state_->wake.wait_for(lock, limit, [this] { return state_->finished; });
    lock.unlock();
    if (ended) {
        thread_.join();
    } else {
        thread_.detach();
    }
    return ended;
}

void Watcher::run(State& s)
{
    std::unique_lock<std::mutex> lock(s.mutex);
    while (!s.done) {
        s.poked = false;
        lock.unlock();
        registerAgain(s);
        for (std::size_t k = 0; k < s.links.size(); ++k) {
            if (s.links[k].input != nullptr) {
                checkInput(s, k);
            } else {
                check(s, k);
            }
            std::lock_guard<std::mutex> again(s.mutex);
            if (s.done) {
                break;
            }
        }
        lock.lock();
        s.wake.wait_for(lock, std::chrono::milliseconds(500), [&s] { return s.done || s.poked; });
    }
    s.finished = true;
    s.wake.notify_all();
}

/// A name server restarted has forgotten every port: the module's own
/// ports are registered again (asked about the first one only), so that
/// a source started since is connected to them and a consumer finds the
/// output. Connections made before never needed it.
void Watcher::registerAgain(const State& s)
{
    if (s.own.empty() || yarp::os::Network::queryName(s.own.front().getName()).isValid()) {
        return;
    }
    bool all = true;
    for (const yarp::os::Contact& where : s.own) {
        all = yarp::os::Network::registerContact(where).isValid() && all;
    }
    if (all) {
        say("the name server had forgotten this module's ports: registered them again");
    }
}

/// An input's link: the connections of other ports closed, its source
/// connected when no port it accepts is.
void Watcher::checkInput(State& s, std::size_t k)
{
    const Link& link = s.links[k];
    Input& input = *link.input;
    bool up = false;
    for (const std::string& name : input.sources()) {
        if (accepts(input, name)) {
            up = true;
        } else {
            input.refuseConnection(name);
            input.drop(name);
        }
    }
    if (up) {
        s.connected[k] = true;
        return;
    }
    const yarp::os::Contact where = yarp::os::Network::queryName(link.source);
    const yarp::os::Contact& blocked = s.blocked[k];
    if (where.isValid() && blocked.isValid() && where.getHost() == blocked.getHost()
        && where.getPort() == blocked.getPort() && !answersAs(where, link.source)) {
        return;  // the name still gives the address of the other port (said when it was connected)
    }
    if (where.isValid() && yarp::os::Network::exists(link.source, true)
        && yarp::os::Network::connect(link.source, link.destination, "", true)) {
        // the port YARP connected, by its own name: the one at the address
        // the name server gave, which may be another port's
        std::string real;
        for (const std::string& name : input.sources()) {
            if (accepts(input, name)) {
                real = name;
                break;
            }
            if (real.empty()) {
                real = name;
            }
        }
        if (real.empty()) {
            real = link.source;  // not listed yet
        }
        if (accepts(input, real)) {
            say("connected " + real + " -> " + link.destination);
            s.connected[k] = true;
            s.made[k] = true;
            s.blocked[k] = yarp::os::Contact();
        } else {
            // its Bottles are refused as they come; its connection is closed next
            say("connected " + real + " -> " + link.destination + " (asked for " + link.source + ")");
            input.refuseConnection(real);
            s.blocked[k] = where;
            s.connected[k] = false;
        }
    } else if (s.connected[k]) {
        say("lost " + link.source + " -> " + link.destination + "; reconnecting when it is back");
        s.connected[k] = false;
    }
}

/// The output's link to a port it connects to.
void Watcher::check(State& s, std::size_t k)
{
    const Link& link = s.links[k];
    if (yarp::os::Network::exists(link.destination, true)
        && yarp::os::Network::isConnected(link.source, link.destination, true)) {
        if (!s.made[k] || listsInput(link.destination, link.source)) {
            s.connected[k] = true;
            return;
        }
        // the destination was restarted under the same name: the connection
        // listed is to its predecessor, and stays until a write fails on it
        // (for a module writing only new data, the next command)
        yarp::os::Network::disconnect(link.source, link.destination, true);
    }
    if (yarp::os::Network::exists(link.source, true) && yarp::os::Network::exists(link.destination, true)
        && yarp::os::Network::connect(link.source, link.destination, "", true)) {
        say("connected " + link.source + " -> " + link.destination);
        s.connected[k] = true;
        s.made[k] = true;
    } else if (s.connected[k]) {
        say("lost " + link.source + " -> " + link.destination + "; reconnecting when it is back");
        s.connected[k] = false;
    }
}

/// Does `port` list a connection from `source` among its inputs (its
/// admin answer to `list in`)? True when it does not answer (left alone).
bool Watcher::listsInput(const std::string& port, const std::string& source)
{
    yarp::os::ContactStyle style;
    style.admin = true;
    style.quiet = true;
    style.timeout = 1.0;
    yarp::os::Bottle cmd;
    cmd.fromString("list in");
    yarp::os::Bottle reply;
    if (!yarp::os::Network::write(yarp::os::Contact(port), cmd, reply, style)) {
        return true;
    }
    for (std::size_t k = 0; k < reply.size(); ++k) {
        if (reply.get(k).asString() == source) {
            return true;
        }
    }
    return false;
}

}  // namespace ybgc
