// Benchmark camera on ROS 2 through rcl, the C API: publishes stamped
// sensor_msgs/Image messages, the same frames as bench/tools/image_producer.cpp
// writes on YARP (the "C rcl hop" of camera images: the floor of a native
// module's ROS 2 side).
//
//   image_source --topic /bench/image_raw --width 640 --height 480 --pixel rgb8|32FC1
//                [--depth 5] [--reliable]
//
// Frame s: the producer's pattern, rows packed (step = width * pixel size),
// its first 16 bytes s (uint64) and t (double), its last 8 bytes s again;
// header.stamp = t, CLOCK_MONOTONIC taken just before rcl_publish. QoS: best
// effort, keep last 5 (ROS's sensor-data profile, a module's default for an
// Image); --reliable: reliable.
//
// Commands on stdin: "wait N TIMEOUT" (N matched subscriptions), "run COUNT
// RATE" (absolute deadlines), "quit"; answers on stdout start with "@" (the
// answers of bench/tools/image_producer.cpp).
#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <rosidl_runtime_c/primitives_sequence_functions.h>
#include <rosidl_runtime_c/string_functions.h>
#include <sensor_msgs/msg/image.h>

#include <time.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <sstream>
#include <string>

namespace {

double monotonicNow()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

void sleepUntil(const timespec& t)
{
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, nullptr) != 0) {
    }
}

void addNs(timespec& t, long long ns)
{
    long long total = static_cast<long long>(t.tv_nsec) + ns;
    t.tv_sec += static_cast<time_t>(total / 1000000000LL);
    t.tv_nsec = static_cast<long>(total % 1000000000LL);
}

bool before(const timespec& a, const timespec& b)
{
    return a.tv_sec < b.tv_sec || (a.tv_sec == b.tv_sec && a.tv_nsec < b.tv_nsec);
}

void say(const std::string& text)
{
    std::printf("@%s\n", text.c_str());
    std::fflush(stdout);
}

int fail(const char* what)
{
    std::fprintf(stderr, "image_source: %s: %s\n", what, rcl_get_error_string().str);
    return 1;
}

}  // namespace

