// The compositor as a graph node (mixray/render/compositor_node.h).
#include "mixray/render/compositor_node.h"

#include <algorithm>
#include <cmath>

#include "mixray/graph/host_time.h"
#include "mixray/graph/thread_priority.h"

namespace mixray::render {
namespace {

constexpr size_t kLatencyWindow = 1024;
constexpr size_t kEnvironmentMapsKept = 4;
constexpr auto kPollInterval = std::chrono::milliseconds(10);

Rgb rgb(const Eigen::Vector3d& v) {
    return Rgb(static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z()));
}

std::string_view shadowName(SoftShadowMethod m) {
    switch (m) {
        case SoftShadowMethod::kHard:
            return "hard";
        case SoftShadowMethod::kUniform:
            return "uniform";
        case SoftShadowMethod::kAdaptive:
            return "adaptive";
    }
    return "?";
}

double percentile(std::vector<double>& sorted, double p) {
    if (sorted.empty())
        return 0;
    const size_t i = std::min(
        sorted.size() - 1,
        static_cast<size_t>(std::ceil(p * static_cast<double>(sorted.size()))) - (p > 0 ? 1 : 0));
    return sorted[i];
}

}  // namespace

std::vector<Light> lightsFromEstimates(const std::vector<tracking::EstimatedLight>& estimates,
                                       std::shared_ptr<const FloatImage> environment_map,
                                       const EstimatedLightSettings& settings) {
    std::vector<Light> out;
    for (size_t i = 0; i < estimates.size(); ++i) {
        const tracking::EstimatedLight& e = estimates[i];
        if (e.intensity.maxCoeff() <= 0)
            continue;
        Light l;
        l.name = "estimated_" + std::to_string(i);
        if (e.position_world && e.angular_radius_rad > 0) {
            const double d = e.position_world->norm();
            l.type = LightType::kSphere;
            l.position = *e.position_world;
            l.radius = static_cast<float>(d * std::tan(e.angular_radius_rad));
            l.intensity = rgb(e.intensity * d * d);
        } else {
            l.type = LightType::kDirectional;
            l.direction = -e.to_light_world.normalized();
            l.intensity = rgb(e.intensity);
        }
        l.shadow_map = settings.shadow_map;
        out.push_back(std::move(l));
    }
    if (environment_map) {
        Light env;
        env.name = "estimated_environment";
        env.type = LightType::kEnvironment;
        env.environment_image = std::move(environment_map);
        out.push_back(std::move(env));
    }
    return out;
}

std::string QualityStep::label() const {
    return "spp " + std::to_string(samples_per_pixel) + ", shadows " +
           std::string(shadowName(soft_shadows)) +
           (soft_shadows == SoftShadowMethod::kHard ? "" : "/" + std::to_string(shadow_samples)) +
           ", depth " + std::to_string(max_depth);
}

RenderOptions QualityStep::applied(RenderOptions options) const {
    options.samples_per_pixel = samples_per_pixel;
    options.shadow_samples = shadow_samples;
    options.max_depth = max_depth;
    options.soft_shadows = soft_shadows;
    return options;
}

std::string rungText(int step, int steps, const std::string& label) {
    return "rung " + std::to_string(step + 1) + " of " + std::to_string(steps) +
           (label.empty() ? "" : " (" + label + ")");
}

std::vector<QualityStep> qualityLadder(const RenderOptions& best) {
    std::vector<QualityStep> ladder;
    QualityStep s{best.samples_per_pixel, best.shadow_samples, best.max_depth, best.soft_shadows};
    const auto add = [&ladder](const QualityStep& step) {
        if (ladder.empty() || step.samples_per_pixel != ladder.back().samples_per_pixel ||
            step.shadow_samples != ladder.back().shadow_samples ||
            step.max_depth != ladder.back().max_depth ||
            step.soft_shadows != ladder.back().soft_shadows)
            ladder.push_back(step);
    };
    add(s);
    s.samples_per_pixel = 1;
    add(s);
    s.shadow_samples = std::max(4, s.shadow_samples / 2);
    add(s);
    s.max_depth = std::min(s.max_depth, 1);
    s.shadow_samples = std::min(s.shadow_samples, 4);
    add(s);
    s.soft_shadows = SoftShadowMethod::kHard;
    s.max_depth = 0;
    add(s);
    return ladder;
}

