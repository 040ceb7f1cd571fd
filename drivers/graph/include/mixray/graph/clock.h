// Device clocks mapped onto host time: an online minimum-delay line fit per clock domain.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

#include "mixray/graph/frame.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"

namespace mixray {

// The clock domain of a device that stamps frames with its own clock: an FNV-1a hash of
// "<backend>/<device name>", never kHostClockDomain. Stable across runs, so a rig's recordings and
// logs name the same device's clock with the same id every time.
ClockDomainId deviceClockDomain(std::string_view backend, std::string_view device_name);

// Options of a ClockModel. Every field has a working default.
struct ClockModelOptions {
    // Device time the fit looks back over. Longer averages arrival jitter better; shorter
    // follows a drift that changes (oscillators drift with temperature) sooner. The drift error
    // scales with the delay of the earliest arrivals over the window length: at 30 fps with
    // exponential jitter of 1 ms mean, 60 s give about 0.05 ppm typically and 0.4 ppm at worst
    // (40 seeds); 30 s give 0.2 and 1.4.
    int64_t window_ns = 60'000'000'000;
    // The window is cut into this many equal buckets and only the earliest-arriving sample of
    // each is kept: memory and fit cost stay fixed whatever the frame rate.
    uint32_t max_points = 256;
    // converged() needs at least this many buckets...
    uint32_t min_points = 8;
    // ...spanning at least this much device time.
    int64_t min_span_ns = 2'000'000'000;
    // A sample arriving this much *before* the fitted line (impossible for a positive
    // latency) means the device clock jumped forward; arriving this much after it
    // `late_samples_for_reset` times in a row means the device clock stalled; device time
    // going back by more than this means it restarted. Smaller steps back are frames of the
    // device's streams observed out of order. A jump smaller than this passes for jitter (the
    // fit recovers as the window slides past it).
    int64_t reset_threshold_ns = 100'000'000;
    uint32_t late_samples_for_reset = 8;
    // Largest |drift| the fit believes. A few early samples close together can suggest any
    // slope; quartz oscillators stay within ±100 ppm and cheap ones within a few hundred.
    double max_drift_ppm = 1000;

    Status validate() const;
};

// A snapshot of a ClockModel's fit, for logs, statistics and tests.
struct ClockEstimate {
    uint64_t samples = 0;   // samples since the last (re)initialisation
    uint32_t points = 0;    // buckets in the window now
    int64_t span_ns = 0;    // device time the window covers
    double drift_ppm = 0;   // device clock rate error: (d device / d host − 1) · 1e6
    int64_t offset_ns = 0;  // host − device at the newest sample's device time
    double jitter_ns = 0;   // average arrival delay above the fitted line (recent samples)
    double spread_ns = 0;   // median height of the buckets' earliest samples above the line
    uint32_t resets = 0;    // device clock resets detected over the model's life
    bool converged = false;
};

// What a sample did to the model.
enum class ClockSampleResult : uint8_t {
    kAccepted,  // used in the fit
    kReset,     // the device clock jumped: the model restarted from this sample
};

// Maps one device clock onto host time: host_ns ≈ offset + device_ns / (1 + drift), fitted
// online from (device stamp, host arrival stamp) pairs. drift is the device clock's rate error
// (+100 ppm: the device counts 100 µs too many per host second).
//
// Arrival = true time + a positive, jittery latency, so a least-squares line would sit in the
// middle of the jitter and its slope would wander with bursts of late frames. Instead the
// model fits the lower envelope (the NTP/PTP minimum-delay idea, here the linear-programming
// estimator of Moon, Skelly and Towsley): the line below every sample of the window that is
// as close to them as possible on average. That line is the supporting line of the samples'
// lower convex hull at their mean device time. Its error shrinks with the earliest arrivals,
// not with the average one, so a few prompt frames pin it however late the rest are.
// The line maps device time to "capture time + the device's minimum latency"; a latency
// every frame of a device has is indistinguishable from a clock offset.
//
// A device clock that jumps backwards, jumps forward (a sample before the envelope) or stalls
// (samples persistently far above it) restarts the fit; the drift is kept as the prior until
// the new window determines its own. All arithmetic runs relative to a reference sample, so
// 1e18 ns stamps lose no precision.
//
// Thread-bound: a plain value, used from one thread at a time (ClockSync adds a lock).
class ClockModel {
public:
    explicit ClockModel(const ClockModelOptions& options = {});

