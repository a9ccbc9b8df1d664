// A driver of the C++ runtime's commands (ybgc_services.hpp) without any
// middleware: each line of stdin is one case, tab-separated, and its result
// is one line of stdout; tests/test_services_cpp_unit.py gives the same cases
// to the Python runtime (ybg/runtime/services.py) and compares, line by line.
//
//   elements BOTTLE START TYPES|- CONVERTERS WORDS QUERIES
//       the elements of BOTTLE from START, declared TYPES (space-separated;
//       - undeclared), converted by CONVERTERS (;-separated name,scale,offset,
//       to_float,start,stop|-), TRUE WORDS (space-separated): "ok" or
//       "unfit:WHY", then a result for each query (space-separated): text,
//       real:K, integer:K, word:K, boolean:K, int8:K, float32:K (element K
//       into such a field), reals:START:STOP|-:BOUND (into a float64[]
//       sequence), fixed3:START (into a float64[3]); a value or "unfit:WHY"
//   put WIRE CTYPE VALUE          the Bottle of put(): its text and its item's tag
//   puteachconv CTYPE VALUES SCALE OFFSET   putEachConverted of a sequence (,-separated VALUES)
//   first BOTTLE                  firstWord
//   totals NAME CALLS ANSWERED TIMED_OUT NO_SERVER UNFIT   totalsLine, then addStats' text
//   reason TEMPLATE REPLY WHY     reasonText
//   status NAME TIMEOUT CALLS ANSWERED TIMED_OUT NO_SERVER UNFIT LAST_FAILED LAST
//                                 status() of node `node`: level, name, message, key=value;...
#include "ybgc_services.hpp"

#include <rosidl_runtime_c/primitives_sequence_functions.h>

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <yarp/os/Bottle.h>

using ybgc::services::Elements;