Status CompositorOptions::validate() const {
    if (name.empty() || color_stream.empty() || output_stream.empty())
        return {ErrorCode::kInvalidArgument,
                "compositor: name, color_stream and output_stream are required"};
    if (!(target_fps >= 0) || !std::isfinite(target_fps))
        return {ErrorCode::kInvalidArgument, "compositor: target_fps must be >= 0"};
    if (queue_capacity < 2 || output_buffers < 2)
        return {ErrorCode::kInvalidArgument,
                "compositor: queue_capacity and output_buffers must be at least 2"};
    return render.validate();
}

Result<std::unique_ptr<CompositorNode>> CompositorNode::create(CompositorOptions options,
                                                               SceneDescription scene,
                                                               CompositeCallback on_composite) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    MIXRAY_RETURN_IF_ERROR(scene.validate());
    std::unique_ptr<CompositorNode> node(
        new CompositorNode(std::move(options), std::move(scene), std::move(on_composite)));
    // The first rung now, so a scene that does not load fails here, not in the thread.
    auto first = node->renderer(0);
    if (!first)
        return first.status();
    if (!node->options_.lossless)
        MIXRAY_RETURN_IF_ERROR(node->warmUp());
    return node;
}

Status CompositorNode::warmUp() {
    // Live, every rung the ladder may step to is built and has rendered once before the first
    // frame comes: a renderer's first frame builds its camera-ray cache and thread state, which
    // took 50 to 150 ms of one frame's latency (each step down the ladder at start-up was
    // such a frame). A grey image seen from the identity pose; the output is thrown away.
    Image grey(
        ImageDesc::packed(PixelFormat::kRGB8, options_.camera.width, options_.camera.height));
    std::fill(grey.bytes().begin(), grey.bytes().end(), uint8_t{128});
    RenderInputs in;
    in.camera_image = grey.view();
    in.camera = options_.camera;
    in.T_world_anchor = options_.T_world_anchor;
    for (int step = 0; step < static_cast<int>(ladder_.size()); ++step) {
        auto r = renderer(step);
        if (!r)
            return r.status();
        MIXRAY_RETURN_IF_ERROR((*r)->render(in, layers_).withContext(options_.name + ": warm-up"));
    }
    return Status::ok();
}

CompositorNode::CompositorNode(CompositorOptions options, SceneDescription scene,
                               CompositeCallback on_composite)
    : options_(std::move(options)),
      scene_(std::move(scene)),
      on_composite_(std::move(on_composite)),
      ladder_(qualityLadder(options_.render)),
      renderers_(ladder_.size()),
      renderer_lights_version_(ladder_.size(), 0),
      quality_(static_cast<int>(ladder_.size()), options_.lossless ? 0 : options_.target_fps) {
    latencies_ms_.reserve(kLatencyWindow);
    stats_.quality_steps = static_cast<int>(ladder_.size());
    stats_.quality_label = ladder_.front().label();
    for (const SceneObject& object : scene_.objects)
        if (object.role == ObjectRole::kVirtual)
            stats_.objects.push_back({object.name, object.anchor, 0});
}

CompositorNode::~CompositorNode() {
    stop();
}

Result<Renderer*> CompositorNode::renderer(int step) {
    auto& slot = renderers_[static_cast<size_t>(step)];
    if (!slot) {
        RenderOptions o = ladder_[static_cast<size_t>(step)].applied(options_.render);
        o.yield_to_capture = o.yield_to_capture || !options_.lossless;
        auto made = Renderer::create(scene_, o);
        if (!made)
            return made.status();
        slot = std::move(made).value();
    }
    return slot.get();
}

