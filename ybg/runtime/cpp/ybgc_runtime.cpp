// The runtime library of the C++ modules ybgc generates: the behaviour
// behind ybgc_runtime.hpp (docs/runtime.md). Inputs, layout checks,
// freshness, matching, converters, timing, connections, shutdown.
#include "ybgc_runtime.hpp"  // ybgc:runtime-import

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <functional>
#include <initializer_list>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <pthread.h>
#include <signal.h>

#include <yarp/conf/version.h>
#include <yarp/os/Bottle.h>
#include <yarp/os/BufferedPort.h>
#include <yarp/os/Carriers.h>
#include <yarp/os/ConnectionReader.h>
#include <yarp/os/ConnectionWriter.h>
#include <yarp/os/Contact.h>
#include <yarp/os/ContactStyle.h>
#include <yarp/os/Network.h>
#include <yarp/os/PortInfo.h>
#include <yarp/os/PortReader.h>
#include <yarp/os/PortReport.h>
#include <yarp/os/Portable.h>
#include <yarp/os/ResourceFinder.h>
#include <yarp/os/RpcServer.h>
#include <yarp/os/Stamp.h>
#include <yarp/os/Type.h>
#include <yarp/os/TypedReaderCallback.h>
#include <yarp/os/Value.h>

namespace ybgc {

const char* gModule = "";

std::mutex& printMutex()
{
    static std::mutex m;
    return m;
}

/// Prints "<module>: <text>" on stdout, at once.
void say(const std::string& text)
{
    std::lock_guard<std::mutex> lock(printMutex());
    std::fprintf(stdout, "%s: %s\n", gModule, text.c_str());
    std::fflush(stdout);
}

/// Prints lines as they are (totals, verbose values).
void printLines(const std::string& text)
{
    std::lock_guard<std::mutex> lock(printMutex());
    std::fputs(text.c_str(), stdout);
    std::fflush(stdout);
}

/// A float written as Python's repr() writes it: the shortest digits that
/// read back exactly, "1.0", "0.0001", "1e-05", "1e+16", "nan", "-inf".
std::int64_t secondsToNs(double t)
{
    const double sec = std::floor(t);
    return static_cast<std::int64_t>(sec) * 1000000000
        + static_cast<std::int64_t>(std::nearbyint((t - sec) * 1e9));
}

std::string reprFloat(double x)
{
    if (std::isnan(x)) {
        return "nan";
    }
    if (std::isinf(x)) {
        return x > 0 ? "inf" : "-inf";
    }
    char buf[64];
    const std::to_chars_result r = std::to_chars(buf, buf + sizeof buf, x, std::chars_format::scientific);
    std::string sci(buf, r.ptr);  // "-1.2345e+02"
    const bool negative = sci[0] == '-';
    if (negative) {
        sci.erase(0, 1);
    }
    const std::size_t e = sci.find('e');
    const int exponent = std::atoi(sci.c_str() + e + 1);
    std::string digits = sci.substr(0, e);
    digits.erase(std::remove(digits.begin(), digits.end(), '.'), digits.end());
    const int n = static_cast<int>(digits.size());
    std::string out;
    if (exponent >= -4 && exponent < 16) {
        if (exponent < 0) {
            out = "0." + std::string(static_cast<std::size_t>(-exponent - 1), '0') + digits;
        } else if (n <= exponent + 1) {
            out = digits + std::string(static_cast<std::size_t>(exponent + 1 - n), '0') + ".0";
        } else {
            out = digits.substr(0, static_cast<std::size_t>(exponent + 1)) + "."
                + digits.substr(static_cast<std::size_t>(exponent + 1));
        }
    } else {
        out = digits.substr(0, 1);
        if (n > 1) {
            out += "." + digits.substr(1);
        }
        char exp[16];
        std::snprintf(exp, sizeof exp, "e%c%02d", exponent < 0 ? '-' : '+', std::abs(exponent));
        out += exp;
    }
    return negative ? "-" + out : out;
}

void convert(Mux& mux, double scale, double offset, bool toFloat, std::size_t start, std::size_t stop)
{
    if (scale == 1.0 && offset == 0.0 && !toFloat) {
        return;
    }
    stop = std::min(stop, mux.size());
    for (std::size_t k = start; k < stop; ++k) {
        Element& e = mux[k];
        if (!e.isNumber()) {
            continue;
        }
        const double y = e.asReal() * scale + offset;
        if (toFloat || e.kind == Element::Kind::Real) {
            e = Element::ofReal(y);
        } else {
            e = Element::ofInteger(Element::ofReal(y).asInteger());
        }
    }
}

// --- orientation and geometry converters, element-wise expressions ------------

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
const double kDeg = 3.141592653589793 / 180.0;
const double kRad = 180.0 / 3.141592653589793;
/// |cos| of the middle Euler angle under which quatToEuler takes it for +-pi/2
constexpr double kGimbalLock = 1e-8;

struct Quat
{
    double x, y, z, w;
    double operator[](int k) const { return k == 0 ? x : (k == 1 ? y : (k == 2 ? z : w)); }
};

/// +1.0 for an even permutation of (0, 1, 2), -1.0 for an odd one.
double parity(int i, int j, int k)
{
    return ((i == 0 && j == 1 && k == 2) || (i == 1 && j == 2 && k == 0) || (i == 2 && j == 0 && k == 1))
               ? 1.0 : -1.0;
}

/// The quaternion product p q: q first, then p.
Quat qmul(const Quat& p, const Quat& q)
{
    return {p.w * q.x + p.x * q.w + p.y * q.z - p.z * q.y,
            p.w * q.y - p.x * q.z + p.y * q.w + p.z * q.x,
            p.w * q.z + p.x * q.y - p.y * q.x + p.z * q.w,
            p.w * q.w - p.x * q.x - p.y * q.y - p.z * q.z};
}

/// The one of q and -q (the same rotation) whose w is not negative.
Quat positive(const Quat& q)
{
    if (q.w < 0.0) {
        return {-q.x, -q.y, -q.z, -q.w};
    }
    return q;
}

Quat unit(const Quat& q)
{
    const double n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    return {q.x / n, q.y / n, q.z / n, q.w / n};
}

/// Element (r, c) of the rotation matrix of the unit quaternion q.
double rot(const Quat& q, int r, int c)
{
    if (r == c) {
        const int a = r == 0 ? 1 : 0;
        const int b = r == 2 ? 1 : 2;
        return 1.0 - 2.0 * (q[a] * q[a] + q[b] * q[b]);
    }
    const int m = 3 - r - c;
    return 2.0 * (q[r] * q[c] - parity(r, c, m) * q[m] * q.w);
}

/// The axis order "xyz" ... as axis indices (unknown: "xyz").
void axesOf(const char* axes, int out[3])
{
    for (int k = 0; k < 3; ++k) {
        const char c = axes != nullptr ? axes[k] : '\0';
        out[k] = c == 'y' ? 1 : (c == 'z' ? 2 : 0);
        if (c == '\0') {
            out[0] = 0, out[1] = 1, out[2] = 2;
            return;
        }
    }
}

Quat eulerToQuat(double a1, double a2, double a3, const char* axes, bool degrees)
{
    if (degrees) {
        a1 = a1 * kDeg;
        a2 = a2 * kDeg;
        a3 = a3 * kDeg;
    }
    int ax[3];
    axesOf(axes, ax);
    const double angles[3] = {a1, a2, a3};
    Quat q{0.0, 0.0, 0.0, 1.0};
    for (int k = 0; k < 3; ++k) {
        const double h = angles[k] * 0.5;
        double e[4] = {0.0, 0.0, 0.0, std::cos(h)};
        e[ax[k]] = std::sin(h);
        q = qmul({e[0], e[1], e[2], e[3]}, q);
    }
    return positive(q);
}

std::vector<double> quatToEuler(const Quat& in, const char* axes, bool degrees)
{
    const Quat q = unit(in);
    int ax[3];
    axesOf(axes, ax);
    const int i = ax[0], j = ax[1], k = ax[2];
    const double s = parity(i, j, k);
    const double rkj = rot(q, k, j);
    const double rkk = rot(q, k, k);
    const double c = std::sqrt(rkj * rkj + rkk * rkk);  // |cos(a2)|
    const double a2 = std::atan2(-s * rot(q, k, i), c);
    double a1 = 0.0;
    double a3 = 0.0;
    if (c < kGimbalLock) {
        // the middle angle is +-pi/2: only a1 + a3 (or a1 - a3) is defined; a3 = 0
        a1 = std::atan2(-s * rot(q, j, k), rot(q, j, j));
    } else {
        a1 = std::atan2(s * rkj, rkk);
        a3 = std::atan2(s * rot(q, j, i), rot(q, i, i));
    }
    if (degrees) {
        return {a1 * kRad, a2 * kRad, a3 * kRad};
    }
    return {a1, a2, a3};
}

Quat axisAngleToQuat(double ax, double ay, double az, double theta)
{
    const double n = std::sqrt(ax * ax + ay * ay + az * az);
    if (n == 0.0) {
        return {0.0, 0.0, 0.0, 1.0};
    }
    const double h = theta * 0.5;
    const double s = std::sin(h) / n;
    return positive({ax * s, ay * s, az * s, std::cos(h)});
}

std::vector<double> quatToAxisAngle(const Quat& in)
{
    const Quat q = positive(unit(in));
    const double v = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z);
    if (v == 0.0) {
        return {0.0, 0.0, 1.0, 0.0};
    }
    return {q.x / v, q.y / v, q.z / v, 2.0 * std::atan2(v, q.w)};
}

