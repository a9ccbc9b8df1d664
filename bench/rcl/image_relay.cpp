// The reference relay of camera images: the least a bridge from a YARP image
// port to a ROS 2 sensor_msgs/Image topic has to do, written by hand against
// YARP and the rcl C API, for the generated C++ module (ybgc --backend cpp on
// an image config) to be measured against the same chain of processes
// (producer -> relay -> rcl sink: one YARP hop, one ROS 2 hop).
//
//   image_relay --input /bench/cam:o [--prefix /bench/image_relay] [--topic T]
//               [--depth N] [--reliable] [--strict]
//
// It reads the input on a BufferedPort<yarp::sig::FlexImage> with a callback
// (any pixel type; --strict: every frame kept, as a module with a queue
// reads; else the newest only), and in the callback copies the frame's rows
// once, without YARP's row padding (one memcpy when there is none), into the
// data of one sensor_msgs/Image kept from frame to frame (sized again only
// when the frame's size changes), sets height, width, encoding (rgb8, 32FC1,
// ...), step and header.stamp from the frame's envelope (the node's clock
// without one), and publishes it (best effort, keep last N: ROS's
// sensor-data QoS, the module's default for an Image; --reliable: reliable).
// No checks, no freshness, no statistics: only the work. SIGINT/SIGTERM
// close the port and exit 0.

#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <rosidl_runtime_c/primitives_sequence_functions.h>
#include <rosidl_runtime_c/string_functions.h>
#include <sensor_msgs/msg/image.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include <yarp/os/BufferedPort.h>
#include <yarp/os/Network.h>
#include <yarp/os/Stamp.h>
#include <yarp/os/TypedReaderCallback.h>
#include <yarp/sig/Image.h>

namespace {

std::atomic<bool> gStop{false};

void onSignal(int) { gStop = true; }

int fail(const char* what)
{
    std::fprintf(stderr, "image_relay: %s: %s\n", what, rcl_get_error_string().str);
    return 1;
}

const char* encodingOf(int code)
{
    switch (code) {
    case VOCAB_PIXEL_RGB: return "rgb8";
    case VOCAB_PIXEL_BGR: return "bgr8";
    case VOCAB_PIXEL_RGBA: return "rgba8";
    case VOCAB_PIXEL_BGRA: return "bgra8";
    case VOCAB_PIXEL_MONO: return "mono8";
    case VOCAB_PIXEL_MONO16: return "mono16";
    case VOCAB_PIXEL_MONO_FLOAT: return "32FC1";
    default: return nullptr;
    }
}

struct Relay : public yarp::os::TypedReaderCallback<yarp::sig::FlexImage>
{
    yarp::os::BufferedPort<yarp::sig::FlexImage> port;
    rcl_publisher_t* publisher = nullptr;
    rcl_clock_t* clock = nullptr;
    sensor_msgs__msg__Image* msg = nullptr;
    int code = 0;  // the pixel code of msg's encoding

    using yarp::os::TypedReaderCallback<yarp::sig::FlexImage>::onRead;
    void onRead(yarp::sig::FlexImage& frame) override
    {
        const char* encoding = encodingOf(frame.getPixelCode());
        if (encoding == nullptr || frame.width() == 0 || frame.height() == 0) {
            return;
        }
        const std::size_t height = frame.height();
        const std::size_t row = frame.width() * frame.getPixelSize();
        if (msg->data.size != row * height) {
            rosidl_runtime_c__uint8__Sequence__fini(&msg->data);
            if (!rosidl_runtime_c__uint8__Sequence__init(&msg->data, row * height)) {
                return;
            }
        }
        const unsigned char* src = frame.getRawImage();
        const std::size_t srcStep = frame.getRowSize();
        if (srcStep == row) {
            std::memcpy(msg->data.data, src, row * height);
        } else {
            for (std::size_t y = 0; y < height; ++y) {
                std::memcpy(msg->data.data + y * row, src + y * srcStep, row);
            }
        }
        msg->height = static_cast<std::uint32_t>(height);
        msg->width = static_cast<std::uint32_t>(frame.width());
        msg->step = static_cast<std::uint32_t>(row);
        msg->is_bigendian = 0;
        if (code != frame.getPixelCode()) {
            code = frame.getPixelCode();
            rosidl_runtime_c__String__assign(&msg->encoding, encoding);
        }
        yarp::os::Stamp stamp;
        std::int64_t ns = 0;
        if (port.getEnvelope(stamp) && stamp.isValid()) {
            ns = static_cast<std::int64_t>(stamp.getTime() * 1e9 + 0.5);
        } else {
            rcl_time_point_value_t now = 0;
            if (rcl_clock_get_now(clock, &now) == RCL_RET_OK) {
                ns = now;
            }
        }
        msg->header.stamp.sec = static_cast<std::int32_t>(ns / 1000000000);
        msg->header.stamp.nanosec = static_cast<std::uint32_t>(ns % 1000000000);
        if (rcl_publish(publisher, msg, nullptr) != RCL_RET_OK) {
            rcl_reset_error();
        }
    }
};

}  // namespace