Status CompositorNode::connect(Graph& graph) {
    graph_ = &graph;
    const auto color = graph.findStream(options_.color_stream);
    if (!color)
        return {ErrorCode::kNotFound, options_.name + ": no stream " + options_.color_stream};
    const StreamInfo info = graph.stream(*color);
    if (info.format.format != PixelFormat::kRGB8 && info.format.format != PixelFormat::kBGR8)
        return {ErrorCode::kUnsupported, options_.name + ": " + info.name +
                                             " is not rgb8 or bgr8, so it cannot be composited"};
    if (options_.camera.width != info.format.width || options_.camera.height != info.format.height)
        return {ErrorCode::kInvalidArgument,
                options_.name + ": the camera model is " + std::to_string(options_.camera.width) +
                    "x" + std::to_string(options_.camera.height) + " but " + info.name + " is " +
                    std::to_string(info.format.width) + "x" + std::to_string(info.format.height)};
    const double fps = info.nominal_fps > 0 ? info.nominal_fps : 30;

    SyncNodeOptions sync;
    sync.name = options_.name;
    sync.streams.push_back(options_.color_stream);
    const auto addInput = [&](const std::string& stream, int& index) {
        if (stream.empty())
            return;
        index = static_cast<int>(sync.streams.size());
        sync.streams.push_back(stream);
    };
    addInput(options_.depth_stream, depth_index_);
    addInput(options_.pose_stream, pose_index_);
    addInput(options_.light_stream, light_index_);
    // Live, every frame held here is a device buffer held: keep only what matching needs, which
    // is the colour frames of the last half second: a frame's pose and lights come from the
    // tracking node that long after it at worst, and a frame dropped before they come can never
    // form a set (on a slow machine, or under a sanitizer, no composite at all would be made).
    const size_t capacity = options_.lossless ? options_.queue_capacity : 3;
    sync.queue = {capacity, options_.lossless ? QueuePolicy::kLossless : QueuePolicy::kLive,
                  options_.name};
    sync.sync.time_base = options_.time_base;
    // Frames of one instant: under half a colour period apart.
    sync.sync.max_skew_ns = static_cast<int64_t>(0.45e9 / fps);
    sync.sync.queue_size = static_cast<uint32_t>(options_.lossless ? options_.queue_capacity : 16);
    for (const std::string& name : sync.streams) {
        const auto id = graph.findStream(name);
        if (!id)
            return {ErrorCode::kNotFound, options_.name + ": no stream " + name};
        // Records published per colour frame come at its rate.
        sync.sync.min_period_ns.push_back(minFramePeriodNs(graph.stream(*id)));
    }
    // Offline the renderer sets the pace: a source waiting on it is not a dead source.
    if (options_.lossless)
        sync.stall_timeout = std::chrono::hours(1);
    sync_ = std::make_unique<SyncNode>(std::move(sync), [this](const SyncSet& set) { onSet(set); });
    MIXRAY_RETURN_IF_ERROR(sync_->connect(graph));

    if (!options_.environment_map_stream.empty()) {
        const auto maps = graph.findStream(options_.environment_map_stream);
        if (!maps)
            return {ErrorCode::kNotFound,
                    options_.name + ": no stream " + options_.environment_map_stream};
        auto queue =
            graph.subscribe(*maps, {kEnvironmentMapsKept,
                                    options_.lossless ? QueuePolicy::kLossless : QueuePolicy::kLive,
                                    options_.name});
        if (!queue)
            return queue.status();
        map_queue_ = std::move(queue).value();
    }

    StreamInfo out;
    out.name = options_.output_stream;
    // Streams are named device/stream ("composite/color" is device "composite"), which is how
    // other hosts address it (a dds device HOST/composite).
    out.device = out.name.substr(0, out.name.find('/'));
    out.kind = StreamKind::kColor;
    out.format = ImageDesc::packed(PixelFormat::kRGB8, info.format.width, info.format.height);
    out.nominal_fps = info.nominal_fps;
    out.clock_domain = info.clock_domain;
    out.tags["composite_of"] = info.name;
    auto output = addPooledStream(graph, out, options_.output_buffers);
    if (!output)
        return output.status();
    output_ = std::move(output).value();
    return Status::ok();
}

