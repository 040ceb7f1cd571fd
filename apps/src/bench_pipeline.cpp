// mixray bench pipeline: the whole AR pipeline (replay, tracking, light estimation, compositor,
// recorder) on the bundled session with the demo's scene. Fast pace: composites/s against the
// renderer alone on the same frames, with the same lights and options, in the same run; then the
// same for the graph and compositor alone (recorded poses, uncompressed replay). Real
// pace: delivered fps against the session's rate, latency percentiles against two frame periods,
// the quality-ladder rungs used, sets skipped, and every captured frame counted in the recording.
#include "bench_pipeline.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "backends.h"
#include "console.h"
#include "cpu_load.h"
#include "mixray/graph/mkv.h"
#include "mixray/render/ar_pipeline.h"
#include "mixray/render/renderer.h"
#include "mixray/render/scene_file.h"
#include "mixray/replay/convert.h"
#include "mixray/replay/open_recording.h"
#include "mixray/tracking/pipeline.h"
#include "test_data_paths.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

struct BenchPipelineOptions {
    std::string session = (sourceDir() / "fixtures/sessions/sim_tabletop.mkv").string();
    std::string objects = (sourceDir() / "fixtures/scenes/sim_tabletop_demo.yaml").string();
    std::string real_scene;  // default: the session's NAME.scene.yaml
    std::string pace = "both";
    int passes = 3;
    double seconds = 10;
    double target_fps = -1;  // -1: the colour stream's rate
    // What mixray run renders with by default, so the figures are the live claim's.
    int samples = 1;
    int shadow_samples = 8;
    int max_depth = 2;
    int threads = 0;
    std::string record;  // default: a temporary file, removed after it was counted
    bool no_record = false;
    MkvCompression compression = MkvCompression::kHuffyuv;  // mixray run's default
    int load = 0;  // busy processes beside the pipeline at real pace (CpuLoad)
    bool json = false;
};

