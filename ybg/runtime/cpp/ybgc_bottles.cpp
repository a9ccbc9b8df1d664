// The C++ runtime's Bottles (ybgc_runtime.hpp): the output Bottle written
// element by element with its tags, input Bottles (and the values read from
// ROS 2 topics) checked against an input's layout, a Bottle serialized for
// ROS 1, and the YARP output that writes each message on its port.
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <yarp/conf/version.h>
#include <yarp/os/Bottle.h>
#include <yarp/os/BufferedPort.h>
#include <yarp/os/Contact.h>
#include <yarp/os/Type.h>
#include <yarp/os/Value.h>

namespace ybgc {

// --- writing Bottles ------------------------------------------------------------

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

/// Appends each row of a mux of rows as a nested list.
void putRows(yarp::os::Bottle& b, const Rows& rows, Wire wire)
{
    for (const Mux& row : rows) {
        putRange(b.addList(), row, 0, kToEnd, wire);
    }
}

/// Appends a time, `ns` nanoseconds since the epoch, as a nested list (sec nsec).
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

// --- reading and checking input Bottles -------------------------------------------

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
        if (writePatiently(port_, patient_)) {
            ++missed_;
        }
        return true;
    }

    std::uint64_t missed() const override { return missed_; }

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
    std::atomic<std::uint64_t> missed_{0};  // messages a busy reader missed
};

std::unique_ptr<MessageSink> yarpOutput(const OutputSpec& spec, MakeMessage make)
{
    return std::make_unique<Output>(spec, std::move(make));
}

}  // namespace ybgc
