// The C++ geometry converters and expressions on values read from stdin, for
// tests/test_geometry.py, which compares them bit for bit with Python's.
// Built against the runtime (ybgc_runtime.cpp) with -ffp-contract=off, as a
// module is; "expressions.inc" (written by the test) defines kExpressions.
//
// stdin, one request a line, numbers as C99 hex floats (Python's float.hex()):
//     g <converter> <axes> <0|1 degrees> <value>...   a geometry converter
//     e <k> <x>                                       expression k at x
// stdout: one line a request, the results as hex floats (%a).
#include "ybgc_runtime.hpp"

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "expressions.inc"

namespace {

const std::map<std::string, ybgc::Geometry> kGeometry = {
    {"euler_to_quat", ybgc::Geometry::EulerToQuat},
    {"quat_to_euler", ybgc::Geometry::QuatToEuler},
    {"axis_angle_to_quat", ybgc::Geometry::AxisAngleToQuat},
    {"quat_to_axis_angle", ybgc::Geometry::QuatToAxisAngle},
    {"matrix_to_quat", ybgc::Geometry::MatrixToQuat},
    {"transform_to_pose", ybgc::Geometry::TransformToPose},
    {"quat_normalize", ybgc::Geometry::QuatNormalize},
};

double hex(const std::string& text)
{
    return std::strtod(text.c_str(), nullptr);
}

} // namespace

int main()
{
    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream in(line);
        std::string kind;
        in >> kind;
        std::vector<double> out;
        if (kind == "g") {
            std::string name, axes, degrees, word;
            in >> name >> axes >> degrees;
            std::vector<double> values;
            while (in >> word) {
                values.push_back(hex(word));
            }
            out = ybgc::geometry(kGeometry.at(name), values, axes.c_str(), degrees == "1");
        } else if (kind == "e") {
            std::size_t k = 0;
            std::string x;
            in >> k >> x;
            out.push_back(kExpressions[k](hex(x)));
        }
        std::string text;
        for (double v : out) {
            char buf[64];
            std::snprintf(buf, sizeof buf, "%a ", v);
            text += buf;
        }
        std::printf("%s\n", text.c_str());
        std::fflush(stdout);
    }
    return 0;
}