Quat matrixToQuat(double m00, double m01, double m02, double m10, double m11, double m12, double m20,
                  double m21, double m22)
{
    const double tr = m00 + m11 + m22;
    Quat q;
    if (tr > 0.0) {
        const double s = std::sqrt(tr + 1.0) * 2.0;
        q = {(m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s};
    } else if (m00 > m11 && m00 > m22) {
        const double s = std::sqrt(1.0 + m00 - m11 - m22) * 2.0;
        q = {0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s};
    } else if (m11 > m22) {
        const double s = std::sqrt(1.0 + m11 - m00 - m22) * 2.0;
        q = {(m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s};
    } else {
        const double s = std::sqrt(1.0 + m22 - m00 - m11) * 2.0;
        q = {(m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s};
    }
    return positive(unit(q));
}

std::vector<double> ofQuat(const Quat& q)
{
    return {q.x, q.y, q.z, q.w};
}

} // namespace

std::size_t geometryWidthIn(Geometry g)
{
    switch (g) {
    case Geometry::EulerToQuat: return 3;
    case Geometry::MatrixToQuat: return 9;
    case Geometry::TransformToPose: return 16;
    default: return 4;
    }
}

std::size_t geometryWidthOut(Geometry g)
{
    switch (g) {
    case Geometry::QuatToEuler: return 3;
    case Geometry::TransformToPose: return 7;
    default: return 4;
    }
}

std::vector<double> geometry(Geometry g, const std::vector<double>& in, const char* axes, bool degrees)
{
    std::vector<double> out;
    if (in.size() != geometryWidthIn(g)) {
        return std::vector<double>(geometryWidthOut(g), kNan);
    }
    const double* v = in.data();
    switch (g) {
    case Geometry::EulerToQuat: out = ofQuat(eulerToQuat(v[0], v[1], v[2], axes, degrees)); break;
    case Geometry::QuatToEuler: out = quatToEuler({v[0], v[1], v[2], v[3]}, axes, degrees); break;
    case Geometry::AxisAngleToQuat: out = ofQuat(axisAngleToQuat(v[0], v[1], v[2], v[3])); break;
    case Geometry::QuatToAxisAngle: out = quatToAxisAngle({v[0], v[1], v[2], v[3]}); break;
    case Geometry::MatrixToQuat:
        out = ofQuat(matrixToQuat(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]));
        break;
    case Geometry::TransformToPose: {
        const Quat q = matrixToQuat(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
        out = {v[3], v[7], v[11], q.x, q.y, q.z, q.w};
        break;
    }
    case Geometry::QuatNormalize: out = ofQuat(unit({v[0], v[1], v[2], v[3]})); break;
    }
    for (double x : out) {
        if (!std::isfinite(x)) {
            return std::vector<double>(out.size(), kNan);
        }
    }
    return out;
}

void convertGeometry(Mux& mux, Geometry g, std::size_t start, const char* axes, bool degrees)
{
    const std::size_t width = geometryWidthIn(g);
    if (start > mux.size() || mux.size() - start < width) {
        return;
    }
    std::vector<double> in;
    for (std::size_t k = start; k < start + width; ++k) {
        in.push_back(mux[k].isNumber() ? mux[k].asReal() : kNan);
    }
    const std::vector<double> out = geometry(g, in, axes, degrees);
    std::vector<Element> elements;
    for (double x : out) {
        elements.push_back(Element::ofReal(x));
    }
    mux.erase(mux.begin() + static_cast<std::ptrdiff_t>(start),
              mux.begin() + static_cast<std::ptrdiff_t>(start + width));
    mux.insert(mux.begin() + static_cast<std::ptrdiff_t>(start), elements.begin(), elements.end());
}

void convertEach(Mux& mux, double (*f)(double), std::size_t start, std::size_t stop)
{
    stop = std::min(stop, mux.size());
    for (std::size_t k = start; k < stop; ++k) {
        if (mux[k].isNumber()) {
            mux[k] = Element::ofReal(f(mux[k].asReal()));
        }
    }
}

double minOf(double a, double b)
{
    return std::min(a, b);
}

double maxOf(double a, double b)
{
    return std::max(a, b);
}

double clamp(double x, double lo, double hi)
{
    return minOf(maxOf(x, lo), hi);
}

/// Prints every element of a mux: "[<mux>] <index>: <value>".
void printMux(const char* name, const Mux& mux)
{
    std::string out;
    for (std::size_t k = 0; k < mux.size(); ++k) {
        out += "[" + std::string(name) + "] " + std::to_string(k) + ": " + mux[k].repr() + "\n";
    }
    printLines(out);
}

void printMux(const char* name, const Rows& rows)
{
    std::string out;
    for (std::size_t k = 0; k < rows.size(); ++k) {
        out += "[" + std::string(name) + "] " + std::to_string(k) + ": [";
        for (std::size_t j = 0; j < rows[k].size(); ++j) {
            out += (j > 0 ? ", " : "") + rows[k][j].repr();
        }
        out += "]\n";
    }
    printLines(out);
}

void putInteger(yarp::os::Bottle& b, std::int64_t x, Wire wire)
{
    switch (wire) {
    case Wire::Int8:
        b.addInt8(static_cast<std::int8_t>(x));
        break;
    case Wire::Int16:
        b.addInt16(static_cast<std::int16_t>(x));
        break;
    case Wire::Int32:
        b.addInt32(static_cast<std::int32_t>(x));
        break;
    case Wire::Int64:
        b.addInt64(x);
        break;
    case Wire::Float32:
        b.addFloat32(static_cast<float>(x));
        break;
    case Wire::Float64:
        b.addFloat64(static_cast<double>(x));
        break;
    case Wire::String:
        b.addString(std::to_string(x));
        break;
    case Wire::Number:
        if (x >= INT32_MIN && x <= INT32_MAX) {
            b.addInt32(static_cast<std::int32_t>(x));
        } else {
            b.addInt64(x);
        }
        break;
    }
}

/// Appends one mux element to `b` as `wire`.
void put(yarp::os::Bottle& b, const Element& e, Wire wire)
{
    switch (wire) {
    case Wire::Float32:
        b.addFloat32(static_cast<float>(e.asReal()));
        break;
    case Wire::Float64:
        b.addFloat64(e.asReal());
        break;
    case Wire::String:
        b.addString(e.str());
        break;
    case Wire::Number:
        if (e.kind == Element::Kind::Real) {
            b.addFloat64(e.real);
        } else if (e.kind == Element::Kind::Text) {
            b.addString(e.text);
        } else {
            putInteger(b, e.integer, Wire::Number);
        }
        break;
    default:
        putInteger(b, e.asInteger(), wire);
        break;
    }
}

/// Appends the elements [start, stop) of a mux to `b`, one by one.
void putRange(yarp::os::Bottle& b, const Mux& mux, std::size_t start, std::size_t stop, Wire wire)
{
    stop = std::min(stop, mux.size());
    for (std::size_t k = start; k < stop; ++k) {
        put(b, mux[k], wire);
    }
}

/// Appends a time, `ns` nanoseconds since the epoch, as a nested list (sec nsec).
void putRows(yarp::os::Bottle& b, const Rows& rows, Wire wire)
{
    for (const Mux& row : rows) {
        putRange(b.addList(), row, 0, kToEnd, wire);
    }
}

void putTime(yarp::os::Bottle& b, std::int64_t ns, Wire secWire, Wire nsecWire)
{
    std::int64_t sec = ns / 1000000000;
    std::int64_t nsec = ns % 1000000000;
    if (nsec < 0) {
        nsec += 1000000000;
        sec -= 1;
    }
    yarp::os::Bottle& t = b.addList();
    putInteger(t, sec, secWire);
    putInteger(t, nsec, nsecWire);
}

void append(Mux& mux, const Latest& input)
{
    mux.insert(mux.end(), input.values.begin(), input.values.end());
}

void append(Rows& rows, const Latest& input)
{
    rows.insert(rows.end(), input.rows.begin(), input.rows.end());
}

bool isInteger(const yarp::os::Value& v)
{
    return v.isInt8() || v.isInt16() || v.isInt32() || v.isInt64();
}

/// YARP 4 gave float32 the Bottle tag that YARP 3 gives float64, so on YARP 4
/// a float32 element is most likely a YARP 3 producer's float64, read as other
/// values: it is taken only where the input declares float32.
constexpr bool kFloat32Ambiguous = YARP_VERSION_MAJOR >= 4;

/// A number an input takes (`float32`: the input declares a float32 there).
bool isNumber(const yarp::os::Value& v, bool float32 = false)
{
    return isInteger(v) || v.isFloat64() || (v.isFloat32() && (float32 || !kFloat32Ambiguous));
}

std::string describe(const yarp::os::Value& v)
{
    if (v.isList()) {
        return "a list";
    }
    if (v.isString()) {
        return "a string";
    }
    if (v.isFloat64() || v.isFloat32()) {
        return "a float";
    }
    if (isInteger(v)) {
        return "an integer";
    }
    if (v.isVocab32()) {
        return "a vocab";
    }
    return "a " + v.toString();
}

/// Why element `k` is not the number wanted.
std::string notA(std::size_t k, const yarp::os::Value& v, const std::string& wanted)
{
    if (kFloat32Ambiguous && v.isFloat32()) {
        return "element " + std::to_string(k) + " is a float32 (on YARP " YARP_VERSION ", what a YARP 3 "
               "producer's float64 reads as: YARP 4 changed the Bottle tags; declare the port (float32 xN) "
               "if it really sends float32)";
    }
    return "element " + std::to_string(k) + " is " + describe(v) + ", " + wanted;
}

void leaves(const yarp::os::Bottle& b, std::vector<const yarp::os::Value*>& out)
{
    for (std::size_t k = 0; k < b.size(); ++k) {
        const yarp::os::Value& v = b.get(k);
        if (v.isList()) {
            leaves(*v.asList(), out);
        } else {
            out.push_back(&v);
        }
    }
}

/// The items of an input Bottle: its elements; for a ROS 1 topic, the
/// fields read (an array field gives all its elements), or every leaf.
bool items(const yarp::os::Bottle& b, const InputSpec& spec, std::vector<const yarp::os::Value*>& out,
           std::string& why)
{
    out.clear();
    if (spec.kind == InputKind::Yarp) {
        for (std::size_t k = 0; k < b.size(); ++k) {
            out.push_back(&b.get(k));
        }
        return true;
    }
    if (spec.fields.empty()) {
        leaves(b, out);
        return true;
    }
    for (const FieldPath& f : spec.fields) {
        const yarp::os::Bottle* list = &b;
        const yarp::os::Value* v = nullptr;
        for (std::size_t level = 0; level < f.at.size(); ++level) {
            const int i = f.at[level];
            if (list == nullptr || i < 0 || static_cast<std::size_t>(i) >= list->size()) {
                why = std::string("the message has no field ") + f.name;
                return false;
            }
            v = &list->get(static_cast<std::size_t>(i));
            list = v->isList() ? v->asList() : nullptr;
        }
        if (v == nullptr) {
            why = std::string("the message has no field ") + f.name;
            return false;
        }
        if (list != nullptr) {
            for (std::size_t k = 0; k < list->size(); ++k) {
                out.push_back(&list->get(k));
            }
        } else {
            out.push_back(v);
        }
    }
    return true;
}

enum class Expect { Float, Float32, Integer, Bool, Text };

Expect expectOf(const std::string& type)
{
    if (type == "float64") {
        return Expect::Float;
    }
    if (type == "float32") {
        return Expect::Float32;
    }
    if (type == "bool") {
        return Expect::Bool;
    }
    if (type == "string") {
        return Expect::Text;
    }
    return Expect::Integer;
}

bool parseBottle(const yarp::os::Bottle& b, const InputSpec& spec, bool dropNan, Mux& out, std::string& why,
                 std::vector<const yarp::os::Value*>& in)
{
    if (!items(b, spec, in, why)) {
        return false;
    }
    out.clear();
    out.reserve(in.size());
    if (!spec.declared) {
        // any number, as it came: an integer stays an integer
        for (std::size_t k = 0; k < in.size(); ++k) {
            const yarp::os::Value& v = *in[k];
            if (!isNumber(v)) {
                why = notA(k, v, "not a number");
                return false;
            }
            out.push_back(isInteger(v) ? Element::ofInteger(v.asInt64()) : Element::ofReal(v.asFloat64()));
        }
    } else {
        std::size_t width = 0;
        for (const Group& g : spec.layout) {
            width += static_cast<std::size_t>(g.count);
        }
        if (in.size() != width) {
            why = std::to_string(in.size()) + " elements, expected " + std::to_string(width);
            return false;
        }
        std::size_t k = 0;
        for (const Group& g : spec.layout) {
            const Expect expect = expectOf(g.type);
            for (int n = 0; n < g.count; ++n, ++k) {
                const yarp::os::Value& v = *in[k];
                // the text of a failure, built only on failure (not per element)
                const auto at = [&v, k] { return "element " + std::to_string(k) + " is " + describe(v); };
                switch (expect) {
                case Expect::Float:
                case Expect::Float32:
                    if (!isNumber(v, expect == Expect::Float32)) {
                        why = notA(k, v, std::string("expected ") + g.type);
                        return false;
                    }
                    out.push_back(Element::ofReal(v.asFloat64()));
                    break;
                case Expect::Integer:
                    if (!isInteger(v)) {
                        why = at() + ", expected " + g.type;
                        return false;
                    }
                    out.push_back(Element::ofInteger(v.asInt64()));
                    break;
                case Expect::Text:
                    if (!v.isString()) {
                        why = at() + ", expected a string";
                        return false;
                    }
                    out.push_back(Element::ofText(v.asString()));
                    break;
                case Expect::Bool:
                    if (v.isBool()) {
                        out.push_back(Element::ofBool(v.asBool()));
                    } else if (isInteger(v) && (v.asInt64() == 0 || v.asInt64() == 1)) {
                        out.push_back(Element::ofBool(v.asInt64() == 1));
                    } else {
                        why = at() + ", expected a bool (0 or 1)";
                        return false;
                    }
                    break;
                }
            }
        }
    }
    if (dropNan) {
        for (std::size_t k = 0; k < out.size(); ++k) {
            if (out[k].kind == Element::Kind::Real && std::isnan(out[k].real)) {
                why = "element " + std::to_string(k) + " is NaN";
                return false;
            }
        }
    }
    return true;
}

bool checkValues(Mux& values, const InputSpec& spec, bool dropNan, std::string& why)
{
    const auto at = [](std::size_t k) { return "element " + std::to_string(k); };
    if (!spec.declared) {
        for (std::size_t k = 0; k < values.size(); ++k) {
            Element& e = values[k];
            if (e.kind != Element::Kind::Real && e.kind != Element::Kind::Integer) {
                why = at(k) + " is not a number";
                return false;
            }
            e = Element::ofReal(e.asReal());
        }
    } else {
        std::size_t width = 0;
        for (const Group& g : spec.layout) {
            width += static_cast<std::size_t>(g.count);
        }
        if (values.size() != width) {
            why = std::to_string(values.size()) + " elements, expected " + std::to_string(width);
            return false;
        }
        std::size_t k = 0;
        for (const Group& g : spec.layout) {
            const Expect expect = expectOf(g.type);
            for (int n = 0; n < g.count; ++n, ++k) {
                Element& e = values[k];
                switch (expect) {
                case Expect::Float:
                case Expect::Float32:
                    if (e.kind != Element::Kind::Real && e.kind != Element::Kind::Integer) {
                        why = at(k) + " is not a number, expected " + g.type;
                        return false;
                    }
                    e = Element::ofReal(e.asReal());
                    break;
                case Expect::Integer:
                    if (e.kind != Element::Kind::Integer) {
                        why = at(k) + " is not an integer, expected " + g.type;
                        return false;
                    }
                    break;
                case Expect::Bool:
                    if (e.kind == Element::Kind::Integer && (e.integer == 0 || e.integer == 1)) {
                        e = Element::ofBool(e.integer == 1);
                    } else if (e.kind != Element::Kind::Boolean) {
                        why = at(k) + " is not a bool (0 or 1)";
                        return false;
                    }
                    break;
                case Expect::Text:
                    why = at(k) + " has the type " + g.type + ", not read from ROS 2";
                    return false;
                }
            }
        }
    }
    if (dropNan) {
        for (std::size_t k = 0; k < values.size(); ++k) {
            if (values[k].kind == Element::Kind::Real && std::isnan(values[k].real)) {
                why = at(k) + " is NaN";
                return false;
            }
        }
    }
    return true;
}

// --- what is kept of each input, and which Bottles a message uses ----------------------

std::string cutText(const std::string& source, std::size_t width, std::size_t reads)
{
    return "input " + source + ": a Bottle of " + std::to_string(width) + " values, of which the message reads "
           + "the first " + std::to_string(reads) + "; the other " + std::to_string(width - reads)
           + " are dropped (declare the port's elements in the config to check its width); said once";
}

bool accept(InputState& in, Mux& values, bool hasEnvelope, double envelope, SteadyClock::time_point arrival,
            std::size_t queue)
{
    if (in.spec.reads >= 0 && values.size() > static_cast<std::size_t>(in.spec.reads) && !in.reportedCut) {
        in.reportedCut = true;
        say(cutText(in.spec.source, values.size(), static_cast<std::size_t>(in.spec.reads)));
    }
    in.queue.emplace_back();
    Pending& entry = in.queue.back();
    entry.data.values.swap(values);
    entry.data.hasEnvelope = hasEnvelope;
    entry.data.envelope = hasEnvelope ? envelope : 0.0;
    entry.arrival = arrival;
    if (in.queue.size() > queue) {
        in.queue.pop_front();
        ++in.unused;
    }
    in.arrival = arrival;
    const bool wasFresh = in.state == Freshness::Fresh;
    if (in.state == Freshness::Stale) {
        say("input " + std::string(in.spec.source) + " is fresh again");
    }
    in.state = Freshness::Fresh;
    return wasFresh;
}

void refuse(InputState& in, const std::string& why)
{
    ++in.dropped;
    if (!in.reportedDrop) {
        in.reportedDrop = true;
        say("input " + std::string(in.spec.source) + ": dropped a Bottle (" + why + "); further drops are only counted");
    }
}

bool accepts(const InputState& in, const std::string& name)
{
    return std::find(in.accepted.begin(), in.accepted.end(), name) != in.accepted.end();
}

std::string foreignText(const std::string& source, const std::string& other)
{
    return "input " + source + ": " + other + " is connected to its port, not " + source + " (the name server gave "
           + source + " the address of " + other + ", or the connection was made by hand): its Bottles are refused "
           + "(dropped and counted), the connection closed and " + source + " tried again; to take them, `accept` "
           + "it in the config or give --accept " + source + "=" + other + "; said once";
}

bool refuseForeign(InputState& in, const std::string& other, bool bottle)
{
    if (bottle) {
        ++in.refused;
    }
    if (std::find(in.foreign.begin(), in.foreign.end(), other) != in.foreign.end()) {
        return false;
    }
    in.foreign.push_back(other);
    say(foreignText(in.spec.source, other));
    return true;
}

Matcher::Matcher(const BridgeSpec& spec, std::vector<InputState*> inputs, bool eventDriven) :
        spec_(spec), inputs_(std::move(inputs)), eventDriven_(eventDriven)
{
    for (std::size_t k = 0; k < inputs_.size(); ++k) {
        const int mux = spec.inputs[k].mux;
        if (spec.needed.empty() || std::find(spec.needed.begin(), spec.needed.end(), mux) != spec.needed.end()) {
            needed_.push_back(inputs_[k]);
        }
    }
    for (InputState* in : inputs_) {
        latest_.add(in->latest);
        if (!eventDriven_ || std::find(needed_.begin(), needed_.end(), in) == needed_.end()) {
            sampled_.push_back(in);
        }
    }
}

SteadyClock::time_point Matcher::checkFreshness(SteadyClock::time_point now)
{
    SteadyClock::time_point deadline = SteadyClock::time_point::max();
    for (InputState* in : inputs_) {
        if (in->state == Freshness::Waiting) {
            if (!in->reportedWaiting) {
                in->reportedWaiting = true;
                say("waiting for " + std::string(in->spec.source));
            }
            continue;
        }
        if (in->state != Freshness::Fresh) {
            continue;
        }
        if (!in->isFresh(now)) {
            in->state = Freshness::Stale;
            ++in->stalePeriods;
            char text[64];
            std::snprintf(text, sizeof text, "%.1f", std::chrono::duration<double>(now - in->arrival).count());
            say("input " + std::string(in->spec.source) + " is stale (no data for " + text + " s)");
        } else {
            const auto limit = std::chrono::duration_cast<SteadyClock::duration>(
                std::chrono::duration<double>(in->timeout));
            deadline = std::min(deadline, in->arrival + limit + std::chrono::microseconds(1));
        }
    }
    return deadline;
}

bool Matcher::ready(SteadyClock::time_point now, bool eventDriven) const
{
    for (const InputState* in : needed_) {
        if (spec_.hold ? in->state == Freshness::Waiting : !in->isFresh(now)) {
            return false;
        }
    }
    if (!eventDriven && !spec_.newOnly) {
        return true;  // publish = always: every cycle, the newest values
    }
    // new data, by the trigger (at a fixed rate with publish = new too)
    if (needed_.empty()) {
        return false;  // nothing arrives to publish for
    }
    std::size_t updated = 0;
    for (const InputState* in : needed_) {
        updated += in->queue.empty() ? 0 : 1;
    }
    return spec_.triggerAll ? updated == needed_.size() : updated > 0;
}

/// A queued Bottle's time: its envelope stamp, or its arrival.
double Matcher::when(const Pending& p, bool byEnvelope)
{
    return byEnvelope ? p.data.envelope : std::chrono::duration<double>(p.arrival.time_since_epoch()).count();
}

/// The index of the input's queued Bottle nearest in time to
/// `reference` (the older one on a tie).
std::size_t Matcher::nearest(const InputState& in, double reference, bool byEnvelope)
{
    std::size_t best = 0;
    double gap = std::fabs(when(in.queue[0], byEnvelope) - reference);
    for (std::size_t k = 1; k < in.queue.size(); ++k) {
        const double g = std::fabs(when(in.queue[k], byEnvelope) - reference);
        if (g < gap) {
            gap = g;
            best = k;
        }
    }
    return best;
}

/// Queued Bottle `k` becomes what messages use; the older ones are unused.
void Matcher::use(InputState& in, std::size_t k)
{
    in.unused += k;
    in.queue.erase(in.queue.begin(), in.queue.begin() + static_cast<std::ptrdiff_t>(k));
    in.latest = std::move(in.queue.front().data);
    in.hasLatest = true;
    in.queue.pop_front();
}

void Matcher::take()
{
    if (eventDriven_ && spec_.triggerAll) {
        // one Bottle of every needed input, matched in time to the newest
        // of the oldest ones: by envelope stamps when all of them have one
        bool byEnvelope = true;
        for (const InputState* in : needed_) {
            for (const Pending& p : in->queue) {
                byEnvelope = byEnvelope && p.data.hasEnvelope;
            }
        }
        double reference = when(needed_.front()->queue.front(), byEnvelope);
        for (const InputState* in : needed_) {
            reference = std::max(reference, when(in->queue.front(), byEnvelope));
        }
        for (InputState* in : needed_) {
            use(*in, nearest(*in, reference, byEnvelope));
        }
    } else if (eventDriven_) {
        // the oldest unused Bottle of any needed input; an input no message
        // used yet joins with its Bottle nearest in time to it
        InputState* first = nullptr;
        for (InputState* in : needed_) {
            if (!in->queue.empty() && (first == nullptr || in->queue.front().arrival < first->queue.front().arrival)) {
                first = in;
            }
        }
        const double reference = when(first->queue.front(), false);
        use(*first, 0);
        for (InputState* in : needed_) {
            if (!in->hasLatest && !in->queue.empty()) {
                use(*in, nearest(*in, reference, false));
            }
        }
    }
    for (InputState* in : sampled_) {
        if (!in->queue.empty()) {
            use(*in, in->queue.size() - 1);
        }
    }
}

// --- inputs -------------------------------------------------------------------------

class Input;

/// Told of every accepted Bottle, in the input's callback thread, with
/// Shared::mutex held.
class ArrivalListener
{
public:
    virtual ~ArrivalListener() = default;
    virtual void arrived(Input& input, bool wasFresh) = 0;
};

/// What the input callbacks and the loop share; guarded by `mutex`.
struct Shared
{
    std::mutex mutex;
    std::condition_variable wake;  // stop, or an input became fresh (new stale deadline)
    bool stopping = false;
    bool dropNan = false;
    std::size_t queue = 1;  // unused Bottles kept per input (BridgeSpec::queue)
    ArrivalListener* listener = nullptr;
    std::function<void()> foreign;  // an input refused a Bottle of another port: the watcher closes its connection
};

/// An input Bottle with the name of the port that sent it: YARP's name for
/// the connection's remote end (what YARP prints as "Receiving input from"),
/// which is the sender's own name, whatever name the connection was asked for.
class SourcedBottle : public yarp::os::Portable
{
public:
    bool read(yarp::os::ConnectionReader& connection) override
    {
        source = connection.getRemoteContact().getName();
        return bottle.read(connection);
    }

    bool write(yarp::os::ConnectionWriter& connection) const override { return bottle.write(connection); }

    yarp::os::Bottle bottle;
    std::string source;
};

/// The ports connected to a port, as it reports them itself (no network):
/// YARP's names for the senders of its input connections.
class InputSources : public yarp::os::PortReport
{
public:
    void report(const yarp::os::PortInfo& info) override
    {
        if (info.tag == yarp::os::PortInfo::PORTINFO_CONNECTION && info.incoming && !info.sourceName.empty()
            && info.sourceName[0] == '/') {
            names.push_back(info.sourceName);
        }
    }

    std::vector<std::string> names;
};

/// An admin command to the port at `where` (its contact: no name server
/// needed); false when it does not answer.
bool admin(const yarp::os::Contact& where, const std::string& command, yarp::os::Bottle& reply)
{
    yarp::os::ContactStyle style;
    style.admin = true;
    style.quiet = true;
    style.timeout = 1.0;
    yarp::os::Bottle cmd;
    for (std::size_t start = 0; start < command.size();) {
        const std::size_t end = std::min(command.find(' ', start), command.size());
        cmd.addString(command.substr(start, end - start));
        start = end + 1;
    }
    return yarp::os::Network::write(where, cmd, reply, style);
}

/// One input: its own port, read by YARP's callback thread, keeping only
/// the newest accepted Bottle with its arrival time and envelope. Each
/// Bottle comes with the name of the port that sent it: from a YARP port
/// input, a Bottle of any port it does not accept is refused, never used.
class Input : public InputState, public yarp::os::TypedReaderCallback<SourcedBottle>
{
public:
    Input(Shared& shared, const InputSpec& spec, std::string local, double timeout) :
            InputState(spec, timeout), local(std::move(local)), shared_(shared)
    {
    }

    bool open()
    {
        if (spec.kind == InputKind::Ros2) {
            return true;  // no port: the InputFeed delivers its values
        }
        // queue > 1: every Bottle reaches onRead, in order (kBacklog bounds
        // it); 1: the newest only, as YARP reads by default
        port_.setStrict(shared_.queue > 1);
        if (spec.kind == InputKind::Ros1) {
            port_.setReadOnly();
        }
        port_.useCallback(*this);
        if (!port_.open(local)) {
            return false;
        }
        registered = port_.getName();
        return true;
    }

    void interrupt()
    {
        if (spec.kind != InputKind::Ros2) {
            port_.interrupt();
        }
    }

    void close()
    {
        if (spec.kind != InputKind::Ros2) {
            port_.disableCallback();
            port_.close();
        }
    }

    /// The ports connected to its port, by YARP's names for them.
    std::vector<std::string> sources()
    {
        InputSources report;
        port_.getReport(report);
        return report.names;
    }

    /// Closes the connection from port `name` to its port (an admin `del`
    /// to its own port, which needs no name server: `name` may be a port
    /// the name server does not know).
    void drop(const std::string& name)
    {
        yarp::os::Bottle reply;
        admin(port_.where(), "del " + name, reply);
    }

    using yarp::os::TypedReaderCallback<SourcedBottle>::onRead;

    void onRead(SourcedBottle& in) override
    {
        const SteadyClock::time_point now = SteadyClock::now();
        if (spec.kind == InputKind::Yarp && !accepts(*this, in.source)) {
            std::function<void()> watcher;
            {
                std::lock_guard<std::mutex> lock(shared_.mutex);
                refuseForeign(*this, in.source, true);
                watcher = shared_.foreign;
            }
            if (watcher) {
                watcher();  // closes the connection now, in its own thread
            }
            return;
        }
        const yarp::os::Bottle& bottle = in.bottle;
        if (port_.getPendingReads() > kBacklog) {
            ++received;  // far behind: skipped unread, so that the reader catches up
            ++unused;
            return;
        }
        yarp::os::Stamp stamp;
        const bool hasEnvelope = port_.getEnvelope(stamp) && stamp.isValid();
        std::string why;
        const bool ok = parseBottle(bottle, spec, shared_.dropNan, scratch_, why, items_);
        take(ok, scratch_, hasEnvelope, hasEnvelope ? stamp.getTime() : 0.0, why, now);
    }

    /// One message read by an InputFeed (its thread): checked against the
    /// layout (each row of it: one that does not check drops it whole), then
    /// as a Bottle.
    void deliver(Reading& reading)
    {
        const SteadyClock::time_point now = SteadyClock::now();
        std::string why;
        bool ok = reading.isRows || checkValues(reading.values, spec, shared_.dropNan, why);
        for (std::size_t k = 0; ok && reading.isRows && k < reading.rows.size(); ++k) {
            if (!checkValues(reading.rows[k], spec, shared_.dropNan, why)) {
                why = "element " + std::to_string(k) + ": " + why;
                ok = false;
            }
        }
        take(ok, reading.values, reading.hasEnvelope, reading.envelope, why, now,
             reading.isRows ? &reading.rows : nullptr);
    }

    /// Its port's name and address, once open.
    yarp::os::Contact where() const { return port_.where(); }

    /// A connection of port `other`, which it does not accept: said once.
    void refuseConnection(const std::string& other)
    {
        std::lock_guard<std::mutex> lock(shared_.mutex);
        refuseForeign(*this, other, false);
    }

    const std::string local;  // this module's own port
    std::string registered;   // its name in the name server (topic-@node for ROS)

private:
    /// A message read (accepted when `ok`, else refused for `why`), under
    /// the lock; `rows`: its rows (moved out), for an array of messages.
    void take(bool ok, Mux& values, bool hasEnvelope, double envelope, const std::string& why,
              SteadyClock::time_point now, Rows* rows = nullptr)
    {
        std::lock_guard<std::mutex> lock(shared_.mutex);
        ++received;
        if (!ok) {
            refuse(*this, why);
            return;
        }
        const bool wasFresh = accept(*this, values, hasEnvelope, envelope, now, shared_.queue);
        if (rows != nullptr) {
            queue.back().data.rows.swap(*rows);
        }
        if (shared_.listener != nullptr) {
            shared_.listener->arrived(*this, wasFresh);
        }
    }

    Shared& shared_;
    yarp::os::BufferedPort<SourcedBottle> port_;
    Mux scratch_;  // only touched by the callback thread
    std::vector<const yarp::os::Value*> items_;
};

// --- connections --------------------------------------------------------------------

/// A connection the watcher keeps up: to an input's port from its source
/// (`input` set), or from the output to a port it connects to.
struct Link
{
    std::string source;
    std::string destination;
    Input* input = nullptr;
};

/// Does the port at `where` answer as the port `name` (an admin `prop get`,
/// which a port answers with its process only for its own name)?
bool answersAs(const yarp::os::Contact& where, const std::string& name)
{
    yarp::os::Bottle reply;
    return admin(where, "prop get " + name, reply) && reply.check("process");
}

/// Every 0.5 s, connects each link whose source exists and that is not
/// connected, so that a source that starts late or is restarted is picked
/// up. An input's port reports its connections itself (no network traffic):
/// one from its source (or a port it accepts) leaves it alone; one from any
/// other port is closed (said once); the network is asked only about a
/// missing one, and once a period whether the name server still knows the
/// module's first port (registerAgain). What YARP connected is the port that
/// answered at the address the name server gave: it is said by its own name,
/// and when it is another port its Bottles are refused and its connection
/// closed; that address is then connected again only once the port there
/// answers as the source. Its own thread: the loop never waits for it. Its
/// state is shared with the thread, so that a thread held up by a peer that
/// does not answer can be left behind at exit.
class Watcher
{
public:
    /// `own`: the module's own ports, kept registered with the name server.
    Watcher(std::vector<Link> links, std::vector<yarp::os::Contact> own) : state_(std::make_shared<State>())
    {
        state_->connected.assign(links.size(), false);
        state_->made.assign(links.size(), false);
        state_->blocked.assign(links.size(), yarp::os::Contact());
        state_->links = std::move(links);
        state_->own = std::move(own);
    }

    void start()
    {
        std::shared_ptr<State> state = state_;
        thread_ = std::thread([state] { run(*state); });
    }

    /// What wakes it at once (an input refused a Bottle: its connection is
    /// closed now); callable from any thread, also once it has stopped.
    std::function<void()> waker() const
    {
        std::shared_ptr<State> state = state_;
        return [state] {
            std::lock_guard<std::mutex> lock(state->mutex);
            state->poked = true;
            state->wake.notify_all();
        };
    }

    /// Stops the thread; false if it did not end within `limit`.
    bool stop(std::chrono::milliseconds limit)
    {
        if (!thread_.joinable()) {
            return true;
        }
        std::unique_lock<std::mutex> lock(state_->mutex);
        state_->done = true;
        state_->wake.notify_all();
        const bool ended = state_->wake.wait_for(lock, limit, [this] { return state_->finished; });
        lock.unlock();
        if (ended) {
            thread_.join();
        } else {
            thread_.detach();
        }
        return ended;
    }

private:
    struct State
    {
        std::vector<Link> links;
        std::vector<yarp::os::Contact> own;
        std::vector<bool> connected;
        std::vector<bool> made;  // connected by this watcher
        std::vector<yarp::os::Contact> blocked;  // where another port answered to the source's name
        std::mutex mutex;
        std::condition_variable wake;
        bool done = false;
        bool poked = false;
        bool finished = false;
    };

    static void run(State& s)
    {
        std::unique_lock<std::mutex> lock(s.mutex);
        while (!s.done) {
            s.poked = false;
            lock.unlock();
            registerAgain(s);
            for (std::size_t k = 0; k < s.links.size(); ++k) {
                if (s.links[k].input != nullptr) {
                    checkInput(s, k);
                } else {
                    check(s, k);
                }
                std::lock_guard<std::mutex> again(s.mutex);
                if (s.done) {
                    break;
                }
            }
            lock.lock();
            s.wake.wait_for(lock, std::chrono::milliseconds(500), [&s] { return s.done || s.poked; });
        }
        s.finished = true;
        s.wake.notify_all();
    }

    /// A name server restarted has forgotten every port: the module's own
    /// ports are registered again (asked about the first one only), so that
    /// a source started since is connected to them and a consumer finds the
    /// output. Connections made before never needed it.
    static void registerAgain(const State& s)
    {
        if (s.own.empty() || yarp::os::Network::queryName(s.own.front().getName()).isValid()) {
            return;
        }
        bool all = true;
        for (const yarp::os::Contact& where : s.own) {
            all = yarp::os::Network::registerContact(where).isValid() && all;
        }
        if (all) {
            say("the name server had forgotten this module's ports: registered them again");
        }
    }

    /// An input's link: the connections of other ports closed, its source
    /// connected when no port it accepts is.
    static void checkInput(State& s, std::size_t k)
    {
        const Link& link = s.links[k];
        Input& input = *link.input;
        bool up = false;
        for (const std::string& name : input.sources()) {
            if (accepts(input, name)) {
                up = true;
            } else {
                input.refuseConnection(name);
                input.drop(name);
            }
        }
        if (up) {
            s.connected[k] = true;
            return;
        }
        const yarp::os::Contact where = yarp::os::Network::queryName(link.source);
        const yarp::os::Contact& blocked = s.blocked[k];
        if (where.isValid() && blocked.isValid() && where.getHost() == blocked.getHost()
            && where.getPort() == blocked.getPort() && !answersAs(where, link.source)) {
            return;  // the name still gives the address of the other port (said when it was connected)
        }
        if (where.isValid() && yarp::os::Network::exists(link.source, true)
            && yarp::os::Network::connect(link.source, link.destination, "", true)) {
            // the port YARP connected, by its own name: the one at the address
            // the name server gave, which may be another port's
            std::string real;
            for (const std::string& name : input.sources()) {
                if (accepts(input, name)) {
                    real = name;
                    break;
                }
                if (real.empty()) {
                    real = name;
                }
            }
            if (real.empty()) {
                real = link.source;  // not listed yet
            }
            if (accepts(input, real)) {
                say("connected " + real + " -> " + link.destination);
                s.connected[k] = true;
                s.made[k] = true;
                s.blocked[k] = yarp::os::Contact();
            } else {
                // its Bottles are refused as they come; its connection is closed next
                say("connected " + real + " -> " + link.destination + " (asked for " + link.source + ")");
                input.refuseConnection(real);
                s.blocked[k] = where;
                s.connected[k] = false;
            }
        } else if (s.connected[k]) {
            say("lost " + link.source + " -> " + link.destination + "; reconnecting when it is back");
            s.connected[k] = false;
        }
    }

    /// The output's link to a port it connects to.
    static void check(State& s, std::size_t k)
    {
        const Link& link = s.links[k];
        if (yarp::os::Network::exists(link.destination, true)
            && yarp::os::Network::isConnected(link.source, link.destination, true)) {
            if (!s.made[k] || listsInput(link.destination, link.source)) {
                s.connected[k] = true;
                return;
            }
            // the destination was restarted under the same name: the connection
            // listed is to its predecessor, and stays until a write fails on it
            // (for a module writing only new data, the next command)
            yarp::os::Network::disconnect(link.source, link.destination, true);
        }
        if (yarp::os::Network::exists(link.source, true) && yarp::os::Network::exists(link.destination, true)
            && yarp::os::Network::connect(link.source, link.destination, "", true)) {
            say("connected " + link.source + " -> " + link.destination);
            s.connected[k] = true;
            s.made[k] = true;
        } else if (s.connected[k]) {
            say("lost " + link.source + " -> " + link.destination + "; reconnecting when it is back");
            s.connected[k] = false;
        }
    }

    /// Does `port` list a connection from `source` among its inputs (its
    /// admin answer to `list in`)? True when it does not answer (left alone).
    static bool listsInput(const std::string& port, const std::string& source)
    {
        yarp::os::ContactStyle style;
        style.admin = true;
        style.quiet = true;
        style.timeout = 1.0;
        yarp::os::Bottle cmd;
        cmd.fromString("list in");
        yarp::os::Bottle reply;
        if (!yarp::os::Network::write(yarp::os::Contact(port), cmd, reply, style)) {
            return true;
        }
        for (std::size_t k = 0; k < reply.size(); ++k) {
            if (reply.get(k).asString() == source) {
                return true;
            }
        }
        return false;
    }

    std::shared_ptr<State> state_;
    std::thread thread_;
};

// --- SIGINT and SIGTERM ----------------------------------------------------------------

/// Blocks SIGINT and SIGTERM in every thread (construct it before any
/// thread starts) and waits for them in a thread of its own: the first one
/// asks the loop to stop; if the module is not closed 1.9 s later, or a
/// second signal comes, the process exits at once.
class SignalWatch
{
public:
    SignalWatch()
    {
        sigemptyset(&set_);
        sigaddset(&set_, SIGINT);
        sigaddset(&set_, SIGTERM);
        pthread_sigmask(SIG_BLOCK, &set_, nullptr);
    }

    void start(std::function<void()> onStop)
    {
        thread_ = std::thread([this, onStop] { run(onStop); });
    }

    /// Everything is closed: end the thread.
    void finish()
    {
        if (!thread_.joinable()) {
            return;
        }
        finished_ = true;
        pthread_kill(thread_.native_handle(), SIGTERM);
        thread_.join();
    }

private:
    void run(const std::function<void()>& onStop)
    {
        int sig = 0;
        while (sigwait(&set_, &sig) != 0) {
        }
        if (finished_) {
            return;
        }
        onStop();
        const timespec limit = {1, 900000000};
        while (true) {
            const int r = sigtimedwait(&set_, nullptr, &limit);
            if (finished_) {
                return;
            }
            if (r < 0 && errno == EINTR) {
                continue;
            }
            say(r < 0 ? "closing takes too long; exiting without closing every port"
                      : "second signal; exiting without closing every port");
            std::_Exit(1);
        }
    }

    sigset_t set_;
    std::thread thread_;
    std::atomic<bool> finished_{false};
};

// --- ROS 1 -------------------------------------------------------------------------------

/// YARP 3.5 leaves a closed topic@node port registered with the ROS master:
/// withdraw it (as a publisher or a subscriber), with short timeouts.
void withdrawFromRosMaster(const std::string& port, bool publisher)
{
    const std::size_t at = port.find('@');
    if (at == std::string::npos) {
        return;
    }
    const std::string topic = port.substr(0, at);
    const std::string node = port.substr(at + 1);
    yarp::os::Contact master = yarp::os::Network::queryName("/ros");
    if (!master.isValid()) {
        return;
    }
    yarp::os::ContactStyle style;
    style.quiet = true;
    style.timeout = 0.25;
    style.carrier = "xmlrpc";
    yarp::os::Bottle cmd;
    yarp::os::Bottle reply;
    cmd.addString("lookupNode");
    cmd.addString(node);
    cmd.addString(node);
    if (!yarp::os::Network::write(master, cmd, reply, style) || reply.get(0).asInt32() != 1) {
        return;
    }
    const std::string api = reply.get(2).asString();
    cmd.clear();
    reply.clear();
    cmd.addString(publisher ? "unregisterPublisher" : "unregisterSubscriber");
    cmd.addString(node);
    cmd.addString(topic);
    cmd.addString(api);
    yarp::os::Network::write(master, cmd, reply, style);
}

// --- ROS 1 serialization ------------------------------------------------------------------

namespace {

void putLittleEndian(std::string& out, std::uint64_t x, int bytes)
{
    for (int k = 0; k < bytes; ++k) {
        out.push_back(static_cast<char>((x >> (8 * k)) & 0xff));
    }
}

bool ros1Items(const yarp::os::Bottle& b, const char*& shape, std::string& out);

bool ros1Value(const yarp::os::Value& v, const char*& shape, std::string& out)
{
    if (v.isList()) {
        const char kind = *shape;
        if (kind != 's' && kind != 'f') {
            return false;
        }
        ++shape;
        if (kind == 's') {
            putLittleEndian(out, v.asList()->size(), 4);
        }
        return ros1Items(*v.asList(), shape, out);
    }
    if (v.isString()) {
        const std::string text = v.asString();
        putLittleEndian(out, text.size(), 4);
        out += text;
    } else if (v.isFloat64()) {
        const double x = v.asFloat64();
        std::uint64_t bits = 0;
        std::memcpy(&bits, &x, sizeof bits);
        putLittleEndian(out, bits, 8);
    } else if (v.isFloat32()) {
        const float x = v.asFloat32();
        std::uint32_t bits = 0;
        std::memcpy(&bits, &x, sizeof bits);
        putLittleEndian(out, bits, 4);
    } else if (v.isInt8()) {
        putLittleEndian(out, static_cast<std::uint8_t>(v.asInt8()), 1);
    } else if (v.isInt16()) {
        putLittleEndian(out, static_cast<std::uint16_t>(v.asInt16()), 2);
    } else if (v.isInt32()) {
        putLittleEndian(out, static_cast<std::uint32_t>(v.asInt32()), 4);
    } else if (v.isInt64()) {
        putLittleEndian(out, static_cast<std::uint64_t>(v.asInt64()), 8);
    } else {
        return false;
    }
    return true;
}

bool ros1Items(const yarp::os::Bottle& b, const char*& shape, std::string& out)
{
    for (std::size_t k = 0; k < b.size(); ++k) {
        if (!ros1Value(b.get(k), shape, out)) {
            return false;
        }
    }
    return true;
}

}  // namespace

bool ros1Bytes(const yarp::os::Bottle& msg, const char* shape, std::string& out)
{
    out.clear();
    return ros1Items(msg, shape, out) && *shape == '\0';
}

// --- the output ---------------------------------------------------------------------------

std::string tooShort(const std::string& sizes)
{
    return "a mux has fewer elements than the message needs (" + sizes + ")";
}

/// Writes each message, a Bottle built by MakeMessage, on a BufferedPort,
/// never waiting for a slow reader (a reader that lags misses messages, the
/// module does not stall).
class Output : public MessageSink
{
public:
    Output(const OutputSpec& spec, MakeMessage make) : spec_(spec), make_(std::move(make)) {}

    bool open() override
    {
        port_.setWriteOnly();
        if (spec_.kind == OutputKind::Ros1 && serialized()) {
            // the type itself, not a Bottle for YARP to translate: the blob goes as it
            // is (named on the wire too, or opening the port makes it a Bottle again)
            port_.promiseType(yarp::os::Type::byName(spec_.msgType, spec_.msgType));
        } else if (spec_.kind == OutputKind::Ros1 && spec_.msgType[0] != '\0') {
            port_.promiseType(yarp::os::Type::byNameOnWire(spec_.msgType));
        }
        if (!port_.open(spec_.port)) {
            return false;
        }
        registered_ = port_.getName();
        return true;
    }

    /// Its name in the name server (topic+@node for ROS).
    std::string registered() const override { return registered_; }

    /// The wall clock.
    std::int64_t nowNs() override
    {
        return std::chrono::duration_cast<std::chrono::nanoseconds>(
                   std::chrono::system_clock::now().time_since_epoch()).count();
    }

    bool publish(const Inputs& in, const Context& ctx, std::string& failure) override
    {
        yarp::os::Bottle& msg = prepare();
        if (!make_(in, ctx, msg, failure)) {
            unprepare();
            failure = tooShort(failure);
            return false;
        }
        if (!write()) {
            failure = "it does not have the layout of " + std::string(spec_.msgType) + ", to serialize for ROS 1";
            return false;
        }
        return true;
    }

    yarp::os::Bottle& prepare()
    {
        yarp::os::Bottle& b = port_.prepare();
        b.clear();
        prepared_ = &b;
        return b;
    }

    /// Is the message sent serialized by ros1Bytes (OutputSpec::ros1Shape)?
    bool serialized() const { return spec_.ros1Shape != nullptr && spec_.ros1Shape[0] != '\0'; }
    void unprepare() { port_.unprepare(); }

    /// Its port's name and address, once open.
    yarp::os::Contact where() const override { return port_.where(); }

    /// Writes the prepared message. A message written while the previous one
    /// is still being sent is dropped for the connections that are still
    /// busy; so it waits for them a little (50 ms at most), unless a reader
    /// has already shown that it stalls. False (nothing written) when a
    /// serialized message does not have the layout of its type.
    bool write()
    {
        if (serialized() && prepared_ != nullptr) {
            std::string bytes;
            if (!ros1Bytes(*prepared_, spec_.ros1Shape, bytes)) {
                port_.unprepare();
                return false;
            }
            prepared_->clear();
            prepared_->add(yarp::os::Value(bytes.data(), static_cast<int>(bytes.size())));
        }
        if (port_.isWriting()) {
            if (patient_) {
                const SteadyClock::time_point deadline = SteadyClock::now() + std::chrono::milliseconds(50);
                while (port_.isWriting() && SteadyClock::now() < deadline) {
                    std::this_thread::sleep_for(std::chrono::microseconds(50));
                }
                patient_ = !port_.isWriting();
            }
        } else {
            patient_ = true;
        }
        port_.write();
        return true;
    }

    void close() override
    {
        port_.interrupt();
        port_.close();
    }

    std::string describe() const override
    {
        return std::string(spec_.msgType[0] != '\0' ? spec_.msgType : "untyped Bottles") + " on " + spec_.port;
    }

private:
    const OutputSpec& spec_;
    MakeMessage make_;
    yarp::os::BufferedPort<yarp::os::Bottle> port_;
    std::string registered_;
    yarp::os::Bottle* prepared_ = nullptr;  // the message being built
    bool patient_ = true;
};


// --- the RPC port (the convention of YARP modules) ------------------------------------------

/// What `help` answers on the RPC port, one line a command.
const char* const kRpcHelp[] = {
    "help: this list",
    "stats: the totals so far: per input (input SOURCE received N dropped N stale N unused N refused N), "
    "(published N skipped N failures N), (rate ACHIEVED configured HZ|event-driven)",
    "quit: stop the module (it closes its ports and exits 0, as on SIGINT)",
};

/// A rate achieved as `stats` gives it: messages per second, two decimals.
std::string rateText(double rate)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.2f", rate);
    return buf;
}

/// The rate achieved: messages published per second since the previous
/// reading (the first: since the meter was made, at start).
class RateMeter
{
public:
    explicit RateMeter(SteadyClock::time_point now) : then_(now) {}

    double read(SteadyClock::time_point now, std::uint64_t published)
    {
        const double seconds = std::chrono::duration<double>(now - then_).count();
        const double rate = seconds > 0 ? static_cast<double>(published - before_) / seconds : 0.0;
        then_ = now;
        before_ = published;
        return rate;
    }

private:
    SteadyClock::time_point then_;
    std::uint64_t before_ = 0;
};

/// The module's RPC port `<prefix>/rpc:i`, as YARP modules have one (`yarp
/// rpc /<module>/rpc:i`): `help`, `stats`, `quit` (also `exit`, `bye`: the
/// RFModule convention). Each command is answered in YARP's own thread for
/// the port, the totals read under the bridge's lock; the loop and the
/// inputs never wait for it.
class RpcPort : public yarp::os::PortReader
{
public:
    /// `rate`: the configured rate in Hz, 0 for event-driven.
    RpcPort(std::string name, std::function<Totals()> totals, std::function<void()> quit, double rate) :
            name(std::move(name)), totals_(std::move(totals)), quit_(std::move(quit)), rate_(rate),
            meter_(SteadyClock::now())
    {
    }

    bool open()
    {
        port_.setReader(*this);
        return port_.open(name);
    }

    /// Closed; after a `quit` it asked for, once its `bye` is on its way:
    /// YARP sends a reply when read() has returned, so a port closed at once
    /// could drop it (the caller would not know the module heard it).
    void close()
    {
        if (quitAsked_) {
            const SteadyClock::time_point deadline = SteadyClock::now() + std::chrono::milliseconds(500);
            while (reading_ && SteadyClock::now() < deadline) {
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(50));  // read() returned: the reply is sent
        }
        port_.interrupt();
        port_.close();
    }

    bool read(yarp::os::ConnectionReader& connection) override
    {
        reading_ = true;
        yarp::os::Bottle command;
        if (!command.read(connection)) {
            reading_ = false;
            return false;
        }
        yarp::os::Bottle reply;
        respond(command, reply);
        yarp::os::ConnectionWriter* writer = connection.getWriter();
        if (writer != nullptr) {
            reply.write(*writer);
        }
        reading_ = false;
        return true;
    }

    const std::string name;

private:
    /// `reply` to `command`; false for an unknown one.
    bool respond(const yarp::os::Bottle& command, yarp::os::Bottle& reply)
    {
        const std::string word = command.size() > 0 ? command.get(0).toString() : std::string();
        if (word == "help") {
            reply.addVocab32("many");
            for (const char* line : kRpcHelp) {
                reply.addString(line);
            }
        } else if (word == "stats") {
            const Totals totals = totals_();
            reply.addVocab32("many");
            for (const Totals::PerInput& in : totals.inputs) {
                yarp::os::Bottle& item = reply.addList();
                item.addString("input");
                item.addString(in.source);
                for (const auto& [key, n] : {std::pair<const char*, std::uint64_t>{"received", in.received},
                                             {"dropped", in.dropped}, {"stale", in.stale}, {"unused", in.unused},
                                             {"refused", in.refused}}) {
                    item.addString(key);
                    item.addInt64(static_cast<std::int64_t>(n));
                }
            }
            yarp::os::Bottle& counts = reply.addList();
            for (const auto& [key, n] : {std::pair<const char*, std::uint64_t>{"published", totals.published},
                                         {"skipped", totals.skipped}, {"failures", totals.failures}}) {
                counts.addString(key);
                counts.addInt64(static_cast<std::int64_t>(n));
            }
            // the rates as text, with the digits that mean something (a float64
            // prints with 21 digits)
            yarp::os::Bottle& rate = reply.addList();
            rate.addString("rate");
            {
                std::lock_guard<std::mutex> lock(meterMutex_);
                rate.addString(rateText(meter_.read(SteadyClock::now(), totals.published)));
            }
            rate.addString("configured");
            rate.addString(rate_ > 0 ? reprFloat(rate_) : std::string("event-driven"));
        } else if (word == "quit" || word == "exit" || word == "bye") {
            say("asked to quit on the RPC port");
            quitAsked_ = true;
            quit_();
            reply.addVocab32("bye");
        } else {
            reply.addString("unknown command '" + word + "'; the commands: help, stats, quit");
            return false;
        }
        return true;
    }

    std::function<Totals()> totals_;
    std::function<void()> quit_;
    const double rate_;
    std::atomic<bool> reading_{false};
    std::atomic<bool> quitAsked_{false};
    std::mutex meterMutex_;
    RateMeter meter_;
    yarp::os::RpcServer port_;
};

/// The YARP config file read from a ResourceFinder context given alone (--context CTX).
const char* const kDefaultConfigFile = "config.ini";

struct Options
{
    std::string prefix;
    std::string from;     // --from FILE
    std::string context;  // --context CTX
    double rate = 0.0;
    bool hasTimeout = false;
    double timeout = 0.0;
    bool verbose = false;
    std::vector<std::pair<std::string, std::string>> accept;  // --accept: (input's source, other port)
};

std::string formatNumber(double x)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
}

