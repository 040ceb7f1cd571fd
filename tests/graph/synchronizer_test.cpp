// Synchronizer: true sets recovered from jittery, drifting, lossy streams; bounds, drops, no
// copies.
#include "mixray/graph/synchronizer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <map>
#include <new>
#include <set>
#include <utility>
#include <vector>

#include "mixray/pattern/random.h"

// Counts heap allocations, to show the synchronizer's steady state makes none. GCC flags the
// malloc/free pair inside replaced operators once they are inlined; the pairing is correct.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace {
std::atomic<uint64_t> g_allocations{0};
}  // namespace

void* operator new(std::size_t bytes) {
    g_allocations.fetch_add(1, std::memory_order_relaxed);
    if (void* p = std::malloc(bytes ? bytes : 1))
        return p;
    std::abort();
}
void* operator new(std::size_t bytes, const std::nothrow_t&) noexcept {
    g_allocations.fetch_add(1, std::memory_order_relaxed);
    return std::malloc(bytes ? bytes : 1);
}
void operator delete(void* p) noexcept {
    std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
    std::free(p);
}

namespace mixray {
namespace {

using Random = pattern::SplitMix64;

// A simulated device: its clock and the link its frames arrive through.
struct DeviceSim {
    ClockDomainId domain = 1;
    int64_t offset_ns = 0;
    double drift_ppm = 0;
    int64_t latency_ns = 2'000'000;
    double jitter_mean_ns = 1'000'000;
    bool uniform_jitter = false;  // uniform on [0, 2·mean] instead of exponential
    uint64_t reset_at = 0;        // capture index at which the clock restarts from 0; 0: never
};

struct StreamSim {
    StreamId id = 0;
    size_t device = 0;
    double drop_ratio = 0;
};

// One frame as it reaches the synchronizer.
struct Arrival {
    size_t stream = 0;
    uint64_t k = 0;  // ground-truth capture index: equal k means one true set
    int64_t device_ns = 0;
    int64_t host_ns = 0;
};

// Ground truth: capture instants t_k shared by all streams (irregular by ±2 ms), each
// device's clock reading at t_k, each frame's arrival t_k + latency + jitter, random drops.
// Returns the frames in arrival order; present[s][k] says which exist.
struct Scenario {
    std::vector<DeviceSim> devices;
    std::vector<StreamSim> streams;
    uint64_t captures = 1800;
    double fps = 30;
    int64_t capture_jitter_ns = 2'000'000;
    int64_t t0_ns = 5'000'000'000'000;
    uint64_t seed = 1;

    std::vector<std::vector<bool>> present;
    std::vector<int64_t> instants;

    int64_t deviceStamp(const DeviceSim& d, uint64_t k) const {
        const long double rate = 1.0L + static_cast<long double>(d.drift_ppm) * 1e-6L;
        if (d.reset_at > 0 && k >= d.reset_at) {
            return static_cast<int64_t>(
                std::llroundl(static_cast<long double>(instants[k] - instants[d.reset_at]) * rate));
        }
        return d.offset_ns + static_cast<int64_t>(std::llroundl(
                                 static_cast<long double>(instants[k] - t0_ns) * rate));
    }

    std::vector<Arrival> generate() {
        Random random(seed);
        instants.resize(captures);
        for (uint64_t k = 0; k < captures; ++k) {
            const double wobble =
                (random.uniform() * 2 - 1) * static_cast<double>(capture_jitter_ns);
            instants[k] = t0_ns + std::llround(static_cast<double>(k) * 1e9 / fps + wobble);
        }
        present.assign(streams.size(), std::vector<bool>(captures, false));
        std::vector<Arrival> out;
        for (uint64_t k = 0; k < captures; ++k) {
            for (size_t s = 0; s < streams.size(); ++s) {
                const DeviceSim& d = devices[streams[s].device];
                const bool lost = random.uniform() < streams[s].drop_ratio;
                const double delay = d.uniform_jitter ? random.uniform() * 2 * d.jitter_mean_ns
                                                      : random.exponential(d.jitter_mean_ns);
                if (lost)
                    continue;
                present[s][k] = true;
                out.push_back(
                    {s, k, deviceStamp(d, k), instants[k] + d.latency_ns + std::llround(delay)});
            }
        }
        std::stable_sort(out.begin(), out.end(),
                         [](const Arrival& a, const Arrival& b) { return a.host_ns < b.host_ns; });
        return out;
    }

