// mixray render: composites a scene's virtual objects into every colour frame of a recording.
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <optional>
#include <thread>

#include "backends.h"
#include "cli.h"
#include "console.h"
#include "mixray/calibration/calibration_file.h"
#include "mixray/graph/mkv.h"
#include "mixray/render/ar_pipeline.h"
#include "mixray/render/output.h"
#include "mixray/render/renderer.h"
#include "mixray/render/scene_file.h"
#include "mixray/replay/open_recording.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;

struct RenderCommandOptions {
    std::string session;
    std::string scene;
    std::string output;
    std::string png_dir;  // every `png_every`-th composite as PNG
    int png_every = 30;
    bool layers = false;  // also I_m, I_r, M as EXR next to the PNGs
    int max_depth = 3;
    int samples = 1;
    std::string shadows = "adaptive";
    std::string depth_rays = "screen";
    int shadow_samples = 20;
    int threads = 0;
    uint64_t max_frames = 0;  // 0: all
    std::string pose_stream;  // empty: the only pose stream, when the scene has no camera pose
    std::string calibration;  // a calibration file: the colour camera and depth registrations
};

Result<render::SoftShadowMethod> shadowMethod(const std::string& name) {
    if (name == "hard")
        return render::SoftShadowMethod::kHard;
    if (name == "uniform")
        return render::SoftShadowMethod::kUniform;
    if (name == "adaptive")
        return render::SoftShadowMethod::kAdaptive;
    return {ErrorCode::kInvalidArgument,
            "--shadows " + name + ": expected hard, uniform or adaptive"};
}

Result<render::DepthSecondaryRays> depthRays(const std::string& name) {
    if (name == "none")
        return render::DepthSecondaryRays::kNone;
    if (name == "screen")
        return render::DepthSecondaryRays::kScreenSpace;
    if (name == "mesh")
        return render::DepthSecondaryRays::kMesh;
    return {ErrorCode::kInvalidArgument,
            "--depth-rays " + name + ": expected none, screen or mesh"};
}