namespace {

std::vector<std::string> split(const std::string& text, char sep)
{
    std::vector<std::string> out;
    std::string item;
    std::istringstream in(text);
    while (std::getline(in, item, sep)) {
        out.push_back(item);
    }
    if (!text.empty() && text.back() == sep) {
        out.emplace_back();
    }
    return out;
}

std::string unfit(const std::string& why)
{
    return "unfit:" + why;
}

std::string query(const Elements& e, const std::string& q)
{
    const std::vector<std::string> parts = split(q, ':');
    const std::string& op = parts[0];
    std::string why;
    const auto k = [&parts](std::size_t i) { return static_cast<std::size_t>(std::stoul(parts.at(i))); };
    if (op == "text") {
        return e.text();
    }
    if (op == "real") {
        double x = 0;
        return e.real(k(1), x, why) ? ybgc::reprFloat(x) : unfit(why);
    }
    if (op == "integer") {
        std::int64_t x = 0;
        return e.integer(k(1), x, why) ? std::to_string(x) : unfit(why);
    }
    if (op == "word") {
        std::string x;
        return e.word(k(1), x, why) ? x : unfit(why);
    }
    if (op == "boolean") {
        bool x = false;
        return e.boolean(k(1), x, why) ? (x ? "True" : "False") : unfit(why);
    }
    if (op == "int8") {
        std::int8_t x = 0;
        return e.set(x, k(1), why) ? std::to_string(x) : unfit(why);
    }
    if (op == "float32") {
        float x = 0;
        return e.set(x, k(1), why) ? ybgc::reprFloat(static_cast<double>(x)) : unfit(why);
    }
    if (op == "reals") {
        rosidl_runtime_c__double__Sequence seq;
        rosidl_runtime_c__double__Sequence__init(&seq, 0);
        const std::size_t stop = parts.at(2) == "-" ? ybgc::kToEnd : k(2);
        std::string out;
        if (e.setRange(seq, k(1), stop, k(3), "f", why)) {
            for (std::size_t i = 0; i < seq.size; ++i) {
                out += (i > 0 ? "," : "") + ybgc::reprFloat(seq.data[i]);
            }
        } else {
            out = unfit(why);
        }
        rosidl_runtime_c__double__Sequence__fini(&seq);
        return out;
    }
    if (op == "fixed3") {
        double a[3] = {0, 0, 0};
        if (!e.setRange(a, k(1), ybgc::kToEnd, 0, "f", why)) {
            return unfit(why);
        }
        return ybgc::reprFloat(a[0]) + "," + ybgc::reprFloat(a[1]) + "," + ybgc::reprFloat(a[2]);
    }
    return "unknown query " + q;
}

std::string elements(const std::vector<std::string>& f)
{
    yarp::os::Bottle b;
    b.fromString(f.at(1));
    const std::size_t start = std::stoul(f.at(2));
    const bool declared = f.at(3) != "-";
    std::vector<std::string> typeNames = declared ? split(f.at(3), ' ') : std::vector<std::string>();
    std::vector<const char*> types;
    for (const std::string& t : typeNames) {
        types.push_back(t.c_str());
    }
    std::vector<std::string> convNames;
    std::vector<ybgc::services::Converter> converters;
    const std::vector<std::string> items = f.at(4).empty() ? std::vector<std::string>() : split(f.at(4), ';');
    convNames.reserve(items.size());
    for (const std::string& item : items) {
        const std::vector<std::string> c = split(item, ',');
        convNames.push_back(c.at(0));
        converters.push_back({convNames.back().c_str(), std::stod(c.at(1)), std::stod(c.at(2)), c.at(3) == "1",
                              std::stoul(c.at(4)), c.at(5) == "-" ? ybgc::kToEnd : std::stoul(c.at(5))});
    }
    const std::vector<std::string> wordNames = split(f.at(5), ' ');
    std::vector<const char*> words;
    for (const std::string& w : wordNames) {
        words.push_back(w.c_str());
    }
    Elements e(b, start, words);
    std::string why;
    if (!e.check(declared, types, converters, why)) {
        return unfit(why);
    }
    std::string out = "ok";
    for (const std::string& q : split(f.at(6), ' ')) {
        if (!q.empty()) {
            out += "\t" + query(e, q);
        }
    }
    return out;
}

ybgc::Wire wireOf(const std::string& w)
{
    return w == "int32" ? ybgc::Wire::Int32 : w == "int64" ? ybgc::Wire::Int64
        : w == "float64" ? ybgc::Wire::Float64 : ybgc::Wire::String;
}

std::string tag(const yarp::os::Value& v)
{
    return v.isInt32() ? "int32" : v.isInt64() ? "int64" : v.isFloat64() ? "float64" : v.isString() ? "string" : "?";
}

template <class T>
T parse(const std::string& text)
{
    if constexpr (std::is_floating_point_v<T>) {
        return static_cast<T>(std::strtod(text.c_str(), nullptr));
    } else if constexpr (std::is_signed_v<T>) {
        return static_cast<T>(std::strtoll(text.c_str(), nullptr, 10));
    } else {
        return static_cast<T>(std::strtoull(text.c_str(), nullptr, 10));
    }
}

template <class T>
std::string put(const std::string& wire, const std::string& value)
{
    yarp::os::Bottle b;
    ybgc::services::put(b, parse<T>(value), wireOf(wire));
    return b.toString() + "\t" + tag(b.get(0));
}

std::string put(const std::vector<std::string>& f)
{
    const std::string& t = f.at(2);
    const std::string& w = f.at(1);
    const std::string& v = f.at(3);
    if (t == "int8") return put<std::int8_t>(w, v);
    if (t == "uint8") return put<std::uint8_t>(w, v);
    if (t == "int16") return put<std::int16_t>(w, v);
    if (t == "uint16") return put<std::uint16_t>(w, v);
    if (t == "int32") return put<std::int32_t>(w, v);
    if (t == "uint32") return put<std::uint32_t>(w, v);
    if (t == "int64") return put<std::int64_t>(w, v);
    if (t == "uint64") return put<std::uint64_t>(w, v);
    if (t == "float32") return put<float>(w, v);
    if (t == "float64") return put<double>(w, v);
    if (t == "bool") return put<bool>(w, v);
    if (t == "string") {
        rosidl_runtime_c__String s;
        rosidl_runtime_c__String__init(&s);
        ybgc::ros2::setString(s, v);
        yarp::os::Bottle b;
        ybgc::services::put(b, s, wireOf(w));
        rosidl_runtime_c__String__fini(&s);
        return b.toString() + "\t" + tag(b.get(0));
    }
    return "unknown type " + t;
}

std::string putEachConverted(const std::vector<std::string>& f)
{
    yarp::os::Bottle b;
    const std::vector<std::string> values = split(f.at(2), ',');
    const double scale = std::stod(f.at(3));
    const double offset = std::stod(f.at(4));
    if (f.at(1) == "int32") {
        rosidl_runtime_c__int32__Sequence seq;
        rosidl_runtime_c__int32__Sequence__init(&seq, values.size());
        for (std::size_t i = 0; i < values.size(); ++i) {
            seq.data[i] = parse<std::int32_t>(values[i]);
        }
        ybgc::services::putEachConverted(b, seq, scale, offset);
        rosidl_runtime_c__int32__Sequence__fini(&seq);
    } else {
        rosidl_runtime_c__double__Sequence seq;
        rosidl_runtime_c__double__Sequence__init(&seq, values.size());
        for (std::size_t i = 0; i < values.size(); ++i) {
            seq.data[i] = parse<double>(values[i]);
        }
        ybgc::services::putEachConverted(b, seq, scale, offset);
        rosidl_runtime_c__double__Sequence__fini(&seq);
    }
    return b.toString();
}

}  // namespace

