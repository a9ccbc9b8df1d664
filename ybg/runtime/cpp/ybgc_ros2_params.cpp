// The plain logic of the C++ runtime's ROS 2 side (ybgc_ros2.hpp), no rcl
// node: the ROS arguments of a command line and the options they give, the
// parameters of a node as rclcpp matches them, the QoS overrides, the
// module's options given as parameters, and the statuses /diagnostics
// publishes. ybgc_ros2_node.cpp opens the node with them, ybgc_ros2.cpp its
// publisher and subscriptions.
#include "ybgc_ros2.hpp"  // ybgc:runtime-import
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <initializer_list>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace ybgc {
namespace ros2 {

// --- the node's parameters and QoS -------------------------------------------------------

namespace {

/// Does `pattern` from `p` match `name` from `n` (`**` any run, `*` any run
/// without a `/`)?
bool globMatches(const std::string& pattern, std::size_t p, const std::string& name, std::size_t n)
{
    while (p < pattern.size()) {
        if (pattern[p] == '*') {
            const bool any = p + 1 < pattern.size() && pattern[p + 1] == '*';
            const std::size_t rest = p + (any ? 2 : 1);
            for (std::size_t k = n; k <= name.size(); ++k) {
                if (globMatches(pattern, rest, name, k)) {
                    return true;
                }
                if (k < name.size() && !any && name[k] == '/') {
                    return false;
                }
            }
            return false;
        }
        if (n >= name.size() || pattern[p] != name[n]) {
            return false;
        }
        ++p;
        ++n;
    }
    return n == name.size();
}

/// printf's text of one number (the Python node's % formats are C's).
std::string printed(const char* format, double x)
{
    char text[64];
    std::snprintf(text, sizeof text, format, x);
    return text;
}

/// A parameter's value as a number (a double, or an integer); false for another value.
bool asNumber(const rcl_variant_t& v, double& out)
{
    if (v.double_value != nullptr) {
        out = *v.double_value;
        return true;
    }
    if (v.integer_value != nullptr) {
        out = static_cast<double>(*v.integer_value);
        return true;
    }
    return false;
}

/// The text of a parameter's value, to say it.
std::string valueText(const rcl_variant_t& v)
{
    if (v.string_value != nullptr) {
        return std::string("'") + v.string_value + "'";
    }
    if (v.integer_value != nullptr) {
        return std::to_string(*v.integer_value);
    }
    if (v.double_value != nullptr) {
        return std::to_string(*v.double_value);
    }
    if (v.bool_value != nullptr) {
        return *v.bool_value ? "true" : "false";
    }
    return "an array";
}

}  // namespace

bool nodeMatches(const std::string& pattern, const std::string& fqn)
{
    const std::string full = !pattern.empty() && pattern[0] == '/' ? pattern : "/" + pattern;
    return globMatches(full, 0, fqn, 0);
}

const rcl_variant_t* parameter(const rcl_params_t* params, const std::string& fqn, const std::string& name)
{
    if (params == nullptr) {
        return nullptr;
    }
    const rcl_variant_t* found = nullptr;
    for (std::size_t k = 0; k < params->num_nodes; ++k) {
        if (params->node_names[k] == nullptr || !nodeMatches(params->node_names[k], fqn)) {
            continue;
        }
        const rcl_node_params_t& node = params->params[k];
        for (std::size_t j = 0; j < node.num_params; ++j) {
            if (node.parameter_names[j] != nullptr && name == node.parameter_names[j]) {
                found = &node.parameter_values[j];
            }
        }
    }
    return found;
}

bool overrideQos(const rcl_params_t* params, const std::string& fqn, const std::string& topic, const char* entity,
                 rmw_qos_profile_t& qos, std::string& error)
{
    const std::string prefix = "qos_overrides." + topic + "." + entity + ".";
    struct Word
    {
        const char* text;
        int value;
    };
    // one of the words a policy accepts, or the error that says them
    auto choose = [&](const char* policy, std::initializer_list<Word> words, int& out) {
        const rcl_variant_t* v = parameter(params, fqn, prefix + policy);
        if (v == nullptr) {
            return true;
        }
        std::string accepted;
        for (const Word& w : words) {
            if (v->string_value != nullptr && std::strcmp(v->string_value, w.text) == 0) {
                out = w.value;
                return true;
            }
            accepted += (accepted.empty() ? "" : ", ") + std::string(w.text);
        }
        error = prefix + policy + ": " + valueText(*v) + " is not one of " + accepted;
        return false;
    };
    int history = qos.history;
    int reliability = qos.reliability;
    int durability = qos.durability;
    if (!choose("history", {{"keep_last", RMW_QOS_POLICY_HISTORY_KEEP_LAST},
                            {"keep_all", RMW_QOS_POLICY_HISTORY_KEEP_ALL}}, history)
        || !choose("reliability", {{"reliable", RMW_QOS_POLICY_RELIABILITY_RELIABLE},
                                   {"best_effort", RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT}}, reliability)
        || !choose("durability", {{"volatile", RMW_QOS_POLICY_DURABILITY_VOLATILE},
                                  {"transient_local", RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL}}, durability)) {
        return false;
    }
    std::size_t depth = qos.depth;
    if (const rcl_variant_t* v = parameter(params, fqn, prefix + "depth")) {
        if (v->integer_value == nullptr || *v->integer_value < 0) {
            error = prefix + "depth: " + valueText(*v) + " is not an integer of at least 0";
            return false;
        }
        depth = static_cast<std::size_t>(*v->integer_value);
    }
    qos.history = static_cast<rmw_qos_history_policy_t>(history);
    qos.reliability = static_cast<rmw_qos_reliability_policy_t>(reliability);
    qos.durability = static_cast<rmw_qos_durability_policy_t>(durability);
    qos.depth = depth;
    return true;
}

std::string describeQos(const rmw_qos_profile_t& qos)
{
    std::string text = qos.reliability == RMW_QOS_POLICY_RELIABILITY_RELIABLE ? "reliable" : "best_effort";
    text += qos.durability == RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL ? ", transient_local" : ", volatile";
    text += qos.history == RMW_QOS_POLICY_HISTORY_KEEP_ALL ? ", keep_all" : ", depth " + std::to_string(qos.depth);
    return text;
}

bool diagnosticsOptions(const rcl_params_t* params, const std::string& fqn, bool& on, double& period,
                        std::string& error)
{
    if (const rcl_variant_t* v = parameter(params, fqn, "diagnostics")) {
        if (v->bool_value == nullptr) {
            error = "parameter diagnostics must be true or false, got " + valueText(*v);
            return false;
        }
        on = *v->bool_value;
    }
    if (const rcl_variant_t* v = parameter(params, fqn, "diagnostic_updater.period")) {
        double p = 0.0;
        if (!asNumber(*v, p)) {
            error = "parameter diagnostic_updater.period must be a number, got " + valueText(*v);
            return false;
        }
        if (!(p > 0)) {
            error = "parameter diagnostic_updater.period must be positive";
            return false;
        }
        period = p;
    }
    return true;
}

bool parameterOptions(const rcl_params_t* params, const std::string& fqn, std::vector<std::string>& options,
                      std::string& error)
{
    // each number with every digit: the option is parsed back
    if (const rcl_variant_t* v = parameter(params, fqn, "rate")) {
        double rate = 0.0;
        if (!asNumber(*v, rate)) {
            error = "parameter rate must be a number, got " + valueText(*v);
            return false;
        }
        if (!(rate >= 0) || !std::isfinite(rate)) {
            error = "parameter rate must be 0 (event-driven) or positive";
            return false;
        }
        options.push_back("--rate=" + printed("%.17g", rate));
    }
    if (const rcl_variant_t* v = parameter(params, fqn, "timeout")) {
        double timeout = 0.0;
        if (!asNumber(*v, timeout)) {
            error = "parameter timeout must be a number, got " + valueText(*v);
            return false;
        }
        if (!(timeout >= 0) || !std::isfinite(timeout)) {
            error = "parameter timeout must be positive (or 0: the config's)";
            return false;
        }
        if (timeout > 0) {
            options.push_back("--timeout=" + printed("%.17g", timeout));
        }
    }
    if (const rcl_variant_t* v = parameter(params, fqn, "prefix")) {
        if (v->string_value == nullptr || v->string_value[0] != '/') {
            error = "parameter prefix must be a string starting with /";
            return false;
        }
        options.push_back(std::string("--prefix=") + v->string_value);
    }
    if (const rcl_variant_t* v = parameter(params, fqn, "verbose")) {
        if (v->bool_value == nullptr) {
            error = "parameter verbose must be true or false";
            return false;
        }
        if (*v->bool_value) {
            options.push_back("--verbose");
        }
    }
    if (const rcl_variant_t* v = parameter(params, fqn, "accept")) {
        // `PORT=OTHER` (or `OTHER`) items: a list of strings, or one string of them separated by commas
        std::vector<std::string> items;
        if (v->string_value != nullptr) {
            const std::string text = v->string_value;
            for (std::size_t start = 0; start <= text.size();) {
                const std::size_t end = std::min(text.find(',', start), text.size());
                std::string item = text.substr(start, end - start);
                item.erase(0, item.find_first_not_of(" \t"));
                item.erase(item.find_last_not_of(" \t") + 1);
                if (!item.empty()) {
                    items.push_back(item);
                }
                start = end + 1;
            }
        } else if (v->string_array_value != nullptr) {
            for (std::size_t k = 0; k < v->string_array_value->size; ++k) {
                items.emplace_back(v->string_array_value->data[k]);
            }
        } else {
            error = "parameter accept must be a string or a list of strings, PORT=OTHER, got " + valueText(*v);
            return false;
        }
        for (const std::string& item : items) {
            options.push_back("--accept=" + item);
        }
    }
    return true;
}

// --- the command line ----------------------------------------------------------------------

}  // namespace ros2

RosCommandLine::RosCommandLine(int argc, char* argv[], const char* module, const char* node, bool stream)
{
    if (Host::current() == nullptr) {
        gModule = module;
    }
    rosArgs = takeRosArgs(argc, argv);
    std::vector<std::string> options;
    status = ros2::checkRosArgs(rosArgs, node, &options);
    if (!stream) {
        // the parameters a bridge of commands takes (prefix, verbose)
        options.erase(std::remove_if(options.begin(), options.end(), [](const std::string& option) {
                          return option.rfind("--prefix=", 0) != 0 && option != "--verbose";
                      }), options.end());
    }
    line_ = std::make_unique<CommandLine>(argc, argv, options);
}

namespace ros2 {

// --- /diagnostics ------------------------------------------------------------------------

namespace {

/// diagnostic_updater's FrequencyStatus tolerance: below (1 - it) x the configured rate is a warning
constexpr double kRateTolerance = 0.1;

/// The key-values of the incompatible peers of its ROS 2 `kind` of `topic`,
/// appended to `values` when it has one (as the Python node's event_values).
void addEvents(std::vector<std::pair<std::string, std::string>>& values, const Totals& totals, const char* kind,
               const std::string& topic)
{
    for (const Totals::Ros2Endpoint& e : totals.ros2) {
        if (e.kind == kind && e.topic == topic) {
            values.emplace_back("incompatible QoS", std::to_string(e.qos));
            values.emplace_back("incompatible type", std::to_string(e.type));
            return;
        }
    }
}

}  // namespace

std::vector<Status> statuses(const Totals& totals, const std::string& node, double achieved)
{
    std::vector<Status> out;
    for (const Totals::PerInput& in : totals.inputs) {
        Status s;
        s.name = node + ": input " + in.source;
        if (in.state == Freshness::Waiting) {
            s.level = Status::Error;
            s.message = "no data received yet";
        } else if (in.state == Freshness::Stale) {
            s.level = Status::Warn;
            s.message = "stale: no data for " + printed("%.1f", in.age) + " s";
        } else {
            s.message = "fresh";
        }
        s.values = {{"received", std::to_string(in.received)},
                    {"dropped", std::to_string(in.dropped)},
                    {"stale periods", std::to_string(in.stale)},
                    {"unused", std::to_string(in.unused)},
                    {"refused", std::to_string(in.refused)},
                    {"age (s)", in.age < 0 ? "" : printed("%.3f", in.age)},
                    {"timeout (s)", printed("%g", in.timeout)}};
        addEvents(s.values, totals, "subscription", in.source);
        out.push_back(std::move(s));
    }
    Status s;
    s.name = node + ": output " + totals.output;
    if (totals.rate <= 0) {
        s.message = "event-driven: " + printed("%.2f", achieved) + " Hz";
    } else if (achieved < totals.rate * (1.0 - kRateTolerance)) {
        s.level = Status::Warn;
        s.message = "rate too low: " + printed("%.2f", achieved) + " Hz of " + printed("%g", totals.rate) + " Hz";
    } else {
        s.message = printed("%.2f", achieved) + " Hz of " + printed("%g", totals.rate) + " Hz";
    }
    s.values = {{"published", std::to_string(totals.published)},
                {"rate achieved (Hz)", printed("%.3f", achieved)},
                {"rate configured (Hz)", totals.rate <= 0 ? "event-driven" : printed("%g", totals.rate)},
                {"skipped cycles", std::to_string(totals.skipped)},
                {"build failures", std::to_string(totals.failures)},
                {"missed by readers", std::to_string(totals.missed)}};
    addEvents(s.values, totals, "publisher", totals.output);
    out.push_back(std::move(s));
    return out;
}

double RateWindow::add(double seconds, std::uint64_t published)
{
    samples_.emplace_back(seconds, published);
    while (samples_.size() > window_ + 1) {
        samples_.pop_front();
    }
    const auto& [t0, n0] = samples_.front();
    const auto& [t1, n1] = samples_.back();
    return t1 > t0 ? static_cast<double>(n1 - n0) / (t1 - t0) : 0.0;
}

}  // namespace ros2
}  // namespace ybgc