double secondsSince(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// Nearest-rank percentile of sorted values.
double percentile(const std::vector<double>& sorted, double p) {
    if (sorted.empty())
        return 0;
    const double rank = std::ceil(p * static_cast<double>(sorted.size()));
    return sorted[std::min(sorted.size() - 1, static_cast<size_t>(std::max(rank, 1.0)) - 1)];
}

double mean(const std::vector<double>& v) {
    double sum = 0;
    for (double x : v)
        sum += x;
    return v.empty() ? 0 : sum / static_cast<double>(v.size());
}

// Everything but the source and the callbacks, as mixray run builds it for a recording.
struct Inputs {
    render::ArPipelineOptions ar;
    std::string color_stream;
    std::string recorded_pose_stream;  // the session's own camera poses, if it has them
    double color_fps = 30;
    int width = 0, height = 0;
};

Result<Inputs> loadInputs(const BenchPipelineOptions& options) {
    auto reader = replay::openRecording(options.session);
    if (!reader)
        return reader.status();
    Inputs in;
    auto setup = tracking::findTrackingSetup(options.session, **reader, "");
    if (!setup)
        return setup.status();
    auto site = tracking::findRigSite(**reader, "");
    if (!site)
        return site.status();
    auto offset = tracking::recordingUtcOffset(**reader);
    if (!offset)
        return offset.status();
    in.ar.setup = *setup;
    in.ar.tracking.site = *site;
    in.ar.tracking.utc_minus_host_ns = *offset;
    in.ar.record_attachments = (*reader)->attachments();
    in.ar.record_tags = (*reader)->tags();
    for (const StreamInfo& s : (*reader)->streams()) {
        if (s.kind == StreamKind::kPose && in.recorded_pose_stream.empty())
            in.recorded_pose_stream = s.name;
        if (s.name == setup->camera.stream) {
            in.color_stream = s.name;
            in.color_fps = s.nominal_fps > 0 ? s.nominal_fps : 30;
            in.width = s.format.width;
            in.height = s.format.height;
        }
    }
    if (in.color_stream.empty())
        return Status(ErrorCode::kNotFound,
                      options.session + " has no stream " + setup->camera.stream + " to track");

    fs::path real_scene = options.real_scene;
    if (real_scene.empty()) {
        real_scene = options.session;
        real_scene.replace_extension(".scene.yaml");
    }
    auto composed = render::composeArScene(real_scene, options.objects);
    if (!composed)
        return composed.status();
    for (const std::string& note : composed->notes)
        std::fprintf(stderr, "mixray bench pipeline: %s\n", note.c_str());
    in.ar.scene = std::move(composed->scene);
    in.ar.render.samples_per_pixel = options.samples;
    in.ar.render.shadow_samples = options.shadow_samples;
    in.ar.render.max_depth = options.max_depth;
    in.ar.render.threads = options.threads;
    in.ar.render.depth_secondary = render::DepthSecondaryRays::kNone;
    in.ar.target_fps = options.target_fps;
    return in;
}

bool sameLights(const std::vector<render::Light>& a, const std::vector<render::Light>& b) {
    if (a.size() != b.size())
        return false;
    for (size_t i = 0; i < a.size(); ++i)
        if (a[i].type != b[i].type || a[i].position != b[i].position ||
            a[i].direction != b[i].direction || a[i].radius != b[i].radius ||
            !(a[i].intensity == b[i].intensity) || a[i].environment_image != b[i].environment_image)
            return false;
    return true;
}

// One rendered composite's inputs and result, copied out of the pipeline's pools.
struct CollectedFrame {
    Image color, depth, composite;
    std::optional<Eigen::Isometry3d> T_world_cam;  // none: the compositor's fixed pose
    std::optional<std::vector<render::Light>> lights;
};

struct FastFigures {
    uint64_t composites = 0, rendered = 0;
    double pipeline_s = std::numeric_limits<double>::infinity();  // best pass
    double renderer_s = std::numeric_limits<double>::infinity();  // best pass
    double pipeline_render_ms = 0;                                // mean, in the best pass
    double renderer_render_ms = 0;                                // mean, in the best pass
    double track_ms = 0, probe_ms = 0;                            // mean per colour frame
    uint64_t identical = 0;
    int passes = 0;
    std::vector<render::Light> last_lights;  // the lights of the last composite rendered
};

Result<FastFigures> benchFast(const BenchPipelineOptions& options, const fs::path& session,
                              const render::ArPipelineOptions& config) {
    FastFigures f;
    f.passes = options.passes;
    std::vector<CollectedFrame> frames;
    std::optional<render::CompositorOptions> compositor;
    render::ArSource source;
    source.recording = session;
    source.pace = render::ArSource::Pace::kFast;
    for (int pass = 0; pass < options.passes; ++pass) {
        render::ArPipelineOptions ar = config;
        std::mutex mutex;
        std::vector<double> render_ms, track_ms, probe_ms;
        uint64_t composites = 0;
        ar.on_tracked = [&](const tracking::TrackedFrame& t) {
            std::lock_guard lock(mutex);
            track_ms.push_back(t.track_ms);
            probe_ms.push_back(t.probe_ms);
        };
        ar.on_composite = [&](const render::CompositeFrame& c) {
            std::lock_guard lock(mutex);
            ++composites;
            if (!c.rendered)
                return;
            render_ms.push_back(c.stats.seconds * 1e3);
            if (pass != 0)
                return;
            CollectedFrame k;
            k.color = Image::copyOf(c.color.image());
            if (c.depth)
                k.depth = Image::copyOf(c.depth.image());
            k.composite = Image::copyOf(c.composite.image());
            if (c.pose)
                k.T_world_cam = c.pose->transform();
            if (c.lights_used) {
                k.lights = *c.lights_used;
                f.last_lights = *c.lights_used;
            }
            frames.push_back(std::move(k));
        };
        auto pipeline = render::ArPipeline::create(makeBackendRegistry(), source, std::move(ar));
        if (!pipeline)
            return pipeline.status();
        const auto start = Clock::now();
        MIXRAY_RETURN_IF_ERROR((*pipeline)->start());
        if (!(*pipeline)->waitDone(std::chrono::minutes(10)))
            return Status(ErrorCode::kInternal, "the pipeline did not finish in 10 minutes");
        const double seconds = secondsSince(start);
        (*pipeline)->stop();
        MIXRAY_RETURN_IF_ERROR((*pipeline)->status());
        if (!(*pipeline)->compositor())
            return Status(ErrorCode::kInternal, "the pipeline has no compositor");
        if (!compositor)
            compositor = (*pipeline)->compositor()->options();
        std::fprintf(stderr, "bench pipeline: fast pass %d: %llu composites in %.2f s\n", pass + 1,
                     static_cast<unsigned long long>(composites), seconds);
        if (seconds < f.pipeline_s) {
            f.pipeline_s = seconds;
            f.composites = composites;
            f.rendered = render_ms.size();
            f.pipeline_render_ms = mean(render_ms);
            f.track_ms = mean(track_ms);
            f.probe_ms = mean(probe_ms);
        }
    }

    // The renderer alone: the same scene, options, camera, poses, depth and lights, from
    // creating it (the pipeline builds its BVH in its first frame too) to the last frame.
    const render::CompositorOptions& c = *compositor;
    render::RenderLayers layers;
    for (int pass = 0; pass < options.passes; ++pass) {
        std::vector<double> render_ms;
        uint64_t identical = 0;
        const auto start = Clock::now();
        auto renderer = render::Renderer::create(*config.scene, c.render);
        if (!renderer)
            return renderer.status();
        const std::vector<render::Light>* current = nullptr;
        for (const CollectedFrame& k : frames) {
            if (k.lights && (!current || !sameLights(*current, *k.lights))) {
                MIXRAY_RETURN_IF_ERROR((*renderer)->setLights(*k.lights));
                current = &*k.lights;
            }
            render::RenderInputs in;
            in.camera_image = k.color.view();
            in.camera = c.camera;
            in.T_world_cam = k.T_world_cam.value_or(c.fixed_T_world_cam);
            if (k.depth.view().data) {
                in.depth_mm = k.depth.view();
                if (c.depth_registration)
                    in.depth_registration = &*c.depth_registration;
            }
            in.T_world_anchor = c.T_world_anchor;
            render::RenderStats stats;
            MIXRAY_RETURN_IF_ERROR((*renderer)->render(in, layers, &stats));
            render_ms.push_back(stats.seconds * 1e3);
            identical += sameImage(layers.composite.view(), k.composite.view());
        }
        const double seconds = secondsSince(start);
        if (seconds < f.renderer_s) {
            f.renderer_s = seconds;
            f.renderer_render_ms = mean(render_ms);
        }
        f.identical = identical;
    }
    return f;
}

// The graph and the compositor without tracking or light estimation: the same session, scene
// and options, the camera placed by the session's recorded poses and lit by the lights the
// whole pipeline ended with, so that the comparison with the renderer alone is what the graph
// itself costs.
render::ArPipelineOptions graphOnly(const Inputs& inputs,
                                    const std::vector<render::Light>& lights) {
    render::ArPipelineOptions ar = inputs.ar;
    render::FixedCamera camera = ar.scene->camera.value_or(render::FixedCamera{});
    if (!camera.model)
        camera.model = ar.setup->camera.model;  // what tracking would have used
    camera.has_pose = false;
    ar.scene->camera = camera;
    ar.setup.reset();
    ar.pose_stream = inputs.recorded_pose_stream;
    ar.scene->lights = lights;
    return ar;
}

// `session` copied to `copy` with its images uncompressed: replaying it costs a copy per frame
// where the FFV1 original costs a decode, as a live rig's frames arrive ready to use.
Status writeUncompressedCopy(const fs::path& session, const fs::path& copy) {
    auto reader = replay::openRecording(session);
    if (!reader)
        return reader.status();
    MkvWriterOptions writer_options;
    writer_options.compression = MkvCompression::kNone;
    writer_options.flush_every_frame = false;
    auto writer = createMkvWriter(copy, replay::headerOf(**reader), writer_options);
    if (!writer)
        return writer.status();
    auto converted = replay::convertRecording(**reader, **writer);
    return converted ? Status::ok() : converted.status();
}

struct StreamCount {
    std::string name;
    uint64_t published = 0, in_file = 0;
    bool captured = false;  // a device's raw frames, not a pipeline node's records
};

struct RealFigures {
    double seconds = 0;
    double color_fps = 0;     // the session's nominal rate
    uint64_t captured = 0;    // colour frames the replayed camera published
    uint64_t composites = 0;  // published by the compositor
    uint64_t sets = 0, superseded = 0, for_recording = 0, without_pose = 0, corrupt = 0,
             publish_failures = 0, at_stop = 0;
    std::vector<double> latencies_ms;  // sorted
    std::map<int, uint64_t> rungs;     // ladder rung -> composites
    std::vector<std::string> rung_labels;
    int final_rung = 0;
    double render_ms = 0;
    bool recorded = false;
    std::vector<StreamCount> streams;
    uint64_t recorder_dropped = 0;
    uint64_t lost_at_source = 0;  // raw frames the devices could not publish (a full pool)
    int load = 0;                 // busy processes beside the pipeline
    std::string compression;

    // Raw frames published on recorded streams and how many of them the file lacks.
    uint64_t rawPublished() const {
        uint64_t n = 0;
        for (const StreamCount& sc : streams)
            n += sc.captured ? sc.published : 0;
        return n;
    }
    uint64_t rawMissing() const {
        uint64_t n = 0;
        for (const StreamCount& sc : streams)
            n += sc.captured && sc.in_file < sc.published ? sc.published - sc.in_file : 0;
        return n;
    }
};

// Frames per stream name in a recording, read back from the file.
Result<std::map<std::string, uint64_t>> countFrames(const fs::path& path) {
    auto reader = replay::openRecording(path);
    if (!reader)
        return reader.status();
    std::map<std::string, uint64_t> counts;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame) {
            if (frame.status().code() == ErrorCode::kEndOfStream)
                break;
            return frame.status().withContext(path.string());
        }
        ++counts[(*reader)->streams().at(frame->meta().stream).name];
    }
    return counts;
}