/// The module's loop: gathers inputs into muxes, converts, builds and
/// publishes messages. Event-driven, the message is built and written in
/// the callback of the input whose Bottle completes it (no thread in
/// between, so nothing is added to the latency) and the loop only wakes
/// when an input would go stale. At a fixed rate, the loop publishes at
/// absolute deadlines.
class Bridge : public ArrivalListener
{
public:
    Bridge(const BridgeSpec& spec, const Options& options, MessageSink& output, InputFeed* feed) :
            spec_(spec), options_(options), output_(output), feed_(feed),
            eventDriven_(!(options.rate > 0))
    {
        shared_.dropNan = spec.dropNan;
        shared_.queue = spec.queue;
        shared_.listener = this;
        for (const InputSpec& in : spec.inputs) {
            const std::string mux = spec.muxes[static_cast<std::size_t>(in.mux)].name;
            const std::string index = std::to_string(in.index);
            const std::string local = in.kind == InputKind::Ros1
                ? std::string(in.source) + "@" + options.prefix + "/" + mux + "_in" + index
                : in.kind == InputKind::Ros2 ? std::string(in.source)
                : options.prefix + "/" + mux + "/in" + index + ":i";
            inputs_.push_back(std::make_unique<Input>(shared_, in, local,
                                                      options.hasTimeout ? options.timeout : in.timeout));
            std::vector<std::string>& accepted = inputs_.back()->accepted;
            accepted.emplace_back(in.source);
            for (const char* other : in.accepts) {
                accepted.emplace_back(other);
            }
            for (const auto& [port, other] : options.accept) {
                if (in.kind == InputKind::Yarp && port == in.source) {
                    accepted.push_back(other);
                }
            }
        }
        std::vector<InputState*> states;
        for (const auto& in : inputs_) {
            states.push_back(in.get());
        }
        matcher_ = std::make_unique<Matcher>(spec, std::move(states), eventDriven_);
    }

