// The whole AR pipeline as one device graph (mixray/render/ar_pipeline.h).
#include "mixray/render/ar_pipeline.h"

#include <algorithm>
#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

namespace mixray::render {

void applyCalibratedLens(const calibration::CalibratedCamera& camera, SceneDescription& scene) {
    if (!camera.lens || (scene.camera && scene.camera->aperture))
        return;
    if (!scene.camera) {
        scene.camera.emplace();
        scene.camera->has_pose = false;
    }
    LensAperture aperture;
    aperture.f_number = static_cast<float>(camera.lens->f_number);
    aperture.focal_length_mm = static_cast<float>(camera.lens->focal_length_mm);
    aperture.focus_distance_m = static_cast<float>(camera.lens->focus_distance_m);
    scene.camera->aperture = aperture;
}
namespace {

using Clock = std::chrono::steady_clock;

std::string streamList(const Graph& graph) {
    std::string names;
    for (const StreamInfo& s : graph.streams())
        names += (names.empty() ? "" : ", ") + s.name;
    return names.empty() ? "none" : names;
}

// The colour stream: the setup's camera, else the one asked for, else the first rgb8 one.
Result<std::string> pickColor(const Graph& graph, const ArPipelineOptions& o) {
    std::string wanted = o.setup ? o.setup->camera.stream : o.color_stream;
    if (!wanted.empty()) {
        if (!graph.findStream(wanted))
            return Status(ErrorCode::kNotFound,
                          "no stream " + wanted + " (the source has: " + streamList(graph) + ")");
        return wanted;
    }
    for (const StreamInfo& s : graph.streams())
        if (s.kind == StreamKind::kColor &&
            (s.format.format == PixelFormat::kRGB8 || s.format.format == PixelFormat::kBGR8))
            return s.name;
    return Status(ErrorCode::kUnsupported,
                  "the source has no rgb8/bgr8 colour stream (it has: " + streamList(graph) + ")");
}

struct DepthChoice {
    std::string stream;
    std::optional<calibration::DepthRegistration> registration;
};

// One the calibration registers into the colour camera, else a depth16 stream of its size
// that is not raw (tagged aligned_with an IR camera: its pixels are not the colour camera's).
Result<DepthChoice> pickDepth(const Graph& graph, const StreamInfo& color,
                              const calibration::CalibrationFile* calibration) {
    DepthChoice out;
    for (const StreamInfo& s : graph.streams()) {
        if (!calibration || s.format.format != PixelFormat::kDepth16)
            continue;
        auto registration = calibration->depthRegistration(s.name);
        if (!registration)
            continue;
        const auto entry =
            std::find_if(calibration->depth.begin(), calibration->depth.end(),
                         [&](const calibration::CalibratedDepth& d) { return d.stream == s.name; });
        if (entry->color_camera != color.name)
            continue;
        if (registration->depth.width != s.format.width ||
            registration->depth.height != s.format.height)
            return Status(ErrorCode::kInvalidArgument,
                          "the calibration's " + entry->depth_camera + " is " +
                              std::to_string(registration->depth.width) + "x" +
                              std::to_string(registration->depth.height) + " but " + s.name +
                              " is " + std::to_string(s.format.width) + "x" +
                              std::to_string(s.format.height));
        out.stream = s.name;
        out.registration = std::move(registration).value();
        return out;
    }
    for (const StreamInfo& s : graph.streams()) {
        if (s.kind == StreamKind::kDepth && s.format.format == PixelFormat::kDepth16 &&
            s.format.width == color.format.width && s.format.height == color.format.height &&
            !s.tags.count("aligned_with")) {
            out.stream = s.name;
            break;
        }
    }
    return out;
}

Result<std::string> pickPoseStream(const Graph& graph, const std::string& wanted) {
    std::vector<std::string> poses;
    for (const StreamInfo& s : graph.streams())
        if (s.kind == StreamKind::kPose)
            poses.push_back(s.name);
    std::string names;
    for (const auto& p : poses)
        names += (names.empty() ? "" : ", ") + p;
    if (!wanted.empty()) {
        if (std::find(poses.begin(), poses.end(), wanted) == poses.end())
            return Status(ErrorCode::kNotFound, "no pose stream " + wanted + " (pose streams: " +
                                                    (names.empty() ? "none" : names) + ")");
        return wanted;
    }
    if (poses.empty())
        return Status(ErrorCode::kNotFound,
                      "the scene's camera has no pose and the source has no pose stream to "
                      "place it (track markers with a setup, or give the scene a camera pose)");
    if (poses.size() > 1) {
        return Status(ErrorCode::kInvalidArgument,
                      "the source has several pose streams (" + names + "): name one");
    }
    return poses.front();
}

}  // namespace

// Frames per stream over the last second, and whether each stream ended, from a live edge of
// capacity 1 per stream that the pipeline drains itself.
struct ArPipeline::RateWindow {
    struct Sample {
        Clock::time_point at;
        uint64_t count = 0;
    };
    struct Watch {
        StreamId id = kInvalidStream;
        std::shared_ptr<FrameQueue> queue;
        bool source = false;          // published by a device (not a pipeline stage)
        std::vector<Sample> samples;  // the last ~2 s
        double measured_fps = 0;      // the last rate measured while frames came
    };
    std::mutex mutex;
    std::vector<Watch> watches;
};

ArPipeline::~ArPipeline() {
    stop();
}

Result<std::unique_ptr<ArPipeline>> ArPipeline::create(const BackendRegistry& backends,
                                                       const ArSource& source,
                                                       ArPipelineOptions options) {
    if (source.rig.has_value() == !source.recording.empty())
        return Status(ErrorCode::kInvalidArgument,
                      "an AR pipeline needs exactly one source: a rig or a recording");
    const bool lossless = source.pace == ArSource::Pace::kFast;
    if (lossless && source.rig)
        return Status(ErrorCode::kInvalidArgument,
                      "a rig's devices are live: pace fast applies to recordings only");
    std::unique_ptr<ArPipeline> p(new ArPipeline);
    p->graph_ = std::make_unique<Graph>();
    p->live_ = !lossless;
    Graph& graph = *p->graph_;

    std::vector<DeviceConfig> configs;
    if (source.rig) {
        MIXRAY_RETURN_IF_ERROR(source.rig->validate());
        configs = source.rig->deviceConfigs();
    } else {
        DeviceConfig c;
        c.name = "recording";
        c.driver = "replay";
        c.id = source.recording.string();
        c.options["names"] = "recorded";
        c.options["pace"] = lossless ? "fast" : "original";
        if (!lossless) {
            c.options["stamps"] = "arrival";
            // Live consumers (tracking, compositor, recorder, view) each hold a few frames of a
            // stream; the device must not run out of buffers before they drop old ones.
            c.options["buffers"] = "32";
        }
        c.options["loop"] = source.loop ? "true" : "false";
        configs.push_back(std::move(c));
    }
    for (const DeviceConfig& c : configs) {
        auto device = backends.open(c);
        if (!device)
            return device.status().withContext(c.id.empty() ? c.name : c.id);
        Device* raw = device->get();
        MIXRAY_RETURN_IF_ERROR(graph.addNode(std::move(device).value()));
        p->devices_.push_back(raw);
    }

    const StreamId source_streams = static_cast<StreamId>(graph.streamCount());
    const bool compositing = options.scene.has_value();
    if (options.setup || compositing) {
        auto color = pickColor(graph, options);
        if (!color)
            return color.status();
        p->color_stream_ = *color;
    }

    std::string pose_stream, light_stream, map_stream;
    if (options.setup) {
        tracking::TrackingNodeOptions t;
        t.setup = *options.setup;
        t.pipeline = options.tracking;
        t.lossless = lossless;
        t.max_color_frames = options.max_color_frames;
        auto nodes = tracking::TrackingNodes::add(graph, std::move(t), options.on_tracked);
        if (!nodes)
            return nodes.status();
        p->tracking_ = std::move(nodes).value();
        pose_stream = p->tracking_->options().pose_stream;
        light_stream = p->tracking_->options().light_stream;
        if (p->tracking_->hasEnvironmentMaps())
            map_stream = p->tracking_->options().environment_map_stream;
    }

    if (compositing) {
        SceneDescription scene = std::move(*options.scene);
        const StreamInfo color = graph.stream(*graph.findStream(p->color_stream_));
        // The camera: the calibration's model of the colour stream, else the scene's, else the
        // tracking setup's.
        std::optional<calibration::CameraModel> model;
        if (options.calibration) {
            if (const calibration::CalibratedCamera* c = options.calibration->find(color.name)) {
                model = c->model;
                applyCalibratedLens(*c, scene);
            }
        }
        if (!model && scene.camera && scene.camera->model)
            model = scene.camera->model;
        if (!model && options.setup)
            model = options.setup->camera.model;
        if (!model)
            return Status(ErrorCode::kInvalidArgument,
                          scene.source_path.string() +
                              ": the scene's camera has no model, and no calibration or "
                              "tracking setup gives one for " +
                              color.name);
        p->camera_ = *model;
        CompositorOptions c;
        c.color_stream = color.name;
        c.camera = *model;
        c.render = options.render;
        c.lossless = lossless;
        c.target_fps = lossless                 ? 0
                       : options.target_fps < 0 ? (color.nominal_fps > 0 ? color.nominal_fps : 30)
                                                : options.target_fps;
        c.skip_without_pose = options.skip_without_pose;
        c.time_base = source.rig ? SyncTimeBase::kCommon : SyncTimeBase::kHost;
        c.T_world_anchor = options.T_world_anchor;
        if (options.use_depth) {
            auto depth =
                pickDepth(graph, color, options.calibration ? &*options.calibration : nullptr);
            if (!depth)
                return depth.status();
            c.depth_stream = depth->stream;
            c.depth_registration = std::move(depth->registration);
            if (c.depth_registration)
                c.depth_registration->color = *model;
        }
        if (!pose_stream.empty() && options.pose_stream.empty()) {
            c.pose_stream = pose_stream;
        } else if (!options.pose_stream.empty() || !scene.camera || !scene.camera->has_pose) {
            auto recorded = pickPoseStream(graph, options.pose_stream);
            if (!recorded)
                return recorded.status();
            c.pose_stream = *recorded;
        } else {
            c.fixed_T_world_cam = scene.camera->T_world_cam;
        }
        c.light_stream = light_stream;
        c.environment_map_stream = map_stream;
        auto node = CompositorNode::create(std::move(c), std::move(scene), options.on_composite);
        if (!node)
            return node.status();
        p->compositor_ = node->get();
        MIXRAY_RETURN_IF_ERROR(graph.addNode(std::move(node).value()));
    }

    // Watch every stream for rates and ends.
    p->rates_ = std::make_unique<RateWindow>();
    for (StreamId id = 0; id < graph.streamCount(); ++id) {
        auto queue = graph.subscribe(id, {.capacity = 1,
                                          .policy = QueuePolicy::kLive,
                                          .name = "pipeline-watch",
                                          .newest_only = true});
        if (!queue)
            return queue.status();
        p->rates_->watches.push_back({id, std::move(queue).value(), id < source_streams, {}, 0});
    }

    if (!options.record.empty()) {
        RecorderOptions r;
        r.path = options.record;
        r.policy = lossless ? QueuePolicy::kLossless : QueuePolicy::kLive;
        r.writer.compression = options.record_compression.value_or(
            lossless ? MkvCompression::kFfv1 : MkvCompression::kHuffyuv);
        // Live, clusters close every second instead of every frame (a crash loses at most
        // that), and the queues ride out the disk's hiccups.
        if (!lossless) {
            r.writer.flush_every_frame = false;
            r.queue_capacity = 8;
        }
        r.attachments = options.record_attachments;
        r.tags = options.record_tags;
        auto recorder = std::make_unique<Recorder>(std::move(r));
        p->recorder_ = recorder.get();
        MIXRAY_RETURN_IF_ERROR(graph.addNode(std::move(recorder)));
    }
    return p;
}

Status ArPipeline::start() {
    started_ = Clock::now();
    return graph_->start();
}

bool ArPipeline::waitDone(std::chrono::nanoseconds timeout) const {
    const auto deadline = Clock::now() + timeout;
    if (compositor_)
        return compositor_->waitDone(timeout);
    if (tracking_)
        return tracking_->waitDone(timeout);
    // A monitor: done when every source stream ended.
    while (Clock::now() < deadline) {
        bool all = true;
        for (const auto& w : rates_->watches)
            all = all && (!w.source || w.queue->closed());
        if (all)
            return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
}

void ArPipeline::stop() {
    if (!graph_)
        return;
    // Live, upstream first: the devices, then the nodes that publish what they computed from
    // their frames. Each frame published before its producer stopped is then already in the
    // recorder's queue (or counted as dropped by it) when the graph closes the queues, which the
    // recorder drains into the file: a frame is never published after its recorder stopped
    // listening. (Lossless edges could block a source on a full queue: there the graph's own
    // order, queues closed first, is the one that cannot deadlock.)
    if (live_) {
        for (Device* d : devices_)
            d->stop();
        if (tracking_)
            tracking_->stop();
        if (compositor_)
            compositor_->stop();
    }
    graph_->stop();
}

Status ArPipeline::status() const {
    if (tracking_)
        MIXRAY_RETURN_IF_ERROR(tracking_->status());
    if (compositor_)
        MIXRAY_RETURN_IF_ERROR(compositor_->status());
    if (recorder_) {
        const RecorderStats r = recorder_->stats();
        if (!r.error)
            return r.error;
    }
    return Status::ok();
}

Status ArPipeline::inputStatus() const {
    for (const Device* d : devices_)
        MIXRAY_RETURN_IF_ERROR(d->inputStatus());
    return Status::ok();
}

std::string ArPipeline::compositeStream() const {
    return compositor_ ? graph_->stream(compositor_->outputStream()).name : std::string();
}

namespace {

// A device is stalled when one of its streams that has delivered is silent for this many of its
// frame periods, and at least kStalledAtLeast (scheduling jitter on a loaded machine is not a
// stall). Drivers notice a camera gone only after their loss timeouts (Aravis: seconds); the
// user is told at once.
constexpr double kStalledAfterPeriods = 5;
constexpr double kStalledAtLeastS = 0.5;
// The period assumed for a stream with no nominal rate that has not been measured yet.
constexpr double kUnknownRateFps = 2;

// What one device's source streams did, for its state.
struct DeviceActivity {
    int total = 0;
    int ended = 0;
    int never = 0;         // not ended, nothing published yet
    double stalled_s = 0;  // the longest silence among its stalled streams; 0: none stalled
};

}  // namespace

ArPipelineStats ArPipeline::stats() const {
    ArPipelineStats s;
    const auto now = Clock::now();
    s.seconds = std::chrono::duration<double>(now - started_).count();
    std::map<std::string, DeviceActivity> activity;
    {
        std::lock_guard lock(rates_->mutex);
        for (auto& w : rates_->watches) {
            while (w.queue->tryPop()) {
            }
            const StreamInfo info = graph_->stream(w.id);
            ArPipelineStats::Stream st;
            st.name = info.name;
            st.device = info.device;
            st.published = graph_->publishedCount(w.id);
            st.lost = graph_->lostCount(w.id);
            st.captured = w.source;
            w.samples.push_back({now, st.published});
            while (w.samples.size() > 2 && now - w.samples[1].at >= std::chrono::seconds(1))
                w.samples.erase(w.samples.begin());
            const double dt = std::chrono::duration<double>(now - w.samples.front().at).count();
            st.fps =
                dt > 0.2 ? static_cast<double>(st.published - w.samples.front().count) / dt : 0;
            if (st.fps > 0)
                w.measured_fps = st.fps;
            if (!w.source) {
                s.streams.push_back(std::move(st));
                continue;
            }
            DeviceActivity& a = activity[info.device];
            ++a.total;
            const auto last = graph_->lastPublished(w.id);
            if (w.queue->closed()) {
                ++a.ended;
            } else if (!last) {
                ++a.never;
            } else if (live_) {
                // At fast pace the source waits for the pipeline on lossless edges: its
                // silence is back-pressure, not a stall.
                const double fps = info.nominal_fps > 0 ? info.nominal_fps
                                   : w.measured_fps > 0 ? w.measured_fps
                                                        : kUnknownRateFps;
                const double silent = std::chrono::duration<double>(now - *last).count();
                if (silent > std::max(kStalledAfterPeriods / fps, kStalledAtLeastS))
                    a.stalled_s = std::max(a.stalled_s, silent);
            }
            s.streams.push_back(std::move(st));
        }
    }
    // Devices as their streams name them: a recording stands in for the rig that made it, so
    // its devices (kinect, env) are listed, not the replay device itself.
    std::vector<std::string> names;
    for (size_t i = 0; i < s.streams.size(); ++i) {
        const std::string& device = s.streams[i].device;
        if (rates_->watches[i].source &&
            std::find(names.begin(), names.end(), device) == names.end())
            names.push_back(device);
    }
    for (const std::string& name : names) {
        const DeviceActivity& a = activity[name];
        ArPipelineStats::Device dev;
        dev.name = name;
        // The driver's word where it gives one (it knows a camera being reopened from a slow
        // one), except that a device the driver still calls streaming is stalled as soon as
        // its frames stop; for a recording standing in for its rig, judged from its streams.
        DeviceState said = DeviceState::kUnknown;
        for (const Device* d : devices_) {
            if (d->name() == name) {
                said = d->state();
                dev.clock = d->clockReport();
            }
        }
        if (said != DeviceState::kUnknown && said != DeviceState::kStreaming) {
            dev.state = toString(said);
        } else if (a.stalled_s > 0) {
            dev.state = "stalled";
            dev.silent_s = a.stalled_s;
        } else if (said == DeviceState::kStreaming) {
            dev.state = "streaming";
        } else if (a.ended == a.total) {
            dev.state = "ended";
        } else if (a.never < a.total - a.ended) {
            dev.state = "streaming";
        } else {
            dev.state = "waiting";
        }
        s.devices.push_back(std::move(dev));
    }
    // A view's or a watch's own rate is not a drop (QueueOptions::newest_only: skipped).
    for (const EdgeStats& e : graph_->edgeStats()) {
        s.edge_drops += e.queue.dropped;
        s.queued_frames += e.queue.size;
    }
    if (tracking_)
        s.tracking = tracking_->stats();
    if (compositor_)
        s.compositor = compositor_->stats();
    if (recorder_)
        s.recorder = recorder_->stats();
    s.input = inputStatus();
    return s;
}

std::vector<std::string> ArPipelineStats::warnings() const {
    std::vector<std::string> lines;
    if (!input)
        lines.push_back("input incomplete: " + input.message());
    if (compositor) {
        for (std::string& line : compositor->damage())
            lines.push_back(std::move(line));
        for (std::string& line : compositor->neverDrawn())
            lines.push_back(std::move(line));
    }
    return lines;
}

std::string ArPipelineStats::json() const {
    using nlohmann::json;
    json j;
    json devs = json::array();
    for (const auto& d : devices) {
        json dev = {{"name", d.name}, {"state", d.state}};
        if (d.state == "stalled")
            dev["silent_s"] = std::round(d.silent_s * 10) / 10;
        if (!d.clock.empty())
            dev["clock"] = d.clock;
        devs.push_back(std::move(dev));
    }
    j["devices"] = devs;
    json sts = json::array();
    for (const auto& st : streams)
        sts.push_back({{"name", st.name},
                       {"fps", std::round(st.fps * 10) / 10},
                       {"published", st.published},
                       {"dropped", st.lost}});
    j["streams"] = sts;
    j["edge_drops"] = edge_drops;
    j["queued_frames"] = queued_frames;
    j["seconds"] = std::round(seconds * 10) / 10;
    json messages = json::array();
    if (compositor) {
        const CompositorStats& c = *compositor;
        j["latency_ms"] = {{"p50", c.latency.p50_ms},
                           {"p95", c.latency.p95_ms},
                           {"p99", c.latency.p99_ms},
                           {"max", c.latency.max_ms}};
        j["sync"] = {{"skew_ms_mean", c.sync.skew_mean_ns / 1e6},
                     {"skew_ms_max", static_cast<double>(c.sync.skew_max_ns) / 1e6},
                     {"sets", c.sync.sets_emitted},
                     {"frames_unmatched", c.sync.framesDropped()},
                     {"skipped", c.skipped_superseded}};
        j["ladder"] = {
            {"rung", c.qualityRung()}, {"rungs", c.quality_steps}, {"label", c.quality_label}};
        j["composites"] = {{"published", c.composites},
                           {"rendered", c.rendered},
                           {"passed_through", c.passed_through},
                           {"render_ms_mean", c.render_ms_mean},
                           {"estimated_lights", c.estimated_lights},
                           {"skipped_for_recording", c.skipped_for_recording}};
        if (c.skipped_for_recording > 0)
            messages.push_back(std::to_string(c.skipped_for_recording) +
                               " composites skipped while the recorder caught up (captured "
                               "frames go first)");
        if (c.passed_through > 0)
            messages.push_back(std::to_string(c.passed_through) +
                               " composites without a pose: the camera image as is");
    }
    if (tracking) {
        j["tracking"] = {{"color_frames", tracking->color_frames},
                         {"skipped", tracking->color_skipped},
                         {"light_records", tracking->light_records},
                         {"environment_frames", tracking->environment_frames},
                         {"environment_skipped", tracking->environment_skipped}};
    }
    if (recorder) {
        j["recorder"] = {{"written", recorder->frames_written},
                         {"dropped", recorder->frames_dropped},
                         {"waited_in_memory", recorder->frames_spilled},
                         {"bytes", recorder->bytes_written}};
        if (!recorder->error)
            messages.push_back("recording stopped: " + recorder->error.message());
    }
    j["input"] = {{"complete", input.isOk()}};
    if (!input)
        j["input"]["damage"] = input.message();
    if (compositor) {
        json objects = json::array();
        for (const CompositorStats::ObjectDrawn& o : compositor->objects)
            objects.push_back({{"name", o.name}, {"anchor", o.anchor}, {"drawn", o.frames}});
        j["objects"] = objects;
    }
    for (const std::string& line : warnings())
        messages.push_back(line);
    j["messages"] = messages;
    return j.dump();
}

}  // namespace mixray::render
