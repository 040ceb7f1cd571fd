// Another host's clock on this host's time base, from NTP-style request/response exchanges
// over DDS (RFC 5905's on-wire offset and delay, with a drift fit over the exchanges of least
// delay).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>

namespace mixray::dds {

// One exchange's four stamps: t1 and t4 on this host's clock (request sent, answer received),
// t2 and t3 on the other's (request received, answer sent). All CLOCK_MONOTONIC.
struct TimeExchangeStamps {
    int64_t t1_ns = 0;
    int64_t t2_ns = 0;
    int64_t t3_ns = 0;
    int64_t t4_ns = 0;

    // The other clock minus this one, assuming the request and the answer took equally long.
    int64_t offset_ns() const { return ((t2_ns - t1_ns) + (t3_ns - t4_ns)) / 2; }
    // The time on the network both ways (the round trip less the other host's turnaround).
    int64_t delay_ns() const { return (t4_ns - t1_ns) - (t3_ns - t2_ns); }
};

struct HostClockEstimate {
    // The other clock minus this one at this host's time reference_ns, changing by drift_ppm
    // (the other clock's rate relative to this one, in parts per million).
    int64_t offset_ns = 0;
    int64_t reference_ns = 0;
    double drift_ppm = 0;
    // Root mean square of the offsets of the exchanges used around the fitted line: how well
    // the line explains them.
    int64_t residual_ns = 0;
    // The least delay seen. Half of it bounds the error an asymmetric path can add, which no
    // exchange can see.
    int64_t min_delay_ns = 0;
    size_t exchanges = 0;  // kept (the last HostClockEstimator::kWindow)
    size_t used = 0;       // of them, those of least delay that the fit used
    uint64_t jumps = 0;    // times the other clock jumped and the fit started again
    // Set when the offset comes from both hosts' wall clocks instead of the exchanges' fit
    // (wallClockReason()): why ("clock: wall", "both PTP-locked to grandmaster …"). The
    // offset is then this host's CLOCK_REALTIME − CLOCK_MONOTONIC minus the other's (its last
    // answer), drift 0, and exchange_offset_ns keeps the fit's offset as a check.
    std::string wall_clocks;
    int64_t exchange_offset_ns = 0;

    // The other clock's time at this host's time `local_ns`, and the inverse (clamped to the
    // int64 range: stamps from another host can be anything).
    int64_t toRemote(int64_t local_ns) const;
    int64_t toLocal(int64_t remote_ns) const;
    // "+1000.000123 s, drift +0.4 ppm, residual 12 µs, round trip ≥ 140 µs (6 of 24
    // exchanges)", and ", 1 clock jump" when there were some; from the wall clocks,
    // "+1000.000002 s from the wall clocks (clock: wall), exchanges' fit +38 µs from it,
    // residual …".
    std::string describe() const;
};

// What a host says of its wall clock in its clock exchanges.
struct WallClockState {
    bool ptp_locked = false;
    std::string ptp_grandmaster;
};

// Whether another host's stamps map through both hosts' wall clocks rather than the
// exchanges' fit, and why: always when the user says the wall clocks are in step (`forced`,
// clock: wall); otherwise when both are PTP-locked to one grandmaster (PTP holds them within a
// microsecond or so, far closer than exchanges over a network measure). nullopt: the fit.
std::optional<std::string> wallClockReason(bool forced, const WallClockState& here,
                                           const WallClockState& there);

// `fit` with its offset taken from the wall clocks for `reason`: this host's CLOCK_REALTIME −
// CLOCK_MONOTONIC minus the other's (the other's monotonic clock is ahead by as much as its
// wall clock is behind its monotonic one, relatively), drift 0, the fit's offset kept in
// exchange_offset_ns. Clamped to the int64 range (the other's figure can be anything).
HostClockEstimate fromWallClocks(HostClockEstimate fit, int64_t here_realtime_minus_monotonic_ns,
                                 int64_t there_realtime_minus_monotonic_ns, std::string reason);

// Keeps the last kWindow exchanges and fits the other clock to this one. The exchanges whose
// delay is within kDelaySlack of the least (at least kMinUsed of them) are the ones queues did
// not hold up; a line through their offsets gives offset and drift once they span
// kDriftSpanNs, the mean offset before. An exchange whose offset the fit cannot explain by
// its delay means the other clock jumped (the host came back rebooted, or is another
// machine): the fit starts again from it. Not thread-safe.
class HostClockEstimator {
public:
    static constexpr size_t kWindow = 64;
    static constexpr size_t kMinUsed = 4;
    static constexpr int64_t kDriftSpanNs = 10'000'000'000;
    static constexpr double kDelaySlack = 1.5;  // of the least delay, and at least 50 µs more

    // Exchanges with a negative delay or turnaround (stamps out of order) or a stamp beyond
    // ±2^61 ns are not kept; false then.
    bool add(const TimeExchangeStamps& stamps);
    uint64_t jumps() const { return jumps_; }
    // nullopt until kMinUsed exchanges are kept.
    std::optional<HostClockEstimate> estimate() const;
    size_t size() const { return exchanges_.size(); }

private:
    std::deque<TimeExchangeStamps> exchanges_;
    uint64_t jumps_ = 0;
};

}  // namespace mixray::dds
