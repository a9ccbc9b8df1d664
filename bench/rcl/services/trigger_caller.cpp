// The caller of the service benchmark: std_srvs/srv/Trigger calls through
// rcl, the C API, timed one by one.
//
//   trigger_caller --service /bench/trigger [--callers 1] [--calls 1000]
//                  [--warmup 50] [--wait 30] [--timeout 5] [--depth 1000] [--out FILE]
//
// Each caller is a thread with an rcl client of its own (one node), making
// its calls one after another: rcl_send_request, then rcl_wait on the client
// until the response of that sequence number is taken. The time of a call
// is from before the send to after the take (CLOCK_MONOTONIC). The callers
// first wait for the server (rcl_service_server_is_available), then make
// --warmup calls each, not counted, then --calls each, all at once.
// Each client keeps the last --depth responses (rcl's default keeps 10):
// Fast DDS delivers every response of a service to every client of it,
// each client taking its own, and with 8 callers a client's own response
// is otherwise sometimes pushed out by the others' before it is taken (a
// lost call, as much with a bare rcl server as through a bridge).
// Prints one line: "calls N failed F timed_out T seconds S per_second R";
// --out writes every counted call's time in ns, one a line.
#include "common.hpp"

#include <std_srvs/srv/trigger.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <thread>

namespace {

struct Caller
{
    rcl_client_t client = rcl_get_zero_initialized_client();
    rcl_wait_set_t ws = rcl_get_zero_initialized_wait_set();  // the client alone
    std::vector<std::int64_t> ns;
    long failed = 0;    // success false
    long timedOut = 0;  // no response within --timeout
};

// one call: its time in ns, or -1 when no response came within timeout
std::int64_t call(Caller& c, bool& success, std::int64_t timeoutNs)
{
    std_srvs__srv__Trigger_Request request;
    std_srvs__srv__Trigger_Request__init(&request);
    std_srvs__srv__Trigger_Response response;
    std_srvs__srv__Trigger_Response__init(&response);
    rcl_wait_set_t& ws = c.ws;
    const std::int64_t t0 = bench::nowNs();
    std::int64_t seq = 0;
    std::int64_t out = -1;
    if (rcl_send_request(&c.client, &request, &seq) == RCL_RET_OK) {
        while (bench::nowNs() - t0 < timeoutNs) {
            bench::check(rcl_wait_set_clear(&ws));
            bench::check(rcl_wait_set_add_client(&ws, &c.client, nullptr));
            const rcl_ret_t w = rcl_wait(&ws, timeoutNs - (bench::nowNs() - t0));
            if (w == RCL_RET_TIMEOUT) {
                break;
            }
            if (w != RCL_RET_OK) {
                rcl_reset_error();
                continue;
            }
            rmw_service_info_t info;
            if (rcl_take_response_with_info(&c.client, &info, &response) == RCL_RET_OK
                && info.request_id.sequence_number == seq) {
                out = bench::nowNs() - t0;
                success = response.success;
                break;
            }
            rcl_reset_error();
        }
    } else {
        rcl_reset_error();
    }
    std_srvs__srv__Trigger_Request__fini(&request);
    std_srvs__srv__Trigger_Response__fini(&response);
    return out;
}

}  // namespace