int main()
{
    std::string line;
    while (std::getline(std::cin, line)) {
        const std::vector<std::string> f = split(line, '\t');
        std::string out;
        if (f.empty()) {
            out = "";
        } else if (f[0] == "elements") {
            out = elements(f);
        } else if (f[0] == "put") {
            out = put(f);
        } else if (f[0] == "puteachconv") {
            out = putEachConverted(f);
        } else if (f[0] == "first") {
            yarp::os::Bottle b;
            b.fromString(f.at(1));
            out = ybgc::services::firstWord(b);
        } else if (f[0] == "totals") {
            ybgc::services::Counts c;
            c.calls = std::stoull(f.at(2));
            c.answered = std::stoull(f.at(3));
            c.timedOut = std::stoull(f.at(4));
            c.noServer = std::stoull(f.at(5));
            c.unfit = std::stoull(f.at(6));
            yarp::os::Bottle b;
            ybgc::services::addStats(b, f.at(1).c_str(), c);
            out = ybgc::services::totalsLine(f.at(1).c_str(), c) + "\t" + b.toString();
        } else if (f[0] == "status") {
            ybgc::services::Spec spec{};
            spec.name = f.at(1).c_str();
            spec.timeout = std::stod(f.at(2));
            ybgc::services::Counts c;
            c.calls = std::stoull(f.at(3));
            c.answered = std::stoull(f.at(4));
            c.timedOut = std::stoull(f.at(5));
            c.noServer = std::stoull(f.at(6));
            c.unfit = std::stoull(f.at(7));
            c.lastFailed = f.at(8) == "1";
            c.last = f.at(9);
            const ybgc::ros2::Status st = ybgc::services::status(spec, c, "node");
            out = std::to_string(st.level) + "\t" + st.name + "\t" + st.message + "\t";
            for (std::size_t k = 0; k < st.values.size(); ++k) {
                out += (k > 0 ? ";" : "") + st.values[k].first + "=" + st.values[k].second;
            }
        } else if (f[0] == "reason") {
            out = ybgc::services::reasonText(f.at(1), f.at(2), f.at(3));
        } else {
            out = "unknown case " + f[0];
        }
        std::cout << out << "\n";
    }
    return 0;
}
