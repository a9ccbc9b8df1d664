// Unit tests of the ROS 2 side of the C++ runtime library
// (ybg/runtime/cpp/ybgc_ros2.hpp/.cpp), built against one YARP and the ROS 2
// wheels by tests/test_runtime_cpp.py and run with no name server and no ROS
// 2 graph: how a mux element becomes a field of each C type (as the Python
// ROS 2 node converts it), strings filled again for each publish, stamps,
// sequences and fixed arrays sized from a range of a mux, the ROS
// arguments of a command line, the node names of parameters, and the QoS
// that qos_overrides parameters give (parsed by rcl from a command line and
// a parameter file), and the statuses of /diagnostics. Each failed check prints its line; the exit
// status is the number of failures.
#include "ybgc_ros2.hpp"
#include "ybgc_internal.hpp"  // the command line, every kind of bridge's

#include <builtin_interfaces/msg/time.h>
#include <rcl/arguments.h>
#include <rcl/error_handling.h>
#include <rcl_yaml_param_parser/parser.h>
#include <rmw/qos_profiles.h>
#include <sensor_msgs/msg/imu.h>
#include <sensor_msgs/msg/joint_state.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

namespace {

int gFailures = 0;
int gChecks = 0;

void check(bool ok, const char* what, int line)
{
    ++gChecks;
    if (!ok) {
        ++gFailures;
        std::printf("FAIL line %d: %s\n", line, what);
    }
}

#define CHECK(cond) check((cond), #cond, __LINE__)

using ybgc::Element;
using ybgc::Mux;

std::string text(const rosidl_runtime_c__String& s)
{
    return std::string(s.data, s.size);
}

void testScalars()
{
    // a real as float(x), an integer as int(x) (a real truncated toward 0), a bool as bool(x)
    CHECK(ybgc::ros2::as<double>(Element::ofInteger(3)) == 3.0);
    CHECK(ybgc::ros2::as<float>(Element::ofReal(0.1)) == 0.1f);
    CHECK(ybgc::ros2::as<std::int32_t>(Element::ofReal(-2.7)) == -2);
    CHECK(ybgc::ros2::as<std::uint8_t>(Element::ofInteger(7)) == 7);
    CHECK(ybgc::ros2::as<bool>(Element::ofReal(0.5)));
    CHECK(!ybgc::ros2::as<bool>(Element::ofReal(0.0)));
    CHECK(ybgc::ros2::as<bool>(Element::ofInteger(2)));
    CHECK(std::isnan(ybgc::ros2::as<double>(Element::ofReal(std::nan("")))));
    CHECK(std::signbit(ybgc::ros2::as<double>(Element::ofReal(-0.0))));
    std::int16_t wrapped = 0;
    ybgc::ros2::assign(wrapped, std::int64_t{70000});  // a constant wraps like its type
    CHECK(wrapped == static_cast<std::int16_t>(70000));
}

void testStrings()
{
    rosidl_runtime_c__String s;
    CHECK(rosidl_runtime_c__String__init(&s));
    ybgc::ros2::setString(s, "base_link");
    CHECK(text(s) == "base_link" && s.data[s.size] == '\0');
    // a shorter text reuses the buffer; a longer one than it holds gets a new one
    // (the same capacity: no new allocation, which malloc could have placed at the same address)
    const char* buffer = s.data;
    const std::size_t capacity = s.capacity;
    ybgc::ros2::setString(s, "odom");
    CHECK(text(s) == "odom" && s.data == buffer && s.capacity == capacity && s.data[4] == '\0');
    ybgc::ros2::setString(s, "base_link");
    CHECK(text(s) == "base_link" && s.data == buffer && s.capacity == capacity);
    ybgc::ros2::setString(s, std::string(100, 'x'));
    CHECK(text(s) == std::string(100, 'x') && s.capacity > 100);
    ybgc::ros2::setString(s, std::string("a\0b", 3));  // any bytes, as rosidl's assignn
    CHECK(s.size == 3 && std::memcmp(s.data, "a\0b", 3) == 0);
    ybgc::ros2::setString(s, "");
    CHECK(s.size == 0 && s.data[0] == '\0');
    // a number in a string field, as Python's str() writes it
    ybgc::ros2::set(s, Element::ofReal(2.0));
    CHECK(text(s) == "2.0");
    ybgc::ros2::set(s, Element::ofInteger(-7));
    CHECK(text(s) == "-7");
    rosidl_runtime_c__String__fini(&s);
}

void testTime()
{
    builtin_interfaces__msg__Time t;
    builtin_interfaces__msg__Time__init(&t);
    ybgc::ros2::setTime(t, 1700000000123456789LL);
    CHECK(t.sec == 1700000000 && t.nanosec == 123456789u);
    // before the epoch: divmod, as rclpy's Time.to_msg()
    ybgc::ros2::setTime(t, -1);
    CHECK(t.sec == -1 && t.nanosec == 999999999u);
    ybgc::ros2::setTime(t, -1000000000LL);
    CHECK(t.sec == -1 && t.nanosec == 0u);
    builtin_interfaces__msg__Time__fini(&t);
}

void testSequences()
{
    sensor_msgs__msg__JointState* msg = sensor_msgs__msg__JointState__create();
    Mux mux{Element::ofReal(0.5), Element::ofInteger(2), Element::ofReal(-1.25), Element::ofReal(4.0)};
    CHECK(ybgc::ros2::setRange(msg->position, mux, 0, ybgc::kToEnd));
    CHECK(msg->position.size == 4 && msg->position.data[1] == 2.0 && msg->position.data[3] == 4.0);
    CHECK(ybgc::ros2::setRange(msg->position, mux, 1, 3));  // resized to the range
    CHECK(msg->position.size == 2 && msg->position.data[0] == 2.0 && msg->position.data[1] == -1.25);
    CHECK(ybgc::ros2::setRange(msg->position, mux, 2, 4));  // the same count: the same storage
    CHECK(msg->position.size == 2 && msg->position.data[0] == -1.25);
    const double* same = msg->position.data;
    CHECK(ybgc::ros2::setRange(msg->position, mux, 0, 2) && msg->position.data == same);
    // a range beyond the mux, backwards, or more than a bounded sequence holds: refused
    CHECK(!ybgc::ros2::setRange(msg->position, mux, 2, 6));
    CHECK(!ybgc::ros2::setRange(msg->position, mux, 3, 1));
    CHECK(!ybgc::ros2::setRange(msg->position, mux, 0, ybgc::kToEnd, 3));
    CHECK(ybgc::ros2::setRange(msg->position, mux, 1, ybgc::kToEnd, 3));
    CHECK(ybgc::ros2::setRange(msg->velocity, mux, 4, ybgc::kToEnd) && msg->velocity.size == 0);
    // constants: names filled again for each publish keep their count
    ybgc::ros2::setStrings(msg->name, {"j0", "j1", "j2"});
    CHECK(msg->name.size == 3 && text(msg->name.data[2]) == "j2");
    ybgc::ros2::setStrings(msg->name, {"j0", "j1", "j2"});
    CHECK(msg->name.size == 3 && text(msg->name.data[0]) == "j0");
    ybgc::ros2::setValues<double>(msg->effort, {1.5, -2.0});
    CHECK(msg->effort.size == 2 && msg->effort.data[1] == -2.0);
    sensor_msgs__msg__JointState__destroy(msg);
}

void testFixedArrays()
{
    sensor_msgs__msg__Imu* imu = sensor_msgs__msg__Imu__create();
    Mux nine;
    for (int k = 0; k < 9; ++k) {
        nine.push_back(Element::ofReal(k * 0.5));
    }
    CHECK(ybgc::ros2::setRange(imu->orientation_covariance, nine, 0, 9));
    CHECK(imu->orientation_covariance[8] == 4.0);
    // a fixed-size array takes exactly its size
    CHECK(!ybgc::ros2::setRange(imu->orientation_covariance, nine, 0, 8));
    nine.push_back(Element::ofReal(9.0));
    CHECK(!ybgc::ros2::setRange(imu->orientation_covariance, nine, 0, ybgc::kToEnd));
    CHECK(ybgc::ros2::setRange(imu->orientation_covariance, nine, 1, ybgc::kToEnd));
    CHECK(imu->orientation_covariance[0] == 0.5 && imu->orientation_covariance[8] == 9.0);
    ybgc::ros2::setValues<double>(imu->angular_velocity_covariance, {-1, 0, 0, 0, 0, 0, 0, 0, 0});
    CHECK(imu->angular_velocity_covariance[0] == -1.0);
    sensor_msgs__msg__Imu__destroy(imu);
}

void testRosArgs()
{
    std::vector<std::string> words{"module", "--prefix", "/x", "--ros-args", "-p", "use_sim_time:=true", "--",
                                   "--rate", "10"};
    std::vector<char*> argv;
    for (std::string& w : words) {
        argv.push_back(w.data());
    }
    argv.push_back(nullptr);
    int argc = static_cast<int>(words.size());
    const std::vector<std::string> ros = ybgc::takeRosArgs(argc, argv.data());
    CHECK(ros == (std::vector<std::string>{"--ros-args", "-p", "use_sim_time:=true"}));
    CHECK(argc == 5 && std::string(argv[1]) == "--prefix" && std::string(argv[3]) == "--rate");
    CHECK(argv[5] == nullptr);
}

void testNodeNames()
{
    using ybgc::ros2::nodeMatches;
    CHECK(nodeMatches("/**", "/bridge"));
    CHECK(nodeMatches("/**", "/robot/left/bridge"));
    CHECK(nodeMatches("/*", "/bridge"));
    CHECK(!nodeMatches("/*", "/robot/bridge"));
    CHECK(nodeMatches("/robot/*", "/robot/bridge"));
    CHECK(!nodeMatches("/robot/*", "/robot/left/bridge"));
    CHECK(nodeMatches("/**/bridge", "/robot/left/bridge"));
    CHECK(nodeMatches("bridge", "/bridge"));  // a parameter file's name without its slash
    CHECK(nodeMatches("/bri*", "/bridge"));
    CHECK(!nodeMatches("/bridge", "/bridge2"));
    CHECK(!nodeMatches("/other", "/bridge"));
}

/// The parameters of a command line's ROS arguments, as rcl parses them.
struct Params
{
    rcl_arguments_t args = rcl_get_zero_initialized_arguments();
    rcl_params_t* params = nullptr;

