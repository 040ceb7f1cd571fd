// Pattern devices: option parsing, the simulated capture loop and the backend that lists them.
#include "mixray/pattern/pattern_backend.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "mixray/graph/clock.h"
#include "mixray/graph/device_options.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/thread_priority.h"
#include "mixray/pattern/random.h"

namespace mixray::pattern {
namespace {

constexpr int kMaxSide = kMaxPatternSide;

struct VirtualDevice {
    std::string_view id;
    std::string_view model;
    std::vector<PatternStream> offered;
    std::vector<PatternStream> defaults;
};

const std::vector<VirtualDevice>& virtualDevices() {
    static const std::vector<VirtualDevice> kDevices = {
        {kRgbdId,
         "mixray test pattern RGB-D",
         {PatternStream::kColor, PatternStream::kDepth, PatternStream::kInfrared},
         {PatternStream::kColor, PatternStream::kDepth}},
        {kMonoId, "mixray test pattern mono", {PatternStream::kMono}, {PatternStream::kMono}},
    };
    return kDevices;
}

const VirtualDevice* findVirtual(std::string_view id) {
    for (const auto& d : virtualDevices()) {
        if (d.id == id)
            return &d;
    }
    return nullptr;
}

PatternStreamOptions defaultStream(PatternStream stream) {
    if (stream == PatternStream::kMono)
        return {stream, 1280, 960};
    return {stream, 640, 480};
}

// splitmix64: tiny, fast and the same on every platform (std distributions are not).
using Random = SplitMix64;

uint32_t fnv1a(std::string_view text) {
    uint32_t h = 2166136261u;
    for (char c : text) {
        h ^= static_cast<uint8_t>(c);
        h *= 16777619u;
    }
    return h;
}

// "30", "29.97": a rate as people write it in mode strings.
std::string formatFps(double fps) {
    char text[32];
    std::snprintf(text, sizeof(text), "%g", fps);
    return text;
}

}  // namespace

ClockDomainId defaultClockDomain(std::string_view device_name) {
    return deviceClockDomain("pattern", device_name);
}

Result<PatternOptions> PatternOptions::fromConfig(const DeviceConfig& config) {
    PatternOptions o;
    o.id = config.id.empty() ? std::string(kRgbdId) : config.id;
    const VirtualDevice* device = findVirtual(o.id);
    if (!device) {
        return {ErrorCode::kNotFound, "pattern device '" + config.name + "': no virtual device '" +
                                          o.id + "' (known: rgbd, mono)"};
    }
    DeviceOptionReader reader(config, "pattern");

    std::vector<std::string> names;
    const std::string* list = reader.find("streams");
    if (list && !config.streams.empty()) {
        return {ErrorCode::kInvalidArgument,
                "pattern device '" + config.name +
                    "': streams are listed both in the rig's stream list and in option "
                    "'streams'; give them once"};
    }
    if (list) {
        names = splitOptionList(*list);
        if (names.empty())
            return reader.error("streams", *list, "a comma list of streams");
    } else {
        names = config.streams;
    }
    if (names.empty()) {
        for (PatternStream s : device->defaults)
            names.emplace_back(toString(s));
    }
    for (const std::string& name : names) {
        auto stream = patternStreamFromString(name);
        if (!stream || std::find(device->offered.begin(), device->offered.end(), *stream) ==
                           device->offered.end()) {
            std::string offered;
            for (PatternStream s : device->offered) {
                offered += (offered.empty() ? "" : ", ") + std::string(toString(s));
            }
            return {ErrorCode::kInvalidArgument, "pattern device '" + config.name + "': option '" +
                                                     "streams': '" + o.id + "' has no stream '" +
                                                     name + "' (it offers " + offered + ")"};
        }
        for (const auto& existing : o.streams) {
            if (existing.stream == *stream) {
                return {ErrorCode::kInvalidArgument, "pattern device '" + config.name +
                                                         "': option 'streams': '" + name +
                                                         "' listed twice"};
            }
        }
        PatternStreamOptions so = defaultStream(*stream);
        const std::string prefix(toString(*stream));
        MIXRAY_RETURN_IF_ERROR(reader.integer(prefix + ".width", so.width, kMinPatternWidth,
                                              kMaxSide, "an integer in [16, 16384]"));
        MIXRAY_RETURN_IF_ERROR(reader.integer(prefix + ".height", so.height, kMinPatternHeight,
                                              kMaxSide, "an integer in [8, 16384]"));
        o.streams.push_back(so);
    }

    MIXRAY_RETURN_IF_ERROR(reader.real("fps", o.fps, 1e-3, 1e5, "a rate in [0.001, 100000]"));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer<uint64_t>("frames", o.frames, 0, UINT64_MAX, "a frame count >= 0"));
    MIXRAY_RETURN_IF_ERROR(reader.boolean("realtime", o.realtime));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer<int64_t>("epoch_ns", o.epoch_ns, 0, INT64_MAX / 2, "nanoseconds >= 0"));
    double phase_us = 0;
    MIXRAY_RETURN_IF_ERROR(
        reader.real("phase_us", phase_us, -1e9, 1e9, "microseconds in [-1e9, 1e9]"));
    o.phase_ns = std::llround(phase_us * 1e3);
    MIXRAY_RETURN_IF_ERROR(reader.integer<int64_t>("offset_ns", o.offset_ns, INT64_MIN / 2,
                                                   INT64_MAX / 2, "nanoseconds within ±4.6e18"));
    MIXRAY_RETURN_IF_ERROR(
        reader.real("drift_ppm", o.drift_ppm, -1e4, 1e4, "ppm in [-10000, 10000]"));
    double latency_us = 0;
    MIXRAY_RETURN_IF_ERROR(
        reader.real("latency_us", latency_us, 0, 1e7, "microseconds in [0, 1e7]"));
    o.latency_ns = std::llround(latency_us * 1e3);
    double jitter_us = 0;
    MIXRAY_RETURN_IF_ERROR(reader.real("jitter_us", jitter_us, 0, 1e7, "microseconds in [0, 1e7]"));
    o.jitter_ns = jitter_us * 1e3;
    MIXRAY_RETURN_IF_ERROR(reader.integer<uint64_t>("reset_at_frame", o.reset_at_frame, 0,
                                                    UINT64_MAX, "a frame number >= 0"));
    MIXRAY_RETURN_IF_ERROR(reader.real("drop_ratio", o.drop_ratio, 0, 1, "a probability in [0, 1)",
                                       DeviceOptionReader::Bound::kClosed,
                                       DeviceOptionReader::Bound::kOpen));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer<uint64_t>("seed", o.seed, 0, UINT64_MAX, "an unsigned integer"));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer<size_t>("buffers", o.buffers, 1, 1024, "an integer in [1, 1024]"));
    if (const std::string* fill = reader.find("fill")) {
        if (*fill == "full") {
            o.fill = Fill::kFull;
        } else if (*fill == "stamp") {
            o.fill = Fill::kStamp;
        } else {
            return reader.error("fill", *fill, "full or stamp");
        }
    }
    o.clock_domain = defaultClockDomain(config.name);
    MIXRAY_RETURN_IF_ERROR(reader.integer<uint32_t>("clock_domain", o.clock_domain, 1, UINT32_MAX,
                                                    "an integer >= 1 (0 is the host clock)"));
    MIXRAY_RETURN_IF_ERROR(
        reader.leftovers("streams, <stream>.width, <stream>.height, fps, frames, realtime, "
                         "epoch_ns, phase_us, offset_ns, drift_ppm, latency_us, jitter_us, "
                         "reset_at_frame, drop_ratio, seed, buffers, fill, clock_domain"));
    MIXRAY_RETURN_IF_ERROR(o.validate().withContext("pattern device '" + config.name + "'"));
    return o;
}