    void requestStop()
    {
        {
            std::lock_guard<std::mutex> lock(shared_.mutex);
            shared_.stopping = true;
        }
        shared_.wake.notify_all();
    }

    /// The totals as they stand, read under the lock (the RPC port's `stats`).
    Totals totals()
    {
        std::lock_guard<std::mutex> lock(shared_.mutex);
        Totals out;
        const SteadyClock::time_point now = SteadyClock::now();
        for (const auto& in : inputs_) {
            Totals::PerInput t{in->spec.source, in->received, in->dropped, in->stalePeriods, in->unused};
            t.refused = in->refused;
            t.foreign = in->foreign;
            t.state = in->state;
            t.age = in->state == Freshness::Waiting ? -1.0 : std::chrono::duration<double>(now - in->arrival).count();
            t.timeout = in->timeout;
            out.inputs.push_back(std::move(t));
        }
        out.module = spec_.module;
        out.output = spec_.output.port;
        out.rate = eventDriven_ ? 0.0 : options_.rate;
        out.published = published_;
        out.skipped = skippedCycles_;
        out.failures = buildFailures_;
        return out;
    }

    /// Opens everything, loops until stopped, closes; the exit status.
    int run()
    {
        int status = 0;
        std::size_t opened = 0;
        bool outputOpen = false;
        for (; opened < inputs_.size(); ++opened) {
            if (!inputs_[opened]->open()) {
                say("cannot open the port " + inputs_[opened]->local);
                status = 1;
                break;
            }
        }
        if (status == 0) {
            outputOpen = output_.open();
            if (!outputOpen) {
                output_.close();
                say(std::string("cannot open the output ") + spec_.output.port);
                status = 1;
            }
        }
        bool feedOpen = false;
        if (status == 0 && feed_ != nullptr) {
            feedOpen = feed_->open([this](std::size_t k, Reading& reading) { inputs_[k]->deliver(reading); });
            if (!feedOpen) {
                feed_->close();
                status = 1;
            }
        }
        RpcPort rpc(
            options_.prefix + "/rpc:i", [this] { return totals(); }, [this] { requestStop(); },
            eventDriven_ ? 0.0 : options_.rate);
        const bool rpcOpen = status == 0 && rpc.open();
        if (status == 0 && !rpcOpen) {
            say("cannot open the RPC port " + rpc.name);
            status = 1;
        }
        std::vector<Link> links;
        for (const auto& in : inputs_) {
            if (in->spec.kind == InputKind::Yarp) {
                links.push_back({in->spec.source, in->local, in.get()});
            }
        }
        if (spec_.output.connectTo[0] != '\0') {
            links.push_back({spec_.output.port, spec_.output.connectTo, nullptr});
        }
        std::vector<yarp::os::Contact> own;
        for (const auto& in : inputs_) {
            if (in->spec.kind == InputKind::Yarp) {
                own.push_back(in->where());
            }
        }
        if (spec_.output.kind == OutputKind::Yarp) {
            own.push_back(output_.where());
        }
        Watcher watcher(std::move(links), std::move(own));
        {
            std::lock_guard<std::mutex> lock(shared_.mutex);
            shared_.foreign = watcher.waker();
        }
        if (status == 0) {
            // a ROS 2 node among them reports the totals (its /diagnostics)
            output_.watch([this] { return totals(); });
            if (feed_ != nullptr) {
                feed_->watch([this] { return totals(); });
            }
            say("publishing " + output_.describe() + ", "
                + (eventDriven_ ? std::string("event-driven") : formatNumber(options_.rate) + " Hz"));
            watcher.start();
            if (eventDriven_) {
                loopEventDriven();
            } else {
                loopFixedRate();
            }
        }
        if (rpcOpen) {
            rpc.close();
        }
        // Closing waits for the peers; one that does not answer (a stalled
        // reader) would hold it: after a deadline the names are unregistered
        // and the process ends without waiting any longer.
        const bool watcherStopped = watcher.stop(std::chrono::milliseconds(300));
        if (feedOpen) {
            feed_->close();  // before the output, whose node it may share
        }
        const bool closed = closeAll(opened, outputOpen, std::chrono::milliseconds(800));
        printTotals();
        if (!closed || !watcherStopped) {
            if (!closed) {
                say("a peer did not answer while the ports closed; their names were unregistered");
            }
            std::fflush(stdout);
            std::_Exit(status);
        }
        return status;
    }