    explicit Params(std::vector<std::string> words)
    {
        std::vector<const char*> argv{"module"};
        for (const std::string& w : words) {
            argv.push_back(w.c_str());
        }
        if (rcl_parse_arguments(static_cast<int>(argv.size()), argv.data(), rcl_get_default_allocator(), &args)
                != RCL_RET_OK
            || rcl_arguments_get_param_overrides(&args, &params) != RCL_RET_OK) {
            std::printf("rcl refused the arguments: %s\n", rcl_get_error_string().str);
            rcl_reset_error();
        }
    }
    ~Params()
    {
        if (params != nullptr) {
            rcl_yaml_node_struct_fini(params);
        }
        if (rcl_arguments_fini(&args) != RCL_RET_OK) {
            rcl_reset_error();
        }
    }
};

rmw_qos_profile_t configQos()
{
    rmw_qos_profile_t qos = rmw_qos_profile_default;
    qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
    qos.depth = 10;
    qos.reliability = RMW_QOS_POLICY_RELIABILITY_RELIABLE;
    qos.durability = RMW_QOS_POLICY_DURABILITY_VOLATILE;
    return qos;
}

void testQosOverrides()
{
    using ybgc::ros2::overrideQos;
    std::string error;
    {
        Params p({"--ros-args", "-p", "qos_overrides./joint_states.publisher.durability:=transient_local", "-p",
                  "qos_overrides./joint_states.publisher.depth:=3", "-p",
                  "qos_overrides./joint_states.publisher.reliability:=best_effort", "-p",
                  "qos_overrides./goal.subscription.history:=keep_all"});
        CHECK(p.params != nullptr);
        rmw_qos_profile_t qos = configQos();
        CHECK(overrideQos(p.params, "/bridge", "/joint_states", "publisher", qos, error));
        CHECK(qos.durability == RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL);
        CHECK(qos.reliability == RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT);
        CHECK(qos.depth == 3 && qos.history == RMW_QOS_POLICY_HISTORY_KEEP_LAST);
        CHECK(ybgc::ros2::describeQos(qos) == "best_effort, transient_local, depth 3");
        // a subscription's overrides are not a publisher's, nor another topic's
        rmw_qos_profile_t other = configQos();
        CHECK(overrideQos(p.params, "/bridge", "/goal", "publisher", other, error));
        CHECK(overrideQos(p.params, "/bridge", "/joint_states", "subscription", other, error));
        CHECK(ybgc::ros2::describeQos(other) == "reliable, volatile, depth 10");
        CHECK(overrideQos(p.params, "/bridge", "/goal", "subscription", other, error));
        CHECK(other.history == RMW_QOS_POLICY_HISTORY_KEEP_ALL && other.depth == 10);
        CHECK(ybgc::ros2::describeQos(other) == "reliable, volatile, keep_all");
    }
    {
        // no parameters at all: the config's QoS
        rmw_qos_profile_t qos = configQos();
        CHECK(overrideQos(nullptr, "/bridge", "/joint_states", "publisher", qos, error));
        CHECK(ybgc::ros2::describeQos(qos) == "reliable, volatile, depth 10");
    }
    // what ROS 2 refuses: the parameter, the value and what it accepts
    const std::vector<std::pair<std::string, std::string>> refused{
        {"reliability:=sometimes", "qos_overrides./t.publisher.reliability: 'sometimes' is not one of reliable, "
                                   "best_effort"},
        {"durability:=3", "qos_overrides./t.publisher.durability: 3 is not one of volatile, transient_local"},
        {"history:=keep_some", "qos_overrides./t.publisher.history: 'keep_some' is not one of keep_last, keep_all"},
        {"depth:=-1", "qos_overrides./t.publisher.depth: -1 is not an integer of at least 0"},
        {"depth:=three", "qos_overrides./t.publisher.depth: 'three' is not an integer of at least 0"},
    };
    for (const auto& [arg, said] : refused) {
        Params p({"--ros-args", "-p", "qos_overrides./t.publisher." + arg});
        rmw_qos_profile_t qos = configQos();
        error.clear();
        CHECK(!overrideQos(p.params, "/bridge", "/t", "publisher", qos, error));
        CHECK(error == said);
        if (error != said) {
            std::printf("  said: %s\n", error.c_str());
        }
        CHECK(ybgc::ros2::describeQos(qos) == "reliable, volatile, depth 10");  // left as it was
    }
}

void testParameterFile(const std::string& folder)
{
    // a parameter file names nodes: the node's own entry wins over /** when it comes later,
    // and another node's entry does not apply
    const std::string path = folder + "/params.yaml";
    std::ofstream(path) << "/**:\n"
                           "  ros__parameters:\n"
                           "    use_sim_time: true\n"
                           "    qos_overrides:\n"
                           "      /t:\n"
                           "        publisher:\n"
                           "          depth: 5\n"
                           "bridge:\n"
                           "  ros__parameters:\n"
                           "    qos_overrides:\n"
                           "      /t:\n"
                           "        publisher:\n"
                           "          depth: 7\n"
                           "/other:\n"
                           "  ros__parameters:\n"
                           "    use_sim_time: false\n";
    Params p({"--ros-args", "--params-file", path});
    CHECK(p.params != nullptr);
    const rcl_variant_t* sim = ybgc::ros2::parameter(p.params, "/bridge", "use_sim_time");
    CHECK(sim != nullptr && sim->bool_value != nullptr && *sim->bool_value);
    std::string error;
    rmw_qos_profile_t qos = configQos();
    CHECK(ybgc::ros2::overrideQos(p.params, "/bridge", "/t", "publisher", qos, error) && qos.depth == 7);
    qos = configQos();
    CHECK(ybgc::ros2::overrideQos(p.params, "/robot/bridge", "/t", "publisher", qos, error) && qos.depth == 5);
    const rcl_variant_t* other = ybgc::ros2::parameter(p.params, "/other", "use_sim_time");
    CHECK(other != nullptr && other->bool_value != nullptr && !*other->bool_value);
    CHECK(ybgc::ros2::parameter(p.params, "/bridge", "no_such_parameter") == nullptr);
}

using ybgc::ros2::Status;

/// {key: value} of a status.
std::string value(const Status& s, const std::string& key)
{
    for (const auto& [k, v] : s.values) {
        if (k == key) {
            return v;
        }
    }
    return "<none>";
}

void testDiagnostics()
{
    // the levels and texts of the statuses, as the Python node's (tests/test_diagnostics.py)
    ybgc::Totals t;
    t.module = "diag_bridge";
    t.output = "/diag/point";
    t.published = 7;
    t.failures = 2;
    std::vector<Status> all = ybgc::ros2::statuses(t, "diag", 2.5);
    CHECK(all.size() == 1 && all[0].name == "diag: output /diag/point");
    CHECK(all[0].level == Status::Ok && all[0].message == "event-driven: 2.50 Hz");
    CHECK(value(all[0], "rate configured (Hz)") == "event-driven" && value(all[0], "build failures") == "2");
    CHECK(value(all[0], "published") == "7" && value(all[0], "rate achieved (Hz)") == "2.500");
    t.rate = 20.0;
    all = ybgc::ros2::statuses(t, "diag", 18.0);
    CHECK(all[0].level == Status::Ok && all[0].message == "18.00 Hz of 20 Hz");
    all = ybgc::ros2::statuses(t, "diag", 17.99);
    CHECK(all[0].level == Status::Warn && all[0].message == "rate too low: 17.99 Hz of 20 Hz");
    CHECK(value(all[0], "rate configured (Hz)") == "20");

    ybgc::Totals::PerInput in{"/diag/arm:o", 0, 0, 0, 0};
    in.timeout = 0.5;
    t.inputs = {in};
    all = ybgc::ros2::statuses(t, "diag", 0.0);
    CHECK(all.size() == 2 && all[0].name == "diag: input /diag/arm:o");
    CHECK(all[0].level == Status::Error && all[0].message == "no data received yet");
    CHECK(value(all[0], "age (s)") == "" && value(all[0], "timeout (s)") == "0.5");
    t.inputs[0].state = ybgc::Freshness::Stale;
    t.inputs[0].age = 2.25;
    t.inputs[0].received = 12;
    t.inputs[0].dropped = 3;
    t.inputs[0].refused = 4;  // Bottles of other ports than its source
    all = ybgc::ros2::statuses(t, "diag", 0.0);
    CHECK(all[0].level == Status::Warn && all[0].message == "stale: no data for 2.2 s");
    CHECK((all[0].values == std::vector<std::pair<std::string, std::string>>{
        {"received", "12"}, {"dropped", "3"}, {"stale periods", "0"}, {"unused", "0"}, {"refused", "4"},
        {"age (s)", "2.250"}, {"timeout (s)", "0.5"}}));
    t.inputs[0].state = ybgc::Freshness::Fresh;
    all = ybgc::ros2::statuses(t, "diag", 0.0);
    CHECK(all[0].level == Status::Ok && all[0].message == "fresh");

    // the parameters of /diagnostics, checked before anything opens (exit status 2, as the Python node's)
    using ybgc::ros2::checkRosArgs;
    CHECK(checkRosArgs({}, "diag") == 0);
    CHECK(checkRosArgs({"--ros-args", "-p", "diagnostics:=false", "-p", "diagnostic_updater.period:=2"}, "diag")
          == 0);
    CHECK(checkRosArgs({"--ros-args", "-p", "diagnostic_updater.period:=soon"}, "diag") == 2);
    CHECK(checkRosArgs({"--ros-args", "-p", "diagnostic_updater.period:=0.0"}, "diag") == 2);
    CHECK(checkRosArgs({"--ros-args", "-p", "diagnostics:=1"}, "diag") == 2);
    CHECK(checkRosArgs({"--ros-args", "--no-such-flag"}, "diag") == 2);
    CHECK(checkRosArgs({"--ros-args", "-p", "other:diagnostic_updater.period:=-1"}, "diag") == 0);  // another node's
    {
        Params p({"--ros-args", "-p", "diagnostics:=false", "-p", "diagnostic_updater.period:=3"});
        bool on = true;
        double period = 1.0;
        std::string error;
        CHECK(ybgc::ros2::diagnosticsOptions(p.params, "/diag", on, period, error) && !on && period == 3.0);
        Params q({"--ros-args", "-p", "diagnostic_updater.period:=true"});
        CHECK(!ybgc::ros2::diagnosticsOptions(q.params, "/diag", on, period, error));
        CHECK(error == "parameter diagnostic_updater.period must be a number, got true");
        CHECK(period == 3.0);
    }

    // the module's options as the Python node's parameters
    {
        Params p({"--ros-args", "-p", "rate:=25", "-p", "timeout:=0.25", "-p", "prefix:=/robot/bridge", "-p",
                  "verbose:=true"});
        std::vector<std::string> options;
        std::string error;
        CHECK(ybgc::ros2::parameterOptions(p.params, "/diag", options, error));
        CHECK((options == std::vector<std::string>{"--rate=25", "--timeout=0.25", "--prefix=/robot/bridge",
                                                   "--verbose"}));
        Params q({"--ros-args", "-p", "rate:=0.1", "-p", "timeout:=0.0", "-p", "verbose:=false"});
        options.clear();
        CHECK(ybgc::ros2::parameterOptions(q.params, "/diag", options, error));
        CHECK((options == std::vector<std::string>{"--rate=0.10000000000000001"}));  // parsed back: 0.1
        options.clear();
        CHECK(ybgc::ros2::parameterOptions(nullptr, "/diag", options, error) && options.empty());
        const std::vector<std::pair<std::string, std::string>> refused{
            {"rate:=-1", "parameter rate must be 0 (event-driven) or positive"},
            {"rate:=fast", "parameter rate must be a number, got 'fast'"},
            {"timeout:=-0.5", "parameter timeout must be positive (or 0: the config's)"},
            {"prefix:=robot", "parameter prefix must be a string starting with /"},
            {"verbose:=3", "parameter verbose must be true or false"},
        };
        for (const auto& [arg, said] : refused) {
            Params r({"--ros-args", "-p", arg});
            error.clear();
            CHECK(!ybgc::ros2::parameterOptions(r.params, "/diag", options, error) && error == said);
            if (error != said) {
                std::printf("  said: %s\n", error.c_str());
            }
        }
        std::vector<std::string> given;
        CHECK(ybgc::ros2::checkRosArgs({"--ros-args", "-p", "rate:=-1"}, "diag", &given) == 2);
        CHECK(ybgc::ros2::checkRosArgs({"--ros-args", "-p", "rate:=40"}, "diag", &given) == 0);
        CHECK((given == std::vector<std::string>{"--rate=40"}));
    }
    {
        // the command line's own options follow those of the parameters: they win
        std::vector<std::string> words{"module", "--rate", "10"};
        std::vector<char*> argv;
        for (std::string& w : words) {
            argv.push_back(w.data());
        }
        argv.push_back(nullptr);
        ybgc::CommandLine line(3, argv.data(), {"--rate=25", "--verbose"});
        CHECK(line.argc() == 5 && line.argv()[5] == nullptr);
        CHECK(std::string(line.argv()[0]) == "module" && std::string(line.argv()[1]) == "--rate=25");
        CHECK(std::string(line.argv()[3]) == "--rate" && std::string(line.argv()[4]) == "10");
    }
    {
        // a bridge's command line with its ROS arguments: those of a stream give every option, those of
        // commands `prefix` and `verbose` alone; a bad value is status 2
        auto words = [](std::vector<std::string> w) { return w; };
        for (const bool stream : {true, false}) {
            std::vector<std::string> w = words({"module", "--name", "x", "--ros-args", "-p", "rate:=40", "-p",
                                                "diag:verbose:=true", "-p", "prefix:=/p", "--", "--verbose"});
            std::vector<char*> argv;
            for (std::string& s : w) {
                argv.push_back(s.data());
            }
            argv.push_back(nullptr);
            ybgc::RosCommandLine line(static_cast<int>(w.size()), argv.data(), "module", "diag", stream);
            CHECK(line.status == 0);
            CHECK(line.rosArgs.size() == 7 && line.rosArgs[0] == "--ros-args");
            std::vector<std::string> got(line.argv() + 1, line.argv() + line.argc());
            CHECK(got == (stream ? std::vector<std::string>{"--rate=40", "--prefix=/p", "--verbose", "--name", "x",
                                                            "--verbose"}
                                 : std::vector<std::string>{"--prefix=/p", "--verbose", "--name", "x", "--verbose"}));
        }
        std::vector<std::string> w = words({"module", "--ros-args", "-p", "diagnostics:=1"});
        std::vector<char*> argv;
        for (std::string& s : w) {
            argv.push_back(s.data());
        }
        argv.push_back(nullptr);
        CHECK(ybgc::RosCommandLine(static_cast<int>(w.size()), argv.data(), "module", "diag", false).status == 2);
    }

    // the rate over the last 5 periods: the oldest of the last 6 samples to the newest
    ybgc::ros2::RateWindow window;
    CHECK(window.add(0.0, 0) == 0.0);
    CHECK(window.add(1.0, 10) == 10.0);
    for (int k = 2; k <= 5; ++k) {
        window.add(k, 10 * static_cast<std::uint64_t>(k));
    }
    CHECK(window.add(6.0, 160) == 30.0);  // (160 - 10) / (6 - 1): the sample at 0 s has left
    CHECK(window.add(7.0, 160) == 28.0);  // (160 - 20) / (7 - 2)
}

}  // namespace

int main(int argc, char* argv[])
{
    const std::string folder = argc > 1 ? argv[1] : ".";
    testScalars();
    testStrings();
    testTime();
    testSequences();
    testFixedArrays();
    testRosArgs();
    testNodeNames();
    testQosOverrides();
    testParameterFile(folder);
    testDiagnostics();
    std::printf("%d checks, %d failed\n", gChecks, gFailures);
    return gFailures;
}
