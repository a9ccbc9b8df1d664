// Unit tests of the ROS 2 side of the C++ runtime library
// (ybg/runtime/cpp/ybgc_ros2.hpp/.cpp), built against one YARP and the ROS 2
// wheels by tests/test_runtime_cpp.py and run with no name server and no ROS
// 2 graph: how a mux element becomes a field of each C type (as the Python
// ROS 2 node converts it), strings filled again for each publish, stamps,
// sequences and fixed arrays sized from a range of a mux, and the ROS
// arguments of a command line. Each failed check prints its line; the exit
// status is the number of failures.
#include "ybgc_ros2.hpp"

#include <builtin_interfaces/msg/time.h>
#include <sensor_msgs/msg/imu.h>
#include <sensor_msgs/msg/joint_state.h>

#include <cmath>
#include <cstdio>
#include <cstring>
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
    const std::vector<std::string> ros = ybgc::ros2::takeRosArgs(argc, argv.data());
    CHECK(ros == (std::vector<std::string>{"--ros-args", "-p", "use_sim_time:=true"}));
    CHECK(argc == 5 && std::string(argv[1]) == "--prefix" && std::string(argv[3]) == "--rate");
    CHECK(argv[5] == nullptr);
}

}  // namespace

int main()
{
    testScalars();
    testStrings();
    testTime();
    testSequences();
    testFixedArrays();
    testRosArgs();
    std::printf("%d checks, %d failed\n", gChecks, gFailures);
    return gFailures;
}
