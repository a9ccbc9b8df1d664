// The C++ runtime's values and converters (ybgc_runtime.hpp): a float as
// Python's repr() writes it, times in nanoseconds, the scale/offset
// converter, the orientation and geometry converters and the functions of
// expressions, which compute what ybg/runtime/geometry.py computes, to the
// bit (built with -ffp-contract=off).
#include "ybgc_runtime.hpp"  // ybgc:runtime-import

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <initializer_list>
#include <limits>
#include <string>
#include <vector>

namespace ybgc {

std::int64_t secondsToNs(double t)
{
    const double sec = std::floor(t);
    return static_cast<std::int64_t>(sec) * 1000000000
        + static_cast<std::int64_t>(std::nearbyint((t - sec) * 1e9));
}

/// A float written as Python's repr() writes it: the shortest digits that
/// read back exactly, "1.0", "0.0001", "1e-05", "1e+16", "nan", "-inf".
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
/// |w| up to which a quaternion's w is 0 (the rounding of a 180-degree
/// rotation's, some 1e-16), for the sign of the quaternion a converter gives
constexpr double kZeroW = 1e-12;

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

/// The canonical one of q and -q (the same rotation): w > 0; or, when
/// |w| <= kZeroW (a rotation of 180 degrees, whose w the arithmetic leaves at
/// some 1e-16 of either sign), w = 0.0 and the first of x, y, z beyond kZeroW
/// positive. A NaN stays (the result is then all NaN). geometry.py's _positive.
Quat positive(const Quat& q)
{
    if (std::fabs(q.w) <= kZeroW) {
        for (const double v : {q.x, q.y, q.z}) {
            if (std::fabs(v) > kZeroW) {
                if (v < 0.0) {
                    return {-q.x, -q.y, -q.z, 0.0};
                }
                break;
            }
        }
        return {q.x, q.y, q.z, 0.0};
    }
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

}  // namespace ybgc
