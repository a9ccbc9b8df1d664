// What the service benchmark's programs share: command-line options, the
// clock, the latencies written out, and rcl's error reporting.
#pragma once

#include <rcl/error_handling.h>
#include <rcl/graph.h>
#include <rcl/rcl.h>

#include <time.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

namespace bench {

// --key value pairs, and flags (--key alone) as "1"
inline std::map<std::string, std::string> options(int argc, char* argv[])
{
    std::map<std::string, std::string> out;
    for (int i = 1; i < argc; ++i) {
        std::string key = argv[i];
        if (key.rfind("--", 0) != 0) {
            continue;
        }
        key = key.substr(2);
        if (i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0) {
            out[key] = argv[++i];
        } else {
            out[key] = "1";
        }
    }
    return out;
}

inline std::string get(const std::map<std::string, std::string>& o, const std::string& k, const std::string& d)
{
    auto it = o.find(k);
    return it == o.end() ? d : it->second;
}

inline std::int64_t nowNs()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

// a call whose failure leaves nothing to do but clear rcl's error
inline void check(rcl_ret_t ret)
{
    if (ret != RCL_RET_OK) {
        rcl_reset_error();
    }
}

inline int rclFail(const char* prog, const char* what)
{
    std::fprintf(stderr, "%s: %s: %s\n", prog, what, rcl_get_error_string().str);
    rcl_reset_error();
    return 1;
}

// the latencies of every call, in ns, one a line (the benchmark reads them)
inline bool writeLatencies(const std::string& path, const std::vector<std::int64_t>& ns)
{
    FILE* f = std::fopen(path.c_str(), "w");
    if (f == nullptr) {
        return false;
    }
    for (auto v : ns) {
        std::fprintf(f, "%lld\n", static_cast<long long>(v));
    }
    std::fclose(f);
    return true;
}

struct Rcl
{
    rcl_context_t context = rcl_get_zero_initialized_context();
    rcl_node_t node = rcl_get_zero_initialized_node();

    bool init(const char* name)
    {
        rcl_init_options_t options = rcl_get_zero_initialized_init_options();
        if (rcl_init_options_init(&options, rcl_get_default_allocator()) != RCL_RET_OK
            || rcl_init(0, nullptr, &options, &context) != RCL_RET_OK) {
            return false;
        }
        rcl_node_options_t nodeOptions = rcl_node_get_default_options();
        return rcl_node_init(&node, name, "", &context, &nodeOptions) == RCL_RET_OK;
    }

    void fini()
    {
        if (rcl_node_fini(&node) != RCL_RET_OK) {
            rcl_reset_error();
        }
        check(rcl_shutdown(&context));
        check(rcl_context_fini(&context));
    }
};

}  // namespace bench