Status CompositorNode::start() {
    if (!graph_)
        return {ErrorCode::kInternal, options_.name + ": start() before connect()"};
    stop_ = false;
    thread_ = std::thread([this] { run(); });
    return sync_->start();
}

void CompositorNode::stop() {
    stop_ = true;
    stop_render_.request_stop();
    mailbox_cv_.notify_all();
    if (sync_)
        sync_->stop();
    if (map_queue_)
        map_queue_->close();
    if (thread_.joinable())
        thread_.join();
    // The synchronizer has stopped too: a set still waiting will never be composited.
    std::lock_guard lock(mutex_);
    if (mailbox_) {
        mailbox_.reset();
        ++stats_.skipped_at_stop;
    }
}

bool CompositorNode::waitDone(std::chrono::nanoseconds timeout) const {
    std::unique_lock lock(mutex_);
    return done_cv_.wait_for(lock, timeout, [this] { return done_; });
}

Status CompositorNode::status() const {
    std::lock_guard lock(mutex_);
    return status_;
}

std::vector<std::string> CompositorStats::damage() const {
    std::vector<std::string> lines;
    if (skipped_corrupt == 1)
        lines.push_back("1 colour frame marked corrupt by its driver was not composited");
    else if (skipped_corrupt > 1)
        lines.push_back(std::to_string(skipped_corrupt) +
                        " colour frames marked corrupt by their driver were not composited");
    if (damaged_records > 0)
        lines.push_back(std::to_string(damaged_records) + " pose or light record" +
                        (damaged_records == 1 ? " was" : "s were") +
                        " damaged and composited past (first: " + first_damaged_record + ")");
    return lines;
}

std::vector<std::string> CompositorStats::neverDrawn() const {
    std::vector<std::string> lines;
    if (composites == 0)
        return lines;
    const std::string of_all = " in any of " + std::to_string(composites) + " composites";
    for (const ObjectDrawn& o : objects) {
        if (o.frames > 0)
            continue;
        std::string anchor = o.anchor;
        if (anchor.starts_with("marker:"))
            anchor = "marker " + anchor.substr(7);
        lines.push_back("object '" + o.name + "' (anchor " + o.anchor + ") was never drawn: " +
                        (rendered == 0 ? "the camera had no pose" : anchor + " had no pose") +
                        of_all);
    }
    return lines;
}

CompositorStats CompositorNode::stats() const {
    CompositorStats s;
    std::vector<double> sorted;
    {
        std::lock_guard lock(mutex_);
        s = stats_;
        sorted = latencies_ms_;
    }
    if (sync_)
        s.sync = sync_->stats();
    std::sort(sorted.begin(), sorted.end());
    s.latency.count = sorted.size();
    s.latency.p50_ms = percentile(sorted, 0.50);
    s.latency.p95_ms = percentile(sorted, 0.95);
    s.latency.p99_ms = percentile(sorted, 0.99);
    s.latency.max_ms = sorted.empty() ? 0 : sorted.back();
    return s;
}

void CompositorNode::onSet(const SyncSet& set) {
    Pending p;
    p.color = set.frames[0];
    if (depth_index_ >= 0)
        p.depth = set.frames[static_cast<size_t>(depth_index_)];
    if (pose_index_ >= 0)
        p.pose = set.frames[static_cast<size_t>(pose_index_)];
    if (light_index_ >= 0)
        p.lights = set.frames[static_cast<size_t>(light_index_)];
    std::unique_lock lock(mutex_);
    ++stats_.sets;
    if (options_.lossless) {
        // Back-pressure: the synchronizer (and through its lossless edges the sources) waits
        // for the renderer.
        mailbox_cv_.wait(lock, [this] { return !mailbox_ || stop_; });
        if (stop_) {
            ++stats_.skipped_at_stop;
            return;
        }
    } else if (mailbox_) {
        ++stats_.skipped_superseded;
    }
    mailbox_ = std::move(p);
    lock.unlock();
    mailbox_cv_.notify_all();
}

