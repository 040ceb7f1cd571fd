// HostClockEstimator (mixray/dds/host_clock.h): another host's clock from NTP-style exchanges,
// on exchanges made up with a known offset, drift and network delays.
#include "mixray/dds/host_clock.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>

namespace mixray::dds {
namespace {

constexpr int64_t kMs = 1'000'000;

// The other host's clock: `offset_ns` ahead at local time 0, running `drift_ppm` fast.
struct OtherClock {
    int64_t offset_ns;
    double drift_ppm;
    int64_t at(int64_t local_ns) const {
        return local_ns + offset_ns +
               static_cast<int64_t>(std::llround(static_cast<double>(local_ns) * drift_ppm * 1e-6));
    }
};

// An exchange starting at local time t1: the request takes `out_ns`, the other host `turn_ns`
// to answer, the answer `back_ns`.
TimeExchangeStamps exchange(const OtherClock& other, int64_t t1, int64_t out_ns, int64_t turn_ns,
                            int64_t back_ns) {
    const int64_t t2_local = t1 + out_ns;
    const int64_t t3_local = t2_local + turn_ns;
    return {t1, other.at(t2_local), other.at(t3_local), t3_local + back_ns};
}

TEST(HostClockEstimator, SymmetricExchangesGiveTheOffsetAndTheDrift) {
    const OtherClock other{1000'000'000'000, 100};  // 1000 s ahead, 100 ppm fast
    HostClockEstimator estimator;
    EXPECT_FALSE(estimator.estimate().has_value());
    const int64_t start = 50'000 * int64_t{1'000'000'000};  // 50000 s since boot
    for (int i = 0; i < 60; ++i)                            // 11.8 s: enough for a drift fit
        ASSERT_TRUE(estimator.add(exchange(other, start + i * 200 * kMs, 60'000, 20'000, 60'000)));
    const auto estimate = estimator.estimate();
    ASSERT_TRUE(estimate.has_value());
    EXPECT_NEAR(estimate->drift_ppm, 100, 0.01);
    EXPECT_LT(estimate->residual_ns, 100);
    // 120 µs on the network; the other clock's 20 µs turnaround runs 100 ppm fast.
    EXPECT_NEAR(static_cast<double>(estimate->min_delay_ns), 120'000, 5);
    EXPECT_EQ(estimate->exchanges, 60u);
    // Where the exchanges were and 10 s on, both ways.
    for (const int64_t local : {start + 4000 * kMs, start + 22'000 * kMs}) {
        EXPECT_NEAR(static_cast<double>(estimate->toRemote(local)),
                    static_cast<double>(other.at(local)), 1000)
            << local;
        EXPECT_NEAR(static_cast<double>(estimate->toLocal(other.at(local))),
                    static_cast<double>(local), 1000);
    }
    EXPECT_NE(estimate->describe().find("+1005.001180 s, drift +100.0 ppm"), std::string::npos)
        << estimate->describe();
}

TEST(HostClockEstimator, ExchangesHeldUpInQueuesAreLeftOut) {
    const OtherClock other{-3'000 * kMs, 0};
    std::mt19937 random(7);
    std::uniform_int_distribution<int64_t> queued(1 * kMs, 20 * kMs);
    HostClockEstimator estimator;
    size_t fast = 0;
    for (int i = 0; i < 64; ++i) {
        const int64_t t1 = 10'000 * kMs + i * 200 * kMs;
        // One exchange in three goes straight through; the rest wait in a queue one way.
        if (i % 3 == 0) {
            ++fast;
            estimator.add(exchange(other, t1, 80'000, 10'000, 80'000));
        } else if (i % 2 == 0) {
            estimator.add(exchange(other, t1, 80'000 + queued(random), 10'000, 80'000));
        } else {
            estimator.add(exchange(other, t1, 80'000, 10'000, 80'000 + queued(random)));
        }
    }
    const auto estimate = estimator.estimate();
    ASSERT_TRUE(estimate.has_value());
    // A mean over every exchange would be milliseconds off.
    EXPECT_NEAR(static_cast<double>(estimate->offset_ns), -3000.0 * kMs, 1000);
    EXPECT_EQ(estimate->used, fast);
    EXPECT_NEAR(estimate->drift_ppm, 0, 0.01);
}

TEST(HostClockEstimator, NoDriftIsFittedBeforeTheExchangesSpanTenSeconds) {
    const OtherClock other{5 * kMs, 300};
    HostClockEstimator estimator;
    for (int i = 0; i < 8; ++i)
        estimator.add(exchange(other, 1'000 * kMs + i * 20 * kMs, 50'000, 5'000, 50'000));
    const auto estimate = estimator.estimate();
    ASSERT_TRUE(estimate.has_value());
    EXPECT_EQ(estimate->drift_ppm, 0);
    // The mean offset: off by the drift over the distance from the exchanges' middle (10 ms
    // at 300 ppm, 3 µs).
    EXPECT_NEAR(static_cast<double>(estimate->toRemote(1'080 * kMs)),
                static_cast<double>(other.at(1'080 * kMs)), 5000);
}

TEST(HostClockEstimator, StampsOutOfOrderOrOutOfRangeAreRefused) {
    HostClockEstimator estimator;
    EXPECT_FALSE(estimator.add({100, 50, 40, 200}));   // answered before asked
    EXPECT_FALSE(estimator.add({100, 50, 500, 200}));  // turnaround longer than the round trip
    EXPECT_FALSE(estimator.add({200, 50, 60, 100}));   // received before sent
    EXPECT_FALSE(estimator.add(
        {0, std::numeric_limits<int64_t>::max(), std::numeric_limits<int64_t>::max(), 10}));
    EXPECT_EQ(estimator.size(), 0u);
    // A fit maps any stamp, however far, without overflowing.
    for (int i = 0; i < 4; ++i)
        ASSERT_TRUE(estimator.add(
            {i * kMs, (int64_t{1} << 60) + i * kMs, (int64_t{1} << 60) + i * kMs, i * kMs + 10}));
    const auto estimate = estimator.estimate();
    ASSERT_TRUE(estimate.has_value());
    EXPECT_EQ(estimate->toLocal(std::numeric_limits<int64_t>::min()),
              std::numeric_limits<int64_t>::min());
    EXPECT_EQ(estimate->toRemote(std::numeric_limits<int64_t>::max()),
              std::numeric_limits<int64_t>::max());
}

TEST(HostClockEstimator, AClockThatJumpsStartsTheFitAgain) {
    HostClockEstimator estimator;
    const OtherClock before{1000 * kMs * 1000, 0};
    for (int i = 0; i < 20; ++i)
        estimator.add(exchange(before, 10'000 * kMs + i * 200 * kMs, 50'000, 5'000, 50'000));
    // A queued exchange is no jump: its offset is off by less than half its delay.
    estimator.add(exchange(before, 14'100 * kMs, 30 * kMs, 5'000, 50'000));
    EXPECT_EQ(estimator.jumps(), 0u);
    EXPECT_EQ(estimator.size(), 21u);
    // The host came back with a clock 3000 s ahead.
    const OtherClock after{3000 * kMs * 1000, 0};
    for (int i = 0; i < 5; ++i)
        estimator.add(exchange(after, 20'000 * kMs + i * 200 * kMs, 50'000, 5'000, 50'000));
    EXPECT_EQ(estimator.jumps(), 1u);
    EXPECT_EQ(estimator.size(), 5u);
    const auto estimate = estimator.estimate();
    ASSERT_TRUE(estimate.has_value());
    EXPECT_NEAR(static_cast<double>(estimate->offset_ns), 3000e9, 1000);
    EXPECT_NE(estimate->describe().find(", 1 clock jump"), std::string::npos);
}

TEST(HostClockEstimator, KeepsTheLastWindowOfExchanges) {
    const OtherClock other{0, 0};
    HostClockEstimator estimator;
    for (int i = 0; i < 100; ++i)
        estimator.add(exchange(other, i * 200 * kMs, 50'000, 5'000, 50'000));
    EXPECT_EQ(estimator.size(), HostClockEstimator::kWindow);
    EXPECT_EQ(estimator.estimate()->exchanges, HostClockEstimator::kWindow);
}

TEST(WallClocks, AreUsedWhenTheUserSaysOrBothHostsFollowOneGrandmaster) {
    const WallClockState free;
    const WallClockState locked{.ptp_locked = true, .ptp_grandmaster = "9ef2f2.fffe.4fa318"};
    const WallClockState other{.ptp_locked = true, .ptp_grandmaster = "ca3e6e.fffe.8ae66e"};
    EXPECT_EQ(wallClockReason(true, free, free), "clock: wall");
    EXPECT_EQ(wallClockReason(false, locked, locked),
              "both PTP-locked to grandmaster 9ef2f2.fffe.4fa318");
    EXPECT_FALSE(wallClockReason(false, locked, free)) << "the other host is not locked";
    EXPECT_FALSE(wallClockReason(false, free, locked)) << "this host is not locked";
    EXPECT_FALSE(wallClockReason(false, locked, other)) << "two grandmasters, two time bases";
    EXPECT_FALSE(wallClockReason(false, {.ptp_locked = true, .ptp_grandmaster = ""},
                                 {.ptp_locked = true, .ptp_grandmaster = ""}));
}

TEST(WallClocks, TheOffsetIsTheDifferenceOfTheHostsRealtimeMinusMonotonic) {
    HostClockEstimate fit;
    fit.offset_ns = 1'000'000'038'000;  // the exchanges: 1000 s and 38 µs
    fit.reference_ns = 5'000'000'000;
    fit.drift_ppm = 0.3;
    fit.residual_ns = 11'000;
    fit.min_delay_ns = 206'000;
    fit.used = 7;
    fit.exchanges = 20;
    // The other host's monotonic clock is 1000 s ahead and its wall clock the same as this
    // one's: its realtime − monotonic is 1000 s less.
    const int64_t here = 1'795'000'000'000'000'000;
    const HostClockEstimate wall =
        fromWallClocks(fit, here, here - 1'000'000'000'000, "clock: wall");
    EXPECT_EQ(wall.offset_ns, 1'000'000'000'000);
    EXPECT_EQ(wall.exchange_offset_ns, fit.offset_ns);
    EXPECT_EQ(wall.drift_ppm, 0);
    EXPECT_EQ(wall.toLocal(1'000'000'000'000 + 42), 42);
    EXPECT_EQ(wall.describe(),
              "+1000.000000 s from the wall clocks (clock: wall), exchanges' fit +38 µs from it, "
              "residual 11 µs, round trip ≥ 206 µs (7 of 20 exchanges)");
    // Whatever the other host sends, the offset is clamped, never overflowed.
    const HostClockEstimate far = fromWallClocks(fit, std::numeric_limits<int64_t>::max(),
                                                 std::numeric_limits<int64_t>::min(), "x");
    EXPECT_EQ(far.offset_ns, std::numeric_limits<int64_t>::max());
    (void)far.describe();
}

}  // namespace
}  // namespace mixray::dds