int runRender(const RenderCommandOptions& options) {
    setFfmpegLogging(false);
    registerRecordingFormats();
    auto scene = render::loadScene(options.scene);
    if (!scene)
        return fail("render", scene.status());
    render::ArPipelineOptions ar;
    if (!options.calibration.empty()) {
        auto read = calibration::readCalibrationFile(options.calibration);
        if (!read)
            return fail("render", read.status());
        ar.calibration = std::move(read).value();
    }
    if (!scene->camera) {
        return fail("render", {ErrorCode::kInvalidArgument,
                               options.scene + ": the scene needs a camera (its model, or "
                                               "--calibration for it)"});
    }
    ar.pose_stream = options.pose_stream;
    ar.skip_without_pose = true;
    ar.render.max_depth = options.max_depth;
    ar.render.samples_per_pixel = options.samples;
    auto method = shadowMethod(options.shadows);
    if (!method)
        return fail("render", method.status());
    ar.render.soft_shadows = *method;
    auto depth_rays = depthRays(options.depth_rays);
    if (!depth_rays)
        return fail("render", depth_rays.status());
    ar.render.depth_secondary = *depth_rays;
    ar.render.shadow_samples = options.shadow_samples;
    ar.render.threads = options.threads;
    ar.render.keep_layers = options.layers;
    // Marker poses come from tracking, which this command does not run: marker-bound objects
    // are placed at the world origin (the main marker's frame), and the user is told so.
    for (const auto& object : scene->objects) {
        if (object.anchor != "world" && !ar.T_world_anchor.count(object.anchor)) {
            ar.T_world_anchor[object.anchor] = Eigen::Isometry3d::Identity();
            std::fprintf(stderr,
                         "mixray render: no pose for %s in %s; placed at the world origin\n",
                         object.anchor.c_str(), options.session.c_str());
        }
    }
    for (const auto& light : scene->lights)
        if (light.anchor != "world")
            ar.T_world_anchor.try_emplace(light.anchor, Eigen::Isometry3d::Identity());
    ar.scene = std::move(scene).value();

    // From here on a signal stops the work (the frame in progress within a tile) and the video
    // is closed with the frames done, so it plays.
    InterruptFlag interrupt;
    std::unique_ptr<render::VideoWriter> video;
    if (!options.png_dir.empty())
        fs::create_directories(options.png_dir);
    StatusLine status;
    uint64_t frames = 0;
    double render_seconds = 0;
    double worst_seconds = 0;
    Status result;
    std::atomic<bool> failed{false};  // `result` holds an error (written by the callback)
    std::atomic<bool> enough{false};
    ar.on_composite = [&](const render::CompositeFrame& c) {
        if (!result || enough)
            return;
        // Composites one colour frame; false (with `result` set) on an error.
        const auto write = [&]() -> bool {
            result = video->write(c.composite.image(), c.color.meta().host_stamp_ns);
            if (!result)
                return false;
            if (!options.png_dir.empty() &&
                frames % static_cast<uint64_t>(options.png_every) == 0) {
                char name[64];
                std::snprintf(name, sizeof name, "frame_%06llu",
                              static_cast<unsigned long long>(frames));
                const fs::path base = fs::path(options.png_dir) / name;
                result = render::writePng(c.composite.image(), base.string() + ".png");
                if (result && options.layers && c.layers) {
                    result = render::writeExr(c.layers->mixed, base.string() + "_mixed.exr");
                    if (result)
                        result = render::writeExr(c.layers->real_only, base.string() + "_real.exr");
                    if (result)
                        result = render::writeExr(c.layers->mask, base.string() + "_mask.exr");
                }
                if (!result)
                    return false;
            }
            return true;
        };
        if (!write()) {
            failed = true;
            return;
        }
        ++frames;
        render_seconds += c.stats.seconds;
        worst_seconds = std::max(worst_seconds, c.stats.seconds);
        char line[160];
        std::snprintf(
            line, sizeof line, "frame %llu: %.1f ms, %.2f Mrays/s, %llu px traced",
            static_cast<unsigned long long>(frames), c.stats.seconds * 1e3,
            c.stats.seconds > 0 ? static_cast<double>(c.stats.rays()) / c.stats.seconds / 1e6 : 0,
            static_cast<unsigned long long>(c.stats.pixels_traced));
        status.update(line);
        if (options.max_frames > 0 && frames >= options.max_frames)
            enough = true;
    };
    auto pipeline = recordingPipeline(options.session, std::move(ar));
    if (!pipeline)
        return fail("render", pipeline.status());
    const Graph& graph = (*pipeline)->graph();
    const StreamInfo color_info = graph.stream(*graph.findStream((*pipeline)->colorStream()));
    const double fps = color_info.nominal_fps > 0 ? color_info.nominal_fps : 30.0;
    const render::CompositorOptions& compositor = (*pipeline)->compositor()->options();
    if (compositor.depth_registration)
        std::fprintf(stderr, "mixray render: %s registered into %s through %s\n",
                     compositor.depth_stream.c_str(), color_info.name.c_str(),
                     options.calibration.c_str());
    auto made = render::VideoWriter::create(options.output, color_info.format.width,
                                            color_info.format.height, fps);
    if (!made)
        return fail("render", made.status());
    video = std::move(made).value();
    const Status ran =
        runPipeline(**pipeline, [&] { return interrupt.raised() || enough || failed; });
    status.finish();
    if (result)
        result = ran;
    Status closed = video->close();
    // A signal also ends the frame in progress: the renderer drops it whole.
    const bool stopped = interrupt.raised();
    if (!result)
        return fail("render", result);
    if (!closed)
        return fail("render", closed);
    const render::ArPipelineStats stats = (*pipeline)->stats();
    if (stats.compositor && stats.compositor->skipped_without_pose > 0)
        std::fprintf(stderr, "mixray render: %llu colour frames skipped: no pose in %s\n",
                     static_cast<unsigned long long>(stats.compositor->skipped_without_pose),
                     compositor.pose_stream.c_str());
    std::printf("%s: %llu frames composited (%s), mean %.1f ms, worst %.1f ms per frame\n",
                options.output.c_str(), static_cast<unsigned long long>(frames),
                std::string(render::toString(video->codec())).c_str(),
                frames ? render_seconds / static_cast<double>(frames) * 1e3 : 0.0,
                worst_seconds * 1e3);
    const int code = finishPipelineRun("render", stats);
    if (stopped) {
        // The planned count is known when --max-frames set it; the recording's own count would
        // take a pass over the whole file.
        const auto plural = [](uint64_t n) { return n == 1 ? " frame" : " frames"; };
        const uint64_t held = static_cast<uint64_t>(video->framesWritten());
        std::string done = std::to_string(frames);
        if (options.max_frames > 0)
            done += " of " + std::to_string(options.max_frames) + plural(options.max_frames);
        else
            done += std::string(plural(frames)) + " (before the end of the recording)";
        std::fprintf(stderr, "mixray render: stopped by %s after %s; %s holds %llu%s\n",
                     interrupt.signalName().c_str(), done.c_str(), options.output.c_str(),
                     static_cast<unsigned long long>(held), plural(held));
        return interrupt.exitCode();
    }
    return code;
}

}  // namespace

void registerRenderCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "render",
        "Composite a scene's virtual objects into every colour frame of a recording by "
        "ray-traced differential rendering, writing a video (and PNG/EXR frames on request)");
    sub->footer(signalHelp("the video"));
    auto o = std::make_shared<RenderCommandOptions>();
    sub->add_option("SESSION", o->session, "Recording (.mkv, TUM or PCL TIFF folder)")->required();
    sub->add_option("--scene", o->scene, "Scene file (YAML, docs/scene-format.md)")->required();
    sub->add_option("-o,--output", o->output, "Video to write (.mp4: H.264; .mkv: FFV1 lossless)")
        ->required();
    sub->add_option("--calibration", o->calibration,
                    "A calibration file (mixray calibrate's calibration.yaml): the colour "
                    "camera's model, and raw depth registered into it");
    sub->add_option("--png-dir", o->png_dir, "Also write every --png-every-th composite as PNG");
    sub->add_option("--png-every", o->png_every, "Frames between PNGs")
        ->check(CLI::Range(1, 1000000))
        ->capture_default_str();
    sub->add_flag("--layers", o->layers, "With --png-dir: also I_m, I_r and M as EXR");
    sub->add_option("--max-depth", o->max_depth, "Secondary bounces")
        ->check(CLI::Range(0, 16))
        ->capture_default_str();
    sub->add_option("--samples", o->samples, "Samples per pixel (a square number)")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    sub->add_option("--shadows", o->shadows, "hard, uniform or adaptive (RT²AR)")
        ->check(CLI::IsMember({"hard", "uniform", "adaptive"}))
        ->capture_default_str();
    sub->add_option("--depth-rays", o->depth_rays,
                    "What the recording's depth map does beyond hiding virtual objects: none, "
                    "screen (RT²AR's screen-space traversal of secondary and shadow rays) or mesh "
                    "(a mesh per frame that also takes virtual shadows and reflections)")
        ->check(CLI::IsMember({"none", "screen", "mesh"}))
        ->capture_default_str();
    sub->add_option("--shadow-samples", o->shadow_samples, "Rays per spherical light")
        ->check(CLI::Range(1, 1024))
        ->capture_default_str();
    sub->add_option("--threads", o->threads, "Render threads (0: all cores)")
        ->check(CLI::Range(0, 1024));
    sub->add_option("--max-frames", o->max_frames, "Stop after this many frames (0: all)");
    sub->add_option("--pose-stream", o->pose_stream,
                    "Pose stream that places the camera (default: the only one, used when the "
                    "scene's camera has no pose)");
    commands.push_back({sub, [o] { return runRender(*o); }});
}

}  // namespace mixray::cli