    /// An input accepted a Bottle (its callback thread, Shared::mutex held).
    void arrived(Input& /*input*/, bool wasFresh) override
    {
        if (!wasFresh) {
            shared_.wake.notify_all();  // the loop sleeps until the next stale deadline
        }
        if (!eventDriven_ || !publishing_ || shared_.stopping) {
            return;
        }
        while (!shared_.stopping && matcher_->ready(SteadyClock::now(), true)) {
            publish();
        }
    }

private:
    /// Closes the ports in a thread of their own; false if that did not end
    /// within `limit`: the ports' names are then unregistered.
    bool closeAll(std::size_t opened, bool outputOpen, std::chrono::milliseconds limit)
    {
        struct Done
        {
            std::mutex mutex;
            std::condition_variable cv;
            bool done = false;
        };
        auto state = std::make_shared<Done>();
        std::thread closer([this, opened, outputOpen, state] {
            for (std::size_t k = 0; k < opened; ++k) {
                inputs_[k]->interrupt();
            }
            for (std::size_t k = 0; k < opened; ++k) {
                inputs_[k]->close();
            }
            if (outputOpen) {
                output_.close();
            }
            withdrawRos(opened, outputOpen);
            std::lock_guard<std::mutex> lock(state->mutex);
            state->done = true;
            state->cv.notify_all();
        });
        std::unique_lock<std::mutex> lock(state->mutex);
        if (state->cv.wait_for(lock, limit, [&state] { return state->done; })) {
            lock.unlock();
            closer.join();
            return true;
        }
        lock.unlock();
        closer.detach();  // the process ends without it
        for (std::size_t k = 0; k < opened; ++k) {
            if (!inputs_[k]->registered.empty()) {
                yarp::os::Network::unregisterName(inputs_[k]->registered);
            }
        }
        if (outputOpen && !output_.registered().empty()) {
            yarp::os::Network::unregisterName(output_.registered());
        }
        withdrawRos(opened, outputOpen);
        return false;
    }