int main(int argc, char* argv[])
{
    const auto o = bench::options(argc, argv);
    const std::string service = bench::get(o, "service", "/bench/trigger");
    const int callers = std::atoi(bench::get(o, "callers", "1").c_str());
    const long calls = std::atol(bench::get(o, "calls", "1000").c_str());
    const long warmup = std::atol(bench::get(o, "warmup", "50").c_str());
    const double wait = std::atof(bench::get(o, "wait", "30").c_str());
    const auto timeoutNs = static_cast<std::int64_t>(std::atof(bench::get(o, "timeout", "5").c_str()) * 1e9);
    const std::string out = bench::get(o, "out", "");
    const long depth = std::atol(bench::get(o, "depth", "1000").c_str());

    bench::Rcl rcl;
    if (!rcl.init("bench_trigger_caller")) {
        return bench::rclFail("trigger_caller", "rcl init");
    }
    std::vector<std::unique_ptr<Caller>> all;
    for (int i = 0; i < callers; ++i) {
        all.emplace_back(new Caller());
        rcl_client_options_t options = rcl_client_get_default_options();
        options.qos.depth = static_cast<std::size_t>(depth);
        if (rcl_client_init(&all.back()->client, &rcl.node, ROSIDL_GET_SRV_TYPE_SUPPORT(std_srvs, srv, Trigger),
                            service.c_str(), &options) != RCL_RET_OK) {
            return bench::rclFail("trigger_caller", "rcl_client_init");
        }
        if (rcl_wait_set_init(&all.back()->ws, 0, 0, 0, 1, 0, 0, &rcl.context, rcl_get_default_allocator())
            != RCL_RET_OK) {
            return bench::rclFail("trigger_caller", "rcl_wait_set_init");
        }
    }
    const std::int64_t until = bench::nowNs() + static_cast<std::int64_t>(wait * 1e9);
    for (auto& c : all) {
        bool available = false;
        while (!available) {
            if (rcl_service_server_is_available(&rcl.node, &c->client, &available) != RCL_RET_OK) {
                rcl_reset_error();
            }
            if (!available) {
                if (bench::nowNs() > until) {
                    std::fprintf(stderr, "trigger_caller: no server of %s within %g s\n", service.c_str(), wait);
                    return 1;
                }
                std::this_thread::sleep_for(std::chrono::milliseconds(20));
            }
        }
    }
    auto run = [&](Caller& c, long n, bool keep) {
        for (long k = 0; k < n; ++k) {
            bool success = false;
            const std::int64_t t = call(c, success, timeoutNs);
            if (t < 0) {
                ++c.timedOut;
            } else if (!success) {
                ++c.failed;
            }
            if (keep && t >= 0) {
                c.ns.push_back(t);
            }
        }
    };
    {
        std::vector<std::thread> threads;
        for (auto& c : all) {
            threads.emplace_back([&, p = c.get()] { run(*p, warmup, false); });
        }
        for (auto& t : threads) {
            t.join();
        }
    }
    long warmFailed = 0;
    for (auto& c : all) {
        warmFailed += c->failed + c->timedOut;
        c->failed = c->timedOut = 0;
    }
    const std::int64_t t0 = bench::nowNs();
    {
        std::vector<std::thread> threads;
        for (auto& c : all) {
            threads.emplace_back([&, p = c.get()] { run(*p, calls, true); });
        }
        for (auto& t : threads) {
            t.join();
        }
    }
    const double seconds = static_cast<double>(bench::nowNs() - t0) * 1e-9;
    std::vector<std::int64_t> ns;
    long failed = 0;
    long timedOut = 0;
    for (auto& c : all) {
        ns.insert(ns.end(), c->ns.begin(), c->ns.end());
        failed += c->failed;
        timedOut += c->timedOut;
    }
    std::printf("calls %ld failed %ld timed_out %ld seconds %.6f per_second %.2f warmup_failed %ld\n",
                static_cast<long>(callers) * calls, failed, timedOut, seconds,
                seconds > 0 ? static_cast<double>(callers * calls) / seconds : 0.0, warmFailed);
    std::fflush(stdout);
    if (!out.empty() && !bench::writeLatencies(out, ns)) {
        std::fprintf(stderr, "trigger_caller: cannot write %s\n", out.c_str());
        return 1;
    }
    for (auto& c : all) {
        bench::check(rcl_wait_set_fini(&c->ws));
        if (rcl_client_fini(&c->client, &rcl.node) != RCL_RET_OK) {
            rcl_reset_error();
        }
    }
    rcl.fini();
    return 0;
}
