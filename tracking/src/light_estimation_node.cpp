// Light estimation as a graph node (mixray/tracking/light_estimation_node.h).
#include "mixray/tracking/light_estimation_node.h"

#include <algorithm>
#include <condition_variable>
#include <mutex>
#include <optional>

#include "mixray/graph/thread_priority.h"
#include "mixray/tracking/light_record.h"
#include "node_support.h"

namespace mixray::tracking {
namespace {

// Live, the probes are estimated about 5 times a second (PipelineOptions::probe_interval_ms).
constexpr int64_t kLiveProbeIntervalMs = 200;

constexpr auto kPoll = std::chrono::milliseconds(2);

double millisecondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
        .count();
}

bool hasDiffuseProbe(const TrackingSetup& setup) {
    return std::any_of(setup.probes.begin(), setup.probes.end(),
                       [](const LightProbe& p) { return p.material == ProbeMaterial::kDiffuse; });
}

}  // namespace

// Live: the probe estimates of the newest frame handed over, on a thread of its own, so that
// light records keep the colour rate. The node's own probes_ and intensities_ are left alone:
// the worker keeps the current ones.
class LightEstimationNode::ProbeWorker {
public:
    ProbeWorker(const TrackingSetup& setup, size_t probes) : setup_(setup) {
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
        for (auto& probe : current_.probes)
            probe.keep(why, stamp);
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
        // A late estimate holds up no composite: each light record takes the newest there is.
        runAs(ThreadRole::kEstimator);
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
            estimateFrameProbes(setup_, job.color.view(), job.T_world_camera, job.stamp, frame);
            lock.lock();
            current_.probes = std::move(frame.probes);
            current_.intensities = std::move(frame.intensities);
        }
    }

    const TrackingSetup& setup_;
    mutable std::mutex mutex_;
    std::condition_variable cv_;
    std::optional<Job> pending_;
    TrackedFrame current_;
    bool stop_ = false;
    std::thread thread_;
};

Result<std::unique_ptr<LightEstimationNode>> LightEstimationNode::create(
    std::shared_ptr<const TrackingNodeOptions> options, Callback on_lights) {
    if (!options)
        return Status(ErrorCode::kInvalidArgument, "light estimation node: no options");
    MIXRAY_RETURN_IF_ERROR(options->validate());
    return std::unique_ptr<LightEstimationNode>(
        new LightEstimationNode(std::move(options), std::move(on_lights)));
}

LightEstimationNode::LightEstimationNode(std::shared_ptr<const TrackingNodeOptions> options,
                                         Callback on_lights)
    : options_(std::move(options)),
      pipeline_(options_->pipeline),
      on_lights_(std::move(on_lights)) {
    if (!options_->lossless && pipeline_.probe_interval_ms == 0)
        pipeline_.probe_interval_ms = kLiveProbeIntervalMs;
}

LightEstimationNode::~LightEstimationNode() {
    stop();
}

