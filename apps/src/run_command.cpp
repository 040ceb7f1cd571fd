// mixray run: the AR pipeline live — a rig's devices, or a recording replayed as its rig, through
// tracking, light estimation and the compositor; or, without a scene, a monitor of the rig.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "backends.h"
#include "cli.h"
#include "console.h"
#include "dds_options_cli.h"
#include "mixray/calibration/calibration_file.h"
#include "mixray/dds/dds_publisher.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/rig.h"
#include "mixray/liveview/live_view.h"
#include "mixray/render/ar_pipeline.h"
#include "mixray/render/scene_file.h"
#include "mixray/replay/open_recording.h"
#include "mixray/tracking/overlay.h"
#include "mixray/tracking/pipeline.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct RunOptions {
    std::string source;  // RIG.yaml or a recording
    std::string scene;
    std::string real_scene;  // ghosts; default for a recording: its NAME.scene.yaml, "none": none
    std::string setup;
    std::string calibration;
    std::string record;
    // Live, FFV1 with the replay's own decoding took more than the two cores had; ffvhuff
    // costs a tenth of it (docs/benchmarks.md).
    MkvCompression compression = MkvCompression::kHuffyuv;
    std::string output = "out/run";
    std::string pace = "real";
    std::string view;  // [ADDR:]PORT of the live view; empty: none
    // --view-token; empty: none on loopback, a random one for any other address
    std::string view_token;
    bool loop = false;
    double target_fps = -1;  // -1: the colour stream's rate at real pace, 0: no ladder
    double duration_s = 0;   // 0: until the source ends (or a signal)
    int samples = 1;
    int shadow_samples = 8;
    int max_depth = 2;
    int threads = 0;
    int camera_environment = kDefaultCameraEnvironmentWidth;
    // --publish: the composite and the poses over DDS, for other hosts and (--ros2) ROS 2.
    bool publish = false;
    dds::DdsOptions dds;
    std::string ros2_rig;
};

bool isRigFile(const fs::path& path) {
    const std::string ext = path.extension().string();
    return ext == ".yaml" || ext == ".yml";
}

std::string statusText(const render::ArPipelineStats& s, const std::string& color,
                       const std::string& composite) {
    char line[400];
    double color_fps = 0, composite_fps = 0;
    for (const auto& st : s.streams) {
        if (st.name == color)
            color_fps = st.fps;
        if (st.name == composite)
            composite_fps = st.fps;
    }
    std::string devices;
    for (const auto& d : s.devices) {
        if (d.state == "stalled") {
            char silent[32];
            std::snprintf(silent, sizeof silent, " %.1f s", d.silent_s);
            devices += ", " + d.name + " stalled (silent" + silent + ")";
        } else if (d.state != "streaming") {
            devices += ", " + d.name + " " + d.state;
        }
    }
    // What the recording lost, named: the one loss a user cannot make up for.
    if (s.recorder) {
        if (s.recorder->frames_dropped > 0)
            devices += ", recorder dropped " + std::to_string(s.recorder->frames_dropped);
        if (!s.recorder->error.isOk())
            devices += ", recording stopped: " + s.recorder->error.message();
    }
    if (s.compositor) {
        const auto& c = *s.compositor;
        std::snprintf(line, sizeof line,
                      "%.1f s: %s %.1f fps, composite %.1f fps, latency p50 %.0f / p95 %.0f / "
                      "p99 %.0f ms, quality %s, skipped %llu for newer sets, %llu for the "
                      "recorder%s",
                      s.seconds, color.c_str(), color_fps, composite_fps, c.latency.p50_ms,
                      c.latency.p95_ms, c.latency.p99_ms, c.qualityText().c_str(),
                      static_cast<unsigned long long>(c.skipped_superseded),
                      static_cast<unsigned long long>(c.skipped_for_recording), devices.c_str());
        std::string undrawn;
        for (const auto& o : c.objects)
            if (o.frames == 0 && c.composites > 0)
                undrawn += (undrawn.empty() ? ", not drawn: " : ", ") + o.name;
        return line + undrawn;
    } else {
        std::string rates;
        for (const auto& st : s.streams)
            if (st.fps > 0)
                rates += (rates.empty() ? "" : ", ") + st.name + " " +
                         std::to_string(static_cast<int>(std::lround(st.fps))) + " fps";
        std::snprintf(line, sizeof line, "%.1f s: %s; %llu dropped by consumers behind%s",
                      s.seconds, rates.empty() ? "no frames yet" : rates.c_str(),
                      static_cast<unsigned long long>(s.edge_drops), devices.c_str());
    }
    return line;
}

