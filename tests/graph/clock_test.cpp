// Clock model: drift and offset recovered from jittery arrivals, resets, precision, ClockSync.
#include "mixray/graph/clock.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <vector>

#include "mixray/graph/host_time.h"
#include "mixray/pattern/random.h"

namespace mixray {
namespace {

// splitmix64: the same numbers on every platform, unlike std distributions.
using Random = pattern::SplitMix64;

// A device clock observed through a jittery link: capture instants t_k on the host clock,
// device stamps offset + (1 + drift)·(t_k − t_0), arrival t_k + latency + random delay.
struct Link {
    int64_t t0_ns = 1'000'000'000'000;  // host time of the first capture
    int64_t device_offset_ns = 4'200'000'000'000'000'000;
    double drift_ppm = 100;
    double fps = 30;
    int64_t latency_ns = 2'000'000;
    double jitter_mean_ns = 1'000'000;
    bool uniform = false;  // uniform on [0, 2·mean] instead of exponential

    int64_t instant(uint64_t k) const {
        return t0_ns + std::llround(static_cast<double>(k) * 1e9 / fps);
    }
    int64_t device(uint64_t k) const {
        const long double since = static_cast<long double>(instant(k) - t0_ns);
        return device_offset_ns +
               static_cast<int64_t>(std::llroundl(since * (1.0L + drift_ppm * 1e-6L)));
    }
    int64_t arrival(uint64_t k, Random& random) const {
        const double delay =
            uniform ? random.uniform() * 2 * jitter_mean_ns : random.exponential(jitter_mean_ns);
        return instant(k) + latency_ns + std::llround(delay);
    }
};

// Largest |toHost(device) − (capture instant + fixed latency)| over frames [from, to).
int64_t worstMappingError(const ClockModel& model, const Link& link, uint64_t from, uint64_t to) {
    int64_t worst = 0;
    for (uint64_t k = from; k < to; ++k) {
        const int64_t error = model.toHost(link.device(k)) - (link.instant(k) + link.latency_ns);
        worst = std::max(worst, std::abs(error));
    }
    return worst;
}

// One hash names every backend's device clocks: stable, distinct per backend and device name,
// never the host domain; FNV-1a of "<backend>/<name>" as the backends named them before.
TEST(DeviceClockDomain, IsAStableHashOfBackendAndDeviceName) {
    EXPECT_EQ(deviceClockDomain("aravis", "cam"), deviceClockDomain("aravis", "cam"));
    EXPECT_NE(deviceClockDomain("aravis", "cam"), deviceClockDomain("v4l2", "cam"));
    EXPECT_NE(deviceClockDomain("aravis", "cam"), deviceClockDomain("aravis", "cam2"));
    EXPECT_EQ(deviceClockDomain("", ""), 0x2a0c975eu);  // FNV-1a 32 of "/"
    for (const char* name : {"", "kinect", "env", "a/b"})
        EXPECT_NE(deviceClockDomain("pattern", name), kHostClockDomain);
}

TEST(ClockModel, RecoversDriftUnderExponentialJitter) {
    // Several seeds: the 1 ppm bound is not luck of one draw.
    for (uint64_t seed = 1; seed <= 5; ++seed) {
        SCOPED_TRACE(seed);
        Link link;
        Random random(seed);
        ClockModel model;
        constexpr uint64_t kFrames = 30 * 90;  // 90 s at 30 fps: the 60 s window is full
        for (uint64_t k = 0; k < kFrames; ++k) {
            ASSERT_EQ(model.addSample(link.device(k), link.arrival(k, random)),
                      ClockSampleResult::kAccepted);
        }
        EXPECT_TRUE(model.converged());
        EXPECT_NEAR(model.driftPpm(), 100.0, 1.0);
        // The line maps device time to capture time plus the minimum latency, to within a
        // small fraction of the 1 ms mean jitter.
        EXPECT_LT(worstMappingError(model, link, kFrames - 300, kFrames), 50'000);
        const ClockEstimate e = model.estimate();
        EXPECT_EQ(e.samples, kFrames);
        EXPECT_EQ(e.resets, 0u);
        EXPECT_NEAR(e.jitter_ns, 1e6, 0.5e6);  // the average arrival delay above the line
        EXPECT_GT(e.span_ns, 55'000'000'000);
    }
}

TEST(ClockModel, RecoversNegativeDriftUnderUniformJitterAndLateBursts) {
    Link link;
    link.drift_ppm = -100;
    link.uniform = true;
    link.jitter_mean_ns = 1'000'000;  // uniform over 0..2 ms
    Random random(7);
    ClockModel model;
    constexpr uint64_t kFrames = 30 * 90;
    for (uint64_t k = 0; k < kFrames; ++k) {
        int64_t arrival = link.arrival(k, random);
        // Bursts of very late frames (a busy host) must not bend the line: it rests on the
        // earliest arrivals.
        if (k % 200 < 10)
            arrival += 40'000'000;
        ASSERT_EQ(model.addSample(link.device(k), arrival), ClockSampleResult::kAccepted);
    }
    EXPECT_NEAR(model.driftPpm(), -100.0, 1.0);
    EXPECT_LT(worstMappingError(model, link, kFrames - 300, kFrames), 100'000);
}

TEST(ClockModel, KeepsNanosecondPrecisionWithHugeStamps) {
    Link link;
    link.device_offset_ns = 9'000'000'000'000'000'000;  // near INT64_MAX
    link.t0_ns = 3'000'000'000'000'000'000;
    link.jitter_mean_ns = 0;
    link.latency_ns = 0;
    Random random(1);
    ClockModel model;
    constexpr uint64_t kFrames = 30 * 60;
    for (uint64_t k = 0; k < kFrames; ++k)
        model.addSample(link.device(k), link.arrival(k, random));
    EXPECT_NEAR(model.driftPpm(), 100.0, 0.001);
    EXPECT_LE(worstMappingError(model, link, 0, kFrames), 2);
}

TEST(ClockModel, LongRunRebasesWithoutLosingAccuracy) {
    // 40 minutes at 30 fps: the reference point moves twice.
    Link link;
    Random random(3);
    ClockModel model;
    constexpr uint64_t kFrames = 30 * 40 * 60;
    for (uint64_t k = 0; k < kFrames; ++k) {
        ASSERT_EQ(model.addSample(link.device(k), link.arrival(k, random)),
                  ClockSampleResult::kAccepted);
    }
    EXPECT_NEAR(model.driftPpm(), 100.0, 1.0);
    EXPECT_LT(worstMappingError(model, link, kFrames - 300, kFrames), 50'000);
}

TEST(ClockModel, DeviceClockGoingBackwardsRestartsTheFit) {
    Link before;
    Random random(11);
    ClockModel model;
    constexpr uint64_t kBefore = 30 * 20;
    for (uint64_t k = 0; k < kBefore; ++k)
        model.addSample(before.device(k), before.arrival(k, random));
    ASSERT_TRUE(model.converged());

    // The device rebooted: its clock starts again from zero at capture kBefore.
    Link after = before;
    after.t0_ns = before.instant(kBefore);
    after.device_offset_ns = 0;
    EXPECT_EQ(model.addSample(after.device(0), after.arrival(0, random)),
              ClockSampleResult::kReset);
    EXPECT_EQ(model.resetCount(), 1u);
    EXPECT_FALSE(model.converged());
    // The oscillator did not change: its drift carries over until the new window has its own.
    EXPECT_NEAR(model.driftPpm(), 100.0, 1.0);
    // Right after the reset the mapping is as good as the first arrival's delay.
    EXPECT_LT(std::abs(model.toHost(after.device(0)) - (after.instant(0) + after.latency_ns)),
              20'000'000);

    constexpr uint64_t kAfter = 30 * 70;
    for (uint64_t k = 1; k < kAfter; ++k) {
        ASSERT_EQ(model.addSample(after.device(k), after.arrival(k, random)),
                  ClockSampleResult::kAccepted);
    }
    EXPECT_TRUE(model.converged());
    EXPECT_EQ(model.resetCount(), 1u);
    EXPECT_NEAR(model.driftPpm(), 100.0, 1.0);
    EXPECT_LT(worstMappingError(model, after, kAfter - 300, kAfter), 50'000);
}

TEST(ClockModel, StreamsOfOneDeviceInAnyOrderAreNoReset) {
    // Colour and depth share the device clock but reach the model interleaved arbitrarily:
    // colour k+1 before depth k steps device time back by a frame.
    Link link;
    Random random(13);
    ClockModel model;
    constexpr uint64_t kFrames = 30 * 90;
    for (uint64_t k = 0; k + 1 < kFrames; k += 2) {
        for (uint64_t j : {k + 1, k, k, k + 1}) {
            ASSERT_EQ(model.addSample(link.device(j), link.arrival(j, random)),
                      ClockSampleResult::kAccepted)
                << j;
        }
    }
    EXPECT_EQ(model.resetCount(), 0u);
    EXPECT_NEAR(model.driftPpm(), 100.0, 1.0);
    EXPECT_LT(worstMappingError(model, link, kFrames - 300, kFrames), 50'000);
}

TEST(ClockModel, DeviceClockLeapingForwardRestartsTheFit) {
    Link link;
    Random random(5);
    ClockModel model;
    for (uint64_t k = 0; k < 300; ++k)
        model.addSample(link.device(k), link.arrival(k, random));
    // A jump of 5 s in device time with 33 ms of host time: the frame would have arrived long
    // before it was captured.
    EXPECT_EQ(model.addSample(link.device(300) + 5'000'000'000, link.arrival(300, random)),
              ClockSampleResult::kReset);
    EXPECT_EQ(model.resetCount(), 1u);
}

TEST(ClockModel, StalledDeviceClockRestartsAfterRepeatedLateSamples) {
    Link link;
    Random random(9);
    ClockModel model;
    for (uint64_t k = 0; k < 300; ++k)
        model.addSample(link.device(k), link.arrival(k, random));
    // One frame delivered 300 ms late (the host stalled): no reset.
    EXPECT_EQ(model.addSample(link.device(300), link.arrival(300, random) + 300'000'000),
              ClockSampleResult::kAccepted);
    for (uint64_t k = 301; k < 310; ++k)
        model.addSample(link.device(k), link.arrival(k, random));
    EXPECT_EQ(model.resetCount(), 0u);

    // The device clock stood still for 10 s (host time went on): every later frame looks 10 s
    // late. After late_samples_for_reset of them the model restarts.
    const uint32_t needed = model.options().late_samples_for_reset;
    for (uint32_t i = 0; i < needed; ++i) {
        const uint64_t k = 310 + i;
        const auto result =
            model.addSample(link.device(k), link.arrival(k, random) + 10'000'000'000);
        EXPECT_EQ(result,
                  i + 1 == needed ? ClockSampleResult::kReset : ClockSampleResult::kAccepted)
            << i;
    }
    EXPECT_EQ(model.resetCount(), 1u);
}

TEST(ClockModel, IdentityBeforeAnySampleAndOptionChecks) {
    ClockModel model;
    EXPECT_FALSE(model.hasSamples());
    EXPECT_EQ(model.toHost(12345), 12345);
    EXPECT_FALSE(model.converged());

    EXPECT_TRUE(ClockModelOptions{}.validate());
    ClockModelOptions bad;
    bad.max_points = 1;
    EXPECT_EQ(bad.validate().code(), ErrorCode::kInvalidArgument);
    bad = {};
    bad.min_span_ns = bad.window_ns + 1;
    EXPECT_FALSE(bad.validate());
    bad = {};
    bad.reset_threshold_ns = 0;
    EXPECT_FALSE(bad.validate());
}

TEST(ClockSync, MapsEachDomainAndPassesHostFramesThrough) {
    ClockSync sync;
    Link a;
    Link b;
    b.device_offset_ns = 17;
    b.drift_ppm = -40;
    b.latency_ns = 5'000'000;
    Random random(21);
    for (uint64_t k = 0; k < 2700; ++k) {
        FrameMetadata ma;
        ma.clock_domain = 3;
        ma.device_stamp_ns = a.device(k);
        ma.host_stamp_ns = a.arrival(k, random);
        FrameMetadata mb;
        mb.clock_domain = 4;
        mb.device_stamp_ns = b.device(k);
        mb.host_stamp_ns = b.arrival(k, random);
        const int64_t sa = sync.observe(ma);
        const int64_t sb = sync.observe(mb);
        if (k > 300) {
            // The same capture instant, mapped from two unrelated clocks: equal up to the
            // difference of the links' fixed latencies and the fits' small errors.
            EXPECT_NEAR(static_cast<double>(sb - sa), 3e6, 100e3) << k;
        }
    }
    EXPECT_NEAR(sync.estimate(3)->drift_ppm, 100, 1);
    EXPECT_NEAR(sync.estimate(4)->drift_ppm, -40, 1);
    EXPECT_EQ(sync.domains(), (std::vector<ClockDomainId>{3, 4}));
    EXPECT_FALSE(sync.estimate(5).has_value());
    EXPECT_FALSE(sync.toHost(5, 0).has_value());

    FrameMetadata host;
    host.clock_domain = kHostClockDomain;
    host.device_stamp_ns = 123;
    host.host_stamp_ns = 456;
    EXPECT_EQ(sync.observe(host), 123);
    EXPECT_EQ(sync.commonStamp(host), 123);
    FrameMetadata unseen;
    unseen.clock_domain = 99;
    unseen.device_stamp_ns = 1;
    unseen.host_stamp_ns = 789;
    EXPECT_EQ(sync.commonStamp(unseen), 789);  // no model yet: the arrival is all we know
    sync.clear();
    EXPECT_TRUE(sync.domains().empty());
}

// The host clocks are the kernel's: steady_clock is CLOCK_MONOTONIC, and the wall-clock
// difference is the same one read as two calls (within the calls' own gap).
TEST(HostTime, ReadsTheKernelsMonotonicAndRealtimeClocks) {
    const int64_t steady_before = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                      std::chrono::steady_clock::now().time_since_epoch())
                                      .count();
    const int64_t monotonic = monotonicNowNs();
    const int64_t steady_after = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                     std::chrono::steady_clock::now().time_since_epoch())
                                     .count();
    EXPECT_LE(steady_before, monotonic);
    EXPECT_LE(monotonic, steady_after);

    const int64_t difference = realtimeMinusMonotonicNs();
    const int64_t m0 = monotonicNowNs();
    const int64_t wall = realtimeNowNs();
    const int64_t m1 = monotonicNowNs();
    // 10 ms covers a descheduled thread; an NTP slew moves the difference by far less.
    EXPECT_NEAR(static_cast<double>(difference), static_cast<double>(wall - m0), 1e7);
    EXPECT_NEAR(static_cast<double>(difference), static_cast<double>(wall - m1), 1e7);
    // The wall clock is after 2020 on any machine that keeps time.
    EXPECT_GT(wall, int64_t{1'577'836'800} * 1'000'000'000);
}

}  // namespace
}  // namespace mixray