Result<RealFigures> benchReal(const BenchPipelineOptions& options, const Inputs& inputs) {
    RealFigures f;
    f.color_fps = inputs.color_fps;
    render::ArPipelineOptions ar = inputs.ar;
    fs::path record;
    if (!options.no_record) {
        record = options.record.empty()
                     ? fs::temp_directory_path() /
                           ("mixray-bench-pipeline-" + std::to_string(::getpid()) + ".mkv")
                     : fs::path(options.record);
        ar.record = record;
        ar.record_compression = options.compression;
        f.compression = toString(options.compression);
    }
    std::mutex mutex;
    ar.on_composite = [&](const render::CompositeFrame& c) {
        std::lock_guard lock(mutex);
        f.latencies_ms.push_back(c.latency_ms);
        ++f.rungs[c.quality_step];
    };
    for (const render::QualityStep& q : render::qualityLadder(ar.render))
        f.rung_labels.push_back(q.label());
    render::ArSource source;
    source.recording = options.session;
    source.pace = render::ArSource::Pace::kReal;
    source.loop = true;
    auto created = render::ArPipeline::create(makeBackendRegistry(), source, std::move(ar));
    if (!created)
        return created.status();
    render::ArPipeline& p = **created;
    auto load = CpuLoad::start(options.load);
    if (!load)
        return load.status();
    f.load = load->processes();
    MIXRAY_RETURN_IF_ERROR(p.start());
    const auto start = Clock::now();
    {
        StatusLine status;
        while (secondsSince(start) < options.seconds && p.status()) {
            std::this_thread::sleep_for(std::chrono::milliseconds(250));
            const render::ArPipelineStats s = p.stats();
            if (!s.compositor)
                continue;
            char line[200];
            std::snprintf(line, sizeof line,
                          "bench pipeline: real pace %.1f / %.0f s: %llu composites, p99 %.0f ms, "
                          "rung %d",
                          secondsSince(start), options.seconds,
                          static_cast<unsigned long long>(s.compositor->composites),
                          s.compositor->latency.p99_ms, s.compositor->qualityRung());
            status.update(line);
        }
        status.finish();
    }
    f.seconds = secondsSince(start);
    p.stop();
    load->stop();
    MIXRAY_RETURN_IF_ERROR(p.status());
    const render::ArPipelineStats s = p.stats();
    const render::CompositorStats& c = *s.compositor;
    f.composites = c.composites;
    f.sets = c.sets;
    f.superseded = c.skipped_superseded;
    f.for_recording = c.skipped_for_recording;
    f.without_pose = c.skipped_without_pose;
    f.corrupt = c.skipped_corrupt;
    f.publish_failures = c.publish_failures;
    f.at_stop = c.skipped_at_stop;
    f.final_rung = c.quality_step;
    f.render_ms = c.render_ms_mean;
    if (const auto id = p.graph().findStream(p.colorStream()))
        f.captured = p.graph().publishedCount(*id);
    std::sort(f.latencies_ms.begin(), f.latencies_ms.end());
    if (!record.empty() && s.recorder) {
        f.recorded = true;
        f.recorder_dropped = s.recorder->frames_dropped;
        auto counts = countFrames(record);
        if (!counts)
            return counts.status();
        for (const RecorderStreamStats& r : s.recorder->streams) {
            StreamCount sc;
            sc.name = r.stream;
            for (const render::ArPipelineStats::Stream& st : s.streams) {
                if (st.name == r.stream && st.captured) {
                    sc.captured = true;
                    f.lost_at_source += st.lost;
                }
            }
            if (const auto id = p.graph().findStream(r.stream))
                sc.published = p.graph().publishedCount(*id);
            sc.in_file = (*counts)[r.stream];
            f.streams.push_back(sc);
        }
        if (options.record.empty()) {
            std::error_code ec;
            fs::remove(record, ec);
        }
    }
    return f;
}