Status PatternOptions::validate() const {
    const VirtualDevice* device = findVirtual(id);
    if (!device)
        return {ErrorCode::kNotFound, "no virtual device '" + id + "'"};
    if (streams.empty())
        return {ErrorCode::kInvalidArgument, "no streams enabled"};
    for (const auto& s : streams) {
        if (s.width < kMinPatternWidth || s.height < kMinPatternHeight || s.width > kMaxSide ||
            s.height > kMaxSide) {
            return {ErrorCode::kInvalidArgument, "stream '" + std::string(toString(s.stream)) +
                                                     "': size " + std::to_string(s.width) + "x" +
                                                     std::to_string(s.height) +
                                                     " outside 16x8 .. 16384x16384"};
        }
    }
    if (!(fps > 0))
        return {ErrorCode::kInvalidArgument, "fps must be > 0"};
    if (!(drop_ratio >= 0 && drop_ratio < 1)) {
        return {ErrorCode::kInvalidArgument, "drop_ratio must be in [0, 1)"};
    }
    if (latency_ns < 0 || !(jitter_ns >= 0)) {
        return {ErrorCode::kInvalidArgument, "latency and jitter must be >= 0"};
    }
    if (!(std::abs(drift_ppm) < 1e4)) {
        return {ErrorCode::kInvalidArgument, "|drift_ppm| must be < 10000"};
    }
    if (buffers < 1)
        return {ErrorCode::kInvalidArgument, "buffers must be >= 1"};
    if (clock_domain == kHostClockDomain) {
        return {ErrorCode::kInvalidArgument, "clock_domain 0 is the host clock"};
    }
    return Status::ok();
}

