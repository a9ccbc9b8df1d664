// The reference relay of the native ROS 2 path: the least a bridge from YARP
// ports to a ROS 2 topic has to do, written by hand against YARP and the rcl
// C API, for the generated C++ module publishing to ROS 2 (cpp-ros2) to be
// measured against the same chain of processes (producer -> relay -> rclpy
// sink: one YARP hop, one ROS 2 hop).
//
//   rcl_relay --inputs /a:o,/b:o [--prefix /rcl_relay] [--topic T] [--depth N]
//
// It reads every input on a BufferedPort (newest Bottle only) with a callback,
// and in the callback of the input that completes the set (every input has a
// new Bottle since the last publish) copies the inputs' float64 values,
// converted from degrees to radians, into the positions of one
// sensor_msgs/JointState (names j0, j1, ... and frame_id set once), stamps it with the
// node's clock and publishes it (reliable, keep last N). Event-driven only;
// no layout checks, no freshness, no statistics: only the work.
// SIGINT/SIGTERM close the ports and exit 0.

#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <rosidl_runtime_c/primitives_sequence_functions.h>
#include <rosidl_runtime_c/string_functions.h>
#include <sensor_msgs/msg/joint_state.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/BufferedPort.h>
#include <yarp/os/Network.h>
#include <yarp/os/TypedReaderCallback.h>

namespace {

constexpr double kDegToRad = M_PI / 180.0;
std::atomic<bool> gStop{false};

void onSignal(int) { gStop = true; }

int fail(const char* what)
{
    std::fprintf(stderr, "rcl_relay: %s: %s\n", what, rcl_get_error_string().str);
    return 1;
}

struct Relay;

struct Input : public yarp::os::TypedReaderCallback<yarp::os::Bottle>
{
    Relay* relay = nullptr;
    yarp::os::BufferedPort<yarp::os::Bottle> port;
    std::vector<double> values;  // newest values (guarded by Relay::mutex)
    bool fresh = false;          // new since the last publish

    using yarp::os::TypedReaderCallback<yarp::os::Bottle>::onRead;
    void onRead(yarp::os::Bottle& bottle) override;
};

struct Relay
{
    std::vector<std::unique_ptr<Input>> inputs;
    std::mutex mutex;
    rcl_publisher_t* publisher = nullptr;
    rcl_clock_t* clock = nullptr;
    sensor_msgs__msg__JointState* msg = nullptr;

    // Called with the mutex held.
    void publish()
    {
        std::size_t n = 0;
        for (auto& in : inputs) {
            n += in->values.size();
        }
        if (msg->position.size != n) {  // the first time: the names as the benchmark's configs give them
            rosidl_runtime_c__double__Sequence__fini(&msg->position);
            rosidl_runtime_c__double__Sequence__init(&msg->position, n);
            rosidl_runtime_c__String__Sequence__fini(&msg->name);
            rosidl_runtime_c__String__Sequence__init(&msg->name, n);
            for (std::size_t k = 0; k < n; ++k) {
                rosidl_runtime_c__String__assign(&msg->name.data[k], ("j" + std::to_string(k)).c_str());
            }
        }
        double* out = msg->position.data;
        for (auto& in : inputs) {
            for (double v : in->values) {
                *out++ = v * kDegToRad;
            }
            in->fresh = false;
        }
        rcl_time_point_value_t now = 0;
        if (rcl_clock_get_now(clock, &now) == RCL_RET_OK) {
            msg->header.stamp.sec = static_cast<std::int32_t>(now / 1000000000);
            msg->header.stamp.nanosec = static_cast<std::uint32_t>(now % 1000000000);
        }
        if (rcl_publish(publisher, msg, nullptr) != RCL_RET_OK) {
            rcl_reset_error();
        }
    }
};

void Input::onRead(yarp::os::Bottle& bottle)
{
    std::lock_guard<std::mutex> lock(relay->mutex);
    values.resize(bottle.size());
    for (std::size_t i = 0; i < bottle.size(); ++i) {
        values[i] = bottle.get(i).asFloat64();
    }
    fresh = true;
    for (auto& in : relay->inputs) {
        if (!in->fresh) {
            return;
        }
    }
    relay->publish();
}

std::vector<std::string> split(const std::string& s, char sep)
{
    std::vector<std::string> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, sep)) {
        if (!item.empty()) {
            out.push_back(item);
        }
    }
    return out;
}

}  // namespace

