// What the runtime's commands serve (ybgc_services_internal.hpp): a ROS 2
// service, each request made a command Bottle for the YARP port it calls and
// answered from its reply; a YARP RPC port, each command's arguments made a
// request of the ROS 2 service it calls and answered with the reply Bottle
// of its response; `help` there; the failure answers, and why.
#include "ybgc_services_internal.hpp"  // ybgc:runtime-import

#include <rcl/error_handling.h>

#include <algorithm>
#include <mutex>
#include <string>

#include <yarp/os/Bottle.h>

namespace ybgc {
namespace services {

using ros2::finished;
using ros2::rclError;

// --- RosServer ----------------------------------------------------------------------------------------

RosServer::RosServer(CommandsBridge& bridge, std::size_t index, YarpCaller& caller) :
        bridge_(bridge), index_(index), svc_(bridge.spec().services[index]), caller_(caller)
{
}

bool RosServer::open(rcl_node_t* node)
{
    rcl_service_options_t options = rcl_service_get_default_options();
    if (rcl_service_init(&rcl_, node, svc_.type.typeSupport, svc_.spec.service, &options)
        != RCL_RET_OK) {
        say(std::string("cannot serve the ROS 2 service ") + svc_.spec.service + ": " + rclError());
        return false;
    }
    ok_ = true;
    return true;
}

void RosServer::fini(rcl_node_t* node)
{
    std::lock_guard<std::mutex> lock(mutex_);
    if (ok_) {
        finished(rcl_service_fini(&rcl_, node));
        ok_ = false;
    }
}

void RosServer::take()
{
    for (;;) {
        void* request = svc_.type.createRequest();
        if (request == nullptr) {
            return;
        }
        rmw_request_id_t header;
        rcl_ret_t taken = RCL_RET_ERROR;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            taken = ok_ ? rcl_take_request(&rcl_, &header, request) : RCL_RET_ERROR;
        }
        if (taken != RCL_RET_OK) {
            rcl_reset_error();
            svc_.type.destroyRequest(request);
            return;
        }
        bridge_.started(index_);
        caller_.submit(Job{index_, header, request, after(svc_.spec.timeout)});
    }
}

void RosServer::send(rmw_request_id_t& header, void* response)
{
    std::lock_guard<std::mutex> lock(mutex_);
    if (!ok_) {
        return;
    }
    if (rcl_send_response(&rcl_, &header, response) != RCL_RET_OK) {
        const std::string error = rclError();
        if (!reportedSendError_) {
            reportedSendError_ = true;
            say(std::string("cannot send a response of ") + svc_.spec.service + ": " + error
                + "; further errors are not said");
        }
    }
}

// --- answers --------------------------------------------------------------------------------------------

void CommandsBridge::answer(Job& job, Failure failure, const std::string& why, const yarp::os::Bottle* command,
                    const yarp::os::Bottle* reply)
{
    const Service& s = spec_.services[job.service];
    void* response = s.type.createResponse();
    std::string text = why;
    if (response == nullptr) {
        say(std::string("cannot allocate a response of ") + s.type.name);
    } else {
        if (failure == Failure::None && reply != nullptr) {
            Elements e(*reply, 0, s.spec.trueWords);
            std::string unfit;
            if (e.check(s.spec.declared, s.spec.types, s.spec.converters, unfit)
                && s.functions.response(e, response, unfit)) {
                servers_[job.service]->send(job.header, response);
                ended(job.service, Failure::None, "");
                saySuccess(job.service, *command, *reply);
                s.type.destroyResponse(response);
                s.type.destroyRequest(job.request);
                return;
            }
            // a fresh response for the failure answer
            s.type.destroyResponse(response);
            response = s.type.createResponse();
            failure = Failure::Unfit;
            text = reasonText(s.spec.reasons.unfitReply, reply->toString(), unfit);
        }
        if (response != nullptr) {
            s.functions.failedResponse(text, response);
            servers_[job.service]->send(job.header, response);
            s.type.destroyResponse(response);
        }
    }
    ended(job.service, failure == Failure::None ? Failure::TimedOut : failure, text);
    s.type.destroyRequest(job.request);
}

void CommandsBridge::respond(const std::string& port, const yarp::os::Bottle& command, yarp::os::Bottle& reply, bool& quit)
{
    const std::string word = firstWord(command);
    std::size_t first = spec_.services.size();  // the port's first command
    for (std::size_t s = 0; s < spec_.services.size(); ++s) {
        const Spec& sp = spec_.services[s].spec;
        if (sp.serves != Serves::Yarp || port != sp.port) {
            continue;
        }
        if (first == spec_.services.size()) {
            first = s;
        }
        if (word == sp.name) {
            ++active;
            serveYarp(s, command, reply);
            --active;
            return;
        }
    }
    if (word == "help") {
        // a served port: its commands (stats and quit unlisted where it is the module's own too)
        reply.addVocab32("many");
        const auto help = std::find_if(spec_.ports.begin(), spec_.ports.end(),
                                       [&port](const PortHelp& p) { return port == p.port; });
        if (help != spec_.ports.end()) {
            for (const char* line : help->help) {
                reply.addString(line);
            }
        }
        return;
    }
    if (!ownPort.empty() && port == ownPort && answerOwn(word, reply, quit)) {
        return;  // its own RPC port too: stats, quit
    }
    if (first < spec_.services.size()) {
        // a served port: the failure reply (of its first command), and why
        const Service& s = spec_.services[first];
        void* response = s.type.createResponse();
        if (response != nullptr) {
            s.functions.failedReply(response, unknownText(word), reply);
            s.type.destroyResponse(response);
            return;
        }
    }
    unknown(word, reply);
}

std::string CommandsBridge::unknownText(const std::string& word) const
{
    std::string text = spec_.unknownCommand;
    const std::size_t at = text.find("{word}");
    if (at != std::string::npos) {
        text.replace(at, 6, word);
    }
    return text;
}

void CommandsBridge::unknown(const std::string& word, yarp::os::Bottle& reply) const
{
    reply.addVocab32("fail");
    reply.addString(unknownText(word));
}

void CommandsBridge::failedReply(std::size_t s, const std::string& text, yarp::os::Bottle& reply)
{
    const Service& sv = spec_.services[s];
    void* response = sv.type.createResponse();
    if (response == nullptr) {
        reply.addVocab32("fail");
        reply.addString(text);
        return;
    }
    sv.functions.failedReply(response, text, reply);
    sv.type.destroyResponse(response);
}

void CommandsBridge::serveYarp(std::size_t s, const yarp::os::Bottle& command, yarp::os::Bottle& reply)
{
    const Service& sv = spec_.services[s];
    const TimePoint deadline = after(sv.spec.timeout);
    started(s);
    Elements args(command, 1, sv.spec.trueWords);
    std::string why;
    void* request = sv.type.createRequest();
    if (request == nullptr) {
        const std::string text = reasonText(sv.spec.reasons.badArguments, "", "cannot allocate a request");
        ended(s, Failure::Unfit, text);
        failedReply(s, text, reply);
        return;
    }
    if (!args.check(sv.spec.declared, sv.spec.types, sv.spec.converters, why)
        || !sv.functions.request(args, request, why)) {
        sv.type.destroyRequest(request);
        const std::string text = reasonText(sv.spec.reasons.badArguments, "", why);
        ended(s, Failure::Unfit, text);
        failedReply(s, text, reply);
        return;
    }
    void* response = nullptr;
    bool stopped = false;
    const Failure failure = clients_.at(s)->call(request, deadline, response, stopped);
    sv.type.destroyRequest(request);
    if (failure != Failure::None) {
        const std::string text = stopped ? stoppedText(sv)
            : failure == Failure::NoServer ? sv.spec.reasons.noServer : sv.spec.reasons.timedOut;
        ended(s, failure, text);
        failedReply(s, text, reply);
        return;
    }
    sv.functions.reply(response, reply);
    sv.type.destroyResponse(response);
    ended(s, Failure::None, "");
    saySuccess(s, command, reply);
}

}  // namespace services
}  // namespace ybgc