    /// The ROS 1 ports, withdrawn from the ROS master.
    void withdrawRos(std::size_t opened, bool outputOpen)
    {
        for (std::size_t k = 0; k < opened; ++k) {
            if (inputs_[k]->spec.kind == InputKind::Ros1) {
                withdrawFromRosMaster(inputs_[k]->local, false);
            }
        }
        if (outputOpen && spec_.output.kind == OutputKind::Ros1) {
            withdrawFromRosMaster(spec_.output.port, true);
        }
    }

    /// Builds and writes one message from the values taken; Shared::mutex
    /// held, so no input changes meanwhile (and nothing is copied).
    void publish()
    {
        matcher_->take();
        Context ctx;
        ctx.counter = published_;
        if (feed_ == nullptr || !feed_->nowNs(ctx.wallNs)) {
            ctx.wallNs = output_.nowNs();
        }
        ctx.seconds = static_cast<double>(ctx.wallNs) / 1e9;
        ctx.verbose = options_.verbose;
        ctx.inputs = &matcher_->latest();
        std::string failure;
        if (!output_.publish(matcher_->latest(), ctx, failure)) {
            if (++buildFailures_ == 1) {
                say("cannot build the message: " + failure + "; further failures are only counted");
            }
            return;
        }
        ++published_;
    }

