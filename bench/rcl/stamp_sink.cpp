// Benchmark sink of a whole robot's topics on ROS 2 through rcl, the C API:
// records the header.stamp and the receive time (CLOCK_MONOTONIC) of every
// message of several topics, for bench/compose.py. A bridge stamps its
// message with its input's envelope, the producer's send time
// (bench/tools/producer.cpp), so receive time - stamp is the latency.
//
//   stamp_sink --sub /joint_states=sensor_msgs/JointState --sub /tf=tf2_msgs/TFMessage ...
//
// Types: sensor_msgs/JointState, sensor_msgs/Imu, geometry_msgs/WrenchStamped,
// tf2_msgs/TFMessage. A message's key is its topic, and for a JointState its
// topic and first joint name ("/joint_states|head_0"): six bridges publish
// /joint_states, told apart by their joints. For a TFMessage the stamp is its
// first transform's.
//
// One thread waits on every subscription (rcl_wait) and takes each message
// as soon as it is there: a sink that is not the bottleneck, so that the
// latency measured is the bridges' and the middleware's. QoS: best effort,
// keep last 1000.
//
// Commands on stdin (one answer line each on stdout, starting with "@"), the
// protocol of bench/compose.py's Sink:
//   reset        -> "ok" (forget the records)
//   first        -> a JSON object {key: receive time of its first message}
//   clear_first  -> "ok"
//   dump PATH    -> "ok <records>": PATH a JSON list of [key, stamp, recv]
//   matched      -> "matched <topic>=<publishers> ...": the publishers each
//                   subscription has matched
//   quit
#include <geometry_msgs/msg/wrench_stamped.h>
#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <sensor_msgs/msg/imu.h>
#include <sensor_msgs/msg/joint_state.h>
#include <tf2_msgs/msg/tf_message.h>

#include <time.h>

#include <atomic>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

double monotonicNow()
{
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

void say(const std::string& text)
{
    std::printf("@%s\n", text.c_str());
    std::fflush(stdout);
}

int fail(const char* what)
{
    std::fprintf(stderr, "stamp_sink: %s: %s\n", what, rcl_get_error_string().str);
    return 1;
}

double seconds(const builtin_interfaces__msg__Time& t)
{
    return static_cast<double>(t.sec) + static_cast<double>(t.nanosec) * 1e-9;
}

std::string text(const rosidl_runtime_c__String& s)
{
    return std::string(s.data != nullptr ? s.data : "", s.size);
}

std::string jsonString(const std::string& s)
{
    std::string out = "\"";
    for (const char c : s) {
        if (c == '"' || c == '\\') {
            out += '\\';
        }
        out += c;
    }
    return out + "\"";
}

enum class Kind { JointState, Imu, Wrench, Tf };

// One subscription: its topic, its message type and a message to take into.
struct Topic
{
    std::string name;
    Kind kind = Kind::JointState;
    rcl_subscription_t sub = rcl_get_zero_initialized_subscription();
    void* msg = nullptr;

    const rosidl_message_type_support_t* support() const
    {
        switch (kind) {
        case Kind::JointState: return ROSIDL_GET_MSG_TYPE_SUPPORT(sensor_msgs, msg, JointState);
        case Kind::Imu: return ROSIDL_GET_MSG_TYPE_SUPPORT(sensor_msgs, msg, Imu);
        case Kind::Wrench: return ROSIDL_GET_MSG_TYPE_SUPPORT(geometry_msgs, msg, WrenchStamped);
        case Kind::Tf: return ROSIDL_GET_MSG_TYPE_SUPPORT(tf2_msgs, msg, TFMessage);
        }
        return nullptr;
    }

    void create()
    {
        switch (kind) {
        case Kind::JointState: msg = sensor_msgs__msg__JointState__create(); break;
        case Kind::Imu: msg = sensor_msgs__msg__Imu__create(); break;
        case Kind::Wrench: msg = geometry_msgs__msg__WrenchStamped__create(); break;
        case Kind::Tf: msg = tf2_msgs__msg__TFMessage__create(); break;
        }
    }

    // The key and stamp of the message just taken; false when it has none.
    bool read(std::string& key, double& stamp) const
    {
        key = name;
        switch (kind) {
        case Kind::JointState: {
            const auto* m = static_cast<const sensor_msgs__msg__JointState*>(msg);
            if (m->name.size > 0) {
                key += "|" + text(m->name.data[0]);
            }
            stamp = seconds(m->header.stamp);
            return true;
        }
        case Kind::Imu: stamp = seconds(static_cast<const sensor_msgs__msg__Imu*>(msg)->header.stamp); return true;
        case Kind::Wrench:
            stamp = seconds(static_cast<const geometry_msgs__msg__WrenchStamped*>(msg)->header.stamp);
            return true;
        case Kind::Tf: {
            const auto* m = static_cast<const tf2_msgs__msg__TFMessage*>(msg);
            if (m->transforms.size == 0) {
                return false;
            }
            stamp = seconds(m->transforms.data[0].header.stamp);
            return true;
        }
        }
        return false;
    }
};

struct Record
{
    int key;
    double stamp;
    double recv;
};

struct Recorder
{
    std::mutex mutex;
    std::vector<std::string> keys;
    std::map<std::string, int> index;
    std::vector<Record> records;
    std::map<int, double> first;

    void take(const std::string& key, double stamp, double recv)
    {
        std::lock_guard<std::mutex> lock(mutex);
        auto it = index.find(key);
        if (it == index.end()) {
            it = index.emplace(key, static_cast<int>(keys.size())).first;
            keys.push_back(key);
        }
        records.push_back({it->second, stamp, recv});
        first.emplace(it->second, recv);
    }
};

}  // namespace

