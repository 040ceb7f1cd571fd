// The tracking half of the AR pipeline (mixray/tracking/pipeline.h).
#include "mixray/tracking/pipeline.h"

#include <charconv>
#include <chrono>
#include <cmath>
#include <ctime>
#include <iomanip>
#include <sstream>

namespace mixray::tracking {
namespace {

namespace fs = std::filesystem;

double millisecondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
        .count();
}

StreamId findStream(const std::vector<StreamInfo>& streams, const std::string& name) {
    for (StreamId i = 0; i < streams.size(); ++i)
        if (streams[i].name == name)
            return i;
    return kInvalidStream;
}

std::string streamList(const std::vector<StreamInfo>& streams) {
    std::string names;
    for (const StreamInfo& s : streams)
        names += (names.empty() ? "" : ", ") + s.name;
    return names.empty() ? "none" : names;
}

}  // namespace

Result<TrackingSetup> findTrackingSetup(const fs::path& recording, const RecordingReader& reader,
                                        const std::string& explicit_path) {
    if (!explicit_path.empty())
        return loadTrackingSetup(explicit_path);
    for (const Attachment& a : reader.attachments()) {
        if (a.name == "tracking.yaml") {
            const std::string text(a.data.begin(), a.data.end());
            return parseTrackingSetup(text, recording.string() + ":tracking.yaml");
        }
    }
    fs::path beside = recording;
    beside.replace_extension(".tracking.yaml");
    std::error_code ec;
    if (fs::exists(beside, ec))
        return loadTrackingSetup(beside);
    return Status(ErrorCode::kNotFound,
                  "no tracking setup: give --setup FILE (docs/tracking.md#setup-files); the "
                  "recording has no tracking.yaml attachment and " +
                      beside.string() + " does not exist");
}

Result<std::optional<RigSite>> findRigSite(const RecordingReader& reader,
                                           const std::string& rig_path) {
    std::optional<RigDescription> rig;
    if (!rig_path.empty()) {
        auto loaded = loadRig(rig_path);
        if (!loaded)
            return loaded.status();
        rig = std::move(loaded).value();
    } else {
        for (const Attachment& a : reader.attachments()) {
            if (a.name != "rig.yaml")
                continue;
            auto parsed = parseRig(std::string(a.data.begin(), a.data.end()), "rig.yaml");
            if (!parsed)
                return parsed.status().withContext("the recording's rig.yaml");
            rig = std::move(parsed).value();
        }
    }
    if (!rig)
        return std::optional<RigSite>();
    return rig->site;
}

Result<int64_t> parseUtc(const std::string& text) {
    std::tm tm{};
    std::istringstream in(text);
    in >> std::get_time(&tm, "%Y-%m-%dT%H:%M:%S");
    double fraction = 0;
    if (!in.fail() && in.peek() == '.') {
        std::string digits;
        in.get();
        while (std::isdigit(in.peek()))
            digits += static_cast<char>(in.get());
        fraction = digits.empty() ? 0 : std::stod("0." + digits);
    }
    char zone = 0;
    in >> zone;
    if (in.fail() || zone != 'Z' || in.peek() != std::char_traits<char>::eof())
        return Status(ErrorCode::kInvalidArgument,
                      "--utc " + text +
                          ": expected UTC as 2026-06-21T12:00:00Z (seconds may have a fraction)");
    const int64_t seconds = static_cast<int64_t>(timegm(&tm));
    return seconds * 1'000'000'000 + static_cast<int64_t>(std::llround(fraction * 1e9));
}

Result<std::optional<int64_t>> recordingUtcOffset(const RecordingReader& reader) {
    const auto tag = reader.tags().find(std::string(kUtcMinusHostTag));
    if (tag == reader.tags().end())
        return std::optional<int64_t>();
    int64_t offset = 0;
    const std::string& text = tag->second;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), offset);
    if (ec != std::errc() || end != text.data() + text.size())
        return Status(ErrorCode::kCorruptData, "the recording's " + std::string(kUtcMinusHostTag) +
                                                   " tag is not an integer: " + text);
    return std::optional<int64_t>(offset);
}