Status LightEstimationNode::connect(Graph& graph) {
    graph_ = &graph;
    const TrackingSetup& setup = options_->setup;
    const bool lossless = options_->lossless;
    const QueuePolicy policy = lossless ? QueuePolicy::kLossless : QueuePolicy::kLive;
    auto color = detail::findStream(graph, setup.camera.stream, "to estimate lights in");
    if (!color)
        return color.status();
    auto pose = detail::findStream(graph, options_->pose_stream, "of the camera's poses");
    if (!pose)
        return pose.status();
    // Live, the colour frame a pose belongs to is the newest or the one before.
    auto color_queue =
        graph.subscribe(*color, {lossless ? options_->queue_capacity : 2, policy, name()});
    if (!color_queue)
        return color_queue.status();
    color_queue_ = std::move(color_queue).value();
    addInput(color_queue_);
    auto pose_queue =
        graph.subscribe(*pose, {lossless ? options_->queue_capacity : 4, policy, name()});
    if (!pose_queue)
        return pose_queue.status();
    pose_queue_ = std::move(pose_queue).value();
    addInput(pose_queue_);

    has_environment_stream_ = pipeline_.environment && setup.environment &&
                              graph.findStream(setup.environment->stream).has_value();
    if (has_environment_stream_) {
        auto records = detail::findStream(graph, options_->environment_light_stream,
                                          "of the fish-eye's lights");
        if (!records)
            return records.status();
        auto record_queue =
            graph.subscribe(*records, {lossless ? options_->queue_capacity : 2, policy, name()});
        if (!record_queue)
            return record_queue.status();
        environment_record_queue_ = std::move(record_queue).value();
        addInput(environment_record_queue_);
        if (lossless) {
            // Only to know which images were taken before each colour frame: their records
            // must come before its lights can.
            auto images = graph.subscribe(*graph.findStream(setup.environment->stream),
                                          {options_->queue_capacity, policy, name()});
            if (!images)
                return images.status();
            environment_image_queue_ = std::move(images).value();
            addInput(environment_image_queue_);
        }
    }

    const StreamInfo info = graph.stream(*color);
    const double fps = info.nominal_fps > 0 ? info.nominal_fps : 30;
    // Live, as many as the pose stream's (MarkerTrackingNode::connect says why).
    const size_t buffers = lossless
                               ? options_->output_buffers
                               : std::max(options_->output_buffers, static_cast<size_t>(1.5 * fps));
    StreamInfo lights = makeLightStreamInfo(options_->light_stream, info.name, fps);
    lights.device = options_->name;
    lights.clock_domain = info.clock_domain;
    auto out = addPooledStream(graph, lights, buffers);
    if (!out)
        return out.status();
    light_out_ = std::move(out).value();

    if (pipeline_.camera_environment && !has_environment_stream_) {
        auto created = CameraEnvironment::create(*pipeline_.camera_environment);
        if (!created)
            return created.status().withContext("camera_environment");
        camera_environment_.emplace(std::move(created).value());
        auto maps =
            detail::addEnvironmentMapStream(graph, options_->environment_map_stream, options_->name,
                                            info, pipeline_.camera_environment->width);
        if (!maps)
            return maps.status();
        camera_map_out_ = std::move(maps).value();
    }

    probes_.resize(pipeline_.probes ? setup.probes.size() : 0);
    return Status::ok();
}

LightEstimationStats LightEstimationNode::stats() const {
    std::lock_guard lock(stats_mutex_);
    return stats_;
}

void LightEstimationNode::run() {
    if (options_->lossless) {
        runLossless();
    } else {
        if (!probes_.empty())
            probe_worker_ = std::make_unique<ProbeWorker>(options_->setup, probes_.size());
        runLive();
        probe_worker_.reset();
    }
    if (camera_environment_)
        finish(Status::ok(), {light_out_.id, camera_map_out_.id});
    else
        finish(Status::ok(), {light_out_.id});
}

void LightEstimationNode::takeEnvironment() {
    if (environment_image_queue_)
        while (auto image = environment_image_queue_->tryPop())
            environment_stamps_.push_back(image->meta().host_stamp_ns);
    if (!environment_record_queue_)
        return;
    while (auto record = environment_record_queue_->tryPop())
        environment_records_.push_back(std::move(*record));
    if (environment_record_queue_->closed() && environment_record_queue_->stats().size == 0)
        environment_ended_ = true;
}

namespace {

// The fish-eye's estimate as its record carries it (no map: that has a stream of its own).
void applyEnvironmentRecord(const FrameRef& frame, Estimate<EnvironmentEstimate>& estimate) {
    auto record = decodeLightRecord(frame.image());
    if (!record)
        return;
    for (const LightGroup& group : record->groups) {
        if (group.name != "environment")
            continue;
        if (group.good_stamp_ns > 0)
            estimate.value = EnvironmentEstimate{group.lights, nullptr};
        estimate.stale = group.stale;
        estimate.reason = group.reason;
        estimate.stamp_ns = group.stamp_ns;
        estimate.good_stamp_ns = group.good_stamp_ns;
    }
}

}  // namespace

bool LightEstimationNode::environmentUpTo(int64_t stamp) {
    if (!has_environment_stream_)
        return true;
    // One source publishes every stream in time order, so every image stamped at or before
    // the colour frame was published before the frame after it, which the caller has seen:
    // the images are in environment_stamps_ and their records are coming.
    int64_t newest_needed = -1;
    while (true) {
        takeEnvironment();
        while (!environment_stamps_.empty() && environment_stamps_.front() <= stamp) {
            newest_needed = environment_stamps_.front();
            environment_stamps_.pop_front();
        }
        const bool have = newest_needed < 0 ||
                          (!environment_records_.empty() &&
                           environment_records_.back().meta().host_stamp_ns >= newest_needed);
        if (have || environment_ended_)
            break;
        if (stop_)
            return false;
        if (auto record = environment_record_queue_->pop(kPoll))
            environment_records_.push_back(std::move(*record));
    }
    while (!environment_records_.empty() &&
           environment_records_.front().meta().host_stamp_ns <= stamp) {
        applyEnvironmentRecord(environment_records_.front(), environment_);
        environment_records_.pop_front();
    }
    return true;
}