    void loopEventDriven()
    {
        std::unique_lock<std::mutex> lock(shared_.mutex);
        publishing_ = true;
        // Bottles that came before the output was open
        while (matcher_->ready(SteadyClock::now(), true)) {
            publish();
        }
        while (!shared_.stopping) {
            const SteadyClock::time_point deadline = matcher_->checkFreshness(SteadyClock::now());
            if (deadline == SteadyClock::time_point::max()) {
                shared_.wake.wait(lock);
            } else {
                shared_.wake.wait_until(lock, deadline);
            }
        }
        publishing_ = false;
    }

    void loopFixedRate()
    {
        const double period = 1.0 / options_.rate;
        const SteadyClock::time_point start = SteadyClock::now();
        std::uint64_t cycle = 0;  // cycle k is due at start + k * period: absolute, never drifting
        auto dueTime = [&](std::uint64_t k) {
            return start + std::chrono::duration_cast<SteadyClock::duration>(
                               std::chrono::duration<double>(static_cast<double>(k) * period));
        };
        std::unique_lock<std::mutex> lock(shared_.mutex);
        while (true) {
            const SteadyClock::time_point due = dueTime(cycle);
            shared_.wake.wait_until(lock, due, [&] { return shared_.stopping || SteadyClock::now() >= due; });
            if (shared_.stopping) {
                return;
            }
            const SteadyClock::time_point now = SteadyClock::now();
            const double late = std::chrono::duration<double>(now - due).count();
            if (late > period) {
                // overran by more than a whole period: skip, never catch up in a burst
                const auto missed = static_cast<std::uint64_t>(late / period);
                skippedCycles_ += missed;
                cycle += missed;
            }
            ++cycle;
            matcher_->checkFreshness(now);
            if (!matcher_->ready(now, false)) {
                continue;
            }
            publish();
        }
    }

    void printTotals()
    {
        std::string out = "totals:\n";
        for (const auto& in : inputs_) {
            out += "  input " + std::string(in->spec.source) + ": received " + std::to_string(in->received)
                + ", dropped " + std::to_string(in->dropped) + ", stale periods "
                + std::to_string(in->stalePeriods) + ", unused " + std::to_string(in->unused);
            if (in->refused > 0) {
                std::string from;
                for (const std::string& name : in->foreign) {
                    from += (from.empty() ? "" : ", ") + name;
                }
                out += ", refused " + std::to_string(in->refused) + " from " + from;
            }
            out += "\n";
        }
        out += "  published " + std::to_string(published_) + " messages, skipped "
            + std::to_string(skippedCycles_) + " cycles, build failures " + std::to_string(buildFailures_) + "\n";
        printLines(out);
    }

    const BridgeSpec& spec_;
    const Options options_;
    Shared shared_;
    std::vector<std::unique_ptr<Input>> inputs_;
    std::unique_ptr<Matcher> matcher_;  // which Bottles each message uses
    MessageSink& output_;
    InputFeed* feed_;  // the inputs read outside YARP (nullptr: none)
    const bool eventDriven_;
    bool publishing_ = false;  // guarded by Shared::mutex
    std::atomic<std::uint64_t> published_{0};
    std::atomic<std::uint64_t> skippedCycles_{0};
    std::atomic<std::uint64_t> buildFailures_{0};
};

// --- the command line ----------------------------------------------------------------------

void usage(const BridgeSpec& spec, const std::string& prog, std::FILE* out, bool full)
{
    std::fprintf(out,
                 "usage: %s [--name P] [--rate HZ] [--timeout S] [--verbose] [--accept [PORT=]OTHER] [--from FILE]\n"
                 "       [--context CTX] [--help]\n",
                 prog.c_str());
    if (!full) {
        return;
    }
    std::fprintf(out, "\n");
    for (const char* line : spec.description) {
        std::fprintf(out, "%s\n", line);
    }
    std::fprintf(out,
                 "\noptions:\n"
                 "  --name P      prefix of the module's own port names, as YARP modules name it (default: %s)\n"
                 "  --prefix P    the same as --name\n"
                 "  --rate HZ     fixed output rate in Hz, 0 for event-driven (default: %s)\n"
                 "  --timeout S   freshness timeout of every input in seconds (default: the config's)\n"
                 "  --verbose     print every value after conversion, for every mux\n"
                 "  --accept [PORT=]OTHER\n"
                 "                the input of YARP port PORT also takes the Bottles of port OTHER (a replay\n"
                 "                under another name); OTHER alone: the module's one YARP port input; any\n"
                 "                other port's Bottles are refused. May be given several times\n"
                 "  --from FILE   read these options (name, prefix, rate, timeout, verbose) from a YARP\n"
                 "                config file, found by YARP's ResourceFinder; the command line wins\n"
                 "  --context CTX the ResourceFinder's context to look for the file in (alone: %s)\n"
                 "  --help        print this help and exit\n",
                 spec.defaultPrefix, spec.rate > 0 ? formatNumber(spec.rate).c_str() : "event-driven",
                 kDefaultConfigFile);
    bool ros2 = spec.output.kind == OutputKind::Ros2;
    for (const InputSpec& in : spec.inputs) {
        ros2 = ros2 || in.kind == InputKind::Ros2;
    }
    if (ros2) {
        std::fprintf(out,
                     "\nROS arguments (--ros-args ... [--], as for every ROS 2 program): remappings\n"
                     "(-r FROM:=TO), parameters (-p NAME:=VALUE, --params-file FILE), --log-level. Parameters:\n"
                     "  rate, timeout, prefix, verbose, accept\n"
                     "                as the options above (timeout 0: the config's); the options win\n"
                     "  use_sim_time  the node's clock is the simulated time of /clock (default: false)\n"
                     "  diagnostics   publish the bridge's state on /diagnostics (default: true)\n"
                     "  diagnostic_updater.period\n"
                     "                seconds between two /diagnostics messages (default: 1)\n"
                     "  qos_overrides./TOPIC.publisher.POLICY (.subscription. for inputs)\n"
                     "                history, depth, reliability, durability over the config's\n");
    }
    std::fprintf(out, "\nGenerated by ybgc from %s.\n", spec.config);
}