void CompositorNode::drainEnvironmentMaps() {
    if (!map_queue_)
        return;
    while (auto frame = map_queue_->tryPop()) {
        auto decoded = tracking::decodeEnvironmentMapRecord(frame->image());
        if (!decoded)
            continue;  // a damaged map is no map: the previous one stays
        environment_maps_[decoded->header.good_stamp_ns] =
            std::make_shared<const FloatImage>(std::move(decoded->map));
        while (environment_maps_.size() > kEnvironmentMapsKept)
            environment_maps_.erase(environment_maps_.begin());
    }
}

void CompositorNode::run() {
    if (!options_.lossless)
        runAs(ThreadRole::kRenderer);
    Status result;
    while (true) {
        std::optional<Pending> set;
        {
            std::unique_lock lock(mutex_);
            mailbox_cv_.wait_for(lock, kPollInterval, [this] { return mailbox_ || stop_; });
            if (stop_)
                break;
            if (mailbox_) {
                set = std::move(mailbox_);
                mailbox_.reset();
            }
        }
        if (!set) {
            if (sync_->done()) {
                std::lock_guard lock(mutex_);
                if (!mailbox_)
                    break;
            }
            continue;
        }
        mailbox_cv_.notify_all();
        if (!options_.lossless && graph_->recordingBacklog() >= kRecordingBacklogToSkip) {
            std::lock_guard lock(mutex_);
            ++stats_.skipped_for_recording;
            continue;
        }
        result = composite(*set);
        if (result.code() == ErrorCode::kCancelled) {
            std::lock_guard lock(mutex_);
            ++stats_.skipped_at_stop;
        }
        if (!result)
            break;
    }
    if (result.code() == ErrorCode::kCancelled)
        result = Status::ok();
    finish(std::move(result));
}

void CompositorNode::finish(Status status) {
    graph_->endStream(output_.id);
    {
        std::lock_guard lock(mutex_);
        status_ = std::move(status);
        done_ = true;
        stop_ = stop_ || !status_;
    }
    mailbox_cv_.notify_all();
    done_cv_.notify_all();
}

QualityController::QualityController(int steps, double target_fps)
    : steps_(std::max(steps, 1)), target_fps_(target_fps) {}

int QualityController::update(double render_seconds) {
    if (target_fps_ <= 0)
        return step_;
    const double period = 1.0 / target_fps_;
    ema_s_ = frames_at_step_ == 0 ? render_seconds : 0.8 * ema_s_ + 0.2 * render_seconds;
    ++frames_at_step_;
    frames_fast_ = ema_s_ < 0.45 * period ? frames_fast_ + 1 : 0;
    if (ema_s_ > 0.9 * period && step_ < steps_ - 1 && frames_at_step_ >= 3) {
        ++step_;
        frames_at_step_ = 0;
        frames_fast_ = 0;
    } else if (step_ > 0 && frames_fast_ >= static_cast<int>(2 * target_fps_)) {
        --step_;
        frames_at_step_ = 0;
        frames_fast_ = 0;
    }
    return step_;
}