int main(int argc, char* argv[])
{
    std::string source;
    std::string prefix = "/bench/image_relay";
    std::string topic = "/bench/image_raw";
    std::size_t depth = 5;
    bool reliable = false;
    bool strict = false;
    for (int i = 1; i < argc; ++i) {
        const std::string key = argv[i];
        const bool hasValue = i + 1 < argc;
        if (key == "--reliable") {
            reliable = true;
        } else if (key == "--strict") {
            strict = true;
        } else if (key == "--input" && hasValue) {
            source = argv[++i];
        } else if (key == "--prefix" && hasValue) {
            prefix = argv[++i];
        } else if (key == "--topic" && hasValue) {
            topic = argv[++i];
        } else if (key == "--depth" && hasValue) {
            depth = std::strtoul(argv[++i], nullptr, 10);
        } else {
            std::fprintf(stderr, "image_relay: unknown argument %s\n", key.c_str());
            return 2;
        }
    }
    if (source.empty()) {
        std::fprintf(stderr, "usage: image_relay --input PORT [--prefix P] [--topic T] [--depth N] "
                             "[--reliable] [--strict]\n");
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
    if (rcl_node_init(&node, "bench_image_relay", "", &context, &nodeOptions) != RCL_RET_OK) {
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
    pubOptions.qos.reliability = reliable ? RMW_QOS_POLICY_RELIABILITY_RELIABLE
                                          : RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
    if (rcl_publisher_init(&publisher, &node, ROSIDL_GET_MSG_TYPE_SUPPORT(sensor_msgs, msg, Image),
                           topic.c_str(), &pubOptions) != RCL_RET_OK) {
        return fail("rcl_publisher_init");
    }
    Relay relay;
    relay.publisher = &publisher;
    relay.clock = &clock;
    relay.msg = sensor_msgs__msg__Image__create();
    rosidl_runtime_c__String__assign(&relay.msg->header.frame_id, "bench_camera");

    yarp::os::Network yarp;
    if (!yarp::os::Network::checkNetwork(5.0)) {
        std::fprintf(stderr, "image_relay: no YARP name server\n");
        return 1;
    }
    relay.port.setStrict(strict);
    relay.port.useCallback(relay);
    if (!relay.port.open(prefix + "/image:i")) {
        return 1;
    }
    // connect the source (it may start later)
    while (!gStop) {
        if (yarp::os::Network::exists(source, true)
            && yarp::os::Network::connect(source, relay.port.getName(), "tcp", true)) {
            break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    while (!gStop) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    relay.port.interrupt();
    relay.port.disableCallback();
    relay.port.close();
    sensor_msgs__msg__Image__destroy(relay.msg);
    rcl_ret_t ret = rcl_publisher_fini(&publisher, &node);
    ret |= rcl_node_fini(&node);
    ret |= rcl_clock_fini(&clock);
    ret |= rcl_shutdown(&context);
    ret |= rcl_context_fini(&context);
    ret |= rcl_init_options_fini(&options);
    return ret == RCL_RET_OK ? 0 : 1;
}
