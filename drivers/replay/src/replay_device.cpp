// The replay device: options, positioning, and the thread that paces a recording into a graph.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <thread>

#include "image_files.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/thread_priority.h"
#include "mixray/replay/depth_units.h"
#include "mixray/replay/replay_backend.h"

namespace mixray::replay {
namespace {

using Clock = std::chrono::steady_clock;

// How long the thread sleeps while consumers hold every buffer of a stream.
constexpr auto kBufferWait = std::chrono::milliseconds(1);
// Interval assumed between the last frame of a pass and the first of the next when a
// recording has a single timestamp and no nominal rate.
constexpr int64_t kFallbackIntervalNs = 33'333'333;

constexpr const char* kKnownOptions =
    "pace, speed, loop, start, depth_units, buffers, names, stamps";

Status badValue(const std::string& key, const std::string& value, const char* expected) {
    return {ErrorCode::kInvalidArgument,
            "replay option " + key + "='" + value + "': expected " + expected};
}

bool parseDouble(const std::string& text, double* value) {
    auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), *value);
    return ec == std::errc() && end == text.data() + text.size() && std::isfinite(*value);
}

// A rig file's per-stream mode request ("depth.width"): the part before the dot, or empty.
std::string_view modeKey(std::string_view key) {
    const size_t dot = key.rfind('.');
    if (dot == std::string_view::npos || dot == 0)
        return {};
    const std::string_view field = key.substr(dot + 1);
    if (field != "width" && field != "height" && field != "fps" && field != "format")
        return {};
    return key.substr(0, dot);
}

// A recording cannot change its mode: a rig's mode request must describe what was recorded.
Status checkMode(const std::string& key, const std::string& value, const StreamInfo& stream) {
    const std::string_view field = std::string_view(key).substr(key.rfind('.') + 1);
    bool same = true;
    std::string recorded;
    if (field == "width" || field == "height") {
        const int size = field == "width" ? stream.format.width : stream.format.height;
        recorded = std::to_string(size);
        same = value == recorded;
    } else if (field == "format") {
        recorded = std::string(toString(stream.format.format));
        same = value == recorded;
    } else {
        double fps = 0;
        char text[32];
        std::snprintf(text, sizeof(text), "%g", stream.nominal_fps);
        recorded = text;
        // Unknown recorded rates accept any request; known ones within 1 %.
        same = parseDouble(value, &fps) &&
               (stream.nominal_fps <= 0 ||
                std::abs(fps - stream.nominal_fps) <= 0.01 * stream.nominal_fps);
    }
    if (same)
        return Status::ok();
    return {ErrorCode::kInvalidArgument, "replay: the rig asks " + key + "=" + value + " but '" +
                                             stream.name + "' was recorded with " +
                                             std::string(field) + " " + recorded +
                                             " (a recording cannot change its mode)"};
}

}  // namespace

// Where frames of one recording stream go.
struct ReplayDevice::StreamRoute {
    bool enabled = false;
    std::string local_name;  // within the device: "depth"
    std::string graph_name;  // "<device>/<local_name>"
    StreamId graph_id = kInvalidStream;
    int convert_from_per_m = 0;            // non-zero: depth rescaled to mm into own_pool
    std::shared_ptr<BufferPool> own_pool;  // conversions, and copies of frames shared elsewhere
    // Sequence numbers seen in the first pass, for shifting later passes.
    bool seen = false;
    uint64_t first_sequence = 0;
    uint64_t last_sequence = 0;
    uint64_t sequence_shift = 0;
};