json fastFiguresJson(const FastFigures& f) {
    return {{"passes", f.passes},
            {"composites", f.composites},
            {"rendered", f.rendered},
            {"pipeline_s", f.pipeline_s},
            {"pipeline_composites_per_s", static_cast<double>(f.composites) / f.pipeline_s},
            {"renderer_alone_s", f.renderer_s},
            {"renderer_alone_frames_per_s", static_cast<double>(f.rendered) / f.renderer_s},
            {"overhead", f.pipeline_s / f.renderer_s - 1},
            {"render_ms_in_pipeline", f.pipeline_render_ms},
            {"render_ms_alone", f.renderer_render_ms},
            {"track_ms", f.track_ms},
            {"probe_ms", f.probe_ms},
            {"identical_composites", f.identical}};
}

// The whole pipeline's figures, and the graph's own (graphOnly()) under "graph_only".
json fastJson(const FastFigures& f, const std::optional<FastFigures>& graph_only,
              const std::string& pose_stream) {
    json j = fastFiguresJson(f);
    if (graph_only) {
        j["graph_only"] = fastFiguresJson(*graph_only);
        j["graph_only"]["pose_stream"] = pose_stream;
    }
    return j;
}

json realJson(const RealFigures& f) {
    json rungs = json::array();
    for (const auto& [rung, n] : f.rungs)
        rungs.push_back({{"rung", rung + 1},
                         {"label", f.rung_labels.at(static_cast<size_t>(rung))},
                         {"composites", n}});
    json streams = json::array();
    for (const StreamCount& sc : f.streams)
        streams.push_back({{"stream", sc.name},
                           {"published", sc.published},
                           {"in_file", sc.in_file},
                           {"raw", sc.captured}});
    const double bound_ms = 2e3 / f.color_fps;
    return {{"seconds", f.seconds},
            {"session_fps", f.color_fps},
            {"captured", f.captured},
            {"composites", f.composites},
            {"delivered_fps", static_cast<double>(f.composites) / f.seconds},
            {"latency_ms",
             {{"p50", percentile(f.latencies_ms, 0.50)},
              {"p95", percentile(f.latencies_ms, 0.95)},
              {"p99", percentile(f.latencies_ms, 0.99)},
              {"max", f.latencies_ms.empty() ? 0 : f.latencies_ms.back()},
              {"bound", bound_ms}}},
            {"sets",
             {{"total", f.sets},
              {"superseded", f.superseded},
              {"skipped_for_recording", f.for_recording},
              {"without_pose", f.without_pose},
              {"corrupt", f.corrupt},
              {"publish_failures", f.publish_failures},
              {"at_stop", f.at_stop}}},
            {"render_ms", f.render_ms},
            {"ladder", rungs},
            {"final_rung", f.final_rung + 1},
            {"load_processes", f.load},
            {"recording",
             {{"on", f.recorded},
              {"compression", f.compression},
              {"dropped", f.recorder_dropped},
              {"raw_published", f.rawPublished()},
              {"raw_lost", f.rawMissing() + f.lost_at_source},
              {"raw_lost_at_source", f.lost_at_source},
              {"streams", streams}}}};
}