    // Adds one observation: the device stamp of a frame and the host time it arrived.
    ClockSampleResult addSample(int64_t device_ns, int64_t host_ns);

    // Host time of a device instant. Identity until the first sample.
    int64_t toHost(int64_t device_ns) const;

    bool hasSamples() const { return samples_ > 0; }
    bool converged() const;
    // The device clock's rate error in ppm; positive when it runs fast.
    double driftPpm() const { return -slope_ / (1.0 + slope_) * 1e6; }
    // host − device at the newest sample's device time.
    int64_t offsetNs() const;
    uint64_t sampleCount() const { return samples_; }
    uint32_t resetCount() const { return resets_; }
    ClockEstimate estimate() const;

    // Forgets every sample (not the reset count nor the drift prior).
    void reset();

    const ClockModelOptions& options() const { return options_; }

private:
    // A sample relative to the reference: x = device − ref_device_, z = (host − device) −
    // ref_offset_. Fitting z against x (a shear of host against device) keeps the numbers as
    // small as the offsets and delays themselves.
    struct Point {
        int64_t x = 0;
        int64_t z = 0;
    };

    void restart(int64_t device_ns, int64_t host_ns);
    void commitPending();
    void refit();
    void rebase(int64_t dx);
    long double lineZ(int64_t x) const { return line_z0_ + static_cast<long double>(slope_) * x; }

    ClockModelOptions options_;
    int64_t bucket_ns_ = 0;

    int64_t ref_device_ = 0;
    int64_t ref_offset_ = 0;
    int64_t last_device_ = 0;

    // Committed buckets, oldest first, in a ring of max_points entries; the bucket being
    // filled is pending_.
    std::vector<Point> ring_;
    size_t ring_begin_ = 0;
    size_t ring_size_ = 0;
    Point pending_;
    bool has_pending_ = false;
    int64_t bucket_start_x_ = 0;

    // The fitted line z = line_z0_ + slope_ · x, and scratch space for the hull.
    long double line_z0_ = 0;
    double slope_ = 0;
    double slope_prior_ = 0;
    bool has_prior_ = false;
    std::vector<Point> scratch_;
    std::vector<Point> hull_;
    std::vector<double> heights_;

    uint64_t samples_ = 0;
    uint32_t resets_ = 0;
    uint32_t late_run_ = 0;
    double jitter_ns_ = 0;
    double spread_ns_ = 0;
};

// One ClockModel per clock domain, fed frame by frame, so that frames of several devices get
// stamps in one host time base. Frames of kHostClockDomain pass through: their device stamp
// already is host time.
// Thread-safe (internally locked).
class ClockSync {
public:
    explicit ClockSync(const ClockModelOptions& options = {});
    ClockSync(const ClockSync&) = delete;
    ClockSync& operator=(const ClockSync&) = delete;

    // Feeds the frame's stamp pair to its domain's model and returns the frame's stamp in the
    // common time base. Feed each frame once (one feeder per ClockSync).
    int64_t observe(const FrameMetadata& meta);
    // The frame's common-time-base stamp without feeding the model. A domain never observed
    // gives the host arrival stamp.
    int64_t commonStamp(const FrameMetadata& meta) const;
    // Host time of `device_ns` in `domain`; nullopt for a domain never observed.
    std::optional<int64_t> toHost(ClockDomainId domain, int64_t device_ns) const;

    std::optional<ClockEstimate> estimate(ClockDomainId domain) const;
    std::vector<ClockDomainId> domains() const;
    // Forgets every domain.
    void clear();

private:
    ClockModel* find(ClockDomainId domain) const;

    ClockModelOptions options_;
    mutable std::mutex mutex_;
    std::vector<std::pair<ClockDomainId, std::unique_ptr<ClockModel>>> models_;
};

}  // namespace mixray
