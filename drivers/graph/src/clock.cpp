// Minimum-delay (lower convex hull) fit of device clocks onto host time, and the per-domain map.
#include "mixray/graph/clock.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <string>

namespace mixray {
namespace {

// Rebase the reference once samples are this far from it (about 18 minutes of device time),
// so that x stays small next to the 53-bit mantissa the line's evaluation rounds to.
constexpr int64_t kRebaseAfterNs = int64_t{1} << 40;

// Weight of the newest sample in the running jitter average.
constexpr double kJitterAlpha = 1.0 / 32.0;

// > 0 when o → a → b turns left (counter-clockwise), in (x, z) coordinates. Differences are
// bounded by the window, so their products stay exact enough in long double.
long double cross(const auto& o, const auto& a, const auto& b) {
    return static_cast<long double>(a.x - o.x) * static_cast<long double>(b.z - o.z) -
           static_cast<long double>(a.z - o.z) * static_cast<long double>(b.x - o.x);
}

}  // namespace

ClockDomainId deviceClockDomain(std::string_view backend, std::string_view device_name) {
    uint32_t h = 2166136261u;
    const auto mix = [&h](std::string_view text) {
        for (char c : text) {
            h ^= static_cast<uint8_t>(c);
            h *= 16777619u;
        }
    };
    mix(backend);
    mix("/");
    mix(device_name);
    return h == kHostClockDomain ? 1 : h;
}

Status ClockModelOptions::validate() const {
    if (window_ns <= 0)
        return {ErrorCode::kInvalidArgument, "clock model: window_ns must be > 0"};
    if (max_points < 2)
        return {ErrorCode::kInvalidArgument, "clock model: max_points must be >= 2"};
    if (window_ns / max_points <= 0) {
        return {ErrorCode::kInvalidArgument,
                "clock model: window_ns must be at least max_points nanoseconds"};
    }
    if (min_points < 2 || min_points > max_points) {
        return {ErrorCode::kInvalidArgument, "clock model: min_points must be in [2, max_points]"};
    }
    if (min_span_ns < 0 || min_span_ns > window_ns) {
        return {ErrorCode::kInvalidArgument, "clock model: min_span_ns must be in [0, window_ns]"};
    }
    if (reset_threshold_ns <= 0) {
        return {ErrorCode::kInvalidArgument, "clock model: reset_threshold_ns must be > 0"};
    }
    if (late_samples_for_reset < 1) {
        return {ErrorCode::kInvalidArgument, "clock model: late_samples_for_reset must be >= 1"};
    }
    if (!(max_drift_ppm > 0 && max_drift_ppm < 1e5)) {
        return {ErrorCode::kInvalidArgument, "clock model: max_drift_ppm must be in (0, 1e5)"};
    }
    return Status::ok();
}

ClockModel::ClockModel(const ClockModelOptions& options) : options_(options) {
    assert(options_.validate().isOk() && "ClockModel built from invalid options");
    options_.max_points = std::max<uint32_t>(options_.max_points, 2);
    bucket_ns_ = std::max<int64_t>(options_.window_ns / options_.max_points, 1);
    ring_.resize(options_.max_points);
    scratch_.reserve(options_.max_points + 1);
    hull_.reserve(options_.max_points + 1);
    heights_.reserve(options_.max_points + 1);
}

void ClockModel::reset() {
    samples_ = 0;
    ring_begin_ = 0;
    ring_size_ = 0;
    has_pending_ = false;
    late_run_ = 0;
    jitter_ns_ = 0;
    spread_ns_ = 0;
    line_z0_ = 0;
    slope_ = has_prior_ ? slope_prior_ : 0.0;
}

void ClockModel::restart(int64_t device_ns, int64_t host_ns) {
    reset();
    ref_device_ = device_ns;
    ref_offset_ = host_ns - device_ns;
    last_device_ = device_ns;
    pending_ = {0, 0};
    has_pending_ = true;
    bucket_start_x_ = 0;
    samples_ = 1;
    refit();
}

ClockSampleResult ClockModel::addSample(int64_t device_ns, int64_t host_ns) {
    if (samples_ == 0) {
        restart(device_ns, host_ns);
        return ClockSampleResult::kAccepted;
    }
    // Streams of one device reach the model in any interleaving, so device time may step back
    // by a frame or two; only a step back beyond the threshold is a reset.
    bool jumped = device_ns < last_device_ - options_.reset_threshold_ns;
    const int64_t x = device_ns - ref_device_;
    const int64_t z = (host_ns - device_ns) - ref_offset_;
    const long double residual = static_cast<long double>(z) - lineZ(x);
    const auto threshold = static_cast<long double>(options_.reset_threshold_ns);
    if (residual < -threshold) {
        jumped = true;  // arrived before it was captured: the device clock leapt forward
    } else if (residual > threshold) {
        // One late frame is a stalled host; many in a row are a device clock that stalled or
        // restarted close to its old value.
        if (++late_run_ >= options_.late_samples_for_reset)
            jumped = true;
    } else {
        late_run_ = 0;
    }
    if (jumped) {
        // The oscillator is the same after a reset: keep its drift until the new window has
        // measured its own.
        if (converged()) {
            slope_prior_ = slope_;
            has_prior_ = true;
        }
        ++resets_;
        restart(device_ns, host_ns);
        return ClockSampleResult::kReset;
    }

    ++samples_;
    last_device_ = std::max(last_device_, device_ns);
    const double above = static_cast<double>(std::max<long double>(residual, 0));
    jitter_ns_ = samples_ == 2 ? above : jitter_ns_ + kJitterAlpha * (above - jitter_ns_);

    bool changed = false;
    const int64_t last_committed_x =
        ring_size_ ? ring_[(ring_begin_ + ring_size_ - 1) % ring_.size()].x : INT64_MIN;
    if (x <= last_committed_x) {
        // A late sample from a bucket already closed: the hull needs increasing x, and one
        // sample more in an old bucket changes little. It still counts in samples_ and jitter.
    } else if (x >= bucket_start_x_ + bucket_ns_) {
        commitPending();
        pending_ = {x, z};
        bucket_start_x_ = x;
        changed = true;
    } else if (static_cast<long double>(z) - static_cast<long double>(slope_) * x <
               static_cast<long double>(pending_.z) -
                   static_cast<long double>(slope_) * pending_.x) {
        // Same bucket, earlier arrival (measured along the current line, not just in z: over a
        // bucket the drift alone moves z by as much as the best samples differ).
        pending_ = {x, z};
        // Above the line it cannot move the line by more than its share of the mean x: leave
        // the refit to the bucket's close, which keeps the cost per sample near O(1).
        changed = residual < 0;
    }
    if (changed)
        refit();
    if (x > kRebaseAfterNs)
        rebase(ring_size_ ? ring_[ring_begin_].x : pending_.x);
    return ClockSampleResult::kAccepted;
}

void ClockModel::commitPending() {
    const size_t capacity = ring_.size();
    if (ring_size_ == capacity) {
        ring_begin_ = (ring_begin_ + 1) % capacity;
        --ring_size_;
    }
    ring_[(ring_begin_ + ring_size_) % capacity] = pending_;
    ++ring_size_;
    // The window ends at the bucket that opens now, whose first sample is at pending_.x or
    // later; the caller replaces pending_ right after.
    const int64_t newest = pending_.x;
    while (ring_size_ > 1 && newest - ring_[ring_begin_].x > options_.window_ns) {
        ring_begin_ = (ring_begin_ + 1) % capacity;
        --ring_size_;
    }
}

void ClockModel::rebase(int64_t dx) {
    if (dx <= 0)
        return;
    for (size_t i = 0; i < ring_size_; ++i)
        ring_[(ring_begin_ + i) % ring_.size()].x -= dx;
    pending_.x -= dx;
    bucket_start_x_ -= dx;
    ref_device_ += dx;
    line_z0_ += static_cast<long double>(slope_) * dx;
}

void ClockModel::refit() {
    scratch_.clear();
    for (size_t i = 0; i < ring_size_; ++i)
        scratch_.push_back(ring_[(ring_begin_ + i) % ring_.size()]);
    if (has_pending_)
        scratch_.push_back(pending_);
    if (scratch_.empty())
        return;

    const double max_drift = options_.max_drift_ppm * 1e-6;
    const int64_t span = scratch_.back().x - scratch_.front().x;
    double slope = has_prior_ ? slope_prior_ : slope_;
    bool from_hull = false;

    // Andrew's monotone chain, lower half: x is strictly increasing across buckets.
    hull_.clear();
    for (const Point& p : scratch_) {
        while (hull_.size() >= 2 && cross(hull_[hull_.size() - 2], hull_.back(), p) <= 0) {
            hull_.pop_back();
        }
        hull_.push_back(p);
    }
    const bool prior_rules = has_prior_ && span < options_.min_span_ns;
    if (hull_.size() >= 2 && !prior_rules) {
        // The LP estimator minimises the mean height of the samples above the line subject to
        // the line being below all of them: that is the hull edge over the samples' mean x.
        long double sum_x = 0;
        for (const Point& p : scratch_)
            sum_x += static_cast<long double>(p.x);
        const long double mean_x = sum_x / static_cast<long double>(scratch_.size());
        size_t edge = 0;
        while (edge + 2 < hull_.size() && static_cast<long double>(hull_[edge + 1].x) < mean_x) {
            ++edge;
        }
        const Point& a = hull_[edge];
        const Point& b = hull_[edge + 1];
        slope = static_cast<double>(static_cast<long double>(b.z - a.z) /
                                    static_cast<long double>(b.x - a.x));
        from_hull = std::abs(slope) <= max_drift;
        if (from_hull)
            line_z0_ = static_cast<long double>(a.z) - static_cast<long double>(slope) * a.x;
    }
    if (!from_hull) {
        // A prior or clamped slope: the highest line of that slope below every sample.
        slope = std::clamp(slope, -max_drift, max_drift);
        long double best = 0;
        bool first = true;
        for (const Point& p : hull_) {
            const long double c =
                static_cast<long double>(p.z) - static_cast<long double>(slope) * p.x;
            if (first || c < best)
                best = c;
            first = false;
        }
        line_z0_ = best;
    }
    slope_ = slope;

    heights_.clear();
    for (const Point& p : scratch_)
        heights_.push_back(static_cast<double>(p.z - lineZ(p.x)));
    auto mid = heights_.begin() + static_cast<std::ptrdiff_t>(heights_.size() / 2);
    std::nth_element(heights_.begin(), mid, heights_.end());
    spread_ns_ = *mid;
}

int64_t ClockModel::toHost(int64_t device_ns) const {
    if (samples_ == 0)
        return device_ns;
    const int64_t x = device_ns - ref_device_;
    return device_ns + ref_offset_ + static_cast<int64_t>(std::llround(lineZ(x)));
}

int64_t ClockModel::offsetNs() const {
    return toHost(last_device_) - last_device_;
}

bool ClockModel::converged() const {
    if (samples_ == 0)
        return false;
    const size_t points = ring_size_ + (has_pending_ ? 1 : 0);
    const int64_t oldest = ring_size_ ? ring_[ring_begin_].x : pending_.x;
    const int64_t span = (last_device_ - ref_device_) - oldest;
    return points >= options_.min_points && span >= options_.min_span_ns;
}

ClockEstimate ClockModel::estimate() const {
    ClockEstimate e;
    e.samples = samples_;
    e.resets = resets_;
    if (samples_ == 0)
        return e;
    e.points = static_cast<uint32_t>(ring_size_ + (has_pending_ ? 1 : 0));
    const int64_t oldest = ring_size_ ? ring_[ring_begin_].x : pending_.x;
    e.span_ns = (last_device_ - ref_device_) - oldest;
    e.drift_ppm = driftPpm();
    e.offset_ns = offsetNs();
    e.jitter_ns = jitter_ns_;
    e.spread_ns = spread_ns_;
    e.converged = converged();
    return e;
}

ClockSync::ClockSync(const ClockModelOptions& options) : options_(options) {}

ClockModel* ClockSync::find(ClockDomainId domain) const {
    for (const auto& [id, model] : models_) {
        if (id == domain)
            return model.get();
    }
    return nullptr;
}

int64_t ClockSync::observe(const FrameMetadata& meta) {
    if (meta.clock_domain == kHostClockDomain)
        return meta.device_stamp_ns;
    std::lock_guard lock(mutex_);
    ClockModel* model = find(meta.clock_domain);
    if (!model) {
        models_.emplace_back(meta.clock_domain, std::make_unique<ClockModel>(options_));
        model = models_.back().second.get();
    }
    model->addSample(meta.device_stamp_ns, meta.host_stamp_ns);
    return model->toHost(meta.device_stamp_ns);
}

int64_t ClockSync::commonStamp(const FrameMetadata& meta) const {
    if (meta.clock_domain == kHostClockDomain)
        return meta.device_stamp_ns;
    std::lock_guard lock(mutex_);
    const ClockModel* model = find(meta.clock_domain);
    return model ? model->toHost(meta.device_stamp_ns) : meta.host_stamp_ns;
}

std::optional<int64_t> ClockSync::toHost(ClockDomainId domain, int64_t device_ns) const {
    if (domain == kHostClockDomain)
        return device_ns;
    std::lock_guard lock(mutex_);
    const ClockModel* model = find(domain);
    if (!model)
        return std::nullopt;
    return model->toHost(device_ns);
}

std::optional<ClockEstimate> ClockSync::estimate(ClockDomainId domain) const {
    std::lock_guard lock(mutex_);
    const ClockModel* model = find(domain);
    if (!model)
        return std::nullopt;
    return model->estimate();
}

std::vector<ClockDomainId> ClockSync::domains() const {
    std::lock_guard lock(mutex_);
    std::vector<ClockDomainId> out;
    out.reserve(models_.size());
    for (const auto& entry : models_)
        out.push_back(entry.first);
    return out;
}

void ClockSync::clear() {
    std::lock_guard lock(mutex_);
    models_.clear();
}

}  // namespace mixray