TrackingPipeline::~TrackingPipeline() = default;

Result<std::unique_ptr<TrackingPipeline>> TrackingPipeline::create(
    TrackingSetup setup, const std::vector<StreamInfo>& streams, const PipelineOptions& options) {
    MIXRAY_RETURN_IF_ERROR(setup.validate());
    std::unique_ptr<TrackingPipeline> p(new TrackingPipeline);
    p->options_ = options;
    p->color_ = findStream(streams, setup.camera.stream);
    if (p->color_ == kInvalidStream)
        return Status(ErrorCode::kNotFound, "the recording has no stream " + setup.camera.stream +
                                                " to track (it has: " + streamList(streams) + ")");
    const ImageDesc& c = streams[p->color_].format;
    if (c.width != setup.camera.model.width || c.height != setup.camera.model.height) {
        return Status(ErrorCode::kInvalidArgument,
                      setup.camera.stream + " is " + std::to_string(c.width) + "x" +
                          std::to_string(c.height) + " but the setup's camera model is " +
                          std::to_string(setup.camera.model.width) + "x" +
                          std::to_string(setup.camera.model.height));
    }
    auto tracker = MarkerTracker::create(setup.camera.model, setup.targets, setup.tracker);
    if (!tracker)
        return tracker.status();
    p->tracker_ = std::move(tracker).value();
    if (options.environment && setup.environment) {
        p->environment_ = findStream(streams, setup.environment->stream);
        if (p->environment_ != kInvalidStream) {
            p->environment_estimator_ = std::make_unique<AsyncEnvironmentEstimator>(
                setup.environment->camera, setup.environment->lights, setup.environment->map_width);
        }
    }
    p->probes_.resize(options.probes ? setup.probes.size() : 0);
    p->setup_ = std::move(setup);
    return p;
}

