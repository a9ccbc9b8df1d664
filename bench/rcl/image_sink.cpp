// Benchmark image sink on ROS 2 through rcl, the C API: records the receive
// time of every sensor_msgs/Image on a topic, with the header.stamp and the
// sequence number its producer set (bench/tools/image_producer.cpp through a
// bridge, or bench/rcl/image_source.cpp). The latency is receive time -
// header.stamp (both CLOCK_MONOTONIC: a bridge copies the frame's envelope,
// the producer's send time, into header.stamp).
//
//   image_sink --topic /bench/image_raw --width 640 --height 480 --pixel rgb8|32FC1
//              [--depth 20] [--reliable]
//
// One thread waits on the subscription (rcl_wait) and takes each message
// (rcl_take: deserialized into one sensor_msgs/Image) as soon as it is there.
// A message whose size, encoding, step or stamps (the first 16 bytes of its
// data: seq and the send time, which header.stamp must equal to the
// microsecond; the last 8: seq again) do not match is counted as bad. QoS:
// best effort (it matches a best-effort or a reliable publisher), keep last
// 20 (deeper than a publisher's sensor-data 5, so that the sink is not what
// drops a frame); --reliable: reliable.
//
// Commands on stdin (one answer line each on stdout, starting with "@"):
//   count           -> "count <records> <bad>"
//   reset           -> "reset" (forget the records)
//   dump PATH       -> "dumped <records>": raw float64, 11 per record (the
//                      layout of bench/tools/consumer.cpp): recv, 1, bad, seq,
//                      header.stamp, then zeros
//   quit
// "connected" is printed once a publisher is matched.
#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <sensor_msgs/msg/image.h>

#include <time.h>

#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

constexpr int kFields = 11;

double monotonicNow()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

std::mutex gOut;

void say(const std::string& text)
{
    std::lock_guard<std::mutex> lock(gOut);
    std::printf("@%s\n", text.c_str());
    std::fflush(stdout);
}

int fail(const char* what)
{
    std::fprintf(stderr, "image_sink: %s: %s\n", what, rcl_get_error_string().str);
    return 1;
}

struct Recorder
{
    std::size_t width = 640;
    std::size_t height = 480;
    std::string encoding = "rgb8";
    std::size_t pixelSize = 3;

    std::mutex mutex;
    std::vector<double> data;
    long long count = 0;
    long long bad = 0;

    void take(const sensor_msgs__msg__Image& msg, double recv)
    {
        const double stamp = static_cast<double>(msg.header.stamp.sec)
            + static_cast<double>(msg.header.stamp.nanosec) * 1e-9;
        const std::size_t row = width * pixelSize;
        bool isBad = msg.width != width || msg.height != height || msg.step != row
            || msg.data.size != row * height
            || std::string(msg.encoding.data != nullptr ? msg.encoding.data : "", msg.encoding.size) != encoding;
        std::uint64_t seq = 0;
        if (!isBad) {
            std::uint64_t seqEnd = 0;
            double t = NAN;
            std::memcpy(&seq, msg.data.data, 8);
            std::memcpy(&t, msg.data.data + 8, 8);
            std::memcpy(&seqEnd, msg.data.data + row * height - 8, 8);
            isBad = seq != seqEnd || !(std::fabs(stamp - t) < 1e-6);
        }
        const double rec[kFields] = {recv, 1, isBad ? 1.0 : 0.0, static_cast<double>(seq), stamp, 0, 0, 0, 0, 0, 0};
        std::lock_guard<std::mutex> lock(mutex);
        ++count;
        if (isBad) {
            ++bad;
        }
        data.insert(data.end(), rec, rec + kFields);
    }
};

}  // namespace

