#include "mixray/dds/host_clock.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

namespace mixray::dds {

namespace {

// Stamps from another host are any 64-bit value: arithmetic on them is done wide and clamped.
__extension__ typedef __int128 Wide;

int64_t clamped(Wide v) {
    constexpr Wide lo = std::numeric_limits<int64_t>::min();
    constexpr Wide hi = std::numeric_limits<int64_t>::max();
    return static_cast<int64_t>(std::clamp(v, lo, hi));
}

// A double as a wide integer; NaN as 0 and anything beyond ±1e30 as that (a drift near -1e6
// ppm, which a fit of nonsense can give, divides by almost nothing).
Wide wide(double v) {
    if (std::isnan(v))
        return 0;
    return static_cast<Wide>(std::round(std::clamp(v, -1e30, 1e30)));
}

}  // namespace

int64_t HostClockEstimate::toRemote(int64_t local_ns) const {
    const double elapsed = static_cast<double>(static_cast<Wide>(local_ns) - reference_ns);
    return clamped(static_cast<Wide>(local_ns) + offset_ns + wide(elapsed * drift_ppm * 1e-6));
}

int64_t HostClockEstimate::toLocal(int64_t remote_ns) const {
    // remote = local + offset + (local - reference) * drift, solved for local.
    const Wide since_reference = static_cast<Wide>(remote_ns) - offset_ns - reference_ns;
    return clamped(static_cast<Wide>(reference_ns) +
                   wide(static_cast<double>(since_reference) / (1 + drift_ppm * 1e-6)));
}

std::string HostClockEstimate::describe() const {
    char text[300];
    if (wall_clocks.empty()) {
        std::snprintf(text, sizeof text,
                      "%+.6f s, drift %+.1f ppm, residual %lld µs, round trip ≥ %lld µs "
                      "(%zu of %zu exchanges)",
                      static_cast<double>(offset_ns) / 1e9, drift_ppm,
                      static_cast<long long>(residual_ns / 1000),
                      static_cast<long long>(min_delay_ns / 1000), used, exchanges);
    } else {
        std::snprintf(text, sizeof text,
                      "%+.6f s from the wall clocks (%s), exchanges' fit %+lld µs from it, "
                      "residual %lld µs, round trip ≥ %lld µs (%zu of %zu exchanges)",
                      static_cast<double>(offset_ns) / 1e9, wall_clocks.c_str(),
                      static_cast<long long>(
                          clamped((static_cast<Wide>(exchange_offset_ns) - offset_ns) / 1000)),
                      static_cast<long long>(residual_ns / 1000),
                      static_cast<long long>(min_delay_ns / 1000), used, exchanges);
    }
    std::string out = text;
    if (jumps > 0)
        out += ", " + std::to_string(jumps) + (jumps == 1 ? " clock jump" : " clock jumps");
    return out;
}

bool HostClockEstimator::add(const TimeExchangeStamps& stamps) {
    // Within ±2^61 ns (73 years), the differences, their sums and the offset and delay cannot
    // overflow.
    constexpr int64_t kLimit = int64_t{1} << 61;
    for (const int64_t t : {stamps.t1_ns, stamps.t2_ns, stamps.t3_ns, stamps.t4_ns})
        if (t <= -kLimit || t >= kLimit)
            return false;
    if (stamps.t4_ns < stamps.t1_ns || stamps.t3_ns < stamps.t2_ns || stamps.delay_ns() < 0)
        return false;
    if (const std::optional<HostClockEstimate> fit = estimate()) {
        // On a continuous clock an exchange is off the true offset by at most half its delay,
        // and the fit by half the least delay and its scatter; a millisecond more for drift.
        const int64_t mid = stamps.t1_ns + (stamps.t4_ns - stamps.t1_ns) / 2;
        const Wide predicted = static_cast<Wide>(fit->toRemote(mid)) - mid;
        const Wide miss = static_cast<Wide>(stamps.offset_ns()) - predicted;
        const Wide allowed = static_cast<Wide>(stamps.delay_ns()) / 2 + fit->min_delay_ns / 2 +
                             Wide{4} * fit->residual_ns + 1'000'000;
        if (miss > allowed || miss < -allowed) {
            exchanges_.clear();
            ++jumps_;
        }
    }
    exchanges_.push_back(stamps);
    if (exchanges_.size() > kWindow)
        exchanges_.pop_front();
    return true;
}

std::optional<HostClockEstimate> HostClockEstimator::estimate() const {
    if (exchanges_.size() < kMinUsed)
        return std::nullopt;
    std::vector<int64_t> delays;
    for (const TimeExchangeStamps& e : exchanges_)
        delays.push_back(e.delay_ns());
    std::vector<int64_t> sorted = delays;
    std::sort(sorted.begin(), sorted.end());
    const int64_t least = sorted.front();
    const int64_t bound =
        std::max({clamped(wide(static_cast<double>(least) * kDelaySlack)),
                  clamped(static_cast<Wide>(least) + 50'000), sorted[kMinUsed - 1]});
    // The fit in doubles around the newest exchange's local time: nanoseconds since boot
    // squared would lose precision.
    const int64_t reference = (exchanges_.back().t1_ns + exchanges_.back().t4_ns) / 2;
    struct Point {
        double t;  // seconds from the reference
        double offset_ns;
    };
    std::vector<Point> points;
    for (size_t i = 0; i < exchanges_.size(); ++i) {
        if (delays[i] > bound)
            continue;
        const TimeExchangeStamps& e = exchanges_[i];
        points.push_back({static_cast<double>((e.t1_ns + e.t4_ns) / 2 - reference) / 1e9,
                          static_cast<double>(e.offset_ns())});
    }
    double mean_t = 0, mean_o = 0;
    for (const Point& p : points) {
        mean_t += p.t;
        mean_o += p.offset_ns;
    }
    mean_t /= static_cast<double>(points.size());
    mean_o /= static_cast<double>(points.size());
    double first = points.front().t, last = points.front().t;
    double stt = 0, sto = 0;
    for (const Point& p : points) {
        first = std::min(first, p.t);
        last = std::max(last, p.t);
        stt += (p.t - mean_t) * (p.t - mean_t);
        sto += (p.t - mean_t) * (p.offset_ns - mean_o);
    }
    // ns of offset per s is ppm * 1000.
    const double slope =
        (last - first) * 1e9 >= static_cast<double>(kDriftSpanNs) && stt > 0 ? sto / stt : 0.0;
    double squares = 0;
    for (const Point& p : points) {
        const double r = p.offset_ns - (mean_o + slope * (p.t - mean_t));
        squares += r * r;
    }
    HostClockEstimate out;
    out.reference_ns = reference;
    out.offset_ns = clamped(wide(mean_o - slope * mean_t));
    out.drift_ppm = slope / 1e3;
    out.residual_ns = clamped(wide(std::sqrt(squares / static_cast<double>(points.size()))));
    out.min_delay_ns = least;
    out.exchanges = exchanges_.size();
    out.used = points.size();
    out.jumps = jumps_;
    return out;
}

std::optional<std::string> wallClockReason(bool forced, const WallClockState& here,
                                           const WallClockState& there) {
    if (forced)
        return "clock: wall";
    if (here.ptp_locked && there.ptp_locked && !here.ptp_grandmaster.empty() &&
        here.ptp_grandmaster == there.ptp_grandmaster)
        return "both PTP-locked to grandmaster " + here.ptp_grandmaster;
    return std::nullopt;
}

HostClockEstimate fromWallClocks(HostClockEstimate fit, int64_t here_realtime_minus_monotonic_ns,
                                 int64_t there_realtime_minus_monotonic_ns, std::string reason) {
    fit.exchange_offset_ns = fit.offset_ns;
    fit.offset_ns = clamped(static_cast<Wide>(here_realtime_minus_monotonic_ns) -
                            there_realtime_minus_monotonic_ns);
    fit.drift_ppm = 0;
    fit.wall_clocks = std::move(reason);
    return fit;
}

}  // namespace mixray::dds