void printComparison(const FastFigures& f, const char* aim) {
    std::printf("  pipeline        %4llu composites in %6.2f s: %6.1f composites/s\n",
                static_cast<unsigned long long>(f.composites), f.pipeline_s,
                static_cast<double>(f.composites) / f.pipeline_s);
    std::printf(
        "  renderer alone  %4llu frames     in %6.2f s: %6.1f frames/s (%llu of them "
        "byte-identical to the pipeline's)\n",
        static_cast<unsigned long long>(f.rendered), f.renderer_s,
        static_cast<double>(f.rendered) / f.renderer_s,
        static_cast<unsigned long long>(f.identical));
    std::printf("  pipeline / renderer alone: %.3f (overhead %+.1f %%%s)\n",
                f.pipeline_s / f.renderer_s, 100 * (f.pipeline_s / f.renderer_s - 1), aim);
}

void printFast(const FastFigures& f, const std::optional<FastFigures>& graph_only,
               const std::string& pose_stream) {
    std::printf(
        "fast pace, best of %d passes; the whole pipeline (tracking and light estimation "
        "included):\n",
        f.passes);
    printComparison(f, "");
    std::printf(
        "  per frame: render %.1f ms in the pipeline, %.1f ms alone; marker tracking "
        "%.1f ms, probe lights %.1f ms (on the tracking thread, beside the renderer)\n",
        f.pipeline_render_ms, f.renderer_render_ms, f.track_ms, f.probe_ms);
    if (!graph_only) {
        std::printf("  (the session has no pose stream: the graph's own cost is not measured)\n");
        return;
    }
    std::printf(
        "the graph and compositor only (camera from %s, the lights the pipeline ended "
        "with; no tracking or estimation):\n",
        pose_stream.c_str());
    printComparison(*graph_only, "; aim under +10 %");
    std::printf("  per frame: render %.1f ms in the pipeline, %.1f ms alone\n",
                graph_only->pipeline_render_ms, graph_only->renderer_render_ms);
}

