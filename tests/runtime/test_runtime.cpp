// Unit tests of the C++ runtime library (ybg/runtime/cpp/), built against
// one YARP by tests/test_runtime_cpp.py and run with no name server: the
// values a module prints, the converters, the output Bottles, the checks of
// input Bottles, and which Bottles a message uses (queues, matching,
// freshness), driven by hand with the arrival times the test chooses. Each
// failed check prints its line and what was compared; the exit status is the
// number of failures.
#include "ybgc_runtime.hpp"
#include "ybgc_internal.hpp"

#include <yarp/conf/version.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>

namespace {

int gFailures = 0;
int gChecks = 0;

void check(bool ok, const char* what, int line, const std::string& detail = "")
{
    ++gChecks;
    if (!ok) {
        ++gFailures;
        std::printf("FAIL line %d: %s %s\n", line, what, detail.c_str());
    }
}

#define CHECK(cond) check((cond), #cond, __LINE__)
#define CHECK_EQ(a, b) check((a) == (b), #a " == " #b, __LINE__, "got [" + std::string(a) + "]")

using ybgc::Element;
using ybgc::Mux;
using ybgc::Wire;

ybgc::Mux reals(std::initializer_list<double> xs)
{
    Mux m;
    for (double x : xs) {
        m.push_back(Element::ofReal(x));
    }
    return m;
}

void testReprFloat()
{
    // as Python's repr(): the shortest digits that read back exactly
    CHECK_EQ(ybgc::reprFloat(1.0), "1.0");
    CHECK_EQ(ybgc::reprFloat(0.1), "0.1");
    CHECK_EQ(ybgc::reprFloat(-2.5), "-2.5");
    CHECK_EQ(ybgc::reprFloat(0.0001), "0.0001");
    CHECK_EQ(ybgc::reprFloat(1e-05), "1e-05");
    CHECK_EQ(ybgc::reprFloat(1e16), "1e+16");
    CHECK_EQ(ybgc::reprFloat(123456789012345.0), "123456789012345.0");
    CHECK_EQ(ybgc::reprFloat(1.0 / 3.0), "0.3333333333333333");
    CHECK_EQ(ybgc::reprFloat(5e-324), "5e-324");
    CHECK_EQ(ybgc::reprFloat(std::nan("")), "nan");
    CHECK_EQ(ybgc::reprFloat(-std::numeric_limits<double>::infinity()), "-inf");
}

void testSecondsToNs()
{
    // the whole seconds apart from the fraction: exact where t * 1e9 alone gives 1700000000249999872
    CHECK(ybgc::secondsToNs(1700000000.25) == 1700000000250000000LL);
    CHECK(ybgc::secondsToNs(0.5) == 500000000LL);
    CHECK(ybgc::secondsToNs(-0.25) == -250000000LL);
    CHECK(ybgc::secondsToNs(-1.0) == -1000000000LL);
    CHECK(ybgc::secondsToNs(12.000000001) == 12000000001LL);
}

void testElements()
{
    CHECK(Element::ofReal(1e300).asInteger() == std::numeric_limits<std::int64_t>::max());
    CHECK(Element::ofReal(-1e300).asInteger() == std::numeric_limits<std::int64_t>::min());
    CHECK(Element::ofReal(std::nan("")).asInteger() == 0);
    CHECK(Element::ofReal(-2.7).asInteger() == -2);
    CHECK(Element::ofText("x").asReal() == 0.0 && !Element::ofText("x").isNumber());
    CHECK_EQ(Element::ofBool(true).repr(), "True");
    CHECK_EQ(Element::ofInteger(-7).repr(), "-7");
    CHECK_EQ(Element::ofText("it's").repr(), "'it\\'s'");
    CHECK_EQ(Element::ofReal(2.0).str(), "2.0");
    CHECK_EQ(Element::ofText("plain").str(), "plain");
}

void testConvert()
{
    const double deg = M_PI / 180.0;
    Mux m = reals({180.0, 90.0, 45.0});
    ybgc::convert(m, deg, 0.0, false, 1, ybgc::kToEnd);
    CHECK(m[0].real == 180.0 && m[1].real == 90.0 * deg && m[2].real == 45.0 * deg);
    // an integer stays an integer (truncated), unless toFloat
    Mux ints{Element::ofInteger(3), Element::ofInteger(7), Element::ofText("s")};
    ybgc::convert(ints, 0.5, 0.0, false, 0, ybgc::kToEnd);
    CHECK(ints[0].kind == Element::Kind::Integer && ints[0].integer == 1 && ints[1].integer == 3);
    CHECK(ints[2].kind == Element::Kind::Text && ints[2].text == "s");  // a string is left alone
    Mux floats{Element::ofInteger(3)};
    ybgc::convert(floats, 0.5, 0.0, true, 0, ybgc::kToEnd);
    CHECK(floats[0].kind == Element::Kind::Real && floats[0].real == 1.5);
    // a range past the end is cut; exactly x * scale + offset (no contraction)
    Mux r = reals({1.0, 1.0});
    ybgc::convert(r, 3.0, 0.1, false, 1, 99);
    CHECK(r[0].real == 1.0 && r[1].real == 1.0 * 3.0 + 0.1);
}

void testConvertGeometryAndEach()
{
    // a geometry converter replaces its range by its results: the width changes
    Mux m{Element::ofText("id"), Element::ofReal(0.0), Element::ofReal(0.0), Element::ofInteger(90),
          Element::ofReal(7.0)};
    ybgc::convertGeometry(m, ybgc::Geometry::EulerToQuat, 1, "xyz", true);
    CHECK(m.size() == 6 && m[0].text == "id" && m[5].real == 7.0);
    const double h = 90.0 * (M_PI / 180.0) * 0.5;
    CHECK(m[1].real == 0.0 && m[2].real == 0.0 && m[3].real == std::sin(h) && m[4].real == std::cos(h));
    CHECK(ybgc::geometryWidthIn(ybgc::Geometry::TransformToPose) == 16);
    CHECK(ybgc::geometryWidthOut(ybgc::Geometry::TransformToPose) == 7);
    // a mux too short for the range is left as it is
    Mux shortMux = reals({1.0, 2.0});
    ybgc::convertGeometry(shortMux, ybgc::Geometry::QuatNormalize, 0, "xyz", false);
    CHECK(shortMux.size() == 2 && shortMux[1].real == 2.0);
    // a result that cannot be is all NaN
    const std::vector<double> zero = ybgc::geometry(ybgc::Geometry::QuatNormalize, {0.0, 0.0, 0.0, 0.0});
    CHECK(zero.size() == 4 && std::isnan(zero[0]) && std::isnan(zero[3]));
    // an expression on each number of its range, a float64; strings left alone
    Mux e{Element::ofInteger(3), Element::ofText("s"), Element::ofReal(-5.0), Element::ofReal(9.0)};
    ybgc::convertEach(e, [](double x) { return ybgc::clamp(x, -1.0, 1.0) * 0.5; }, 0, 3);
    CHECK(e[0].kind == Element::Kind::Real && e[0].real == 0.5 && e[1].text == "s" && e[2].real == -0.5);
    CHECK(e[3].real == 9.0);
}

void testPut()
{
    yarp::os::Bottle b;
    ybgc::putInteger(b, 300, Wire::Int8);
    ybgc::putInteger(b, (std::int64_t{1} << 32) + 5, Wire::Int32);
    ybgc::put(b, Element::ofReal(2.5), Wire::Float64);
    ybgc::put(b, Element::ofReal(-3.9), Wire::Int64);
    ybgc::put(b, Element::ofReal(0.1), Wire::Float32);
    ybgc::put(b, Element::ofInteger(42), Wire::String);
    CHECK(b.size() == 6);
    CHECK(b.get(0).isInt8() && b.get(0).asInt8() == 44);        // 300 mod 256
    CHECK(b.get(1).isInt32() && b.get(1).asInt32() == 5);       // two's complement cut
    CHECK(b.get(2).isFloat64() && b.get(2).asFloat64() == 2.5);
    CHECK(b.get(3).isInt64() && b.get(3).asInt64() == -3);
    CHECK(b.get(4).isFloat32() && b.get(4).asFloat32() == 0.1f);
    CHECK(b.get(5).isString() && b.get(5).asString() == "42");

    // an undeclared port's elements go on as they came (`set pos 3 45.0`)
    yarp::os::Bottle n;
    ybgc::put(n, Element::ofInteger(3), Wire::Number);
    ybgc::put(n, Element::ofReal(45.0), Wire::Number);
    ybgc::put(n, Element::ofInteger(std::int64_t{1} << 40), Wire::Number);
    CHECK(n.size() == 3 && n.get(0).isInt32() && n.get(0).asInt32() == 3);
    CHECK(n.get(1).isFloat64() && n.get(1).asFloat64() == 45.0);
    CHECK(n.get(2).isInt64() && n.get(2).asInt64() == (std::int64_t{1} << 40));

    yarp::os::Bottle r;
    ybgc::putRange(r, reals({1.0, 2.0, 3.0, 4.0}), 1, 3, Wire::Float64);
    CHECK(r.size() == 2 && r.get(0).asFloat64() == 2.0 && r.get(1).asFloat64() == 3.0);
    yarp::os::Bottle end;
    ybgc::putRange(end, reals({1.0, 2.0}), 1, ybgc::kToEnd, Wire::Float64);
    CHECK(end.size() == 1);

    yarp::os::Bottle t;
    ybgc::putTime(t, 12'500'000'007, Wire::Int32, Wire::Int32);
    CHECK(t.size() == 1 && t.get(0).isList());
    const yarp::os::Bottle* time = t.get(0).asList();
    CHECK(time->size() == 2 && time->get(0).asInt32() == 12 && time->get(1).asInt32() == 500'000'007);
}

// A message holding an array of messages, serialized as ROS 1 does (little
// endian, a sequence with its length, a string with its length, a nested
// message or a time without): what the C++ module sends to a ROS 1 topic.
void testRos1Bytes()
{
    yarp::os::Bottle msg;
    yarp::os::Bottle& array = msg.addList();    // 's': a sequence of one element
    yarp::os::Bottle& element = array.addList();  // 'f': the element
    yarp::os::Bottle& header = element.addList();  // 'f'
    header.addInt32(7);
    ybgc::putTime(header, 1'000'000'002, Wire::Int32, Wire::Int32);  // 'f'
    header.addString("ab");
    element.addString("c");
    element.addInt8(-1);
    element.addFloat64(0.5);
    element.addFloat32(0.25f);
    element.addInt16(-2);
    element.addInt64(std::int64_t{1} << 40);
    msg.addList();  // 's': an empty sequence
    const unsigned char want[] = {
        1, 0, 0, 0,                       // one element
        7, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 'a', 'b',  // header
        1, 0, 0, 0, 'c', 0xff,
        0, 0, 0, 0, 0, 0, 0xe0, 0x3f,     // 0.5
        0, 0, 0x80, 0x3e,                 // 0.25f
        0xfe, 0xff,                       // -2
        0, 0, 0, 0, 0, 1, 0, 0,           // 2^40
        0, 0, 0, 0,                       // no element
    };
    std::string bytes;
    CHECK(ybgc::ros1Bytes(msg, "sfffs", bytes));
    CHECK(bytes == std::string(reinterpret_cast<const char*>(want), sizeof want));
    CHECK(!ybgc::ros1Bytes(msg, "sfff", bytes));    // a list with no letter left
    CHECK(!ybgc::ros1Bytes(msg, "sfffss", bytes));  // a letter with no list left
    CHECK(!ybgc::ros1Bytes(msg, "xfffs", bytes));
}

ybgc::InputSpec yarpInput(bool declared, std::vector<ybgc::Group> layout)
{
    return ybgc::InputSpec{0, 0, "/src:o", ybgc::InputKind::Yarp, 0.5, declared, std::move(layout), {}};
}

bool parse(const std::string& text, const ybgc::InputSpec& spec, bool dropNan, Mux& out, std::string& why)
{
    yarp::os::Bottle b;
    b.fromString(text);
    std::vector<const yarp::os::Value*> scratch;
    return ybgc::parseBottle(b, spec, dropNan, out, why, scratch);
}

void testParseBottle()
{
    Mux out;
    std::string why;
    const auto undeclared = yarpInput(false, {});
    CHECK(parse("1 2.5 -3", undeclared, false, out, why));
    // undeclared: each number as it came, an integer stays an integer
    CHECK(out.size() == 3 && out[0].kind == Element::Kind::Integer && out[0].integer == 1);
    CHECK(out[1].kind == Element::Kind::Real && out[1].real == 2.5 && out[2].integer == -3);
    CHECK(!parse("1 hello", undeclared, false, out, why));
    CHECK_EQ(why, "element 1 is a string, not a number");

    const auto mixed = yarpInput(true, {{"int32", 1}, {"float64", 1}, {"string", 1}, {"bool", 1}});
    CHECK(parse("7 2.5 \"x\" 1", mixed, false, out, why));
    CHECK(out.size() == 4 && out[0].integer == 7 && out[1].real == 2.5 && out[2].text == "x"
          && out[3].kind == Element::Kind::Boolean && out[3].integer == 1);
    CHECK(!parse("7 2.5 \"x\"", mixed, false, out, why));
    CHECK_EQ(why, "3 elements, expected 4");
    CHECK(!parse("1.5 2.5 \"x\" 1", mixed, false, out, why));
    CHECK_EQ(why, "element 0 is a float, expected int32");
    CHECK(!parse("7 2.5 3 1", mixed, false, out, why));
    CHECK_EQ(why, "element 2 is an integer, expected a string");
    CHECK(!parse("7 2.5 \"x\" 2", mixed, false, out, why));
    CHECK_EQ(why, "element 3 is an integer, expected a bool (0 or 1)");

    // NaN dropped only when told
    CHECK(parse("1.0 nan", undeclared, false, out, why) && std::isnan(out[1].real));
    CHECK(!parse("1.0 nan", undeclared, true, out, why));
    CHECK_EQ(why, "element 1 is NaN");

    // a float32 element: on YARP 4 it is what a YARP 3 producer's float64
    // reads as, so it is taken only where float32 is declared
    yarp::os::Bottle f32;
    f32.addFloat32(1.5f);
    std::vector<const yarp::os::Value*> scratch;
    const bool took = ybgc::parseBottle(f32, undeclared, false, out, why, scratch);
    CHECK(took == (YARP_VERSION_MAJOR < 4));
    if (!took) {
        CHECK(why.find("YARP 4 changed the Bottle tags") != std::string::npos);
    }
    CHECK(ybgc::parseBottle(f32, yarpInput(true, {{"float32", 1}}), false, out, why, scratch));
    CHECK(out.size() == 1 && out[0].real == 1.5);

    // a ROS 1 topic read as a Bottle: every leaf, or the fields named
    ybgc::InputSpec ros = yarpInput(false, {});
    ros.kind = ybgc::InputKind::Ros1;
    CHECK(parse("(1 2) 3.5 (4 (5 6))", ros, false, out, why) && out.size() == 6 && out[5].integer == 6);
    ros.fields = {{"y", {1}}, {"deep", {2, 1}}};
    CHECK(parse("(1 2) 3.5 (4 (5 6))", ros, false, out, why));
    CHECK(out.size() == 3 && out[0].real == 3.5 && out[1].integer == 5 && out[2].asReal() == 6.0);
    ros.fields = {{"missing", {9}}};
    CHECK(!parse("(1 2) 3.5", ros, false, out, why));
    CHECK_EQ(why, "the message has no field missing");
}

/// The values of a ROS 2 message checked as the Python node checks them
/// (ros2_io.message_values): the same conversions, the same reasons.
void testCheckValues()
{
    std::string why;
    ybgc::InputSpec spec = yarpInput(false, {});
    spec.kind = ybgc::InputKind::Ros2;
    // undeclared: numbers, each a float64
    Mux m{Element::ofInteger(3), Element::ofReal(2.5)};
    CHECK(ybgc::checkValues(m, spec, false, why));
    CHECK(m[0].kind == Element::Kind::Real && m[0].real == 3.0 && m[1].real == 2.5);
    m = {Element::ofReal(1.0), Element::ofBool(true)};
    CHECK(!ybgc::checkValues(m, spec, false, why));
    CHECK_EQ(why, "element 1 is not a number");
    // declared: the number of values and their kinds
    spec.declared = true;
    spec.layout = {{"float64", 1}, {"int32", 1}, {"bool", 2}};
    m = {Element::ofInteger(2), Element::ofInteger(-7), Element::ofBool(true), Element::ofInteger(0)};
    CHECK(ybgc::checkValues(m, spec, false, why));
    CHECK(m[0].kind == Element::Kind::Real && m[0].real == 2.0 && m[1].kind == Element::Kind::Integer);
    CHECK(m[2].kind == Element::Kind::Boolean && m[3].kind == Element::Kind::Boolean && m[3].integer == 0);
    m = {Element::ofReal(1.0)};
    CHECK(!ybgc::checkValues(m, spec, false, why));
    CHECK_EQ(why, "1 elements, expected 4");
    m = {Element::ofBool(true), Element::ofInteger(1), Element::ofBool(true), Element::ofBool(false)};
    CHECK(!ybgc::checkValues(m, spec, false, why));
    CHECK_EQ(why, "element 0 is not a number, expected float64");
    m = {Element::ofReal(1.0), Element::ofReal(1.0), Element::ofBool(true), Element::ofBool(false)};
    CHECK(!ybgc::checkValues(m, spec, false, why));
    CHECK_EQ(why, "element 1 is not an integer, expected int32");
    m = {Element::ofReal(1.0), Element::ofInteger(1), Element::ofInteger(2), Element::ofBool(false)};
    CHECK(!ybgc::checkValues(m, spec, false, why));
    CHECK_EQ(why, "element 2 is not a bool (0 or 1)");
    m = {Element::ofReal(std::nan("")), Element::ofInteger(1), Element::ofBool(true), Element::ofBool(false)};
    CHECK(ybgc::checkValues(m, spec, false, why));
    CHECK(!ybgc::checkValues(m, spec, true, why));
    CHECK_EQ(why, "element 0 is NaN");
}

/// A mux of rows: appended from an input, printed and written one list a row.
void testRows()
{
    ybgc::Latest in;
    in.rows = {reals({0.5, 1.0}), reals({1.25})};
    ybgc::Rows rows;
    ybgc::append(rows, in);
    CHECK(rows.size() == 2 && rows[1].size() == 1 && rows[1][0].real == 1.25);
    yarp::os::Bottle b;
    b.addString("plan");
    ybgc::putRows(b, rows, Wire::Float64);
    CHECK_EQ(b.toString(), "plan (0.5 1.0) (1.25)");
    CHECK(b.get(1).asList()->get(0).isFloat64());
}

void testAppendAndEnvelope()
{
    ybgc::Latest a;
    a.values = reals({1.0, 2.0});
    a.hasEnvelope = true;
    a.envelope = 3.25;
    ybgc::Latest b;
    b.values = reals({3.0});
    Mux m;
    ybgc::append(m, a);
    ybgc::append(m, b);
    CHECK(m.size() == 3 && m[2].real == 3.0);
    ybgc::Inputs inputs;
    inputs.add(a);
    inputs.add(b);
    ybgc::Context ctx;
    ctx.inputs = &inputs;
    ctx.wallNs = 99;
    CHECK(ctx.envelopeNs({0, 1}) == 3'250'000'000);
    CHECK(ctx.envelopeNs({1}) == 99);  // none of them has one: the wall clock
}

/// An envelope's text as a port carries it (yarp::os::Stamp::write: "%d
/// %.*g"), read as yarp::os::Stamp::read reads it.
void testStampTime()
{
    const auto time = [](const std::string& text, double& t) {
        return ybgc::stampTime(yarp::os::Bytes(const_cast<char*>(text.data()), text.size()), t);
    };
    double t = -1.0;
    CHECK(time("5 1234.5678", t) && t == 1234.5678);
    CHECK(time("30 1795938258.98688", t) && t == 1795938258.98688);
    CHECK(time("0 1700000000.25 extra", t) && t == 1700000000.25);
    t = -1.0;
    CHECK(!time("", t) && t == -1.0);      // no envelope
    CHECK(!time("-1 5.0", t) && t == -1.0);  // an invalid Stamp
    CHECK(!time("(1 2)", t) && !time("7", t) && !time("abc 1.0", t));  // another kind of envelope
    CHECK(!ybgc::stampTime(yarp::os::Bytes(nullptr, 0), t));
    // as Stamp::read's sscanf("%d %lg") reads any text
    for (const char* text : {"5 1234.5678", " 5  1e-3", "5.5 1.0", "5x 1.0", "5 x", "+3 -2.5", "2147483647 1.5",
                             "2147483648 1.5", "7 nan", "7 inf", "-0 3", "0x10 2", "12\t0.25\n", "1 0x1p-2"}) {
        int seq = -1;
        double expected = 0.0;
        const bool valid = std::sscanf(text, "%d %lg", &seq, &expected) == 2 && seq >= 0;
        double got = 0.0;
        const bool ok = time(text, got);
        check(ok == valid && (!ok || got == expected || (std::isnan(got) && std::isnan(expected))), "stampTime",
              __LINE__, text);
    }
}


// --- which Bottles a message uses, driven by hand ------------------------------

using Clock = ybgc::SteadyClock;

Clock::time_point at(double seconds)
{
    return Clock::time_point(std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds)));
}

/// A bridge's spec and inputs (one input a mux, undeclared), no ports.
struct Rig
{
    Rig(int muxes, bool triggerAll, bool hold, std::vector<int> needed, std::size_t queue = 64, double rate = 0.0)
    {
        static const char* names[] = {"a", "b", "c"};
        static const char* sources[] = {"/src/a:o", "/src/b:o", "/src/c:o"};
        spec.module = "test";
        spec.config = "test.ini";
        spec.defaultPrefix = "/test";
        for (int k = 0; k < muxes; ++k) {
            spec.muxes.push_back({names[k]});
            spec.inputs.push_back(ybgc::InputSpec{k, 0, sources[k], ybgc::InputKind::Yarp, 0.5, false, {}, {}});
        }
        spec.needed = std::move(needed);
        spec.output = {ybgc::OutputKind::Yarp, "/test/out:o", "", ""};
        spec.rate = rate;
        spec.triggerAll = triggerAll;
        spec.queue = queue;
        spec.hold = hold;
        spec.dropNan = false;
        std::vector<ybgc::InputState*> states;
        for (const auto& in : spec.inputs) {
            inputs.push_back(std::make_unique<ybgc::InputState>(in, in.timeout));
            states.push_back(inputs.back().get());
        }
        matcher = std::make_unique<ybgc::Matcher>(spec, states, rate <= 0);
    }

    /// A Bottle of one value arrives on input k.
    bool arrive(std::size_t k, double value, double when, bool hasEnvelope = false, double envelope = 0.0)
    {
        Mux values = reals({value});
        ++inputs[k]->received;
        return ybgc::accept(*inputs[k], values, hasEnvelope, envelope, at(when), spec.queue);
    }

    double used(std::size_t k) const { return matcher->latest()[k].values.at(0).real; }

    ybgc::BridgeSpec spec;
    std::vector<std::unique_ptr<ybgc::InputState>> inputs;
    std::unique_ptr<ybgc::Matcher> matcher;
};

/// The room of a Bottle's values goes back to its input once a newer Bottle
/// is used: the next Bottle is read into it, no allocation.
void testRoomOfValuesKept()
{
    Rig r(1, true, false, {});
    ybgc::InputState& in = *r.inputs[0];
    Mux scratch = reals({1.0, 2.0, 3.0});
    ybgc::accept(in, scratch, false, 0.0, at(1.0), r.spec.queue);
    r.matcher->take();
    scratch = reals({4.0, 5.0, 6.0});
    const Element* room = scratch.data();
    ybgc::accept(in, scratch, false, 0.0, at(1.1), r.spec.queue);
    r.matcher->take();  // the second Bottle is used: the first one's room is kept
    CHECK(in.latest.values.data() == room && in.latest.values.size() == 3 && in.latest.values[2].real == 6.0);
    Mux next = reals({7.0});
    ybgc::accept(in, next, false, 0.0, at(1.2), r.spec.queue);
    CHECK(next.capacity() >= 3);  // the room the input gives back, for the next Bottle
}

void testMatchingTriggerAllByEnvelope()
{
    Rig r(2, true, false, {});
    r.arrive(0, 1.0, 10.0, true, 1.0);
    r.arrive(0, 2.0, 10.1, true, 2.0);
    CHECK(!r.matcher->ready(at(10.15), true));  // b has delivered nothing
    r.arrive(1, 20.0, 10.2, true, 2.0);
    CHECK(r.matcher->ready(at(10.2), true));
    r.matcher->take();
    // matched to the newest of the oldest stamps (b's 2.0): a's 1.0 is unused
    CHECK(r.used(0) == 2.0 && r.used(1) == 20.0 && r.inputs[0]->unused == 1);
    CHECK(!r.matcher->ready(at(10.2), true));  // both queues empty again
}

void testMatchingByArrival()
{
    Rig r(2, true, false, {});
    r.arrive(0, 1.0, 1.00);
    r.arrive(0, 2.0, 1.50);
    r.arrive(1, 9.0, 1.45);
    CHECK(r.matcher->ready(at(1.5), true));
    r.matcher->take();
    CHECK(r.used(0) == 2.0 && r.used(1) == 9.0);  // 1.50 is nearer to 1.45 than 1.00
}

void testTriggerAnyAndSampledInputs()
{
    Rig any(2, false, false, {});
    any.arrive(0, 1.0, 1.0);
    CHECK(!any.matcher->ready(at(1.0), true));  // b is waiting (on_stale = skip)
    any.arrive(1, 5.0, 1.1);
    CHECK(any.matcher->ready(at(1.1), true));
    any.matcher->take();
    CHECK(any.used(0) == 1.0 && any.used(1) == 5.0);
    any.arrive(0, 2.0, 1.2);
    CHECK(any.matcher->ready(at(1.2), true));
    any.matcher->take();
    CHECK(any.used(0) == 2.0 && any.used(1) == 5.0);

    // only mux a needed: b is sampled (its newest), never waited for
    Rig some(2, true, false, {0});
    some.arrive(1, 7.0, 0.0);
    CHECK(!some.matcher->ready(at(0.0), true));
    some.arrive(1, 8.0, 0.05);
    some.arrive(0, 1.0, 0.1);
    CHECK(some.matcher->ready(at(0.1), true));
    some.matcher->take();
    CHECK(some.used(0) == 1.0 && some.used(1) == 8.0 && some.inputs[1]->unused == 1);
}

void testQueueBound()
{
    Rig r(2, true, false, {}, 3);
    for (int k = 0; k < 10; ++k) {
        r.arrive(0, k, k, true, k);
    }
    CHECK(r.inputs[0]->queue.size() == 3 && r.inputs[0]->queue.front().data.values[0].real == 7.0);
    CHECK(r.inputs[0]->received == 10 && r.inputs[0]->unused == 7);
    Rig one(1, true, false, {}, 1);
    one.arrive(0, 1.0, 0.0);
    one.arrive(0, 2.0, 0.1);
    CHECK(one.inputs[0]->queue.size() == 1 && one.inputs[0]->unused == 1);
}

void testFreshness()
{
    Rig r(1, true, false, {});
    CHECK(r.matcher->checkFreshness(at(0.0)) == Clock::time_point::max());  // waiting: no deadline
    CHECK(r.inputs[0]->state == ybgc::Freshness::Waiting && r.inputs[0]->reportedWaiting);
    CHECK(!r.arrive(0, 1.0, 1.0));  // was not fresh before
    CHECK(r.arrive(0, 1.5, 1.1));   // was
    const Clock::time_point deadline = r.matcher->checkFreshness(at(1.2));
    CHECK(deadline > at(1.5999) && deadline < at(1.6001));  // when it would go stale
    r.matcher->checkFreshness(at(1.7));
    r.matcher->checkFreshness(at(1.8));
    CHECK(r.inputs[0]->state == ybgc::Freshness::Stale && r.inputs[0]->stalePeriods == 1);
    CHECK(!r.matcher->ready(at(1.8), false));  // skip: a stale input holds the message back
    CHECK(!r.arrive(0, 2.0, 2.0));
    CHECK(r.inputs[0]->state == ybgc::Freshness::Fresh && r.matcher->ready(at(2.0), false));
}

void testPublishNewOnly()
{
    // publish = new at a fixed rate: a cycle publishes only when the trigger holds
    Rig r(2, false, false, {}, 64, 50.0);
    r.spec.newOnly = true;
    r.arrive(0, 1.0, 0.0);
    r.arrive(1, 2.0, 0.0);
    CHECK(r.matcher->ready(at(0.0), false));
    r.matcher->take();
    CHECK(!r.matcher->ready(at(0.02), false));  // nothing new: no message this cycle
    r.arrive(1, 3.0, 0.03);
    CHECK(r.matcher->ready(at(0.04), false));  // any: one new Bottle is enough
    r.matcher->take();
    CHECK(r.used(0) == 1.0 && r.used(1) == 3.0);
    r.spec.triggerAll = true;
    r.arrive(1, 4.0, 0.05);
    CHECK(!r.matcher->ready(at(0.06), false));  // all: a has nothing new
}

void testHoldAndFixedRate()
{
    Rig r(2, true, true, {}, 64, 100.0);
    CHECK(!r.matcher->ready(at(0.0), false));  // nothing delivered yet
    r.arrive(0, 1.0, 0.0);
    r.arrive(0, 2.0, 0.01);
    r.arrive(0, 3.0, 0.02);
    CHECK(!r.matcher->ready(at(0.02), false));  // b still waiting
    r.arrive(1, 9.0, 0.02);
    r.matcher->checkFreshness(at(5.0));  // both stale: hold publishes the last values
    CHECK(r.matcher->ready(at(5.0), false));
    r.matcher->take();
    CHECK(r.used(0) == 3.0 && r.used(1) == 9.0 && r.inputs[0]->unused == 2);  // the newest, the rest unused
}

}  // namespace

/// An undeclared port the message cuts (InputSpec::reads, W511): the first
/// Bottle wider than what the message reads is said, once; all are kept whole.
void testCutSaidOnce()
{
    ybgc::InputSpec spec = yarpInput(false, {});
    spec.reads = 3;
    ybgc::InputState in(spec, spec.timeout);
    const auto now = ybgc::SteadyClock::now();
    Mux three(3, Element::ofReal(1.0));
    ybgc::accept(in, three, false, 0.0, now, 8);
    CHECK(!in.reportedCut);  // exactly what the message reads
    Mux seven(7, Element::ofReal(2.0));
    ybgc::accept(in, seven, false, 0.0, now, 8);
    CHECK(in.reportedCut);
    CHECK(in.queue.size() == 2 && in.queue.back().data.values.size() == 7);
    CHECK(ybgc::cutText("/src:o", 7, 3)
          == "input /src:o: a Bottle of 7 values, of which the message reads the first 3; the other 4 are "
             "dropped (declare the port's elements in the config to check its width); said once");

    ybgc::InputSpec whole = yarpInput(false, {});  // no cut: reads -1
    ybgc::InputState all(whole, whole.timeout);
    Mux wide(9, Element::ofReal(3.0));
    ybgc::accept(all, wide, false, 0.0, now, 8);
    CHECK(whole.reads == -1 && !all.reportedCut);
}

int main()
{
    testReprFloat();
    testSecondsToNs();
    testElements();
    testConvert();
    testConvertGeometryAndEach();
    testPut();
    testRos1Bytes();
    testParseBottle();
    testCheckValues();
    testRows();
    testAppendAndEnvelope();
    testStampTime();
    testRoomOfValuesKept();
    testMatchingTriggerAllByEnvelope();
    testMatchingByArrival();
    testTriggerAnyAndSampledInputs();
    testQueueBound();
    testFreshness();
    testHoldAndFixedRate();
    testPublishNewOnly();
    testCutSaidOnce();
    std::printf("%d checks, %d failed (YARP %s)\n", gChecks, gFailures, YARP_VERSION);
    return gFailures;
}