void LightEstimationNode::runLossless() {
    std::deque<FrameRef> colors;
    bool colors_ended = false;
    while (!stop_) {
        takeEnvironment();
        auto pose = pose_queue_->pop(kPoll);
        if (!pose) {
            if (!pose_queue_->closed())
                continue;
            pose = pose_queue_->tryPop();
            if (!pose)
                break;
        }
        const auto record = decodePoseRecord(pose->image());
        const uint64_t sequence = record ? record->frame_sequence : pose->meta().sequence;
        // The pose's colour frame, and the one after it (or the end of the stream).
        while (!stop_) {
            while (!colors.empty() && colors.front().meta().sequence < sequence)
                colors.pop_front();
            const bool after = colors.size() >= 2 ||
                               (!colors.empty() && colors.front().meta().sequence > sequence);
            if (after || colors_ended)
                break;
            takeEnvironment();
            auto color = color_queue_->pop(kPoll);
            if (!color && color_queue_->closed()) {
                color = color_queue_->tryPop();
                colors_ended = !color;
            }
            if (color)
                colors.push_back(std::move(*color));
        }
        if (stop_ || !environmentUpTo(pose->meta().host_stamp_ns))
            break;
        const bool found = !colors.empty() && colors.front().meta().sequence == sequence;
        estimate(*pose, record, found ? colors.front() : FrameRef());
    }
}

void LightEstimationNode::runLive() {
    FrameRef colors[2];  // the newest two: a pose belongs to one of them
    while (!stop_) {
        auto pose = pose_queue_->pop(kPoll);
        takeEnvironment();
        while (!environment_records_.empty()) {
            applyEnvironmentRecord(environment_records_.front(), environment_);
            environment_records_.pop_front();
        }
        while (auto color = color_queue_->tryPop()) {
            colors[0] = std::move(colors[1]);
            colors[1] = std::move(*color);
        }
        if (!pose) {
            if (pose_queue_->closed() && !(pose = pose_queue_->tryPop()))
                break;
            if (!pose)
                continue;
        }
        // Keep up: a record for every pose, but the probes only for the newest.
        auto record = decodePoseRecord(pose->image());
        FrameRef color;
        for (const FrameRef& c : colors)
            if (c && record && c.meta().sequence == record->frame_sequence)
                color = c;
        estimate(*pose, record, color);
    }
}