void printReal(const RealFigures& f) {
    const double fps = static_cast<double>(f.composites) / f.seconds;
    const double bound_ms = 2e3 / f.color_fps;
    const double p99 = percentile(f.latencies_ms, 0.99);
    std::printf(
        "real pace, looped, %.1f s%s:\n", f.seconds,
        f.load > 0 ? (", beside " + std::to_string(f.load) + " busy processes").c_str() : "");
    std::printf(
        "  delivered %.1f composites/s of the session's %.0f fps (%.2f); %llu colour "
        "frames captured\n",
        fps, f.color_fps, fps / f.color_fps, static_cast<unsigned long long>(f.captured));
    std::printf(
        "  latency p50 %.1f ms, p95 %.1f ms, p99 %.1f ms, max %.1f ms; two frame periods "
        "%.1f ms: p99 %s\n",
        percentile(f.latencies_ms, 0.50), percentile(f.latencies_ms, 0.95), p99,
        f.latencies_ms.empty() ? 0 : f.latencies_ms.back(), bound_ms,
        p99 < bound_ms ? "within" : "OVER");
    std::printf(
        "  sets %llu: composited %llu, superseded by newer %llu, skipped for the recorder %llu, "
        "without pose %llu, corrupt colour frame %llu, no output buffer %llu, at stop %llu\n",
        static_cast<unsigned long long>(f.sets), static_cast<unsigned long long>(f.composites),
        static_cast<unsigned long long>(f.superseded),
        static_cast<unsigned long long>(f.for_recording),
        static_cast<unsigned long long>(f.without_pose), static_cast<unsigned long long>(f.corrupt),
        static_cast<unsigned long long>(f.publish_failures),
        static_cast<unsigned long long>(f.at_stop));
    std::printf("  render %.1f ms per frame; ladder rungs used:", f.render_ms);
    for (const auto& [rung, n] : f.rungs)
        std::printf(" %d (%s) %llu frames;", rung + 1,
                    f.rung_labels.at(static_cast<size_t>(rung)).c_str(),
                    static_cast<unsigned long long>(n));
    std::printf(" at the end rung %d of %zu\n", f.final_rung + 1, f.rung_labels.size());
    if (!f.recorded) {
        std::printf("  recording off\n");
        return;
    }
    uint64_t published = 0, in_file = 0;
    for (const StreamCount& sc : f.streams) {
        published += sc.published;
        in_file += sc.in_file;
    }
    std::printf(
        "  recording (%s): %llu of %llu published frames in the file (read back), %llu "
        "dropped by the recorder\n",
        f.compression.c_str(), static_cast<unsigned long long>(in_file),
        static_cast<unsigned long long>(published),
        static_cast<unsigned long long>(f.recorder_dropped));
    std::printf(
        "  raw frames lost: %llu of %llu the devices captured (%llu missing from the file, %llu "
        "never published: no free buffer)\n",
        static_cast<unsigned long long>(f.rawMissing() + f.lost_at_source),
        static_cast<unsigned long long>(f.rawPublished() + f.lost_at_source),
        static_cast<unsigned long long>(f.rawMissing()),
        static_cast<unsigned long long>(f.lost_at_source));
    for (const StreamCount& sc : f.streams)
        std::printf("    %-28s %6llu published, %6llu in the file\n", sc.name.c_str(),
                    static_cast<unsigned long long>(sc.published),
                    static_cast<unsigned long long>(sc.in_file));
}