PatternDevice::PatternDevice(std::string name, PatternOptions options)
    : name_(std::move(name)), options_(std::move(options)) {
    if (options_.clock_domain == kHostClockDomain)
        options_.clock_domain = defaultClockDomain(name_);
}

PatternDevice::~PatternDevice() {
    stop();
}

DeviceDescriptor PatternDevice::descriptor() const {
    DeviceDescriptor d;
    d.backend = "pattern";
    d.id = options_.id;
    const VirtualDevice* device = findVirtual(options_.id);
    d.model = device ? std::string(device->model) : "mixray test pattern";
    d.serial = "pattern-" + options_.id;
    d.location = "pattern:" + options_.id;
    for (const auto& s : options_.streams) {
        d.modes.push_back(std::string(toString(s.stream)) + " " + std::to_string(s.width) + "x" +
                          std::to_string(s.height) + "@" + formatFps(options_.fps) + " " +
                          std::string(mixray::toString(formatOf(s.stream))));
    }
    return d;
}

Status PatternDevice::connect(Graph& graph) {
    MIXRAY_RETURN_IF_ERROR(options_.validate().withContext("pattern device '" + name_ + "'"));
    if (graph_)
        return {ErrorCode::kInvalidArgument, "pattern device '" + name_ + "' connected twice"};
    for (const auto& s : options_.streams) {
        StreamInfo info;
        info.name = name_ + "/" + std::string(toString(s.stream));
        info.device = name_;
        info.kind = kindOf(s.stream);
        info.format = ImageDesc::packed(formatOf(s.stream), s.width, s.height);
        info.nominal_fps = options_.fps;
        info.clock_domain = options_.clock_domain;
        info.tags["generator"] = "mixray pattern";
        auto stream = addPooledStream(graph, info, options_.buffers);
        if (!stream)
            return stream.status().withContext("pattern device '" + name_ + "'");
        ids_.push_back(stream->id);
        pools_.push_back(std::move(stream->pool));
    }
    graph_ = &graph;
    return Status::ok();
}

Status PatternDevice::start() {
    if (!graph_)
        return {ErrorCode::kInvalidArgument, "pattern device '" + name_ + "': not connected"};
    if (thread_.joinable())
        return Status::ok();
    {
        std::lock_guard lock(mutex_);
        stop_requested_ = false;
    }
    finished_ = false;
    t0_ns_ = (options_.realtime ? monotonicNowNs() : options_.epoch_ns) + options_.phase_ns;
    thread_ = std::thread([this] { run(); });
    return Status::ok();
}

void PatternDevice::stop() {
    {
        std::lock_guard lock(mutex_);
        stop_requested_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable())
        thread_.join();
}

bool PatternDevice::stopRequested() {
    std::lock_guard lock(mutex_);
    return stop_requested_;
}

// Waits until the host clock reaches `host_ns`; false when stop() came first.
bool PatternDevice::sleepUntil(int64_t host_ns) {
    const auto deadline = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(host_ns));
    std::unique_lock lock(mutex_);
    return !wake_.wait_until(lock, deadline, [&] { return stop_requested_; });
}

int64_t PatternDevice::captureInstantNs(uint64_t k) const {
    const long double period = 1e9L / static_cast<long double>(options_.fps);
    return t0_ns_ + static_cast<int64_t>(std::llroundl(static_cast<long double>(k) * period));
}

int64_t PatternDevice::deviceStampNs(uint64_t k) const {
    const long double rate = 1.0L + static_cast<long double>(options_.drift_ppm) * 1e-6L;
    if (options_.reset_at_frame > 0 && k >= options_.reset_at_frame) {
        // The clock restarts from zero at the reset frame.
        const int64_t since = captureInstantNs(k) - captureInstantNs(options_.reset_at_frame);
        return static_cast<int64_t>(std::llroundl(static_cast<long double>(since) * rate));
    }
    const int64_t since = captureInstantNs(k) - t0_ns_;
    return options_.offset_ns +
           static_cast<int64_t>(std::llroundl(static_cast<long double>(since) * rate));
}