    std::vector<uint64_t> trueSets() const {
        std::vector<uint64_t> out;
        for (uint64_t k = 0; k < captures; ++k) {
            bool all = true;
            for (const auto& p : present)
                all = all && p[k];
            if (all)
                out.push_back(k);
        }
        return out;
    }
};

// Makes pooled frames for the streams: tiny payloads, plenty of buffers.
class FrameFactory {
public:
    explicit FrameFactory(size_t streams) {
        for (size_t i = 0; i < streams; ++i) {
            pools_.push_back(
                BufferPool::create({ImageDesc::packed(PixelFormat::kMono8, 16, 8), 0, 64, "s"}));
        }
    }
    FrameRef make(size_t pool, StreamId stream, uint64_t sequence, int64_t device_ns,
                  int64_t host_ns, ClockDomainId domain) {
        WritableFrame w = pools_[pool]->acquire();
        if (!w)
            return {};
        w.meta().stream = stream;
        w.meta().sequence = sequence;
        w.meta().device_stamp_ns = device_ns;
        w.meta().host_stamp_ns = host_ns;
        w.meta().clock_domain = domain;
        return std::move(w).publish();
    }
    const BufferPool& pool(size_t i) const { return *pools_[i]; }

private:
    std::vector<std::shared_ptr<BufferPool>> pools_;
};

std::unique_ptr<Synchronizer> makeSync(std::vector<StreamId> ids, const SyncOptions& options,
                                       ClockSync* clock = nullptr) {
    auto sync = Synchronizer::create(std::move(ids), options, clock);
    EXPECT_TRUE(sync) << sync.status().toString();
    return sync ? std::move(sync).value() : nullptr;
}

// Runs a scenario through a synchronizer and records what came out.
struct Outcome {
    std::vector<uint64_t> set_captures;  // capture index of each emitted set, in order
    std::vector<int64_t> skews_ns;
    std::map<std::pair<size_t, uint64_t>, int> seen;  // (stream, capture) -> sets + drops
    std::map<DropReason, uint64_t> drops;
    bool mixed_set = false;  // a set whose frames come from different captures
    SyncStats stats;
};

Outcome run(Scenario& scenario, const SyncOptions& options, ClockSync* clock = nullptr) {
    std::vector<Arrival> arrivals = scenario.generate();
    std::vector<StreamId> ids;
    for (const auto& s : scenario.streams)
        ids.push_back(s.id);
    auto sync = Synchronizer::create(ids, options, clock);
    EXPECT_TRUE(sync) << sync.status().toString();
    Outcome out;
    auto streamIndex = [&](StreamId id) {
        return static_cast<size_t>(std::find(ids.begin(), ids.end(), id) - ids.begin());
    };
    (*sync)->setSetCallback([&](const SyncSet& set) {
        const uint64_t k = set.frames[0].meta().sequence;
        for (const FrameRef& f : set.frames) {
            out.mixed_set = out.mixed_set || f.meta().sequence != k;
            ++out.seen[{streamIndex(f.meta().stream), f.meta().sequence}];
        }
        out.set_captures.push_back(k);
        out.skews_ns.push_back(set.skew_ns);
    });
    (*sync)->setDropCallback([&](const FrameRef& f, DropReason reason) {
        ++out.seen[{streamIndex(f.meta().stream), f.meta().sequence}];
        ++out.drops[reason];
    });
    FrameFactory factory(ids.size());
    for (const Arrival& a : arrivals) {
        const StreamSim& s = scenario.streams[a.stream];
        FrameRef frame = factory.make(a.stream, s.id, a.k, a.device_ns, a.host_ns,
                                      scenario.devices[s.device].domain);
        EXPECT_TRUE(frame) << "test pool exhausted: the synchronizer holds too many frames";
        EXPECT_TRUE((*sync)->add(std::move(frame)));
    }
    (*sync)->flush();
    out.stats = (*sync)->stats();
    // Every frame was either in a set or reported dropped, exactly once, and was released.
    EXPECT_EQ(out.seen.size(), arrivals.size());
    for (const auto& [key, count] : out.seen)
        EXPECT_EQ(count, 1) << key.first << "/" << key.second;
    for (size_t i = 0; i < ids.size(); ++i)
        EXPECT_EQ(factory.pool(i).inFlight(), 0u);
    return out;
}

// Two devices with unrelated drifting clocks: an RGB-D camera (colour + depth) and a
// machine-vision camera, as in the rig the benchmark models.
Scenario rigScenario() {
    Scenario sc;
    DeviceSim kinect;
    kinect.domain = 7;
    kinect.offset_ns = 4'200'000'000'000'000'000;
    kinect.drift_ppm = 100;
    kinect.latency_ns = 3'000'000;
    DeviceSim mono;
    mono.domain = 8;
    mono.offset_ns = 123'456'789;
    mono.drift_ppm = -60;
    mono.latency_ns = 3'000'000;
    mono.jitter_mean_ns = 1'500'000;
    sc.devices = {kinect, mono};
    sc.streams = {{10, 0, 0.05}, {11, 0, 0.05}, {20, 1, 0.08}};
    return sc;
}

TEST(Synchronizer, RecoversTrueSetsUnderJitterDriftAndDrops) {
    Scenario sc = rigScenario();
    sc.captures = 30 * 90;  // 90 s at 30 fps: the clock fit's 60 s window fills
    ClockSync clock;
    SyncOptions options;
    options.max_skew_ns = 10'000'000;
    Outcome out = run(sc, options, &clock);

    EXPECT_FALSE(out.mixed_set);
    EXPECT_EQ(out.set_captures, sc.trueSets());
    EXPECT_GT(out.set_captures.size(), sc.captures * 3 / 4);
    EXPECT_EQ(out.stats.sets_emitted, out.set_captures.size());
    EXPECT_EQ(out.stats.frames_added, out.seen.size());
    EXPECT_EQ(out.stats.framesDropped(), out.seen.size() - 3 * out.set_captures.size());
    EXPECT_LE(out.stats.skew_max_ns, options.max_skew_ns);
    // Both devices have the same fixed latency: once the fits settle, sets are tight.
    EXPECT_LT(out.stats.skew_mean_ns, 1'000'000);

    // The per-device fits recover the drifts (+100 ppm and −60 ppm) to within 1 ppm.
    auto kinect = clock.estimate(7);
    auto mono = clock.estimate(8);
    ASSERT_TRUE(kinect && mono);
    EXPECT_NEAR(kinect->drift_ppm, 100.0, 1.0);
    EXPECT_NEAR(mono->drift_ppm, -60.0, 1.0);
    EXPECT_TRUE(kinect->converged && mono->converged);
}

TEST(Synchronizer, HostTimeBaseWithBoundedJitter) {
    Scenario sc = rigScenario();
    for (auto& d : sc.devices) {
        d.uniform_jitter = true;
        d.jitter_mean_ns = 1'500'000;  // arrivals spread over 0..3 ms
    }
    SyncOptions options;
    options.time_base = SyncTimeBase::kHost;
    options.max_skew_ns = 10'000'000;
    Outcome out = run(sc, options);
    EXPECT_FALSE(out.mixed_set);
    EXPECT_EQ(out.set_captures, sc.trueSets());
    for (int64_t skew : out.skews_ns)
        EXPECT_LE(skew, 3'000'001);  // the jitter's range
}

TEST(Synchronizer, SurvivesDeviceClockReset) {
    Scenario sc = rigScenario();
    sc.captures = 30 * 120;
    sc.devices[1].reset_at = 30 * 40;  // the mono camera reboots 40 s in
    ClockSync clock;
    SyncOptions options;
    Outcome out = run(sc, options, &clock);
    EXPECT_FALSE(out.mixed_set);
    EXPECT_EQ(out.set_captures, sc.trueSets());
    auto mono = clock.estimate(8);
    ASSERT_TRUE(mono);
    EXPECT_EQ(mono->resets, 1u);
    EXPECT_NEAR(mono->drift_ppm, -60.0, 1.0);
    EXPECT_EQ(clock.estimate(7)->resets, 0u);
}

TEST(Synchronizer, MaxSkewBoundIsRespected) {
    // Explicit stamps: stream 2 lags by 8 ms, and by 15 ms at every fifth capture (too far from
    // its own capture and still 18 ms from the next one).
    auto sync = makeSync({0, 1, 2}, [] {
        SyncOptions o;
        o.max_skew_ns = 10'000'000;
        o.time_base = SyncTimeBase::kHost;
        return o;
    }());
    std::vector<std::pair<uint64_t, int64_t>> sets;
    std::map<DropReason, int> drops;
    sync->setSetCallback([&](const SyncSet& set) {
        EXPECT_EQ(set.skew_ns, set.max_stamp_ns - set.min_stamp_ns);
        sets.emplace_back(set.frames[0].meta().sequence, set.skew_ns);
    });
    sync->setDropCallback([&](const FrameRef&, DropReason reason) { ++drops[reason]; });
    FrameFactory factory(3);
    constexpr int64_t kPeriod = 33'333'333;
    for (uint64_t k = 0; k < 100; ++k) {
        const int64_t t = static_cast<int64_t>(k) * kPeriod;
        const int64_t lag = k % 5 == 0 ? 15'000'000 : 8'000'000;
        for (size_t s = 0; s < 3; ++s) {
            const int64_t stamp = t + (s == 2 ? lag : static_cast<int64_t>(s) * 1'000'000);
            ASSERT_TRUE(sync->add(factory.make(s, static_cast<StreamId>(s), k, 0, 0, 0), stamp));
        }
    }
    sync->flush();
    std::vector<uint64_t> expected;
    for (uint64_t k = 0; k < 100; ++k) {
        if (k % 5 != 0)
            expected.push_back(k);
    }
    std::vector<uint64_t> got;
    for (const auto& [k, skew] : sets) {
        got.push_back(k);
        EXPECT_EQ(skew, 8'000'000);
    }
    EXPECT_EQ(got, expected);
    EXPECT_EQ(sync->stats().skew_max_ns, 8'000'000);
    EXPECT_EQ(sync->stats().framesDropped(), 20u * 3u);
    EXPECT_GT(drops[DropReason::kSkewTooLarge], 0);
}

TEST(Synchronizer, OverflowWhileAStreamStallsIsReported) {
    Scenario sc = rigScenario();
    sc.captures = 600;
    for (auto& s : sc.streams)
        s.drop_ratio = 0;
    // The mono camera goes silent for captures 200..259: the others overflow their queues.
    std::vector<Arrival> all = sc.generate();
    std::vector<StreamId> ids = {10, 11, 20};
    SyncOptions options;
    auto sync = makeSync(ids, options);
    std::vector<uint64_t> sets;
    std::map<DropReason, uint64_t> drops;
    uint64_t frames = 0;
    sync->setSetCallback(
        [&](const SyncSet& set) { sets.push_back(set.frames[0].meta().sequence); });
    sync->setDropCallback([&](const FrameRef&, DropReason reason) { ++drops[reason]; });
    FrameFactory factory(3);
    for (const Arrival& a : all) {
        if (a.stream == 2 && a.k >= 200 && a.k < 260)
            continue;
        ++frames;
        ASSERT_TRUE(sync->add(factory.make(a.stream, ids[a.stream], a.k, a.device_ns, a.host_ns,
                                           sc.devices[sc.streams[a.stream].device].domain)));
    }
    sync->flush();
    std::vector<uint64_t> expected;
    for (uint64_t k = 0; k < 600; ++k) {
        if (k < 200 || k >= 260)
            expected.push_back(k);
    }
    EXPECT_EQ(sets, expected);
    EXPECT_GT(drops[DropReason::kQueueOverflow], 0u);
    uint64_t dropped = 0;
    for (const auto& [reason, n] : drops)
        dropped += n;
    EXPECT_EQ(dropped + 3 * sets.size(), frames);
    EXPECT_EQ(sync->stats().dropped_per_stream[2], 0u);  // the silent stream lost nothing
}

TEST(Synchronizer, OutOfOrderFrameIsDropped) {
    SyncOptions options;
    options.time_base = SyncTimeBase::kHost;
    auto sync = makeSync({0, 1}, options);
    std::vector<DropReason> drops;
    sync->setDropCallback([&](const FrameRef&, DropReason r) { drops.push_back(r); });
    FrameFactory factory(2);
    ASSERT_TRUE(sync->add(factory.make(0, 0, 0, 0, 0, 0), 1'000'000));
    ASSERT_TRUE(sync->add(factory.make(0, 0, 1, 0, 0, 0), 500'000));
    EXPECT_EQ(drops, std::vector<DropReason>{DropReason::kOutOfOrder});
    EXPECT_EQ(sync->stats().dropped_by_reason[static_cast<size_t>(DropReason::kOutOfOrder)], 1u);
}

TEST(Synchronizer, PullModeHandsOutTheSameBuffers) {
    SyncOptions options;
    options.time_base = SyncTimeBase::kDevice;
    auto sync = makeSync({3, 5}, options);
    FrameFactory factory(2);
    std::vector<const uint8_t*> a_data;
    std::vector<const uint8_t*> b_data;
    for (uint64_t k = 0; k < 5; ++k) {
        const int64_t t = static_cast<int64_t>(k) * 33'000'000;
        FrameRef a = factory.make(0, 3, k, t, 0, 1);
        FrameRef b = factory.make(1, 5, k, t + 1'000'000, 0, 1);
        a_data.push_back(a.data());
        b_data.push_back(b.data());
        ASSERT_TRUE(sync->add(std::move(a)));
        ASSERT_TRUE(sync->add(std::move(b)));
    }
    sync->flush();
    SyncSet set;
    for (uint64_t k = 0; k < 5; ++k) {
        ASSERT_TRUE(sync->pop(set)) << k;
        EXPECT_EQ(set.index, k);
        EXPECT_EQ(set.frames[0].data(), a_data[k]);  // the very buffers, not copies
        EXPECT_EQ(set.frames[1].data(), b_data[k]);
        EXPECT_EQ(set.frames[0].useCount(), 1u);
        EXPECT_EQ(set.skew_ns, 1'000'000);
        EXPECT_EQ(set.stampNs(), static_cast<int64_t>(k) * 33'000'000 + 500'000);
    }
    EXPECT_FALSE(sync->pop(set));
    EXPECT_EQ(sync->streams(), (std::vector<StreamId>{3, 5}));
}

TEST(Synchronizer, MinimumPeriodsLetSetsOutWithoutWaiting) {
    // Without rate bounds a set can only be proven best once every stream has a later frame;
    // with them, as soon as its last frame arrives.
    for (bool bounded : {false, true}) {
        SCOPED_TRACE(bounded);
        SyncOptions options;
        options.time_base = SyncTimeBase::kHost;
        if (bounded)
            options.min_period_ns = {30'000'000, 30'000'000};
        auto sync = makeSync({0, 1}, options);
        std::vector<std::pair<uint64_t, uint64_t>> emitted;  // (set capture, adds so far)
        uint64_t adds = 0;
        sync->setSetCallback(
            [&](const SyncSet& set) { emitted.emplace_back(set.frames[0].meta().sequence, adds); });
        FrameFactory factory(2);
        for (uint64_t k = 0; k < 10; ++k) {
            const int64_t t = static_cast<int64_t>(k) * 33'333'333;
            ++adds;
            ASSERT_TRUE(sync->add(factory.make(0, 0, k, 0, 0, 0), t));
            ++adds;
            ASSERT_TRUE(sync->add(factory.make(1, 1, k, 0, 0, 0), t + 2'000'000));
        }
        ASSERT_GE(emitted.size(), 9u);
        for (const auto& [k, when] : emitted) {
            if (bounded) {
                EXPECT_EQ(when, 2 * k + 2) << k;  // on the add of its own second frame
            } else {
                EXPECT_GT(when, 2 * k + 2) << k;
            }
        }
    }
}

TEST(Synchronizer, DifferentRatesPairTheNearestFrames) {
    // 30 fps and 10 fps on one clock: each slow frame pairs with the fast frame closest to it.
    SyncOptions options;
    options.time_base = SyncTimeBase::kDevice;
    options.max_skew_ns = 5'000'000;
    auto sync = makeSync({0, 1}, options);
    std::vector<std::pair<uint64_t, uint64_t>> sets;
    uint64_t dropped = 0;
    sync->setSetCallback([&](const SyncSet& set) {
        sets.emplace_back(set.frames[0].meta().sequence, set.frames[1].meta().sequence);
    });
    sync->setDropCallback([&](const FrameRef&, DropReason) { ++dropped; });
    FrameFactory factory(2);
    for (uint64_t k = 0; k < 90; ++k) {
        const int64_t t = static_cast<int64_t>(k) * 33'333'333;
        ASSERT_TRUE(sync->add(factory.make(0, 0, k, t, 0, 1)));
        if (k % 3 == 1) {
            ASSERT_TRUE(sync->add(factory.make(1, 1, k / 3, t + 1'000'000, 0, 1)));
        }
    }
    sync->flush();
    ASSERT_EQ(sets.size(), 30u);
    for (uint64_t j = 0; j < 30; ++j)
        EXPECT_EQ(sets[j], std::make_pair(3 * j + 1, j));
    EXPECT_EQ(dropped, 60u);
}

TEST(Synchronizer, SteadyStateMakesNoHeapAllocation) {
    Scenario sc = rigScenario();
    sc.captures = 900;
    std::vector<Arrival> arrivals = sc.generate();
    ClockSync clock;
    auto sync = makeSync({10, 11, 20}, SyncOptions{}, &clock);
    uint64_t sets = 0;
    uint64_t drops = 0;
    sync->setSetCallback([&](const SyncSet&) { ++sets; });
    sync->setDropCallback([&](const FrameRef&, DropReason) { ++drops; });
    FrameFactory factory(3);
    const std::vector<StreamId> ids = {10, 11, 20};
    auto feed = [&](size_t from, size_t to) {
        for (size_t i = from; i < to; ++i) {
            const Arrival& a = arrivals[i];
            (void)sync->add(factory.make(a.stream, ids[a.stream], a.k, a.device_ns, a.host_ns,
                                         sc.devices[sc.streams[a.stream].device].domain));
        }
    };
    const size_t warm = arrivals.size() / 3;
    feed(0, warm);  // the clock sync creates its per-domain models here
    const uint64_t before = g_allocations.load();
    const uint64_t sets_before = sets;
    feed(warm, arrivals.size());
    const uint64_t allocations = g_allocations.load() - before;
    EXPECT_EQ(allocations, 0u);
    EXPECT_GT(sets - sets_before, 400u);
    EXPECT_GT(drops, 0u);
}

TEST(Synchronizer, FlushEmitsTheLastSetAndClearDropsEverything) {
    SyncOptions options;
    options.time_base = SyncTimeBase::kHost;
    auto sync = makeSync({0, 1}, options);
    uint64_t sets = 0;
    std::vector<DropReason> drops;
    sync->setSetCallback([&](const SyncSet&) { ++sets; });
    sync->setDropCallback([&](const FrameRef&, DropReason r) { drops.push_back(r); });
    FrameFactory factory(2);
    ASSERT_TRUE(sync->add(factory.make(0, 0, 0, 0, 0, 0), 0));
    ASSERT_TRUE(sync->add(factory.make(1, 1, 0, 0, 0, 0), 1'000'000));
    EXPECT_EQ(sets, 0u);  // a later frame could still make a tighter set
    ASSERT_TRUE(sync->add(factory.make(0, 0, 1, 0, 0, 0), 33'000'000));
    sync->flush();
    EXPECT_EQ(sets, 1u);
    EXPECT_EQ(drops, std::vector<DropReason>{DropReason::kFlushed});

    drops.clear();
    ASSERT_TRUE(sync->add(factory.make(0, 0, 2, 0, 0, 0), 66'000'000));
    ASSERT_TRUE(sync->add(factory.make(1, 1, 2, 0, 0, 0), 67'000'000));
    sync->clear();
    EXPECT_EQ(sets, 1u);
    EXPECT_EQ(drops, (std::vector<DropReason>{DropReason::kFlushed, DropReason::kFlushed}));
    EXPECT_EQ(factory.pool(0).inFlight(), 0u);
    EXPECT_EQ(factory.pool(1).inFlight(), 0u);
}

TEST(Synchronizer, RejectsBadOptionsAndForeignFrames) {
    EXPECT_FALSE(Synchronizer::create({}, SyncOptions{}));
    EXPECT_FALSE(Synchronizer::create({1, 1}, SyncOptions{}));
    SyncOptions small;
    small.queue_size = 1;
    EXPECT_EQ(Synchronizer::create({1, 2}, small).status().code(), ErrorCode::kInvalidArgument);
    SyncOptions periods;
    periods.min_period_ns = {1};
    EXPECT_FALSE(Synchronizer::create({1, 2}, periods));

    auto sync = makeSync({1, 2}, SyncOptions{});
    FrameFactory factory(1);
    EXPECT_EQ(sync->add(factory.make(0, 9, 0, 0, 0, 0)).code(), ErrorCode::kInvalidArgument);
    EXPECT_FALSE(sync->add(FrameRef{}));
    EXPECT_EQ(sync->stats().frames_added, 0u);
    EXPECT_EQ(toString(DropReason::kSkewTooLarge), "skew too large");
}

}  // namespace
}  // namespace mixray