Result<ReplayOptions> ReplayOptions::fromConfig(const std::map<std::string, std::string>& options) {
    ReplayOptions out;
    bool speed_given = false;
    for (const auto& [key, value] : options) {
        if (!modeKey(key).empty()) {
            continue;  // checked against the recording by openReplayDevice()
        }
        if (key == "pace") {
            if (value == "original") {
                out.pace = Pace::kOriginal;
            } else if (value == "fast") {
                out.pace = Pace::kFast;
            } else {
                return badValue(key, value, "original or fast");
            }
        } else if (key == "speed") {
            if (!parseDouble(value, &out.speed) || out.speed <= 0) {
                return badValue(key, value, "a positive number such as 0.5 or 2");
            }
            speed_given = true;
        } else if (key == "loop") {
            if (value == "true" || value == "1" || value == "yes") {
                out.loop = true;
            } else if (value == "false" || value == "0" || value == "no") {
                out.loop = false;
            } else {
                return badValue(key, value, "true or false");
            }
        } else if (key == "start") {
            if (!parseDouble(value, &out.start_s) || out.start_s < 0) {
                return badValue(key, value, "seconds from the beginning, >= 0");
            }
        } else if (key == "depth_units") {
            if (value == "mm") {
                out.depth_in_mm = true;
            } else if (value == "recorded") {
                out.depth_in_mm = false;
            } else {
                return badValue(key, value, "mm or recorded");
            }
        } else if (key == "names") {
            if (value == "device") {
                out.recorded_names = false;
            } else if (value == "recorded") {
                out.recorded_names = true;
            } else {
                return badValue(key, value, "device or recorded");
            }
        } else if (key == "stamps") {
            if (value == "recorded") {
                out.arrival_stamps = false;
            } else if (value == "arrival") {
                out.arrival_stamps = true;
            } else {
                return badValue(key, value, "recorded or arrival");
            }
        } else if (key == "buffers") {
            size_t n = 0;
            auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), n);
            if (ec != std::errc() || end != value.data() + value.size() || n < 1 || n > 1024) {
                return badValue(key, value, "a whole number from 1 to 1024");
            }
            out.buffers_per_stream = n;
        } else {
            return Status(ErrorCode::kInvalidArgument,
                          "unknown replay option '" + key + "' (known: " + kKnownOptions + ")");
        }
    }
    if (out.arrival_stamps && out.pace == Pace::kFast) {
        return Status(ErrorCode::kInvalidArgument,
                      "replay option stamps=arrival applies only with pace=original (as fast as "
                      "consumers allow, arrival times say nothing about the recording)");
    }
    if (speed_given && out.pace == Pace::kFast) {
        return Status(ErrorCode::kInvalidArgument,
                      "replay option speed applies only with pace=original (pace=fast already "
                      "goes as fast as consumers allow)");
    }
    MIXRAY_RETURN_IF_ERROR(out.validate());
    return out;
}

Status ReplayOptions::validate() const {
    if (!(speed > 0) || !std::isfinite(speed)) {
        return {ErrorCode::kInvalidArgument, "replay: speed must be a positive number"};
    }
    if (!(start_s >= 0) || !std::isfinite(start_s) || start_s > 9.2e9) {
        return {ErrorCode::kInvalidArgument, "replay: start must be seconds >= 0"};
    }
    if (buffers_per_stream < 1) {
        return {ErrorCode::kInvalidArgument, "replay: buffers must be at least 1"};
    }
    return Status::ok();
}