std::optional<RenderInputs::ShutterPoses> CompositorNode::shutterFor(const FrameMetadata& color,
                                                                     const PoseRecord& pose) {
    const std::optional<float>& fallback_ms = scene_.camera_matching.motion_blur_exposure_ms;
    if (!fallback_ms)
        return std::nullopt;
    // Motion only between two measured poses of frames close in time: a pose carried over, a
    // lost one or a gap (dropped frames, a pause) gives no velocity to trust.
    const bool measured = pose.status == PoseStatus::kValid;
    const int64_t stamp = color.host_stamp_ns;
    std::optional<RenderInputs::ShutterPoses> out;
    constexpr int64_t kLongestGapNs = 200'000'000;
    const double exposure_s =
        color.exposure_us > 0 ? color.exposure_us * 1e-6 : *fallback_ms * 1e-3;
    if (measured && last_T_world_cam_ && stamp > last_pose_stamp_ns_ &&
        stamp - last_pose_stamp_ns_ <= kLongestGapNs && exposure_s > 0)
        out =
            shutterFromMotion(*last_T_world_cam_, pose.transform(),
                              static_cast<double>(stamp - last_pose_stamp_ns_) * 1e-9, exposure_s);
    if (measured) {
        last_T_world_cam_ = pose.transform();
        last_pose_stamp_ns_ = stamp;
    } else {
        last_T_world_cam_.reset();
    }
    return out;
}