Result<std::optional<TrackedFrame>> TrackingPipeline::push(const FrameRef& frame) {
    const StreamId stream = frame.meta().stream;
    const int64_t stamp = frame.meta().host_stamp_ns;
    if (environment_estimator_ && stream == environment_) {
        environment_estimator_->submit(frame.image(), stamp);
        if (options_.wait_for_environment)
            environment_estimator_->drain();
        return std::optional<TrackedFrame>();
    }
    if (stream != color_)
        return std::optional<TrackedFrame>();

    TrackedFrame out;
    out.index = frames_++;
    out.color = frame;
    auto start = std::chrono::steady_clock::now();
    auto track = tracker_->track(frame.image(), stamp);
    if (!track)
        return track.status().withContext(setup_.camera.stream + " frame " +
                                          std::to_string(frame.meta().sequence));
    out.track = std::move(track).value();
    out.track_ms = millisecondsSince(start);

    const bool fresh_pose =
        out.track.state == TrackState::kTracking && out.track.pose.value.has_value();
    start = std::chrono::steady_clock::now();
    // Between two probe estimates (probe_interval_ms) the last ones stand as they are.
    const bool probe_due = options_.probe_interval_ms <= 0 || !probed_ ||
                           stamp - last_probe_stamp_ns_ >= options_.probe_interval_ms * 1'000'000;
    if (probe_due && fresh_pose) {
        probed_ = true;
        last_probe_stamp_ns_ = stamp;
    }
    for (size_t i = 0; i < probes_.size() && probe_due; ++i) {
        const LightProbe& probe = setup_.probes[i];
        if (!fresh_pose) {
            probes_[i].keep("no fresh camera pose (" + out.track.pose.reason + ")", stamp);
            continue;
        }
        auto lights = estimateProbeLights(frame.image(), setup_.camera.model, *out.track.pose.value,
                                          probe, setup_.probe_options);
        if (lights)
            probes_[i].update(std::move(lights).value(), stamp);
        else
            probes_[i].keep(probe.name + ": " + lights.status().message(), stamp);
    }
    out.probe_ms = millisecondsSince(start);
    out.probes = probes_;
    if (options_.site) {
        if (!options_.utc_minus_host_ns && options_.utc_first_frame_ns)
            options_.utc_minus_host_ns = *options_.utc_first_frame_ns - stamp;
        if (!options_.utc_minus_host_ns) {
            sun_.keep("the time of day is unknown: the recording has no " +
                          std::string(kUtcMinusHostTag) + " tag (give --utc)",
                      stamp);
        } else {
            auto to_sun = sunDirectionWorld(*options_.site, stamp + *options_.utc_minus_host_ns);
            if (!to_sun) {
                sun_.keep(to_sun.status().message(), stamp);
            } else if (to_sun->z() <= 0) {
                sun_.keep("the sun is below the horizon", stamp);
            } else {
                EstimatedLight sun;
                sun.source = LightSource::kSun;
                sun.to_light_world = *to_sun;
                sun.angular_radius_rad = 0.2666 * M_PI / 180;  // the sun's mean apparent radius
                sun_.update(sun, stamp);
            }
        }
        out.sun = sun_;
    }
    if (environment_estimator_) {
        out.environment = environment_estimator_->latest();
        // stamp_ns is the newest environment image's, fresh or not: silence is its age.
        const int64_t silent_ns = stamp - out.environment.stamp_ns;
        if (options_.environment_max_age_ms > 0 && out.environment.stamp_ns > 0 &&
            silent_ns > options_.environment_max_age_ms * 1'000'000)
            out.environment.keep("the environment camera sent no image for " +
                                     std::to_string(silent_ns / 1'000'000) + " ms",
                                 stamp);
    } else if (setup_.environment)
        out.environment.keep("the recording has no stream " + setup_.environment->stream, stamp);

    // Strengths of the lights whose directions are known, from a diffuse probe.
    const std::vector<EstimatedLight> directions = lightDirections(out);
    const LightProbe* diffuse = nullptr;
    for (size_t i = 0; i < probes_.size(); ++i)
        if (setup_.probes[i].material == ProbeMaterial::kDiffuse)
            diffuse = &setup_.probes[i];
    if (!probe_due) {
        // The last fit stands until the next probe estimate.
    } else if (diffuse && fresh_pose && !directions.empty()) {
        std::vector<Eigen::Vector3d> to_light;
        for (const EstimatedLight& l : directions)
            to_light.push_back(l.to_light_world);
        IntensityFitOptions fit_options;
        fit_options.albedo = diffuse->albedo;
        auto fit = fitLightIntensities(frame.image(), setup_.camera.model, *out.track.pose.value,
                                       *diffuse, to_light, fit_options);
        if (fit)
            intensities_.update(std::move(fit).value(), stamp);
        else
            intensities_.keep(fit.status().message(), stamp);
    } else if (diffuse) {
        intensities_.keep(fresh_pose ? "no light directions yet" : "no fresh camera pose", stamp);
    }
    out.intensities = intensities_;
    return std::optional<TrackedFrame>(std::move(out));
}

std::vector<EstimatedLight> TrackingPipeline::lightDirections(const TrackedFrame& frame) const {
    if (frame.environment.value && !frame.environment.value->lights.empty())
        return frame.environment.value->lights;
    if (frame.sun.value && !frame.sun.stale)
        return {*frame.sun.value};
    // Without the fish-eye: a mirror probe's highlights (sharp), else a diffuse probe's.
    for (ProbeMaterial material : {ProbeMaterial::kMirror, ProbeMaterial::kDiffuse}) {
        for (size_t i = 0; i < frame.probes.size(); ++i)
            if (setup_.probes[i].material == material && frame.probes[i].value &&
                !frame.probes[i].value->lights.empty())
                return frame.probes[i].value->lights;
    }
    return {};
}

std::vector<EstimatedLight> TrackingPipeline::renderLights(const TrackedFrame& frame) const {
    std::vector<EstimatedLight> out = lightDirections(frame);
    const bool fitted =
        frame.intensities.value && frame.intensities.value->irradiance.size() == out.size();
    if (fitted)
        for (size_t i = 0; i < out.size(); ++i)
            out[i].intensity = frame.intensities.value->irradiance[i];
    std::erase_if(out, [](const EstimatedLight& l) { return l.intensity.maxCoeff() <= 0; });
    return out;
}

}  // namespace mixray::tracking