Result<std::unique_ptr<ReplayDevice>> openReplayDevice(std::unique_ptr<RecordingReader> reader,
                                                       const DeviceConfig& config) {
    if (!reader)
        return {ErrorCode::kInvalidArgument, "replay: no recording reader"};
    if (config.name.empty()) {
        return {ErrorCode::kInvalidArgument, "replay device needs a name (DeviceConfig::name)"};
    }
    auto options = ReplayOptions::fromConfig(config.options);
    if (!options)
        return options.status();

    std::unique_ptr<ReplayDevice> device(new ReplayDevice());
    device->options_ = *options;
    device->config_name_ = config.name;
    const auto& streams = reader->streams();
    if (streams.empty()) {
        return {ErrorCode::kCorruptData, config.id + ": the recording has no streams"};
    }

    // Graph names: the short name, or the whole name with '_' for '/' when two recording
    // streams share a short name (a rig recording with two depth cameras).
    device->routes_.resize(streams.size());
    for (size_t i = 0; i < streams.size(); ++i) {
        const std::string_view short_name = detail::shortStreamName(streams[i].name);
        const bool unique = std::count_if(streams.begin(), streams.end(), [&](const auto& s) {
                                return detail::shortStreamName(s.name) == short_name;
                            }) == 1;
        std::string local = unique ? std::string(short_name) : streams[i].name;
        std::replace(local.begin(), local.end(), '/', '_');
        device->routes_[i].local_name = local;
        device->routes_[i].graph_name =
            options->recorded_names ? streams[i].name : config.name + "/" + local;
    }

    // Stream filter: recording names, short names or graph names.
    for (auto& route : device->routes_)
        route.enabled = config.streams.empty();
    for (const std::string& wanted : config.streams) {
        bool matched = false;
        for (size_t i = 0; i < streams.size(); ++i) {
            auto& route = device->routes_[i];
            if (wanted == streams[i].name || wanted == route.local_name ||
                wanted == route.graph_name) {
                route.enabled = true;
                matched = true;
            }
        }
        if (!matched) {
            std::string known;
            for (const auto& route : device->routes_) {
                known += (known.empty() ? "" : ", ") + route.local_name;
            }
            return {ErrorCode::kNotFound,
                    "replay: the recording has no stream '" + wanted + "' (it has: " + known + ")"};
        }
    }

    for (size_t i = 0; i < streams.size(); ++i) {
        auto& route = device->routes_[i];
        if (!route.enabled || streams[i].kind != StreamKind::kDepth ||
            streams[i].format.format != PixelFormat::kDepth16 || !options->depth_in_mm) {
            continue;
        }
        auto scale = depthScalePerMetre(streams[i]);
        if (!scale)
            return scale.status();
        if (*scale != kMillimetresPerMetre)
            route.convert_from_per_m = *scale;
    }

    // Mode requests of a rig file must match what was recorded.
    for (const auto& [key, value] : config.options) {
        const std::string_view stream = modeKey(key);
        if (stream.empty())
            continue;
        bool found = false;
        for (size_t i = 0; i < streams.size(); ++i) {
            if (device->routes_[i].local_name != stream)
                continue;
            found = true;
            MIXRAY_RETURN_IF_ERROR(checkMode(key, value, streams[i]));
        }
        if (!found) {
            return {ErrorCode::kInvalidArgument, "replay option " + key +
                                                     ": the recording has no stream '" +
                                                     std::string(stream) + "'"};
        }
    }

    // Position at `start` now, so that a start past the end is an error of open().
    const auto readOne = [&reader]() {
        for (int attempt = 0;; ++attempt) {
            auto frame = reader->next();
            if (frame || frame.status().code() != ErrorCode::kUnavailable || attempt > 1000) {
                return frame;
            }
            std::this_thread::sleep_for(kBufferWait);
        }
    };
    auto first = readOne();
    if (!first) {
        if (first.status().code() == ErrorCode::kEndOfStream) {
            return {ErrorCode::kCorruptData, config.id + ": the recording has no frames"};
        }
        return first.status().withContext(config.id);
    }
    FrameRef frame = std::move(*first);
    device->start_stamp_ns_ = frame.meta().host_stamp_ns;
    if (options->start_s > 0) {
        device->start_stamp_ns_ += std::llround(options->start_s * 1e9);
        frame.reset();  // give the buffer back before seeking
        MIXRAY_RETURN_IF_ERROR(reader->seek(device->start_stamp_ns_).withContext(config.id));
        auto at_start = readOne();
        if (!at_start) {
            if (at_start.status().code() == ErrorCode::kEndOfStream) {
                return {ErrorCode::kInvalidArgument,
                        "replay option start=" + config.options.at("start") +
                            " s is past the last frame of " + config.id};
            }
            return at_start.status().withContext(config.id);
        }
        frame = std::move(*at_start);
    }
    device->first_frame_ = std::move(frame);

    device->descriptor_.backend = "replay";
    device->descriptor_.id = config.id;
    device->descriptor_.model = reader->format() + " recording";
    auto serial = reader->tags().find("serial");
    if (serial != reader->tags().end())
        device->descriptor_.serial = serial->second;
    device->descriptor_.location = config.id;
    for (size_t i = 0; i < streams.size(); ++i) {
        const auto& s = streams[i];
        char fps[32];
        std::snprintf(fps, sizeof(fps), "@%g", s.nominal_fps);
        device->descriptor_.modes.push_back(
            device->routes_[i].local_name + " " + std::to_string(s.format.width) + "x" +
            std::to_string(s.format.height) + (s.nominal_fps > 0 ? fps : "") + " " +
            std::string(toString(s.format.format)));
    }
    device->reader_ = std::move(reader);
    return device;
}

ReplayDevice::~ReplayDevice() {
    stop();
}

Status ReplayDevice::connect(Graph& graph) {
    if (graph_)
        return {ErrorCode::kInvalidArgument, "replay device connected twice"};
    const auto& streams = reader_->streams();
    for (size_t i = 0; i < streams.size(); ++i) {
        auto& route = routes_[i];
        if (!route.enabled)
            continue;
        StreamInfo info = streams[i];
        info.name = route.graph_name;
        if (!options_.recorded_names)
            info.device = config_name_;
        if (route.convert_from_per_m)
            info.tags.erase(kDepthScaleTag);
        auto id = graph.addStream(std::move(info));
        if (!id)
            return id.status();
        route.graph_id = *id;
    }
    graph_ = &graph;
    return Status::ok();
}

