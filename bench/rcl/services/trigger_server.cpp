// The ROS 2 side alone of the service benchmark: a std_srvs/srv/Trigger
// server on rcl, the C API, answering every request at once with success
// true and message "ok" (the direct round trip trigger_caller -> this).
//
//   trigger_server --service /bench/trigger_direct
//
// One thread waits on the service (rcl_wait), takes each request and sends
// its response. SIGINT/SIGTERM end it (exit 0).
#include "common.hpp"

#include <rosidl_runtime_c/string_functions.h>
#include <std_srvs/srv/trigger.h>

#include <atomic>
#include <csignal>

namespace {
std::atomic<bool> gStop{false};
void onSignal(int) { gStop = true; }
}  // namespace

int main(int argc, char* argv[])
{
    const auto o = bench::options(argc, argv);
    const std::string name = bench::get(o, "service", "/bench/trigger_direct");
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
    bench::Rcl rcl;
    if (!rcl.init("bench_trigger_server")) {
        return bench::rclFail("trigger_server", "rcl init");
    }
    rcl_service_t service = rcl_get_zero_initialized_service();
    rcl_service_options_t options = rcl_service_get_default_options();
    if (rcl_service_init(&service, &rcl.node, ROSIDL_GET_SRV_TYPE_SUPPORT(std_srvs, srv, Trigger), name.c_str(),
                         &options) != RCL_RET_OK) {
        return bench::rclFail("trigger_server", "rcl_service_init");
    }
    rcl_wait_set_t ws = rcl_get_zero_initialized_wait_set();
    if (rcl_wait_set_init(&ws, 0, 0, 0, 0, 1, 0, &rcl.context, rcl_get_default_allocator()) != RCL_RET_OK) {
        return bench::rclFail("trigger_server", "rcl_wait_set_init");
    }
    std_srvs__srv__Trigger_Request request;
    std_srvs__srv__Trigger_Request__init(&request);
    std_srvs__srv__Trigger_Response response;
    std_srvs__srv__Trigger_Response__init(&response);
    response.success = true;
    rosidl_runtime_c__String__assign(&response.message, "ok");
    std::printf("ready\n");
    std::fflush(stdout);
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
            if (rcl_send_response(&service, &info.request_id, &response) != RCL_RET_OK) {
                rcl_reset_error();
            }
        }
        rcl_reset_error();
    }
    bench::check(rcl_wait_set_fini(&ws));
    std_srvs__srv__Trigger_Request__fini(&request);
    std_srvs__srv__Trigger_Response__fini(&response);
    if (rcl_service_fini(&service, &rcl.node) != RCL_RET_OK) {
        rcl_reset_error();
    }
    rcl.fini();
    return 0;
}