int main(int argc, char* argv[])
{
    std::string topic = "/bench/image_raw";
    std::size_t depth = 20;
    bool reliable = false;
    Recorder recorder;
    for (int k = 1; k < argc; ++k) {
        const std::string arg = argv[k];
        const bool hasValue = k + 1 < argc;
        if (arg == "--reliable") {
            reliable = true;
        } else if (arg == "--topic" && hasValue) {
            topic = argv[++k];
        } else if (arg == "--width" && hasValue) {
            recorder.width = std::strtoul(argv[++k], nullptr, 10);
        } else if (arg == "--height" && hasValue) {
            recorder.height = std::strtoul(argv[++k], nullptr, 10);
        } else if (arg == "--pixel" && hasValue) {
            recorder.encoding = argv[++k];
        } else if (arg == "--depth" && hasValue) {
            depth = std::strtoul(argv[++k], nullptr, 10);
        } else {
            std::fprintf(stderr, "image_sink: unknown argument %s\n", arg.c_str());
            return 2;
        }
    }
    recorder.pixelSize = recorder.encoding == "32FC1" ? 4 : 3;
    recorder.data.reserve(static_cast<std::size_t>(kFields) * 100000);

    rcl_allocator_t allocator = rcl_get_default_allocator();
    rcl_init_options_t options = rcl_get_zero_initialized_init_options();
    rcl_context_t context = rcl_get_zero_initialized_context();
    if (rcl_init_options_init(&options, allocator) != RCL_RET_OK || rcl_init(0, nullptr, &options, &context) != RCL_RET_OK) {
        return fail("rcl_init");
    }
    rcl_node_t node = rcl_get_zero_initialized_node();
    rcl_node_options_t nodeOptions = rcl_node_get_default_options();
    if (rcl_node_init(&node, "bench_image_sink", "", &context, &nodeOptions) != RCL_RET_OK) {
        return fail("rcl_node_init");
    }
    rcl_subscription_t sub = rcl_get_zero_initialized_subscription();
    rcl_subscription_options_t subOptions = rcl_subscription_get_default_options();
    subOptions.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
    subOptions.qos.depth = depth;
    subOptions.qos.reliability = reliable ? RMW_QOS_POLICY_RELIABILITY_RELIABLE
                                          : RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
    if (rcl_subscription_init(&sub, &node, ROSIDL_GET_MSG_TYPE_SUPPORT(sensor_msgs, msg, Image), topic.c_str(),
                              &subOptions) != RCL_RET_OK) {
        return fail("rcl_subscription_init");
    }
    rcl_wait_set_t waitSet = rcl_get_zero_initialized_wait_set();
    if (rcl_wait_set_init(&waitSet, 1, 0, 0, 0, 0, 0, &context, allocator) != RCL_RET_OK) {
        return fail("rcl_wait_set_init");
    }
    say("ready");

    std::atomic<bool> quitting{false};
    std::thread reader([&] {
        sensor_msgs__msg__Image* msg = sensor_msgs__msg__Image__create();
        bool connected = false;
        while (!quitting) {
            if (!connected) {
                std::size_t publishers = 0;
                if (rcl_subscription_get_publisher_count(&sub, &publishers) == RCL_RET_OK && publishers > 0) {
                    connected = true;
                    say("connected");
                }
            }
            if (rcl_wait_set_clear(&waitSet) != RCL_RET_OK
                || rcl_wait_set_add_subscription(&waitSet, &sub, nullptr) != RCL_RET_OK) {
                rcl_reset_error();
                continue;
            }
            const rcl_ret_t waited = rcl_wait(&waitSet, RCL_MS_TO_NS(100));
            if (waited == RCL_RET_TIMEOUT) {
                continue;
            }
            if (waited != RCL_RET_OK) {
                rcl_reset_error();
                continue;
            }
            while (true) {  // every message there
                rmw_message_info_t info = rmw_get_zero_initialized_message_info();
                const rcl_ret_t took = rcl_take(&sub, msg, &info, nullptr);
                if (took != RCL_RET_OK) {
                    if (took != RCL_RET_SUBSCRIPTION_TAKE_FAILED) {
                        rcl_reset_error();
                    }
                    break;
                }
                recorder.take(*msg, monotonicNow());
            }
        }
        sensor_msgs__msg__Image__destroy(msg);
    });

    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string cmd;
        in >> cmd;
        if (cmd == "count") {
            std::lock_guard<std::mutex> lock(recorder.mutex);
            say("count " + std::to_string(recorder.count) + " " + std::to_string(recorder.bad));
        } else if (cmd == "reset") {
            std::lock_guard<std::mutex> lock(recorder.mutex);
            recorder.data.clear();
            recorder.count = 0;
            recorder.bad = 0;
            say("reset");
        } else if (cmd == "dump") {
            std::string path;
            in >> path;
            std::vector<double> copy;
            {
                std::lock_guard<std::mutex> lock(recorder.mutex);
                copy = recorder.data;
            }
            FILE* f = std::fopen(path.c_str(), "wb");
            if (f == nullptr) {
                say("error cannot write " + path);
                continue;
            }
            std::fwrite(copy.data(), sizeof(double), copy.size(), f);
            std::fclose(f);
            say("dumped " + std::to_string(copy.size() / kFields));
        } else if (cmd == "quit") {
            break;
        } else if (!cmd.empty()) {
            say("error unknown command " + cmd);
        }
    }
    quitting = true;
    reader.join();
    rcl_ret_t ret = rcl_wait_set_fini(&waitSet);
    ret |= rcl_subscription_fini(&sub, &node);
    ret |= rcl_node_fini(&node);
    ret |= rcl_shutdown(&context);
    ret |= rcl_context_fini(&context);
    ret |= rcl_init_options_fini(&options);
    return ret == RCL_RET_OK ? 0 : 1;
}