Status ReplayDevice::start() {
    if (!graph_)
        return {ErrorCode::kInvalidArgument, "replay device started before connect()"};
    if (thread_.joinable())
        return Status::ok();
    if (!first_frame_) {
        // A second run plays from `start` again.
        MIXRAY_RETURN_IF_ERROR(reader_->seek(start_stamp_ns_));
    }
    {
        std::lock_guard lock(mutex_);
        stop_requested_ = false;
        status_ = Status::ok();
    }
    finished_ = false;
    thread_ = std::thread([this] { run(); });
    return Status::ok();
}

void ReplayDevice::stop() {
    {
        std::lock_guard lock(mutex_);
        stop_requested_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable())
        thread_.join();
}

Status ReplayDevice::status() const {
    std::lock_guard lock(mutex_);
    return status_;
}

void ReplayDevice::setError(Status status) {
    std::lock_guard lock(mutex_);
    status_ = std::move(status);
}

bool ReplayDevice::waitFor(Clock::duration duration) {
    std::unique_lock lock(mutex_);
    wake_.wait_for(lock, duration, [this] { return stop_requested_; });
    return !stop_requested_;
}

void ReplayDevice::run() {
    // At the recording's pace it stands in for a device: a frame late here is a frame lost
    // (thread_priority.h). As fast as it can, it is a batch job that waits on its consumers,
    // and at capture priority it would take the cores from every other process's devices.
    if (options_.pace == ReplayOptions::Pace::kOriginal)
        runAs(ThreadRole::kCapture);
    const auto stopping = [this] {
        std::lock_guard lock(mutex_);
        return stop_requested_;
    };
    const auto& streams = reader_->streams();

    // Pacing: wall time of the first published frame and its (shifted) stamp.
    bool clock_started = false;
    Clock::time_point wall0;
    int64_t stamp0 = 0;
    // Loop bookkeeping over the first pass (unshifted stamps).
    uint64_t pass = 0;
    int64_t shift_ns = 0;
    int64_t period_ns = 0;
    bool pass_seen = false;
    int64_t pass_first = 0, pass_last = 0;
    uint64_t distinct_stamps = 0;

    FrameRef frame = std::move(first_frame_);
    while (!stopping()) {
        if (!frame) {
            auto next = reader_->next();
            if (!next) {
                const ErrorCode code = next.status().code();
                if (code == ErrorCode::kUnavailable) {
                    if (!waitFor(kBufferWait))
                        break;
                    continue;
                }
                if (code == ErrorCode::kEndOfStream) {
                    passes_.fetch_add(1);
                    // The reader read past damage: the frames in it are lost, and said.
                    const std::vector<RecordingDamage> damage = reader_->damage();
                    if (!damage.empty()) {
                        setError({ErrorCode::kCorruptData,
                                  "replay " + descriptor_.id + ": " +
                                      std::to_string(damage.size()) +
                                      " damaged stretch(es) skipped, frames in them lost; the "
                                      "first at byte " +
                                      std::to_string(damage.front().byte_offset) + ": " +
                                      damage.front().what});
                    }
                    if (!options_.loop || !pass_seen)
                        break;
                    if (pass == 0) {
                        // One pass lasts its span plus one mean frame interval, so the next
                        // pass starts strictly after this one ended.
                        int64_t interval = kFallbackIntervalNs;
                        if (distinct_stamps > 1) {
                            interval = (pass_last - pass_first) /
                                       static_cast<int64_t>(distinct_stamps - 1);
                        } else {
                            double fps = 0;
                            for (const auto& s : streams)
                                fps = std::max(fps, s.nominal_fps);
                            if (fps > 0)
                                interval = std::llround(1e9 / fps);
                        }
                        period_ns = pass_last - pass_first + std::max<int64_t>(interval, 1);
                        for (auto& route : routes_) {
                            if (route.seen) {
                                route.sequence_shift =
                                    route.last_sequence - route.first_sequence + 1;
                            }
                        }
                    }
                    ++pass;
                    shift_ns += period_ns;
                    Status seek = reader_->seek(start_stamp_ns_);
                    if (!seek) {
                        setError(seek.withContext("replay: going back for the next loop"));
                        break;
                    }
                    continue;
                }
                setError(next.status().withContext("replay " + descriptor_.id));
                break;
            }
            frame = std::move(*next);
        }

        const FrameMetadata meta = frame.meta();
        if (meta.stream >= routes_.size() || !routes_[meta.stream].enabled) {
            frame.reset();
            continue;
        }
        StreamRoute& route = routes_[meta.stream];
        if (pass == 0) {
            if (!pass_seen || meta.host_stamp_ns != pass_last)
                ++distinct_stamps;
            if (!pass_seen)
                pass_first = meta.host_stamp_ns;
            pass_last = meta.host_stamp_ns;
            pass_seen = true;
            if (!route.seen)
                route.first_sequence = meta.sequence;
            route.last_sequence = meta.sequence;
            route.seen = true;
        }
        FrameMetadata out_meta = meta;
        out_meta.stream = route.graph_id;
        out_meta.host_stamp_ns += shift_ns;
        out_meta.device_stamp_ns += shift_ns;
        out_meta.sequence += route.sequence_shift * pass;

        if (options_.pace == ReplayOptions::Pace::kOriginal) {
            if (!clock_started) {
                wall0 = Clock::now();
                stamp0 = out_meta.host_stamp_ns;
                clock_started = true;
            }
            const double offset_ns =
                static_cast<double>(out_meta.host_stamp_ns - stamp0) / options_.speed;
            const auto target = wall0 + std::chrono::nanoseconds(std::llround(offset_ns));
            std::unique_lock lock(mutex_);
            if (wake_.wait_until(lock, target, [this] { return stop_requested_; }))
                break;
            lock.unlock();
        }
        out_meta.graph_stamp_ns = monotonicNowNs();
        // As a live device stamps it: on the host clock, at the instant the recording's timing
        // says it arrives (steady_clock is CLOCK_MONOTONIC). Not when this thread got round to
        // it: on a loaded machine the colour and depth of one instant leave a decode apart, and
        // stamped then they would no longer look like one instant to the synchronizer. How late
        // the frame really is stays in graph_stamp_ns, which latency is measured from.
        if (options_.arrival_stamps)
            out_meta.host_stamp_ns =
                std::chrono::duration_cast<std::chrono::nanoseconds>(
                    (wall0 +
                     std::chrono::nanoseconds(std::llround(
                         static_cast<double>(out_meta.host_stamp_ns - stamp0) / options_.speed)))
                        .time_since_epoch())
                    .count();

        // Forward the reader's buffer itself when this is its only handle; otherwise (or to
        // convert depth units) fill one of our own.
        FrameRef out;
        if (route.convert_from_per_m == 0) {
            WritableFrame writable = WritableFrame::reclaim(frame);
            if (writable) {
                writable.meta() = out_meta;
                out = std::move(writable).publish();
            }
        }
        if (!out) {
            if (!route.own_pool) {
                const StreamInfo& info = streams[meta.stream];
                route.own_pool = BufferPool::create(
                    {info.format, std::max(info.format.bufferBytes(), frame.image().size_bytes),
                     options_.buffers_per_stream, route.graph_name});
                if (!route.own_pool) {
                    setError({ErrorCode::kInternal,
                              "replay: cannot allocate buffers for '" + route.graph_name + "'"});
                    break;
                }
            }
            if (route.convert_from_per_m) {
                WritableFrame writable = route.own_pool->acquire();
                if (writable) {
                    Status status = rescaleDepth(frame.image(), route.convert_from_per_m,
                                                 writable.image(), kMillimetresPerMetre);
                    if (!status) {
                        setError(status.withContext("replay '" + route.graph_name + "'"));
                        break;
                    }
                    writable.meta() = out_meta;
                    out = std::move(writable).publish();
                }
            } else {
                out = copyIntoPool(*route.own_pool, frame.image(), out_meta);
            }
            if (!out) {
                // Consumers hold all of our buffers: wait, keeping the frame.
                if (!waitFor(kBufferWait))
                    break;
                continue;
            }
        }
        frame.reset();
        graph_->publish(out);
        published_.fetch_add(1, std::memory_order_relaxed);
    }
    frame.reset();
    for (const auto& route : routes_) {
        if (route.enabled)
            graph_->endStream(route.graph_id);
    }
    finished_ = true;
}

}  // namespace mixray::replay
