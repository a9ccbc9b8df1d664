// The C++ runtime's inputs (ybgc_runtime.hpp, ybgc_internal.hpp): what is
// kept of each input (its queue, its freshness, its totals), which Bottles a
// message uses (Matcher), and the input ports, whose callbacks check each
// Bottle and the port that sent it.
#include "ybgc_internal.hpp"  // ybgc:runtime-import

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <yarp/os/Bottle.h>
#include <yarp/os/Contact.h>
#include <yarp/os/ContactStyle.h>
#include <yarp/os/Network.h>
#include <yarp/os/PortInfo.h>
#include <yarp/os/PortReport.h>

namespace ybgc {

void append(Mux& mux, const Latest& input)
{
    mux.insert(mux.end(), input.values.begin(), input.values.end());
}

void append(Rows& rows, const Latest& input)
{
    rows.insert(rows.end(), input.rows.begin(), input.rows.end());
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
    values.swap(in.spare);  // the next Bottle is read into the room of one that was used
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

void refuseFrame(InputState& in, const std::string& why)
{
    ++in.refused;
    if (in.unfit++ == 0) {
        in.unfitReason = why;
        say("input " + std::string(in.spec.source) + ": refused a frame (" + why
            + "); further frames refused are only counted");
    }
}

std::string refusedText(const InputState& in)
{
    const std::uint64_t refused = in.refused;
    const std::uint64_t unfit = in.unfit;
    if (refused == 0) {
        return "";
    }
    std::string from;
    for (const std::string& name : in.foreign) {
        from += (from.empty() ? "" : ", ") + name;
    }
    if (unfit == 0) {
        return ", refused " + std::to_string(refused) + " from " + from;
    }
    const std::string frames = std::to_string(unfit) + (unfit == 1 ? " frame (" : " frames (") + in.unfitReason + ")";
    if (refused == unfit) {
        return ", refused " + frames;
    }
    return ", refused " + std::to_string(refused) + ": " + std::to_string(refused - unfit) + " from " + from + ", "
        + frames;
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

bool stampTime(const yarp::os::Bytes& envelope, double& time)
{
    // as yarp::os::Stamp::read reads the text of an envelope, sscanf's
    // "%d %lg" (an int, then a double, each after any blanks), valid with a
    // sequence number from 0; with strtol and strtod, which sscanf uses,
    // without its parsing of the format (a tenth of the instructions)
    if (envelope.get() == nullptr || envelope.length() == 0) {
        return false;
    }
    char text[64];  // a stamp's text is some 30 characters (no allocation for it)
    const std::size_t n = std::min(envelope.length(), sizeof text - 1);
    std::memcpy(text, envelope.get(), n);
    text[n] = '\0';
    char* end = nullptr;
    errno = 0;
    const long seq = std::strtol(text, &end, 10);
    if (end == text || errno == ERANGE || seq < 0 || seq > INT_MAX) {
        return false;
    }
    char* after = nullptr;
    const double t = std::strtod(end, &after);
    if (after == end) {
        return false;
    }
    time = t;
    return true;
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
    if (in.spare.capacity() < in.latest.values.capacity()) {
        in.spare.swap(in.latest.values);  // its room, kept for the input's next Bottle (accept)
    }
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

// --- the input ports -------------------------------------------------------------------

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

Input::Input(Shared& shared, const InputSpec& spec, std::string local, double timeout) :
        InputState(spec, timeout), local(std::move(local)), shared_(shared)
{
}

yarp::os::Contactable& Input::port()
{
    if (frames_ != nullptr) {
        return frames_->port();
    }
    return port_;
}

const yarp::os::Contactable& Input::port() const
{
    if (frames_ != nullptr) {
        return frames_->port();
    }
    return port_;
}

bool Input::open()
{
    if (spec.kind == InputKind::Ros2) {
        return true;  // no port: the InputFeed delivers its values
    }
    if (spec.image != nullptr) {
        if (shared_.frames == nullptr) {
            say("input " + std::string(spec.source) + ": this module cannot read camera images");
            return false;
        }
        frames_ = shared_.frames(*this);
        if (frames_ == nullptr || !frames_->open(local, shared_.queue > 1)) {
            return false;
        }
        registered = port().getName();
        return true;
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

void Input::interrupt()
{
    if (spec.kind != InputKind::Ros2) {
        port().interrupt();
    }
}

void Input::close()
{
    if (frames_ != nullptr) {
        frames_->close();
    } else if (spec.kind != InputKind::Ros2) {
        port_.disableCallback();
        port_.close();
    }
}

std::vector<std::string> Input::sources()
{
    InputSources report;
    port().getReport(report);
    return report.names;
}

void Input::drop(const std::string& name)
{
    yarp::os::Bottle reply;
    admin(port().where(), "del " + name, reply);
}

bool Input::fromAccepted(const std::string& source)
{
    if (spec.kind != InputKind::Yarp || accepts(*this, source)) {
        return true;
    }
    std::function<void()> watcher;
    {
        std::lock_guard<std::mutex> lock(shared_.mutex);
        refuseForeign(*this, source, true);
        watcher = shared_.foreign;
    }
    if (watcher) {
        watcher();  // closes the connection now, in its own thread
    }
    return false;
}

void Input::onRead(SourcedBottle& in)
{
    tModule = shared_.module;  // what this thread says is said under its bridge's name
    const SteadyClock::time_point now = SteadyClock::now();
    if (!fromAccepted(in.source)) {
        return;
    }
    const yarp::os::Bottle& bottle = in.bottle;
    if (port_.getPendingReads() > kBacklog) {
        ++received;  // far behind: skipped unread, so that the reader catches up
        ++unused;
        return;
    }
    std::string why;
    const bool ok = parseBottle(bottle, spec, shared_.dropNan, scratch_, why, items_);
    std::lock_guard<std::mutex> lock(shared_.mutex);
    if (!ok) {
        ++received;
        refuse(*this, why);
        return;
    }
    take(scratch_, in.hasEnvelope, in.hasEnvelope ? in.envelope : 0.0, now);
}

void Input::onFrame(const std::string& source, Frame& frame, bool hasEnvelope, double envelope, int pending,
                    const std::string& why)
{
    tModule = shared_.module;  // what this thread says is said under its bridge's name
    const SteadyClock::time_point now = SteadyClock::now();
    if (!fromAccepted(source)) {
        return;
    }
    std::lock_guard<std::mutex> lock(shared_.mutex);
    if (pending > kBacklog) {
        ++received;  // far behind: skipped, so that the reader catches up
        ++unused;
        return;
    }
    if (!why.empty()) {
        ++received;
        refuseFrame(*this, why);
        return;
    }
    scratch_.clear();
    take(scratch_, hasEnvelope, envelope, now, nullptr, &frame);
}

void Input::deliver(Reading& reading)
{
    tModule = shared_.module;  // what this thread says is said under its bridge's name
    const SteadyClock::time_point now = SteadyClock::now();
    if (spec.image != nullptr) {  // a camera image: its frame, or why it has none
        std::lock_guard<std::mutex> lock(shared_.mutex);
        if (reading.frame == nullptr) {
            ++received;
            refuseFrame(*this, reading.refused.empty() ? "no frame" : reading.refused);
            return;
        }
        take(reading.values, reading.hasEnvelope, reading.envelope, now, nullptr, &reading.frame);
        return;
    }
    std::string why;
    bool ok = reading.isRows || checkValues(reading.values, spec, shared_.dropNan, why);
    for (std::size_t k = 0; ok && reading.isRows && k < reading.rows.size(); ++k) {
        if (!checkValues(reading.rows[k], spec, shared_.dropNan, why)) {
            why = "element " + std::to_string(k) + ": " + why;
            ok = false;
        }
    }
    std::lock_guard<std::mutex> lock(shared_.mutex);
    if (!ok) {
        ++received;
        refuse(*this, why);
        return;
    }
    take(reading.values, reading.hasEnvelope, reading.envelope, now, reading.isRows ? &reading.rows : nullptr);
}

yarp::os::Contact Input::where() const
{
    return port().where();
}

void Input::refuseConnection(const std::string& other)
{
    std::lock_guard<std::mutex> lock(shared_.mutex);
    refuseForeign(*this, other, false);
}

void Input::take(Mux& values, bool hasEnvelope, double envelope, SteadyClock::time_point now, Rows* rows,
                 Frame* frame)
{
    ++received;
    const bool wasFresh = accept(*this, values, hasEnvelope, envelope, now, shared_.queue);
    if (rows != nullptr) {
        queue.back().data.rows.swap(*rows);
    }
    if (frame != nullptr) {
        queue.back().data.frame = std::move(*frame);
    }
    if (shared_.listener != nullptr) {
        shared_.listener->arrived(*this, wasFresh);
    }
}

}  // namespace ybgc
