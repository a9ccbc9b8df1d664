// Benchmark producer on ROS 2 through rcl, the C API (the "C rcl hop": the
// floor of a native module's ROS 2 side): the same messages and commands as
// bench/peers/ros2_source.py, published with rcl_publish from the C struct of
// sensor_msgs/JointState. `position` holds BLOCKS blocks of WIDTH values
// [seq, t, port, fillers...], t = CLOCK_MONOTONIC seconds just before publishing.
//
//     rcl_source --topic /bench/joint_states --width 15 --blocks 2
//
// Commands on stdin: "wait N TIMEOUT" (N matched subscriptions), "run COUNT
// RATE" (absolute deadlines), "quit"; answers on stdout start with "@".
#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <rosidl_runtime_c/primitives_sequence_functions.h>
#include <rosidl_runtime_c/string_functions.h>
#include <sensor_msgs/msg/joint_state.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>

namespace {

double monotonic()
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void say(const std::string& text)
{
    std::printf("@%s\n", text.c_str());
    std::fflush(stdout);
}

int fail(const char* what)
{
    std::fprintf(stderr, "rcl_source: %s: %s\n", what, rcl_get_error_string().str);
    return 1;
}

}  // namespace

int main(int argc, char* argv[])
{
    std::string topic = "/bench/joint_states";
    std::size_t width = 15;
    std::size_t blocks = 2;
    std::size_t depth = 10;
    for (int k = 1; k + 1 < argc; k += 2) {
        const std::string arg = argv[k];
        if (arg == "--topic") {
            topic = argv[k + 1];
        } else if (arg == "--width") {
            width = std::strtoul(argv[k + 1], nullptr, 10);
        } else if (arg == "--blocks") {
            blocks = std::strtoul(argv[k + 1], nullptr, 10);
        } else if (arg == "--depth") {
            depth = std::strtoul(argv[k + 1], nullptr, 10);
        }
    }
    rcl_allocator_t allocator = rcl_get_default_allocator();
    rcl_init_options_t options = rcl_get_zero_initialized_init_options();
    rcl_context_t context = rcl_get_zero_initialized_context();
    if (rcl_init_options_init(&options, allocator) != RCL_RET_OK || rcl_init(0, nullptr, &options, &context) != RCL_RET_OK) {
        return fail("rcl_init");
    }
    rcl_node_t node = rcl_get_zero_initialized_node();
    rcl_node_options_t nodeOptions = rcl_node_get_default_options();
    if (rcl_node_init(&node, "bench_rcl_source", "", &context, &nodeOptions) != RCL_RET_OK) {
        return fail("rcl_node_init");
    }
    rcl_clock_t clock;
    if (rcl_clock_init(RCL_ROS_TIME, &clock, &allocator) != RCL_RET_OK) {
        return fail("rcl_clock_init");
    }
    rcl_publisher_t publisher = rcl_get_zero_initialized_publisher();
    rcl_publisher_options_t pubOptions = rcl_publisher_get_default_options();
    pubOptions.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
    pubOptions.qos.depth = depth;
    pubOptions.qos.reliability = RMW_QOS_POLICY_RELIABILITY_RELIABLE;
    if (rcl_publisher_init(&publisher, &node, ROSIDL_GET_MSG_TYPE_SUPPORT(sensor_msgs, msg, JointState),
                           topic.c_str(), &pubOptions) != RCL_RET_OK) {
        return fail("rcl_publisher_init");
    }
    const std::size_t n = width * blocks;
    sensor_msgs__msg__JointState* msg = sensor_msgs__msg__JointState__create();
    rosidl_runtime_c__String__assign(&msg->header.frame_id, "base_link");
    if (!rosidl_runtime_c__String__Sequence__init(&msg->name, n)
        || !rosidl_runtime_c__double__Sequence__init(&msg->position, n)) {
        return fail("message");
    }
    for (std::size_t i = 0; i < n; ++i) {
        rosidl_runtime_c__String__assign(&msg->name.data[i], ("j" + std::to_string(i)).c_str());
    }
    double* values = msg->position.data;
    for (std::size_t k = 0; k < blocks; ++k) {
        values[k * width + 2] = static_cast<double>(k);
        for (std::size_t i = 3; i < width; ++i) {
            values[k * width + i] = static_cast<double>(k) * 1000.0 + static_cast<double>(i) + 0.5;
        }
    }
    say("ready");
    std::uint64_t seq = 0;
    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string cmd;
        in >> cmd;
        if (cmd == "wait") {
            std::size_t want = 0;
            double timeout = 0.0;
            in >> want >> timeout;
            const double end = monotonic() + timeout;
            std::size_t got = 0;
            while ((rcl_publisher_get_subscription_count(&publisher, &got) != RCL_RET_OK || got < want)
                   && monotonic() < end) {
                std::this_thread::sleep_for(std::chrono::milliseconds(20));
            }
            say((got >= want ? "ok " : "timeout ") + std::to_string(got));
        } else if (cmd == "run") {
            std::uint64_t count = 0;
            double rate = 1.0;
            in >> count >> rate;
            const double period = 1.0 / rate;
            const std::uint64_t first = seq + 1;
            std::uint64_t late = 0;
            const double t0 = monotonic();
            double next = t0;
            for (std::uint64_t c = 0; c < count; ++c) {
                ++seq;
                rcl_time_point_value_t now = 0;
                if (rcl_clock_get_now(&clock, &now) == RCL_RET_OK) {
                    msg->header.stamp.sec = static_cast<std::int32_t>(now / 1000000000);
                    msg->header.stamp.nanosec = static_cast<std::uint32_t>(now % 1000000000);
                }
                const double t = monotonic();
                for (std::size_t k = 0; k < blocks; ++k) {
                    values[k * width] = static_cast<double>(seq);
                    values[k * width + 1] = t;
                }
                if (rcl_publish(&publisher, msg, nullptr) != RCL_RET_OK) {
                    rcl_reset_error();
                }
                next += period;
                const double delay = next - monotonic();
                if (delay > 0) {
                    std::this_thread::sleep_for(std::chrono::duration<double>(delay));
                } else {
                    ++late;
                }
            }
            char done[128];
            std::snprintf(done, sizeof done, "done %llu %llu %llu %.9f", static_cast<unsigned long long>(first),
                          static_cast<unsigned long long>(count), static_cast<unsigned long long>(late),
                          monotonic() - t0);
            say(done);
        } else if (cmd == "quit") {
            break;
        }
    }
    sensor_msgs__msg__JointState__destroy(msg);
    rcl_ret_t ret = rcl_publisher_fini(&publisher, &node);
    ret |= rcl_clock_fini(&clock);
    ret |= rcl_node_fini(&node);
    ret |= rcl_shutdown(&context);
    ret |= rcl_context_fini(&context);
    ret |= rcl_init_options_fini(&options);
    return ret == RCL_RET_OK ? 0 : 1;
}