int main(int argc, char* argv[])
{
    std::vector<std::string> sources;
    std::string prefix = "/rcl_relay";
    std::string topic = "/bench/joint_states";
    std::size_t depth = 10;
    for (int i = 1; i + 1 < argc; i += 2) {
        const std::string key = argv[i];
        if (key == "--inputs") {
            sources = split(argv[i + 1], ',');
        } else if (key == "--prefix") {
            prefix = argv[i + 1];
        } else if (key == "--topic") {
            topic = argv[i + 1];
        } else if (key == "--depth") {
            depth = std::strtoul(argv[i + 1], nullptr, 10);
        }
    }
    if (sources.empty()) {
        std::fprintf(stderr, "usage: rcl_relay --inputs A,B,... [--prefix P] [--topic T] [--depth N]\n");
        return 2;
    }
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
    std::signal(SIGPIPE, SIG_IGN);

    rcl_allocator_t allocator = rcl_get_default_allocator();
    rcl_init_options_t options = rcl_get_zero_initialized_init_options();
    rcl_context_t context = rcl_get_zero_initialized_context();
    if (rcl_init_options_init(&options, allocator) != RCL_RET_OK
        || rcl_init(0, nullptr, &options, &context) != RCL_RET_OK) {
        return fail("rcl_init");
    }
    rcl_node_t node = rcl_get_zero_initialized_node();
    rcl_node_options_t nodeOptions = rcl_node_get_default_options();
    if (rcl_node_init(&node, "bench_rcl_relay", "", &context, &nodeOptions) != RCL_RET_OK) {
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
    Relay relay;
    relay.publisher = &publisher;
    relay.clock = &clock;
    relay.msg = sensor_msgs__msg__JointState__create();
    rosidl_runtime_c__String__assign(&relay.msg->header.frame_id, "base_link");

    yarp::os::Network yarp;
    if (!yarp::os::Network::checkNetwork(5.0)) {
        std::fprintf(stderr, "rcl_relay: no YARP name server\n");
        return 1;
    }
    for (std::size_t i = 0; i < sources.size(); ++i) {
        relay.inputs.emplace_back(new Input());
        Input& in = *relay.inputs.back();
        in.relay = &relay;
        in.port.setStrict(false);
        in.port.useCallback(in);
        if (!in.port.open(prefix + "/in" + std::to_string(i) + ":i")) {
            return 1;
        }
    }
    // connect the sources (they may start later)
    std::vector<bool> connected(sources.size(), false);
    std::size_t left = sources.size();
    while (left > 0 && !gStop) {
        for (std::size_t i = 0; i < sources.size(); ++i) {
            if (!connected[i] && yarp::os::Network::exists(sources[i], true)
                && yarp::os::Network::connect(sources[i], relay.inputs[i]->port.getName(), "tcp", true)) {
                connected[i] = true;
                --left;
            }
        }
        if (left > 0) {
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
    }
    while (!gStop) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    for (auto& in : relay.inputs) {
        in->port.interrupt();
        in->port.disableCallback();
        in->port.close();
    }
    sensor_msgs__msg__JointState__destroy(relay.msg);
    if (rcl_publisher_fini(&publisher, &node) != RCL_RET_OK || rcl_node_fini(&node) != RCL_RET_OK) {
        rcl_reset_error();
    }
    rcl_clock_fini(&clock);
    rcl_shutdown(&context);
    rcl_context_fini(&context);
    return 0;
}
