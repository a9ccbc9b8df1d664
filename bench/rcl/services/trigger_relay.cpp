// The hand-written relay of the service benchmark: the least a bridge from a
// ROS 2 service to a YARP RPC port has to do, written against the rcl C API
// and YARP, for the generated module (examples/home_arm_trigger.ini) to be
// measured against the same chain of processes.
//
//   trigger_relay --service /bench/trigger_relay --call /bench/rpc:i
//                 [--prefix /bench/trigger_relay] [--timeout 5]
//
// It serves std_srvs/srv/Trigger; each request becomes the Bottle
// `home all`, written on a yarp::os::RpcClient connected to --call (with a
// socket timeout of --timeout s), and the reply fills the response:
// success when its first element is one of ok, ack, true, yes, done, the
// message the whole reply as text (Bottle::toString); no reply: success
// false and a message. One thread: rcl_wait on the service, take the
// request, call, send the response (the calls one after another, as the
// module makes them on its one connection). No statistics, no checks of
// the reply's layout: only the work. SIGINT/SIGTERM end it (exit 0),
// printing "requests N answered N" (taken, and responses sent).
#include "common.hpp"

#include <rosidl_runtime_c/string_functions.h>
#include <std_srvs/srv/trigger.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <thread>

#include <yarp/os/Bottle.h>
#include <yarp/os/Network.h>
#include <yarp/os/Port.h>
#include <yarp/os/RpcClient.h>

namespace {
std::atomic<bool> gStop{false};
void onSignal(int) { gStop = true; }

bool isTrue(const std::string& word)
{
    return word == "ok" || word == "ack" || word == "true" || word == "yes" || word == "done";
}
}  // namespace

int main(int argc, char* argv[])
{
    const auto o = bench::options(argc, argv);
    const std::string name = bench::get(o, "service", "/bench/trigger_relay");
    const std::string target = bench::get(o, "call", "/bench/rpc:i");
    const std::string prefix = bench::get(o, "prefix", "/bench/trigger_relay");
    const double timeout = std::atof(bench::get(o, "timeout", "5").c_str());
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
    std::signal(SIGPIPE, SIG_IGN);

    yarp::os::Network yarp;
    if (!yarp::os::Network::checkNetwork(5.0)) {
        std::fprintf(stderr, "trigger_relay: no YARP name server\n");
        return 1;
    }
    yarp::os::RpcClient rpc;
    rpc.asPort().setTimeout(static_cast<float>(timeout));
    if (!rpc.open(prefix + "/rpc:o")) {
        return 1;
    }
    while (!gStop && !(yarp::os::Network::exists(target, true)
                       && yarp::os::Network::connect(rpc.getName(), target, "tcp", true))) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }

    bench::Rcl rcl;
    if (!rcl.init("bench_trigger_relay")) {
        return bench::rclFail("trigger_relay", "rcl init");
    }
    rcl_service_t service = rcl_get_zero_initialized_service();
    rcl_service_options_t options = rcl_service_get_default_options();
    if (rcl_service_init(&service, &rcl.node, ROSIDL_GET_SRV_TYPE_SUPPORT(std_srvs, srv, Trigger), name.c_str(),
                         &options) != RCL_RET_OK) {
        return bench::rclFail("trigger_relay", "rcl_service_init");
    }
    rcl_wait_set_t ws = rcl_get_zero_initialized_wait_set();
    if (rcl_wait_set_init(&ws, 0, 0, 0, 0, 1, 0, &rcl.context, rcl_get_default_allocator()) != RCL_RET_OK) {
        return bench::rclFail("trigger_relay", "rcl_wait_set_init");
    }
    std_srvs__srv__Trigger_Request request;
    std_srvs__srv__Trigger_Request__init(&request);
    std_srvs__srv__Trigger_Response response;
    std_srvs__srv__Trigger_Response__init(&response);
    yarp::os::Bottle command;
    command.addString("home");
    command.addString("all");
    yarp::os::Bottle reply;
    std::printf("ready\n");
    std::fflush(stdout);
    long requests = 0;
    long answered = 0;
    while (!gStop) {
        bench::check(rcl_wait_set_clear(&ws));
        bench::check(rcl_wait_set_add_service(&ws, &service, nullptr));
        const rcl_ret_t w = rcl_wait(&ws, RCL_MS_TO_NS(100));
        if (w == RCL_RET_TIMEOUT) {
            continue;
        }
        if (w != RCL_RET_OK) {
            rcl_reset_error();
            continue;
        }
        rmw_service_info_t info;
        while (rcl_take_request_with_info(&service, &info, &request) == RCL_RET_OK) {
            ++requests;
            reply.clear();
            if (rpc.write(command, reply)) {
                response.success = reply.size() > 0 && isTrue(reply.get(0).toString());
                rosidl_runtime_c__String__assign(&response.message, reply.toString().c_str());
            } else {
                response.success = false;
                rosidl_runtime_c__String__assign(&response.message, (target + " did not answer").c_str());
                if (rpc.getOutputCount() == 0) {
                    yarp::os::Network::connect(rpc.getName(), target, "tcp", true);
                }
            }
            if (rcl_send_response(&service, &info.request_id, &response) == RCL_RET_OK) {
                ++answered;
            } else {
                rcl_reset_error();
            }
        }
        rcl_reset_error();
    }
    std::printf("requests %ld answered %ld\n", requests, answered);
    std::fflush(stdout);
    bench::check(rcl_wait_set_fini(&ws));
    std_srvs__srv__Trigger_Request__fini(&request);
    std_srvs__srv__Trigger_Response__fini(&response);
    if (rcl_service_fini(&service, &rcl.node) != RCL_RET_OK) {
        rcl_reset_error();
    }
    rcl.fini();
    rpc.close();
    return 0;
}