void LightEstimationNode::estimate(const FrameRef& pose_frame, const Result<PoseRecord>& pose,
                                   const FrameRef& color) {
    const TrackingSetup& setup = options_->setup;
    const FrameMetadata& meta = pose_frame.meta();  // the colour frame's, on the pose stream
    const int64_t stamp = meta.host_stamp_ns;
    const uint64_t sequence = pose ? pose->frame_sequence : meta.sequence;
    TrackedFrame f;
    f.color = color;

    if (pipeline_.site) {
        if (!pipeline_.utc_minus_host_ns && pipeline_.utc_first_frame_ns)
            pipeline_.utc_minus_host_ns = *pipeline_.utc_first_frame_ns - stamp;
        if (!pipeline_.utc_minus_host_ns) {
            sun_.keep("the time of day is unknown: the recording has no " +
                          std::string(kUtcMinusHostTag) + " tag (give --utc)",
                      stamp);
        } else {
            auto to_sun = sunDirectionWorld(*pipeline_.site, stamp + *pipeline_.utc_minus_host_ns);
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
        f.sun = sun_;
    }
    if (has_environment_stream_) {
        f.environment = environment_;
        // stamp_ns is the newest environment image's, fresh or not: silence is its age.
        const int64_t silent_ns = stamp - f.environment.stamp_ns;
        if (pipeline_.environment_max_age_ms > 0 && f.environment.stamp_ns > 0 &&
            silent_ns > pipeline_.environment_max_age_ms * 1'000'000)
            f.environment.keep("the environment camera sent no image for " +
                                   std::to_string(silent_ns / 1'000'000) + " ms",
                               stamp);
    } else if (setup.environment && pipeline_.environment) {
        f.environment.keep("the recording has no stream " + setup.environment->stream, stamp);
    }

    const auto start = std::chrono::steady_clock::now();
    const bool fresh_pose = pose && pose->status == PoseStatus::kValid;
    // Between two probe estimates (probe_interval_ms) the last ones stand as they are.
    const bool probe_due = !probes_.empty() && (pipeline_.probe_interval_ms <= 0 || !probed_ ||
                                                stamp - last_probe_stamp_ns_ >=
                                                    pipeline_.probe_interval_ms * 1'000'000);
    const bool diffuse = hasDiffuseProbe(setup) && !probes_.empty();
    if (probe_due && !fresh_pose) {
        const std::string why =
            "no fresh camera pose (" + (pose ? pose->reason : pose.status().message()) + ")";
        if (probe_worker_) {
            probe_worker_->keep(why, stamp, diffuse);
        } else {
            for (auto& p : probes_)
                p.keep(why, stamp);
            if (diffuse)
                intensities_.keep("no fresh camera pose", stamp);
        }
    } else if (probe_due && color) {
        // Live, a frame whose image a newer one replaced waits for the next.
        probed_ = true;
        last_probe_stamp_ns_ = stamp;
        if (probe_worker_) {
            probe_worker_->submit(color.image(), pose->transform(), stamp, f);
        } else {
            f.probes = std::move(probes_);
            f.intensities = std::move(intensities_);
            estimateFrameProbes(setup, color.image(), pose->transform(), stamp, f);
            probes_ = f.probes;
            intensities_ = f.intensities;
        }
    }
    // Between estimates (and live, until the worker finishes) the last ones stand.
    if (probe_worker_) {
        probe_worker_->latest(f);
    } else if (f.probes.empty()) {
        f.probes = probes_;
        f.intensities = intensities_;
    }
    f.probe_ms = millisecondsSince(start);

    LightRecord record;
    record.frame_sequence = sequence;
    record.frame_device_stamp_ns = pose ? pose->frame_device_stamp_ns : meta.device_stamp_ns;
    LightGroup render;
    render.name = "render";
    render.lights = renderLights(setup, f);
    render.stale = render.lights.empty();
    if (render.stale)
        render.reason = "no light estimated yet";
    render.stamp_ns = stamp;
    render.good_stamp_ns = render.stale ? 0 : stamp;
    record.groups.push_back(std::move(render));
    for (size_t i = 0; i < f.probes.size(); ++i)
        record.groups.push_back(toLightGroup("probe:" + setup.probes[i].name, f.probes[i]));
    if (setup.environment && pipeline_.environment)
        record.groups.push_back(toLightGroup("environment", f.environment));
    if (f.sun.value || !f.sun.reason.empty())
        record.groups.push_back(toLightGroup("sun", f.sun));
    if (camera_environment_) {
        if (fresh_pose && color)
            addToCameraEnvironment(color, *pose, meta);
        else if (!camera_environment_estimate_.value)
            camera_environment_estimate_.keep("no colour frame with a fresh pose yet", stamp);
        record.groups.push_back(toLightGroup("camera_environment", camera_environment_estimate_));
    }

    // Observers first: whoever consumes the record may then find the frame it came from.
    if (on_lights_)
        on_lights_(sequence, f);
    const bool published = detail::publishEncoded(*graph_, light_out_, encodeLightRecord(record),
                                                  meta, options_->lossless, stop_);
    std::lock_guard lock(stats_mutex_);
    ++(published ? stats_.light_records : stats_.publish_failures);
}

void LightEstimationNode::addToCameraEnvironment(const FrameRef& color, const PoseRecord& pose,
                                                 const FrameMetadata& meta) {
    const int64_t stamp = meta.host_stamp_ns;
    if (Status added =
            camera_environment_->add(color.image(), options_->setup.camera.model, pose.transform());
        !added) {
        // The last map stands; the group says why this frame did not join it.
        camera_environment_estimate_.keep(added.message(), stamp);
        return;
    }
    // A map is due after `interval` frames, and at once after a frame that could not join (the
    // group went stale saying why; the next map makes it fresh again).
    if (camera_environment_estimate_.value && !camera_environment_estimate_.stale &&
        ++camera_frames_since_map_ < pipeline_.camera_environment_interval)
        return;
    camera_frames_since_map_ = 0;
    camera_environment_estimate_.update(
        EnvironmentEstimate{{}, std::make_shared<const FloatImage>(camera_environment_->map())},
        stamp);
    FrameMetadata map_meta = meta;
    map_meta.sequence = stats().camera_environment_maps;
    const bool published = detail::publishEnvironmentMap(
        *graph_, camera_map_out_, *camera_environment_estimate_.value->environment_map,
        toEnvironmentMapHeader(pose.frame_sequence, pose.frame_device_stamp_ns,
                               camera_environment_estimate_),
        map_meta, options_->lossless, stop_);
    std::lock_guard lock(stats_mutex_);
    ++(published ? stats_.camera_environment_maps : stats_.publish_failures);
}

}  // namespace mixray::tracking
