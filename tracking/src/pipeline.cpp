// The tracking half of the AR pipeline (mixray/tracking/pipeline.h).
#include "mixray/tracking/pipeline.h"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <ctime>
#include <iomanip>
#include <mutex>
#include <sstream>
#include <thread>

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

// The probe estimates of the newest frame handed over, on a thread of its own. The pipeline's
// own probes_ and intensities_ are left alone: the worker keeps the current ones.
class TrackingPipeline::ProbeWorker {
public:
    ProbeWorker(const TrackingPipeline& pipeline, size_t probes) : pipeline_(pipeline) {
        current_.probes.resize(probes);
        thread_ = std::thread([this] { run(); });
    }
    ~ProbeWorker() {
        {
            std::lock_guard lock(mutex_);
            stop_ = true;
        }
        cv_.notify_all();
        thread_.join();
    }
    ProbeWorker(const ProbeWorker&) = delete;
    ProbeWorker& operator=(const ProbeWorker&) = delete;

    // Copies the image; a job not yet started is replaced by the newer one.
    void submit(const ImageView& color, const Eigen::Isometry3d& T_world_camera, int64_t stamp,
                const TrackedFrame& frame) {
        Job job;
        job.color = Image::copyOf(color);
        job.T_world_camera = T_world_camera;
        job.stamp = stamp;
        job.environment = frame.environment;
        job.sun = frame.sun;
        {
            std::lock_guard lock(mutex_);
            pending_ = std::move(job);
        }
        cv_.notify_all();
    }
    // A frame without a fresh pose: the estimates stand, marked stale with the reason. A job
    // already running may finish afterwards and replace them with fresh estimates of its older
    // frame: they carry that frame's stamp, and the next frame without a pose marks them again.
    void keep(const std::string& why, int64_t stamp, bool diffuse) {
        std::lock_guard lock(mutex_);
        for (size_t i = 0; i < current_.probes.size(); ++i)
            current_.probes[i].keep(why, stamp);
        if (diffuse)
            current_.intensities.keep("no fresh camera pose", stamp);
    }
    void latest(TrackedFrame& out) const {
        std::lock_guard lock(mutex_);
        out.probes = current_.probes;
        out.intensities = current_.intensities;
    }

private:
    struct Job {
        Image color;
        Eigen::Isometry3d T_world_camera;
        int64_t stamp = 0;
        Estimate<EnvironmentEstimate> environment;
        Estimate<EstimatedLight> sun;
    };
    void run() {
        std::unique_lock lock(mutex_);
        while (true) {
            cv_.wait(lock, [this] { return stop_ || pending_; });
            if (stop_)
                return;
            Job job = std::move(*pending_);
            pending_.reset();
            TrackedFrame frame;
            frame.probes = current_.probes;
            frame.intensities = current_.intensities;
            frame.environment = std::move(job.environment);
            frame.sun = std::move(job.sun);
            lock.unlock();
            pipeline_.estimateProbes(job.color.view(), job.T_world_camera, job.stamp, frame);
            lock.lock();
            current_.probes = std::move(frame.probes);
            current_.intensities = std::move(frame.intensities);
        }
    }

    const TrackingPipeline& pipeline_;
    mutable std::mutex mutex_;
    std::condition_variable cv_;
    std::optional<Job> pending_;
    TrackedFrame current_;
    bool stop_ = false;
    std::thread thread_;
};

TrackingPipeline::TrackingPipeline() = default;
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
    if (options.async_probes && !p->probes_.empty()) {
        p->probe_worker_ = std::make_unique<ProbeWorker>(*p, p->probes_.size());
    }
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

    start = std::chrono::steady_clock::now();
    // Between two probe estimates (probe_interval_ms) the last ones stand as they are.
    const bool probe_due = options_.probe_interval_ms <= 0 || !probed_ ||
                           stamp - last_probe_stamp_ns_ >= options_.probe_interval_ms * 1'000'000;
    if (probe_due && fresh_pose) {
        probed_ = true;
        last_probe_stamp_ns_ = stamp;
    }
    const bool diffuse =
        std::any_of(setup_.probes.begin(), setup_.probes.end(),
                    [](const LightProbe& p) { return p.material == ProbeMaterial::kDiffuse; }) &&
        !probes_.empty();
    if (probe_due && !fresh_pose) {
        const std::string why = "no fresh camera pose (" + out.track.pose.reason + ")";
        if (probe_worker_) {
            probe_worker_->keep(why, stamp, diffuse);
        } else {
            for (auto& p : probes_)
                p.keep(why, stamp);
            if (diffuse)
                intensities_.keep("no fresh camera pose", stamp);
        }
    } else if (probe_due && probe_worker_) {
        probe_worker_->submit(frame.image(), *out.track.pose.value, stamp, out);
    } else if (probe_due && !probes_.empty()) {
        out.probes = std::move(probes_);
        out.intensities = std::move(intensities_);
        estimateProbes(frame.image(), *out.track.pose.value, stamp, out);
        probes_ = out.probes;
        intensities_ = out.intensities;
        out.probe_ms = millisecondsSince(start);
        return std::optional<TrackedFrame>(std::move(out));
    }
    // Between estimates (and live, until the worker finishes) the last ones stand.
    if (probe_worker_) {
        probe_worker_->latest(out);
    } else {
        out.probes = probes_;
        out.intensities = intensities_;
    }
    out.probe_ms = millisecondsSince(start);
    return std::optional<TrackedFrame>(std::move(out));
}

void TrackingPipeline::estimateProbes(const ImageView& color,
                                      const Eigen::Isometry3d& T_world_camera, int64_t stamp,
                                      TrackedFrame& frame) const {
    for (size_t i = 0; i < frame.probes.size(); ++i) {
        const LightProbe& probe = setup_.probes[i];
        auto lights = estimateProbeLights(color, setup_.camera.model, T_world_camera, probe,
                                          setup_.probe_options);
        if (lights)
            frame.probes[i].update(std::move(lights).value(), stamp);
        else
            frame.probes[i].keep(probe.name + ": " + lights.status().message(), stamp);
    }
    // Strengths of the lights whose directions are known, from a diffuse probe.
    const LightProbe* diffuse = nullptr;
    for (size_t i = 0; i < frame.probes.size(); ++i)
        if (setup_.probes[i].material == ProbeMaterial::kDiffuse)
            diffuse = &setup_.probes[i];
    if (!diffuse)
        return;
    const std::vector<EstimatedLight> directions = lightDirections(frame);
    if (directions.empty()) {
        frame.intensities.keep("no light directions yet", stamp);
        return;
    }
    std::vector<Eigen::Vector3d> to_light;
    for (const EstimatedLight& l : directions)
        to_light.push_back(l.to_light_world);
    IntensityFitOptions fit_options;
    fit_options.albedo = diffuse->albedo;
    auto fit = fitLightIntensities(color, setup_.camera.model, T_world_camera, *diffuse, to_light,
                                   fit_options);
    if (fit)
        frame.intensities.update(std::move(fit).value(), stamp);
    else
        frame.intensities.keep(fit.status().message(), stamp);
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