void PatternDevice::run() {
    runAs(ThreadRole::kCapture);  // a frame late here is a frame lost (thread_priority.h)
    const size_t n = ids_.size();
    Random random(options_.seed * 0x9E3779B97F4A7C15ull ^ fnv1a(name_));
    struct Pending {
        size_t stream = 0;
        int64_t arrival_ns = 0;
        bool lost = false;
    };
    std::array<Pending, kPatternStreamCount> order{};
    bool completed = true;

    for (uint64_t k = 0; options_.frames == 0 || k < options_.frames; ++k) {
        if (stopRequested()) {
            completed = false;
            break;
        }
        const int64_t instant = captureInstantNs(k);
        const int64_t device_ns = deviceStampNs(k);
        // Draw in stream order whatever happens later, so the same seed gives the same run.
        for (size_t i = 0; i < n; ++i) {
            order[i].stream = i;
            order[i].lost = options_.drop_ratio > 0 && random.uniform() < options_.drop_ratio;
            order[i].arrival_ns = instant + options_.latency_ns +
                                  std::llround(random.exponential(options_.jitter_ns));
        }
        // Stable insertion sort by arrival: at most four entries, and unlike std::stable_sort
        // it never asks the heap for a temporary buffer.
        for (size_t i = 1; i < n; ++i) {
            for (size_t j = i; j > 0 && order[j].arrival_ns < order[j - 1].arrival_ns; --j) {
                std::swap(order[j], order[j - 1]);
            }
        }

        for (size_t j = 0; j < n; ++j) {
            const Pending& p = order[j];
            // A simulated drop and a frame without a free buffer are lost to the graph, as a
            // real camera's are: counted where commands report losses (Graph::lostCount).
            if (p.lost) {
                dropped_.fetch_add(1, std::memory_order_relaxed);
                graph_->countLost(ids_[p.stream]);
                continue;
            }
            if (options_.realtime && !sleepUntil(p.arrival_ns)) {
                completed = false;
                break;
            }
            BufferPool& pool = *pools_[p.stream];
            WritableFrame frame = pool.acquire();
            if (!frame && options_.realtime) {
                // A camera does not wait for its consumers: the frame is lost.
                exhausted_.fetch_add(1, std::memory_order_relaxed);
                graph_->countLost(ids_[p.stream]);
                continue;
            }
            while (!frame) {
                // Simulated time waits for the consumers to return a buffer.
                std::unique_lock lock(mutex_);
                if (wake_.wait_for(lock, std::chrono::microseconds(200),
                                   [&] { return stop_requested_; })) {
                    break;
                }
                lock.unlock();
                frame = pool.acquire();
            }
            if (!frame) {
                completed = false;
                break;
            }
            const int64_t host_ns = options_.realtime ? monotonicNowNs() : p.arrival_ns;
            const PatternStream stream = options_.streams[p.stream].stream;
            if (options_.fill == PatternOptions::Fill::kFull) {
                renderPattern(stream, k, frame.image());
            } else {
                stampSequence(k, frame.image());
            }
            FrameMetadata& meta = frame.meta();
            meta.stream = ids_[p.stream];
            meta.sequence = k;
            meta.device_stamp_ns = device_ns;
            meta.host_stamp_ns = host_ns;
            meta.clock_domain = options_.clock_domain;
            graph_->publish(std::move(frame).publish());
            published_.fetch_add(1, std::memory_order_relaxed);
        }
        if (!completed)
            break;
    }
    if (completed) {
        for (StreamId id : ids_)
            graph_->endStream(id);
    }
    finished_ = true;
}

Result<std::vector<DeviceDescriptor>> PatternBackend::enumerate() {
    std::vector<DeviceDescriptor> out;
    for (const auto& device : virtualDevices()) {
        DeviceDescriptor d;
        d.backend = "pattern";
        d.id = std::string(device.id);
        d.model = std::string(device.model);
        d.serial = "pattern-" + d.id;
        d.location = "pattern:" + d.id;
        for (PatternStream s : device.offered) {
            const PatternStreamOptions so = defaultStream(s);
            d.modes.push_back(std::string(toString(s)) + " " + std::to_string(so.width) + "x" +
                              std::to_string(so.height) + "@30 " +
                              std::string(mixray::toString(formatOf(s))));
        }
        out.push_back(std::move(d));
    }
    return out;
}

Result<std::unique_ptr<Device>> PatternBackend::open(const DeviceConfig& config) {
    if (config.name.empty()) {
        return {ErrorCode::kInvalidArgument,
                "pattern device without a name (streams are named "
                "<name>/<stream>)"};
    }
    auto options = PatternOptions::fromConfig(config);
    if (!options)
        return options.status();
    return std::unique_ptr<Device>(
        std::make_unique<PatternDevice>(config.name, std::move(*options)));
}

}  // namespace mixray::pattern