int runBenchPipeline(const BenchPipelineOptions& options) {
    setFfmpegLogging(false);
    registerRecordingFormats();
    auto inputs = loadInputs(options);
    if (!inputs)
        return fail("bench pipeline", inputs.status());
    const render::RenderOptions& r = inputs->ar.render;
    if (!options.json)
        std::printf(
            "bench pipeline: %s (%s %dx%d at %.0f fps) with %s; spp %d, shadows %d, "
            "depth %d, %s threads\n",
            options.session.c_str(), inputs->color_stream.c_str(), inputs->width, inputs->height,
            inputs->color_fps, options.objects.c_str(), r.samples_per_pixel, r.shadow_samples,
            r.max_depth, r.threads > 0 ? std::to_string(r.threads).c_str() : "all");
    json out;
    if (options.pace != "real") {
        auto fast = benchFast(options, options.session, inputs->ar);
        if (!fast)
            return fail("bench pipeline", fast.status());
        std::optional<FastFigures> graph_only;
        if (!inputs->recorded_pose_stream.empty()) {
            std::fprintf(stderr,
                         "bench pipeline: the graph and compositor only, on an "
                         "uncompressed copy of the session\n");
            const fs::path copy =
                fs::temp_directory_path() /
                ("mixray-bench-pipeline-" + std::to_string(getpid()) + "-raw.mkv");
            const Status copied = writeUncompressedCopy(options.session, copy);
            Result<FastFigures> measured =
                copied ? benchFast(options, copy, graphOnly(*inputs, fast->last_lights))
                       : Result<FastFigures>(copied);
            std::error_code ec;
            fs::remove(copy, ec);
            if (!measured)
                return fail("bench pipeline", measured.status());
            graph_only = std::move(measured).value();
        }
        if (options.json)
            out["fast"] = fastJson(*fast, graph_only, inputs->recorded_pose_stream);
        else
            printFast(*fast, graph_only, inputs->recorded_pose_stream);
    }
    if (options.pace != "fast") {
        auto real = benchReal(options, *inputs);
        if (!real)
            return fail("bench pipeline", real.status());
        if (options.json)
            out["real"] = realJson(*real);
        else
            printReal(*real);
    }
    if (options.json)
        std::printf("%s\n", out.dump(2).c_str());
    return kExitOk;
}

}  // namespace