int main(int argc, char* argv[])
{
    std::string topic = "/bench/image_raw";
    std::size_t width = 640;
    std::size_t height = 480;
    std::string pixel = "rgb8";
    std::size_t depth = 5;
    bool reliable = false;
    for (int k = 1; k < argc; ++k) {
        const std::string arg = argv[k];
        const bool hasValue = k + 1 < argc;
        if (arg == "--reliable") {
            reliable = true;
        } else if (arg == "--topic" && hasValue) {
            topic = argv[++k];
        } else if (arg == "--width" && hasValue) {
            width = std::strtoul(argv[++k], nullptr, 10);
        } else if (arg == "--height" && hasValue) {
            height = std::strtoul(argv[++k], nullptr, 10);
        } else if (arg == "--pixel" && hasValue) {
            pixel = argv[++k];
        } else if (arg == "--depth" && hasValue) {
            depth = std::strtoul(argv[++k], nullptr, 10);
        } else {
            std::fprintf(stderr, "image_source: unknown argument %s\n", arg.c_str());
            return 2;
        }
    }
    const bool isDepth = pixel == "32FC1";
    if ((!isDepth && pixel != "rgb8") || width < 8 || height < 2) {
        std::fprintf(stderr, "image_source: --pixel rgb8|32FC1, --width >= 8, --height >= 2\n");
        return 2;
    }
    rcl_allocator_t allocator = rcl_get_default_allocator();
    rcl_init_options_t options = rcl_get_zero_initialized_init_options();
    rcl_context_t context = rcl_get_zero_initialized_context();
    if (rcl_init_options_init(&options, allocator) != RCL_RET_OK || rcl_init(0, nullptr, &options, &context) != RCL_RET_OK) {
        return fail("rcl_init");
    }
    rcl_node_t node = rcl_get_zero_initialized_node();
    rcl_node_options_t nodeOptions = rcl_node_get_default_options();
    if (rcl_node_init(&node, "bench_image_source", "", &context, &nodeOptions) != RCL_RET_OK) {
        return fail("rcl_node_init");
    }
    rcl_publisher_t publisher = rcl_get_zero_initialized_publisher();
    rcl_publisher_options_t pubOptions = rcl_publisher_get_default_options();
    pubOptions.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
    pubOptions.qos.depth = depth;
    pubOptions.qos.reliability = reliable ? RMW_QOS_POLICY_RELIABILITY_RELIABLE
                                          : RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
    if (rcl_publisher_init(&publisher, &node, ROSIDL_GET_MSG_TYPE_SUPPORT(sensor_msgs, msg, Image),
                           topic.c_str(), &pubOptions) != RCL_RET_OK) {
        return fail("rcl_publisher_init");
    }
    sensor_msgs__msg__Image* msg = sensor_msgs__msg__Image__create();
    const std::size_t pixelSize = isDepth ? 4 : 3;
    const std::size_t row = width * pixelSize;
    if (msg == nullptr || !rosidl_runtime_c__uint8__Sequence__init(&msg->data, row * height)) {
        return fail("message");
    }
    rosidl_runtime_c__String__assign(&msg->header.frame_id, "bench_camera");
    rosidl_runtime_c__String__assign(&msg->encoding, isDepth ? "32FC1" : "rgb8");
    msg->width = static_cast<std::uint32_t>(width);
    msg->height = static_cast<std::uint32_t>(height);
    msg->step = static_cast<std::uint32_t>(row);
    msg->is_bigendian = 0;
    for (std::size_t y = 0; y < height; ++y) {  // the pattern of image_producer.cpp
        unsigned char* r = msg->data.data + y * row;
        if (isDepth) {
            auto* d = reinterpret_cast<float*>(r);
            for (std::size_t x = 0; x < width; ++x) {
                d[x] = 0.5f + static_cast<float>((x + y) % 1000) * 0.005f;
            }
        } else {
            for (std::size_t i = 0; i < row; ++i) {
                r[i] = static_cast<unsigned char>((i * 7 + y * 13) & 0xff);
            }
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
            const double end = monotonicNow() + timeout;
            std::size_t got = 0;
            while ((rcl_publisher_get_subscription_count(&publisher, &got) != RCL_RET_OK || got < want)
                   && monotonicNow() < end) {
                timespec t{0, 20 * 1000000L};
                nanosleep(&t, nullptr);
            }
            say((got >= want ? "ok " : "timeout ") + std::to_string(got));
        } else if (cmd == "run") {
            long long count = 0;
            double rate = 30.0;
            in >> count >> rate;
            const long long period = static_cast<long long>(1e9 / rate + 0.5);
            const std::uint64_t first = seq + 1;
            long long late = 0;
            const double t0 = monotonicNow();
            timespec next{};
            clock_gettime(CLOCK_MONOTONIC, &next);
            for (long long c = 0; c < count; ++c) {
                ++seq;
                timespec now{};
                clock_gettime(CLOCK_MONOTONIC, &now);
                const double t = static_cast<double>(now.tv_sec) + static_cast<double>(now.tv_nsec) * 1e-9;
                std::memcpy(msg->data.data, &seq, 8);
                std::memcpy(msg->data.data + 8, &t, 8);
                std::memcpy(msg->data.data + row * height - 8, &seq, 8);
                msg->header.stamp.sec = static_cast<std::int32_t>(now.tv_sec);
                msg->header.stamp.nanosec = static_cast<std::uint32_t>(now.tv_nsec);
                if (rcl_publish(&publisher, msg, nullptr) != RCL_RET_OK) {
                    rcl_reset_error();
                }
                addNs(next, period);
                clock_gettime(CLOCK_MONOTONIC, &now);
                if (before(next, now)) {
                    ++late;
                } else {
                    sleepUntil(next);
                }
            }
            char done[128];
            std::snprintf(done, sizeof done, "done %llu %lld %lld %.9f", static_cast<unsigned long long>(first),
                          count, late, monotonicNow() - t0);
            say(done);
        } else if (cmd == "quit") {
            break;
        } else if (!cmd.empty()) {
            say("error unknown command " + cmd);
        }
    }
    sensor_msgs__msg__Image__destroy(msg);
    rcl_ret_t ret = rcl_publisher_fini(&publisher, &node);
    ret |= rcl_node_fini(&node);
    ret |= rcl_shutdown(&context);
    ret |= rcl_context_fini(&context);
    ret |= rcl_init_options_fini(&options);
    return ret == RCL_RET_OK ? 0 : 1;
}
