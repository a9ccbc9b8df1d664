// The incompatible and matched peers of the C++ runtime's ROS 2 publishers
// and subscriptions (ybgc_ros2.hpp, PeerEvents): rcl events taken by their
// node's thread, counted, and said once in the Python node's words, with
// the peer's QoS or type hash from the ROS graph.
#include "ybgc_ros2.hpp"  // ybgc:runtime-import

#include <rcl/error_handling.h>
#include <rcl/event.h>
#include <rcl/graph.h>
#include <rmw/qos_string_conversions.h>
#include <rmw/topic_endpoint_info_array.h>
#include <rosidl_runtime_c/type_hash.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <initializer_list>
#include <memory>
#include <string>
#include <utility>

namespace ybgc {
namespace ros2 {

// --- incompatible peers ----------------------------------------------------------------

namespace {

/// What the Python node's words say of a policy's value (rmw's names).
std::string policyText(const char* name)
{
    return name != nullptr ? name : "unknown";
}

/// A QoS's reliability and durability, as the Python node says them.
std::string qosWords(const rmw_qos_profile_t& qos)
{
    return policyText(rmw_qos_reliability_policy_to_str(qos.reliability)) + ", "
        + policyText(rmw_qos_durability_policy_to_str(qos.durability));
}

/// Whether a publisher of QoS `pub` gives nothing to a subscription of QoS
/// `sub` by their reliability or durability.
bool conflicts(const rmw_qos_profile_t& pub, const rmw_qos_profile_t& sub)
{
    return (pub.reliability == RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT
            && sub.reliability == RMW_QOS_POLICY_RELIABILITY_RELIABLE)
        || (pub.durability == RMW_QOS_POLICY_DURABILITY_VOLATILE
            && sub.durability == RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL);
}

/// The endpoints of the graph on `topic`: its publishers or its subscriptions.
class Endpoints
{
public:
    Endpoints(const rcl_node_t* node, const char* topic, bool publishers)
    {
        const rcl_ret_t ret = publishers
            ? rcl_get_publishers_info_by_topic(node, &allocator_, topic, false, &array_)
            : rcl_get_subscriptions_info_by_topic(node, &allocator_, topic, false, &array_);
        if (ret != RCL_RET_OK) {
            rcl_reset_error();
        }
    }
    ~Endpoints() { finished(rmw_topic_endpoint_info_array_fini(&array_, &allocator_)); }
    Endpoints(const Endpoints&) = delete;
    Endpoints& operator=(const Endpoints&) = delete;
    const rmw_topic_endpoint_info_t* begin() const { return array_.info_array; }
    const rmw_topic_endpoint_info_t* end() const { return array_.info_array + (array_.info_array ? array_.size : 0); }

private:
    rcutils_allocator_t allocator_ = rcutils_get_default_allocator();
    rmw_topic_endpoint_info_array_t array_ = rmw_get_zero_initialized_topic_endpoint_info_array();
};

/// A type hash as REP-2011 writes it (RIHS01_...).
std::string hashText(const rosidl_type_hash_t& hash)
{
    char* text = nullptr;
    const rcutils_allocator_t allocator = rcutils_get_default_allocator();
    if (rosidl_stringify_type_hash(&hash, allocator, &text) != RCUTILS_RET_OK || text == nullptr) {
        rcutils_reset_error();
        return "unknown";
    }
    std::string out = text;
    allocator.deallocate(text, allocator.state);
    return out;
}

/// What the Python node says (core.py; ybg/lower/ros2_events.py holds both
/// to its texts): the first peer of an incompatible QoS, of another
/// definition of the type; their {names} filled by filled().
const char* const kIncompatibleQosText =
    "ROS 2 {kind} {topic}: a {peer} of an incompatible QoS ({policy}; the {peer}'s: {theirs}; this {kind}'s: "
    "{ours}): no messages between them; further incompatible QoS events of it are only counted";
/// What a publisher says each time its matched subscriptions change ({s}: ""
/// for one, "s" otherwise), as the Python node.
const char* const kSubscribersText = "{topic}: {n} subscriber{s}";
/// ... and a subscription each time its matched publishers change.
const char* const kPublishersText = "{topic}: {n} publisher{s}";
const char* const kIncompatibleTypeText =
    "ROS 2 {kind} {topic}: a {peer} of another definition of {type} (its type hash {theirs}; this {kind}'s: "
    "{ours}): no messages between them; further incompatible type events of it are only counted";

/// `text` with each {name} of `values` replaced by its value (as Python's str.format).
std::string filled(const char* text, std::initializer_list<std::pair<const char*, std::string>> values)
{
    std::string out = text;
    for (const auto& [name, value] : values) {
        const std::string key = std::string("{") + name + "}";
        for (std::size_t at = out.find(key); at != std::string::npos; at = out.find(key, at + value.size())) {
            out.replace(at, key.size(), value);
        }
    }
    return out;
}

/// A count of events from the middleware's `total` (its lifetime count),
/// when `change` says some came; true for the first.
bool counted(std::atomic<std::uint64_t>& n, std::int32_t total, std::int32_t change)
{
    const std::uint64_t before = n.load();
    if (change <= 0 && total <= 0) {
        return false;
    }
    if (change <= 0 && static_cast<std::uint64_t>(total) <= before) {
        return false;
    }
    n = std::max<std::uint64_t>(static_cast<std::uint64_t>(std::max(total, 0)), before + 1);
    return before == 0;
}

}  // namespace

struct PeerEvents::Rcl
{
    Node* node = nullptr;
    const rcl_publisher_t* publisher = nullptr;
    const rcl_subscription_t* subscription = nullptr;
    rcl_event_t qosEvent = rcl_get_zero_initialized_event();
    rcl_event_t typeEvent = rcl_get_zero_initialized_event();
    rcl_event_t matchedEvent = rcl_get_zero_initialized_event();
    bool qosOk = false;
    bool typeOk = false;
    bool matchedOk = false;
    std::atomic<std::uint64_t> qos{0};
    std::atomic<std::uint64_t> type{0};
};

PeerEvents::PeerEvents(const char* kind, std::string topic, std::string typeName) :
        kind_(kind), topic_(std::move(topic)), typeName_(std::move(typeName)), rcl_(std::make_unique<Rcl>())
{
}

PeerEvents::~PeerEvents()
{
    stop();
}

void PeerEvents::watch(Node& node, const rcl_publisher_t* publisher)
{
    Rcl& r = *rcl_;
    r.publisher = publisher;
    // an event kind the rmw does not support (RCL_RET_UNSUPPORTED) is left out
    r.qosOk = rcl_publisher_event_init(&r.qosEvent, publisher, RCL_PUBLISHER_OFFERED_INCOMPATIBLE_QOS)
        == RCL_RET_OK;
    r.typeOk = rcl_publisher_event_init(&r.typeEvent, publisher, RCL_PUBLISHER_INCOMPATIBLE_TYPE) == RCL_RET_OK;
    r.matchedOk = rcl_publisher_event_init(&r.matchedEvent, publisher, RCL_PUBLISHER_MATCHED) == RCL_RET_OK;
    init(node);
}

void PeerEvents::watch(Node& node, const rcl_subscription_t* subscription)
{
    Rcl& r = *rcl_;
    r.subscription = subscription;
    r.qosOk = rcl_subscription_event_init(&r.qosEvent, subscription, RCL_SUBSCRIPTION_REQUESTED_INCOMPATIBLE_QOS)
        == RCL_RET_OK;
    r.typeOk = rcl_subscription_event_init(&r.typeEvent, subscription, RCL_SUBSCRIPTION_INCOMPATIBLE_TYPE)
        == RCL_RET_OK;
    r.matchedOk = rcl_subscription_event_init(&r.matchedEvent, subscription, RCL_SUBSCRIPTION_MATCHED)
        == RCL_RET_OK;
    init(node);
}

void PeerEvents::init(Node& node)
{
    Rcl& r = *rcl_;
    rcl_reset_error();
    r.node = &node;
    if (r.qosOk || r.typeOk || r.matchedOk) {
        node.watch(this);
    }
}

void PeerEvents::stop()
{
    Rcl& r = *rcl_;
    if (r.node != nullptr) {
        r.node->unwatch(this);
        r.node = nullptr;
    }
    if (r.qosOk) {
        finished(rcl_event_fini(&r.qosEvent));
        r.qosOk = false;
    }
    if (r.typeOk) {
        finished(rcl_event_fini(&r.typeEvent));
        r.typeOk = false;
    }
    if (r.matchedOk) {
        finished(rcl_event_fini(&r.matchedEvent));
        r.matchedOk = false;
    }
}

void PeerEvents::take()
{
    Rcl& r = *rcl_;
    if (r.qosOk) {
        rmw_qos_incompatible_event_status_t status{};
        if (rcl_take_event(&r.qosEvent, &status) == RCL_RET_OK) {
            if (counted(r.qos, status.total_count, status.total_count_change)) {
                say(qosText(status.last_policy_kind));
            }
        } else {
            rcl_reset_error();
        }
    }
    if (r.typeOk) {
        rmw_incompatible_type_status_t status{};
        if (rcl_take_event(&r.typeEvent, &status) == RCL_RET_OK) {
            if (counted(r.type, status.total_count, status.total_count_change)) {
                say(typeText());
            }
        } else {
            rcl_reset_error();
        }
    }
    if (r.matchedOk) {
        rmw_matched_status_t status{};
        if (rcl_take_event(&r.matchedEvent, &status) == RCL_RET_OK) {
            if (status.current_count_change != 0) {
                const std::size_t n = status.current_count;
                say(filled(r.publisher != nullptr ? kSubscribersText : kPublishersText,
                           {{"topic", topic_}, {"n", std::to_string(n)}, {"s", n == 1 ? "" : "s"}}));
            }
        } else {
            rcl_reset_error();
        }
    }
}

std::string PeerEvents::qosText(int policy)
{
    Rcl& r = *rcl_;
    const bool publishes = r.publisher != nullptr;
    const rmw_qos_profile_t* ours = publishes ? rcl_publisher_get_actual_qos(r.publisher)
                                              : rcl_subscription_get_actual_qos(r.subscription);
    const char* topic = publishes ? rcl_publisher_get_topic_name(r.publisher)
                                  : rcl_subscription_get_topic_name(r.subscription);
    std::string theirs = "unknown (not in the graph yet)";
    if (ours != nullptr && topic != nullptr) {
        Endpoints peers(r.node->node(), topic, !publishes);
        const rmw_topic_endpoint_info_t* pick = nullptr;
        for (const rmw_topic_endpoint_info_t& e : peers) {
            if (publishes ? conflicts(*ours, e.qos_profile) : conflicts(e.qos_profile, *ours)) {
                pick = &e;
                break;
            }
        }
        if (pick == nullptr && peers.begin() != peers.end()) {
            pick = peers.begin();
        }
        if (pick != nullptr) {
            theirs = qosWords(pick->qos_profile);
        }
    }
    const char* name = rmw_qos_policy_kind_to_str(static_cast<rmw_qos_policy_kind_t>(policy));
    return filled(kIncompatibleQosText, {{"kind", kind_}, {"topic", topic_},
                                         {"peer", publishes ? "subscription" : "publisher"},
                                         {"policy", name != nullptr ? name : "policy " + std::to_string(policy)},
                                         {"theirs", theirs}, {"ours", ours != nullptr ? qosWords(*ours) : "unknown"}});
}

std::string PeerEvents::typeText()
{
    Rcl& r = *rcl_;
    const bool publishes = r.publisher != nullptr;
    const char* topic = publishes ? rcl_publisher_get_topic_name(r.publisher)
                                  : rcl_subscription_get_topic_name(r.subscription);
    std::string theirs = "unknown";
    std::string ours = "unknown";
    if (topic != nullptr) {
        const rcl_node_t* node = r.node->node();
        Endpoints own(node, topic, publishes);
        for (const rmw_topic_endpoint_info_t& e : own) {
            if (e.node_name != nullptr && e.node_namespace != nullptr
                && std::strcmp(e.node_name, rcl_node_get_name(node)) == 0
                && std::strcmp(e.node_namespace, rcl_node_get_namespace(node)) == 0) {
                ours = hashText(e.topic_type_hash);
                break;
            }
        }
        Endpoints peers(node, topic, !publishes);
        for (const rmw_topic_endpoint_info_t& e : peers) {
            const std::string hash = hashText(e.topic_type_hash);
            if (hash != ours) {
                theirs = hash;
                break;
            }
        }
    }
    return filled(kIncompatibleTypeText, {{"kind", kind_}, {"topic", topic_},
                                          {"peer", publishes ? "subscription" : "publisher"}, {"type", typeName_},
                                          {"theirs", theirs}, {"ours", ours}});
}

Totals::Ros2Endpoint PeerEvents::counts() const
{
    return {kind_, topic_, rcl_->qos.load(), rcl_->type.load()};
}

}  // namespace ros2
}  // namespace ybgc