void registerBenchPipeline(CLI::App& bench, Commands& commands) {
    auto* sub = bench.add_subcommand(
        "pipeline",
        "The whole AR pipeline (replay, tracking, light estimation, compositor, recorder) on a "
        "session with the demo's scene: composites/s at fast pace against the renderer alone on "
        "the same frames in the same run, with tracking and estimation and for the graph alone; "
        "at real pace, looped, delivered fps, latency "
        "percentiles, quality-ladder rungs, skipped sets and frames reaching the recording");
    auto o = std::make_shared<BenchPipelineOptions>();
    sub->add_option("--session", o->session, "Recording to replay")->capture_default_str();
    sub->add_option("--objects", o->objects, "Scene file with the virtual objects")
        ->capture_default_str();
    sub->add_option("--real-scene", o->real_scene,
                    "Scene file of the real surroundings, as ghosts (default: the session's "
                    "NAME.scene.yaml)");
    sub->add_option("--pace", o->pace, "fast, real or both")
        ->check(CLI::IsMember({"fast", "real", "both"}))
        ->capture_default_str();
    sub->add_option("--passes", o->passes,
                    "Fast pace: passes over the session, for the pipeline and for the renderer "
                    "alone; the best counts")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    sub->add_option("--seconds", o->seconds, "Real pace: how long to run the looped session")
        ->check(CLI::Range(1.0, 3600.0))
        ->capture_default_str();
    sub->add_option("--target-fps", o->target_fps,
                    "Real pace: the rate the quality ladder holds (default: the colour stream's; "
                    "0: never lower quality)");
    sub->add_option("--samples", o->samples, "Samples per pixel at full quality")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    sub->add_option("--shadow-samples", o->shadow_samples, "Rays per spherical light")
        ->check(CLI::Range(1, 1024))
        ->capture_default_str();
    sub->add_option("--max-depth", o->max_depth, "Secondary bounces at full quality")
        ->check(CLI::Range(0, 16))
        ->capture_default_str();
    sub->add_option("--threads", o->threads, "Render threads (0: all cores)")
        ->check(CLI::Range(0, 1024));
    sub->add_option("--record", o->record,
                    "Real pace: keep the recording here (default: a temporary file, removed "
                    "after its frames were counted)");
    sub->add_flag("--no-record", o->no_record, "Real pace: record nothing");
    addCompressionOption(*sub, o->compression, "real pace: mixray run's default");
    sub->add_option("--load", o->load,
                    "Real pace: run this many busy processes beside the pipeline, as another job "
                    "on the machine would (one per core: the machine has no CPU to spare)")
        ->check(CLI::Range(0, 256))
        ->capture_default_str();
    sub->add_flag("--json", o->json, "Print the figures as JSON");
    commands.push_back({sub, [o] { return runBenchPipeline(*o); }});
}

}  // namespace mixray::cli