bool parseNumber(const std::string& text, double& out)
{
    if (text.empty()) {
        return false;
    }
    char* end = nullptr;
    errno = 0;
    out = std::strtod(text.c_str(), &end);
    return errno == 0 && end == text.c_str() + text.size() && std::isfinite(out);
}

/// Adds `--accept` `value` to `accept`: `PORT=OTHER` (the input of YARP port
/// PORT also takes the Bottles of port OTHER), or `OTHER` for a module of
/// one YARP port input; false (`why` says it) for anything else.
bool parseAccept(const BridgeSpec& spec, const std::string& value, std::vector<std::pair<std::string, std::string>>& accept,
                 std::string& why)
{
    std::vector<std::string> ports;
    for (const InputSpec& in : spec.inputs) {
        if (in.kind == InputKind::Yarp && std::find(ports.begin(), ports.end(), in.source) == ports.end()) {
            ports.emplace_back(in.source);
        }
    }
    std::string read;
    for (const std::string& port : ports) {
        read += (read.empty() ? "" : ", ") + port;
    }
    if (read.empty()) {
        read = "no YARP port";
    }
    const std::size_t split = value.find('=');
    std::string port;
    std::string other = value;
    if (split == std::string::npos) {
        if (ports.size() != 1) {
            why = "--accept " + value + ": say which input takes it, --accept PORT=" + value + " (the module reads "
                + read + ")";
            return false;
        }
        port = ports.front();
    } else {
        port = value.substr(0, split);
        other = value.substr(split + 1);
    }
    if (std::find(ports.begin(), ports.end(), port) == ports.end()) {
        why = "--accept " + value + ": " + port + " is not a YARP port the module reads (it reads " + read + ")";
        return false;
    }
    if (other.size() < 2 || other[0] != '/'
        || std::any_of(other.begin(), other.end(), [](unsigned char c) { return std::isspace(c) != 0; })) {
        why = "--accept " + value + ": '" + other + "' is not a YARP port name";
        return false;
    }
    accept.emplace_back(port, other);
    return true;
}

/// Parses `args` into `opt` (from the config's defaults): -1 to go on, 0
/// after --help, else `why` says what is wrong.
int parseArgs(const BridgeSpec& spec, const std::string& prog, const std::vector<std::string>& args, Options& opt,
              std::string& why)
{
    opt = Options();
    opt.prefix = spec.defaultPrefix;
    opt.rate = spec.rate;
    for (std::size_t k = 0; k < args.size(); ++k) {
        std::string arg = args[k];
        std::string value;
        bool inlineValue = false;
        const std::size_t eq = arg.find('=');
        if (arg.rfind("--", 0) == 0 && eq != std::string::npos) {
            value = arg.substr(eq + 1);
            arg = arg.substr(0, eq);
            inlineValue = true;
        }
        if (arg == "--help" || arg == "-h") {
            usage(spec, prog, stdout, true);
            return 0;
        }
        if (arg == "--verbose") {
            if (inlineValue) {
                why = "--verbose takes no value";
                return 2;
            }
            opt.verbose = true;
            continue;
        }
        if (arg != "--prefix" && arg != "--name" && arg != "--rate" && arg != "--timeout" && arg != "--from"
            && arg != "--context" && arg != "--accept") {
            why = "unknown option " + arg;
            return 2;
        }
        if (!inlineValue) {
            if (k + 1 >= args.size()) {
                why = arg + " needs a value";
                return 2;
            }
            value = args[++k];
        }
        if (arg == "--prefix") {
            if (value.empty() || value[0] != '/') {
                why = "--prefix must start with /";
                return 2;
            }
            opt.prefix = value;
        } else if (arg == "--name") {
            opt.prefix = value.empty() || value[0] != '/' ? "/" + value : value;  // `--name foo`, as YARP modules take it
        } else if (arg == "--from") {
            opt.from = value;
        } else if (arg == "--context") {
            opt.context = value;
        } else if (arg == "--accept") {
            if (!parseAccept(spec, value, opt.accept, why)) {
                return 2;
            }
        } else if (arg == "--rate") {
            if (!parseNumber(value, opt.rate) || opt.rate < 0) {
                why = "--rate must be 0 (event-driven) or positive";
                return 2;
            }
        } else {
            if (!parseNumber(value, opt.timeout) || opt.timeout <= 0) {
                why = "--timeout must be positive";
                return 2;
            }
            opt.hasTimeout = true;
        }
    }
    return -1;
}

/// The options in the YARP config file `--from path` / `--context context`
/// (alone: its kDefaultConfigFile), found by YARP's ResourceFinder as every
/// YARP module finds its own, appended to `out` as command-line arguments;
/// false (`why` says it) when there is no such file.
bool readConfigFile(const BridgeSpec& spec, const std::string& path, const std::string& context,
                    std::vector<std::string>& out, std::string& why)
{
    yarp::os::ResourceFinder finder;
    finder.setQuiet(true);
    finder.setDefaultConfigFile(kDefaultConfigFile);
    std::vector<std::string> args{spec.module};
    if (!context.empty()) {
        args.insert(args.end(), {"--context", context});
    }
    if (!path.empty()) {
        args.insert(args.end(), {"--from", path});
    }
    std::vector<char*> argv;
    for (std::string& arg : args) {
        argv.push_back(&arg[0]);
    }
    const bool configured = finder.configure(static_cast<int>(argv.size()), argv.data());
    const std::string found = configured ? finder.findFile("from") : std::string();
    if (found.empty()) {
        why = "YARP's ResourceFinder finds no config file " + (path.empty() ? std::string(kDefaultConfigFile) : path)
            + (context.empty() ? std::string() : " in the context " + context);
        return false;
    }
    for (const char* key : {"name", "prefix", "rate", "timeout"}) {
        if (finder.check(key)) {
            out.push_back(std::string("--") + key);
            out.push_back(finder.find(key).toString());
        }
    }
    if (finder.check("verbose")) {
        std::string flag = finder.find("verbose").toString();
        std::transform(flag.begin(), flag.end(), flag.begin(), [](unsigned char c) { return std::tolower(c); });
        if (flag == "" || flag == "true" || flag == "1") {
            out.push_back("--verbose");
        } else if (flag != "false" && flag != "0") {
            why = found + ": verbose must be true or false";
            return false;
        }
    }
    return true;
}

/// Parses argv into `opt`: -1 to go on, else the exit status (0 after
/// --help). `--from` / `--context`: the options in that YARP config file
/// come first, so that the command line wins over the file and the file
/// over the config.
int parseOptions(const BridgeSpec& spec, int argc, char* argv[], Options& opt)
{
    std::string prog = argc > 0 && argv[0][0] != '\0' ? argv[0] : spec.module;
    prog = prog.substr(prog.rfind('/') + 1);
    auto fail = [&](const std::string& text) {
        usage(spec, prog, stderr, false);
        std::fprintf(stderr, "%s: error: %s\n", prog.c_str(), text.c_str());
        return 2;
    };
    std::vector<std::string> args(argv + (argc > 0 ? 1 : 0), argv + argc);
    std::string why;
    int status = parseArgs(spec, prog, args, opt, why);
    if (status < 0 && (!opt.from.empty() || !opt.context.empty())) {
        std::vector<std::string> withFile;
        if (!readConfigFile(spec, opt.from, opt.context, withFile, why)) {
            return fail(why);
        }
        withFile.insert(withFile.end(), args.begin(), args.end());
        status = parseArgs(spec, prog, withFile, opt, why);
    }
    if (status >= 0) {
        return status == 0 ? 0 : fail(why);
    }
    while (opt.prefix.size() > 1 && opt.prefix.back() == '/') {
        opt.prefix.pop_back();
    }
    return -1;
}

/// Does this YARP carry ROS 1 topics? It needs the tcpros and xmlrpc carriers
/// (built in up to YARP 3.9, YARP's separate yarp-ros plugins in 3.10 to 3.12,
/// gone in YARP 4) and a name server started with `--ros`. Otherwise a ROS 1
/// port opens as a plain YARP port and the module would publish into nothing.
bool ros1Available(std::string& why)
{
    const yarp::os::Bottle carriers = yarp::os::Carriers::listCarriers();
    for (const char* need : {"tcpros", "xmlrpc"}) {
        bool found = false;
        for (std::size_t k = 0; k < carriers.size() && !found; ++k) {
            found = carriers.get(k).asString() == need;
        }
        if (!found) {
            why = std::string("YARP ") + YARP_VERSION + " has no `" + need + "` carrier: ROS 1 topics need "
                + (YARP_VERSION_MAJOR >= 4 ? "YARP 3.5 to 3.12 (YARP 4 has no ROS 1); with YARP 4 set `via = ros2` and "
                                             "generate the ROS 2 node (ybgc CONFIG --backend ros2)"
                                           : "YARP's yarp-ros plugins (tcpros, xmlrpc) with YARP 3.10 and later");
            return false;
        }
    }
    if (!yarp::os::Network::queryName("/ros").isValid()) {
        why = "the YARP name server does not speak ROS: start it as `yarpserver --ros` with ROS_MASTER_URI "
              "set to the ROS master";
        return false;
    }
    return true;
}

/// Parses the command line and runs the bridge until SIGINT or SIGTERM.
int run(const BridgeSpec& spec, int argc, char* argv[], MakeMessage make, InputFeed* feed)
{
    Output output(spec.output, std::move(make));
    return run(spec, argc, argv, output, feed);
}

int run(const BridgeSpec& spec, int argc, char* argv[], MessageSink& output, InputFeed* feed)
{
    gModule = spec.module;
    Options options;
    const int status = parseOptions(spec, argc, argv, options);
    if (status >= 0) {
        return status;
    }
    if (options.rate <= 0 && spec.inputs.empty()) {
        std::fprintf(stderr, "%s: an event-driven bridge needs at least one input; give --rate\n", spec.module);
        return 2;
    }
    SignalWatch signals;  // before YARP starts any thread
    std::signal(SIGPIPE, SIG_IGN);
    yarp::os::Network network;
    if (!yarp::os::Network::checkNetwork(3.0)) {
        say("cannot reach the YARP name server (is yarpserver running?)");
        return 1;
    }
    bool ros1 = spec.output.kind == OutputKind::Ros1;
    for (const InputSpec& input : spec.inputs) {
        ros1 = ros1 || input.kind == InputKind::Ros1;
    }
    std::string why;
    if (ros1 && !ros1Available(why)) {
        say("cannot use ROS 1 topics: " + why);
        return 1;
    }
    Bridge bridge(spec, options, output, feed);
    signals.start([&bridge] { bridge.requestStop(); });
    const int result = bridge.run();
    signals.finish();
    return result;
}

}  // namespace ybgc