int runRun(const RunOptions& options) {
    setFfmpegLogging(false);
    registerRecordingFormats();
    render::ArSource source;
    render::ArPipelineOptions ar;
    source.pace =
        options.pace == "fast" ? render::ArSource::Pace::kFast : render::ArSource::Pace::kReal;
    source.loop = options.loop;
    const fs::path path = options.source;
    std::unique_ptr<RecordingReader> reader;
    if (isRigFile(path)) {
        auto rig = loadRig(path);
        if (!rig)
            return fail("run", rig.status());
        if (source.pace == render::ArSource::Pace::kFast)
            return fail("run", {ErrorCode::kInvalidArgument,
                                "--pace fast replays recordings; a rig's devices run at their own "
                                "pace"});
        ar.tracking.site = rig->site;
        source.rig = std::move(rig).value();
    } else {
        auto opened = replay::openRecording(options.source);
        if (!opened)
            return fail("run", opened.status());
        reader = std::move(opened).value();
        source.recording = path;
        auto offset = tracking::recordingUtcOffset(*reader);
        if (!offset)
            return fail("run", offset.status());
        ar.tracking.utc_minus_host_ns = *offset;
        auto site = tracking::findRigSite(*reader, "");
        if (!site)
            return fail("run", site.status());
        ar.tracking.site = *site;
        ar.record_attachments = reader->attachments();
        ar.record_tags = reader->tags();
    }

    if (!options.scene.empty()) {
        fs::path real_scene = options.real_scene == "none" ? "" : options.real_scene;
        if (options.real_scene.empty() && reader) {
            fs::path beside = path;
            beside.replace_extension(".scene.yaml");
            std::error_code ec;
            if (fs::exists(beside, ec))
                real_scene = beside;
        }
        if (real_scene.empty()) {
            auto scene = render::loadScene(options.scene);
            if (!scene)
                return fail("run", scene.status());
            ar.scene = std::move(scene).value();
        } else {
            auto composed = render::composeArScene(real_scene, options.scene);
            if (!composed)
                return fail("run", composed.status());
            for (const std::string& note : composed->notes)
                std::fprintf(stderr, "mixray run: %s\n", note.c_str());
            ar.scene = std::move(composed->scene);
        }
    }
    // Tracking: the setup given, else (with a scene) the recording's own.
    if (!options.setup.empty() || (ar.scene && reader)) {
        if (reader) {
            auto setup = tracking::findTrackingSetup(path, *reader, options.setup);
            if (setup)
                ar.setup = std::move(setup).value();
            else if (!options.setup.empty() || !(ar.scene->camera && ar.scene->camera->has_pose))
                return fail("run", setup.status());
        } else {
            auto setup = tracking::loadTrackingSetup(options.setup);
            if (!setup)
                return fail("run", setup.status());
            ar.setup = std::move(setup).value();
        }
    }
    if (ar.scene && !ar.setup && source.rig && !(ar.scene->camera && ar.scene->camera->has_pose))
        return fail("run", {ErrorCode::kInvalidArgument,
                            "a live rig needs --setup to track the camera (or a scene with a "
                            "fixed camera pose)"});
    if (!options.calibration.empty()) {
        auto calibration = calibration::readCalibrationFile(options.calibration);
        if (!calibration)
            return fail("run", calibration.status());
        ar.calibration = std::move(calibration).value();
    }
    reader.reset();
    std::error_code ec;
    for (const fs::path& dir : {fs::path(options.output), fs::path(options.record).parent_path()}) {
        if (dir.empty())
            continue;
        fs::create_directories(dir, ec);
        if (ec)
            return fail("run", {ErrorCode::kIoError,
                                "cannot create " + dir.string() + ": " + ec.message()});
    }
    ar.render.samples_per_pixel = options.samples;
    ar.render.shadow_samples = options.shadow_samples;
    ar.render.max_depth = options.max_depth;
    ar.render.threads = options.threads;
    ar.render.depth_secondary = render::DepthSecondaryRays::kNone;
    ar.record = options.record;
    ar.record_compression = options.compression;
    ar.target_fps = options.target_fps;
    if (options.camera_environment > 0)
        ar.tracking.camera_environment =
            tracking::CameraEnvironmentOptions{.width = options.camera_environment};

    // The live view: a sink on the pipeline's graph, with the tracking overlay on the colour
    // tile and the pipeline's figures beside the tiles.
    std::unique_ptr<liveview::LiveView> view;
    if (!options.view.empty()) {
        liveview::LiveViewOptions view_options;
        if (Status s = liveview::parseViewAddress(options.view, &view_options); !s)
            return fail("run", s);
        view_options.token = options.view_token;
        view_options.title = "mixray run " + path.filename().string();
        auto made = liveview::LiveView::create(view_options);
        if (!made)
            return fail("run", made.status());
        view = std::move(made).value();
        if (ar.setup) {
            liveview::LiveView* v = view.get();
            const tracking::TrackingSetup setup = *ar.setup;
            ar.on_tracked = [v, setup](const tracking::TrackedFrame& f) {
                (void)v->setOverlay(setup.camera.stream,
                                    tracking::trackingOverlay(f, setup).json());
            };
        }
    }

    InterruptFlag interrupt;
    auto pipeline = render::ArPipeline::create(makeBackendRegistry(), source, std::move(ar));
    if (!pipeline)
        return fail("run", pipeline.status().withContext(options.source));
    render::ArPipeline& p = **pipeline;
    const std::string color = p.colorStream();
    const std::string composite = p.compositeStream();
    liveview::LiveView* live_view = view.get();
    if (view) {
        view->setStatusProvider([&p] { return p.stats().json(); });
        if (Status s = p.graph().addNode(std::move(view)); !s)
            return fail("run", s);
    }
    // What the pipeline makes goes over DDS like any stream: the composite to other mixray hosts
    // (a dds device reads it), and with --ros2 as a ROS 2 image and the poses as tf.
    if (options.publish || !options.ros2_rig.empty()) {
        dds::DdsPublisherOptions publishing;
        publishing.dds = options.dds;
        publishing.ros2_rig = options.ros2_rig;
        for (const std::string& made : {composite, std::string("tracking/pose")}) {
            if (!made.empty() && p.graph().findStream(made))
                publishing.streams.push_back(made);
        }
        if (publishing.streams.empty()) {
            return fail("run", {ErrorCode::kInvalidArgument,
                                "--publish: the pipeline makes no composite or poses to publish "
                                "(give --scene, or --setup)"});
        }
        auto publisher = dds::DdsPublisher::create(publishing);
        if (!publisher)
            return fail("run", publisher.status());
        std::string names;
        for (const std::string& name : publishing.streams)
            names += (names.empty() ? "" : ", ") + name;
        std::printf(
            "publishing %s over DDS as host '%s' in domain %d%s\n", names.c_str(),
            (*publisher)->host().c_str(), options.dds.domain,
            options.ros2_rig.empty()
                ? ""
                : (" (ROS 2: images under /" + options.ros2_rig + "/, poses on tf)").c_str());
        if (Status s = p.graph().addNode(std::move(*publisher)); !s)
            return fail("run", s);
    }
    if (Status s = p.start(); !s)
        return fail("run", s);
    if (live_view)
        printLiveViewUrls(*live_view, "live view: ");
    std::fflush(stdout);
    StatusLine status;
    const auto started = std::chrono::steady_clock::now();
    bool timed_out = false;
    while (!p.waitDone(std::chrono::milliseconds(250))) {
        status.update(statusText(p.stats(), color, composite));
        if (interrupt.raised() || !p.status())
            break;
        if (options.duration_s > 0 && std::chrono::steady_clock::now() - started >=
                                          std::chrono::duration<double>(options.duration_s)) {
            timed_out = true;
            break;
        }
    }
    p.stop();
    const render::ArPipelineStats stats = p.stats();
    status.update(statusText(stats, color, composite));
    status.finish();
    if (Status s = p.status(); !s)
        return fail("run", s);

    json summary = json::parse(stats.json());
    summary["source"] = options.source;
    summary["pace"] = options.pace;
    summary["stopped_by"] = interrupt.raised() ? interrupt.signalName()
                            : timed_out        ? "--duration"
                                               : "the end of the source";
    const fs::path summary_path = fs::path(options.output) / "summary.json";
    std::ofstream(summary_path) << summary.dump(2) << "\n";
    if (stats.compositor) {
        const auto& c = *stats.compositor;
        std::printf(
            "%llu composites (%llu rendered) in %.1f s; latency p50 %.1f ms, p95 %.1f ms, p99 "
            "%.1f ms; %llu sets skipped for newer ones, %llu while the recorder caught up; "
            "quality %s\n",
            static_cast<unsigned long long>(c.composites),
            static_cast<unsigned long long>(c.rendered), stats.seconds, c.latency.p50_ms,
            c.latency.p95_ms, c.latency.p99_ms,
            static_cast<unsigned long long>(c.skipped_superseded),
            static_cast<unsigned long long>(c.skipped_for_recording), c.qualityText().c_str());
    }
    if (stats.recorder)
        std::printf("%s: %s\n", options.record.c_str(), stats.recorder->summary().c_str());
    std::printf("wrote %s\n", summary_path.string().c_str());
    const int code = finishPipelineRun("run", stats);
    return interrupt.raised() ? interrupt.exitCode() : code;
}

}  // namespace

void registerRunCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "run",
        "Run AR live: a rig's devices (RIG.yaml) or a recording replayed as its rig, through "
        "marker tracking, light estimation and the ray-traced compositor, in one device graph; "
        "without --scene, a monitor of the rig's streams");
    sub->footer(signalHelp("the recording (--record) and summary.json"));
    auto o = std::make_shared<RunOptions>();
    sub->add_option("SOURCE", o->source, "A rig file (.yaml) or a recording")->required();
    sub->add_option("--scene", o->scene, "Scene with the virtual objects (docs/scene-format.md)");
    sub->add_option("--real-scene", o->real_scene,
                    "Scene file of the real surroundings, composited as ghosts under --scene's "
                    "virtual objects (shadows and reflections on them); default for a recording: "
                    "its NAME.scene.yaml when present; none: --scene alone");
    sub->add_option("--setup", o->setup,
                    "Tracking setup (docs/tracking.md#setup-files); default for a recording: its "
                    "tracking.yaml attachment");
    sub->add_option("--calibration", o->calibration,
                    "Calibration file: the colour camera's model and depth registration");
    sub->add_option("--record", o->record,
                    "Record raw streams, poses, lights and the composite into this .mkv");
    addCompressionOption(*sub, o->compression,
                         "with --record; ffvhuff leaves the CPU to capture and the composite, at "
                         "a rate a laptop disk holds: 12 MB/s for VGA colour and depth at 30 fps");
    sub->add_option("-o,--output", o->output, "Folder for summary.json")->capture_default_str();
    sub->add_option("--pace", o->pace,
                    "real: devices, or the recording at its own pace as its rig delivered it "
                    "(live edges, newest set wins); fast: the recording as fast as the pipeline "
                    "takes it, every frame (lossless)")
        ->check(CLI::IsMember({"real", "fast"}))
        ->capture_default_str();
    sub->add_option("--view", o->view,
                    "Serve the live view (tiles, tracking overlay, figures) on [ADDR:]PORT; "
                    "loopback unless ADDR is given (docs/live-view.md)");
    addViewTokenOption(*sub, o->view_token);
    sub->add_flag("--loop", o->loop, "Play the recording again at its end (long live runs)");
    sub->add_flag("--publish", o->publish,
                  "Publish the composite and the poses over DDS: other hosts read them as a dds "
                  "device HOST/composite (docs/dds.md); binds loopback unless --address says");
    sub->add_option("--ros2", o->ros2_rig,
                    "Also publish them to ROS 2: the composite as /NAME/composite/color/image_raw, "
                    "the poses on tf (implies --publish)");
    addDdsOptions(*sub, o->dds);
    sub->add_option("--target-fps", o->target_fps,
                    "Frame rate the quality ladder holds at real pace (default: the colour "
                    "stream's; 0: never lower quality)");
    sub->add_option("--duration", o->duration_s, "Stop after this many seconds (0: at the end)")
        ->check(CLI::Range(0.0, 1e9));
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
    addCameraEnvironmentOption(*sub, o->camera_environment);
    commands.push_back({sub, [o] { return runRun(*o); }});
}

}  // namespace mixray::cli