int main(int argc, char* argv[])
{
    std::vector<Topic> topics;
    for (int k = 1; k < argc; ++k) {
        const std::string arg = argv[k];
        const auto eq = k + 1 < argc ? std::string(argv[k + 1]).find('=') : std::string::npos;
        if (arg != "--sub" || eq == std::string::npos) {
            std::fprintf(stderr, "stamp_sink: usage: stamp_sink --sub TOPIC=TYPE [--sub ...]\n");
            return 2;
        }
        const std::string value = argv[++k];
        Topic t;
        t.name = value.substr(0, eq);
        const std::string type = value.substr(eq + 1);
        if (type == "sensor_msgs/JointState") {
            t.kind = Kind::JointState;
        } else if (type == "sensor_msgs/Imu") {
            t.kind = Kind::Imu;
        } else if (type == "geometry_msgs/WrenchStamped") {
            t.kind = Kind::Wrench;
        } else if (type == "tf2_msgs/TFMessage") {
            t.kind = Kind::Tf;
        } else {
            std::fprintf(stderr, "stamp_sink: unknown type %s\n", type.c_str());
            return 2;
        }
        topics.push_back(std::move(t));
    }
    if (topics.empty()) {
        std::fprintf(stderr, "stamp_sink: no topic (--sub TOPIC=TYPE)\n");
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
    if (rcl_node_init(&node, "bench_stamp_sink", "", &context, &nodeOptions) != RCL_RET_OK) {
        return fail("rcl_node_init");
    }
    for (Topic& t : topics) {
        rcl_subscription_options_t subOptions = rcl_subscription_get_default_options();
        subOptions.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
        subOptions.qos.depth = 1000;
        subOptions.qos.reliability = RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT;
        if (rcl_subscription_init(&t.sub, &node, t.support(), t.name.c_str(), &subOptions) != RCL_RET_OK) {
            return fail("rcl_subscription_init");
        }
        t.create();
    }
    rcl_wait_set_t waitSet = rcl_get_zero_initialized_wait_set();
    if (rcl_wait_set_init(&waitSet, topics.size(), 0, 0, 0, 0, 0, &context, allocator) != RCL_RET_OK) {
        return fail("rcl_wait_set_init");
    }
    Recorder recorder;
    recorder.records.reserve(1000000);
    say("ready");

    std::atomic<bool> quitting{false};
    std::thread reader([&] {
        std::string key;
        double stamp = 0;
        while (!quitting) {
            if (rcl_wait_set_clear(&waitSet) != RCL_RET_OK) {
                rcl_reset_error();
                continue;
            }
            for (Topic& t : topics) {
                if (rcl_wait_set_add_subscription(&waitSet, &t.sub, nullptr) != RCL_RET_OK) {
                    rcl_reset_error();
                }
            }
            const rcl_ret_t waited = rcl_wait(&waitSet, RCL_MS_TO_NS(100));
            if (waited != RCL_RET_OK) {
                rcl_reset_error();
                continue;
            }
            for (std::size_t i = 0; i < waitSet.size_of_subscriptions; ++i) {
                if (waitSet.subscriptions[i] == nullptr) {
                    continue;
                }
                Topic& t = topics[i];
                while (true) {  // every message there
                    rmw_message_info_t info = rmw_get_zero_initialized_message_info();
                    const rcl_ret_t took = rcl_take(&t.sub, t.msg, &info, nullptr);
                    const double recv = monotonicNow();
                    if (took != RCL_RET_OK) {
                        rcl_reset_error();
                        break;
                    }
                    if (t.read(key, stamp)) {
                        recorder.take(key, stamp, recv);
                    }
                }
            }
        }
    });

    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string cmd;
        in >> cmd;
        if (cmd == "reset") {
            std::lock_guard<std::mutex> lock(recorder.mutex);
            recorder.records.clear();
            say("ok");
        } else if (cmd == "first") {
            std::ostringstream out;
            out.precision(17);
            out << "{";
            std::lock_guard<std::mutex> lock(recorder.mutex);
            const char* sep = "";
            for (const auto& [k, t] : recorder.first) {
                out << sep << jsonString(recorder.keys[k]) << ": " << t;
                sep = ", ";
            }
            out << "}";
            say(out.str());
        } else if (cmd == "clear_first") {
            std::lock_guard<std::mutex> lock(recorder.mutex);
            recorder.first.clear();
            say("ok");
        } else if (cmd == "dump") {
            std::string path;
            in >> path;
            std::vector<Record> records;
            std::vector<std::string> keys;
            {
                std::lock_guard<std::mutex> lock(recorder.mutex);
                records = recorder.records;
                keys = recorder.keys;
            }
            std::ofstream out(path);
            out.precision(17);
            out << "[";
            for (std::size_t i = 0; i < records.size(); ++i) {
                out << (i ? ", " : "") << "[" << jsonString(keys[records[i].key]) << ", " << records[i].stamp << ", "
                    << records[i].recv << "]";
            }
            out << "]\n";
            out.close();
            say(out ? "ok " + std::to_string(records.size()) : "failed to write " + path);
        } else if (cmd == "matched") {
            std::string out = "matched";
            for (Topic& t : topics) {
                std::size_t publishers = 0;
                if (rcl_subscription_get_publisher_count(&t.sub, &publishers) != RCL_RET_OK) {
                    rcl_reset_error();
                }
                out += " " + t.name + "=" + std::to_string(publishers);
            }
            say(out);
        } else if (cmd == "quit") {
            break;
        }
    }
    quitting = true;
    reader.join();
    rcl_wait_set_fini(&waitSet);
    for (Topic& t : topics) {
        (void)rcl_subscription_fini(&t.sub, &node);
    }
    (void)rcl_node_fini(&node);
    (void)rcl_shutdown(&context);
    return 0;
}