Status CompositorNode::composite(const Pending& set) {
    drainEnvironmentMaps();
    if (set.color.meta().status == FrameStatus::kCorrupt) {
        std::lock_guard lock(mutex_);
        ++stats_.skipped_corrupt;
        return Status::ok();
    }
    // A record that does not decode costs its set the pose (or the new lights), not the run.
    const auto damaged = [this](const Status& why) {
        std::lock_guard lock(mutex_);
        if (stats_.damaged_records++ == 0)
            stats_.first_damaged_record = why.message();
    };
    CompositeFrame out;
    out.color = set.color;
    out.depth = set.depth;
    Eigen::Isometry3d T_world_cam = options_.fixed_T_world_cam;
    bool has_pose = true;
    std::optional<RenderInputs::ShutterPoses> shutter;
    if (set.pose) {
        auto pose = decodePoseRecord(set.pose.image());
        if (pose) {
            out.pose = *pose;
            has_pose = pose->status != PoseStatus::kLost;
            if (has_pose)
                T_world_cam = pose->transform();
            shutter = shutterFor(set.color.meta(), *pose);
        } else {
            damaged(pose.status().withContext(options_.pose_stream + " record " +
                                              std::to_string(set.pose.meta().sequence)));
            has_pose = false;
        }
    }
    std::optional<tracking::LightRecord> lights;
    if (set.lights) {
        auto decoded = tracking::decodeLightRecord(set.lights.image());
        if (decoded)
            lights = std::move(decoded).value();
        else
            damaged(decoded.status().withContext(options_.light_stream + " record " +
                                                 std::to_string(set.lights.meta().sequence)));
    }
    if (lights) {
        // The fish-eye's map, else the one built from the colour frames (the light node
        // publishes one or the other).
        std::shared_ptr<const FloatImage> map;
        int64_t map_stamp = 0;
        for (const tracking::LightGroup& g : lights->groups)
            if ((g.name == "environment" || g.name == "camera_environment") && g.good_stamp_ns > 0)
                map_stamp = g.good_stamp_ns;
        if (map_stamp > 0) {
            auto found = environment_maps_.find(map_stamp);
            if (found == environment_maps_.end() && !environment_maps_.empty())
                found = std::prev(environment_maps_.end());
            if (found != environment_maps_.end()) {
                map = found->second;
                map_stamp = found->first;
            }
        }
        // The renderer rebuilds its light data only when the estimates changed.
        std::vector<tracking::EstimatedLight> render_lights;
        for (const tracking::LightGroup& g : lights->groups)
            if (g.name == "render")
                render_lights = g.lights;
        std::vector<Light> scene_lights =
            lightsFromEstimates(render_lights, map, scene_.estimated_lights);
        if (lights_version_ == 0 || map_stamp != last_map_stamp_ns_ ||
            scene_lights.size() != lights_.size() || [&] {
                for (size_t i = 0; i < scene_lights.size(); ++i) {
                    const Light &a = scene_lights[i], &b = lights_[i];
                    if (a.type != b.type || a.position != b.position ||
                        a.direction != b.direction || a.radius != b.radius ||
                        !(a.intensity == b.intensity))
                        return true;
                }
                return false;
            }()) {
            lights_ = std::move(scene_lights);
            last_map_stamp_ns_ = map_stamp;
            ++lights_version_;
        }
        out.lights = std::move(lights).value();
    }

    FrameRef published;
    if (!has_pose) {
        std::lock_guard lock(mutex_);
        if (options_.skip_without_pose) {
            ++stats_.skipped_without_pose;
            return Status::ok();
        }
    }
    const int step = quality_.step();
    if (has_pose) {
        auto r = renderer(step);
        if (!r)
            return r.status();
        Renderer* renderer = *r;
        if (set.lights && renderer_lights_version_[static_cast<size_t>(step)] != lights_version_) {
            MIXRAY_RETURN_IF_ERROR(renderer->setLights(lights_));
            renderer_lights_version_[static_cast<size_t>(step)] = lights_version_;
        }
        RenderInputs in;
        in.camera_image = set.color.image();
        in.camera = options_.camera;
        in.T_world_cam = T_world_cam;
        in.shutter = shutter;
        if (set.depth) {
            in.depth_mm = set.depth.image();
            if (options_.depth_registration)
                in.depth_registration = &*options_.depth_registration;
        }
        in.T_world_anchor = options_.T_world_anchor;
        in.stop = stop_render_.get_token();
        MIXRAY_RETURN_IF_ERROR(renderer->render(in, layers_, &out.stats));
        out.rendered = true;
        out.layers = &layers_;
        if (set.lights)
            out.lights_used = &lights_;
    }
    // Without a pose the camera image goes on as the composite, so the stream has no holes.
    const ImageView src = out.rendered ? layers_.composite.view() : set.color.image();
    WritableFrame frame = acquire(*output_.pool);
    if (frame) {
        std::copy(src.data, src.data + src.size_bytes, frame.image().data);
        frame.meta() = set.color.meta();
        frame.meta().stream = output_.id;
        published = std::move(frame).publish();
    }
    if (!published) {
        std::lock_guard lock(mutex_);
        ++stats_.publish_failures;
        graph_->countLost(output_.id);
        return Status::ok();
    }
    graph_->publish(published);
    const FrameMetadata& captured = set.color.meta();
    out.latency_ms = static_cast<double>(monotonicNowNs() - (captured.graph_stamp_ns != 0
                                                                 ? captured.graph_stamp_ns
                                                                 : captured.host_stamp_ns)) /
                     1e6;
    out.composite = published;
    out.quality_step = step;
    {
        std::lock_guard lock(mutex_);
        out.index = stats_.composites++;
        (out.rendered ? stats_.rendered : stats_.passed_through)++;
        if (out.rendered)
            for (CompositorStats::ObjectDrawn& o : stats_.objects)
                if (o.anchor == "world" || options_.T_world_anchor.count(o.anchor))
                    ++o.frames;
        if (latencies_ms_.size() < kLatencyWindow)
            latencies_ms_.push_back(out.latency_ms);
        else
            latencies_ms_[latency_next_] = out.latency_ms;
        latency_next_ = (latency_next_ + 1) % kLatencyWindow;
        if (out.rendered) {
            render_ms_sum_ += out.stats.seconds * 1e3;
            stats_.render_ms_mean = render_ms_sum_ / static_cast<double>(stats_.rendered);
            stats_.estimated_lights = lights_.size();
        }
    }
    // Offline every frame is rendered at full quality: the ladder is for live runs only.
    if (out.rendered && !options_.lossless)
        quality_.update(out.stats.seconds);
    {
        std::lock_guard lock(mutex_);
        stats_.quality_step = quality_.step();
        stats_.quality_label = ladder_[static_cast<size_t>(quality_.step())].label();
    }
    if (on_composite_)
        on_composite_(out);
    return Status::ok();
}

WritableFrame CompositorNode::acquire(BufferPool& pool) {
    // Lossless, a record waits for a consumer to return a buffer; live, it is dropped (counted).
    return options_.lossless ? acquireWaiting(pool, [this] { return stop_.load(); })
                             : pool.acquire();
}

}  // namespace mixray::render
