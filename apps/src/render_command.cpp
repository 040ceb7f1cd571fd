// mixray render: composites a scene's virtual objects into every colour frame of a recording.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <optional>
#include <thread>

#include "cli.h"
#include "console.h"
#include "mixray/calibration/calibration_file.h"
#include "mixray/graph/mkv.h"
#include "mixray/render/output.h"
#include "mixray/render/renderer.h"
#include "mixray/render/scene_file.h"
#include "mixray/replay/depth_units.h"
#include "mixray/replay/open_recording.h"
#include "pose_track.h"
#include "recording_frames.h"

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

// The recording's stream to composite into (the first rgb8/bgr8 colour stream) and the depth
// stream that occludes, if any: one the calibration registers into the colour camera, else the
// first depth16 stream of the colour stream's size that is not raw (tagged aligned_with an IR
// camera: its pixels are not the colour camera's).
struct Streams {
    StreamId color = kInvalidStream;
    StreamId depth = kInvalidStream;
    std::optional<calibration::DepthRegistration> registration;  // for a raw depth stream
};
Result<Streams> pickStreams(const RecordingReader& reader,
                            const calibration::CalibrationFile* calibration) {
    Streams s;
    const auto& streams = reader.streams();
    for (StreamId i = 0; i < streams.size(); ++i) {
        const auto format = streams[i].format.format;
        if (s.color == kInvalidStream && streams[i].kind == StreamKind::kColor &&
            (format == PixelFormat::kRGB8 || format == PixelFormat::kBGR8)) {
            s.color = i;
        }
    }
    if (s.color == kInvalidStream) {
        return {ErrorCode::kUnsupported,
                "the recording has no rgb8/bgr8 colour stream to composite into"};
    }
    const ImageDesc& c = streams[s.color].format;
    for (StreamId i = 0; i < streams.size() && calibration; ++i) {
        if (streams[i].format.format != PixelFormat::kDepth16)
            continue;
        auto registration = calibration->depthRegistration(streams[i].name);
        if (!registration)
            continue;
        const auto entry = std::find_if(
            calibration->depth.begin(), calibration->depth.end(),
            [&](const calibration::CalibratedDepth& d) { return d.stream == streams[i].name; });
        if (entry->color_camera != streams[s.color].name)
            continue;
        if (registration->depth.width != streams[i].format.width ||
            registration->depth.height != streams[i].format.height)
            return Status(ErrorCode::kInvalidArgument,
                          "the calibration's " + entry->depth_camera + " is " +
                              std::to_string(registration->depth.width) + "x" +
                              std::to_string(registration->depth.height) + " but " +
                              streams[i].name + " is " + std::to_string(streams[i].format.width) +
                              "x" + std::to_string(streams[i].format.height));
        s.depth = i;
        s.registration = std::move(registration).value();
        return s;
    }
    for (StreamId i = 0; i < streams.size(); ++i) {
        if (streams[i].kind == StreamKind::kDepth &&
            streams[i].format.format == PixelFormat::kDepth16 &&
            streams[i].format.width == c.width && streams[i].format.height == c.height &&
            !streams[i].tags.count("aligned_with")) {
            s.depth = i;
            break;
        }
    }
    return s;
}

// The two newest depth maps of the occluding stream, in millimetres (TUM folders store 5000
// units per metre; see mixray/replay/depth_units.h), so a colour frame takes the nearer one.
class DepthFrames {
public:
    static Result<DepthFrames> create(const std::vector<StreamInfo>& streams, StreamId depth) {
        DepthFrames frames;
        if (depth == kInvalidStream)
            return frames;
        auto scale = replay::depthScalePerMetre(streams[depth]);
        if (!scale)
            return scale.status();
        frames.units_per_m_ = *scale;
        return frames;
    }

    Status push(const FrameRef& frame) {
        std::swap(older_, newer_);
        newer_.stamp_ns = frame.meta().host_stamp_ns;
        newer_.frame = frame;
        if (units_per_m_ == replay::kMillimetresPerMetre)
            return Status::ok();
        const ImageDesc mm = ImageDesc::packed(PixelFormat::kDepth16, frame.image().desc.width,
                                               frame.image().desc.height);
        if (!(newer_.converted.desc() == mm))
            newer_.converted = Image(mm);
        return replay::rescaleDepth(frame.image(), units_per_m_, newer_.converted.mutableView(),
                                    replay::kMillimetresPerMetre);
    }

    std::optional<ImageView> closestTo(int64_t stamp_ns) const {
        const Entry* best = nullptr;
        for (const Entry* e : {&newer_, &older_})
            if (e->frame && (!best || std::llabs(e->stamp_ns - stamp_ns) <
                                          std::llabs(best->stamp_ns - stamp_ns)))
                best = e;
        if (!best)
            return std::nullopt;
        return units_per_m_ == replay::kMillimetresPerMetre ? best->frame.image()
                                                            : best->converted.view();
    }

private:
    struct Entry {
        int64_t stamp_ns = 0;
        FrameRef frame;
        Image converted;  // in mm, when the stream's units are not
    };
    int units_per_m_ = replay::kMillimetresPerMetre;
    Entry newer_, older_;
};

int runRender(const RenderCommandOptions& options) {
    setFfmpegLogging(false);
    auto scene = render::loadScene(options.scene);
    if (!scene)
        return fail("render", scene.status());
    std::optional<calibration::CalibrationFile> calibration;
    if (!options.calibration.empty()) {
        auto read = calibration::readCalibrationFile(options.calibration);
        if (!read)
            return fail("render", read.status());
        calibration = std::move(read).value();
    }
    if (!scene->camera) {
        return fail("render", {ErrorCode::kInvalidArgument,
                               options.scene + ": the scene needs a camera (its model, or "
                                               "--calibration for it)"});
    }
    // Without a fixed pose (or when asked), the camera follows the recording's pose stream.
    std::optional<PoseTrack> poses;
    if (!scene->camera->has_pose || !options.pose_stream.empty()) {
        auto track = readPoseTrack(options.session, options.pose_stream);
        if (!track)
            return fail("render", track.status().withContext(
                                      "the scene's camera has no pose, so it must come from a "
                                      "pose stream"));
        poses = std::move(track).value();
    }
    auto reader = replay::openRecording(options.session);
    if (!reader)
        return fail("render", reader.status());
    auto streams = pickStreams(**reader, calibration ? &*calibration : nullptr);
    if (!streams)
        return fail("render", streams.status().withContext(options.session));
    const StreamInfo color_info = (*reader)->streams()[streams->color];
    // The calibration's model of the colour stream's camera wins over the scene's.
    if (calibration) {
        if (const calibration::CalibratedCamera* c = calibration->find(color_info.name))
            scene->camera->model = c->model;
    }
    if (!scene->camera->model) {
        return fail("render",
                    {ErrorCode::kInvalidArgument, options.scene +
                                                      ": the scene's camera has no model and no "
                                                      "--calibration names " +
                                                      color_info.name});
    }
    const calibration::CameraModel& camera = *scene->camera->model;
    if (streams->registration) {
        streams->registration->color = camera;
        std::fprintf(stderr, "mixray render: %s registered into %s through %s\n",
                     (*reader)->streams()[streams->depth].name.c_str(), color_info.name.c_str(),
                     options.calibration.c_str());
    }
    if (camera.width != color_info.format.width || camera.height != color_info.format.height) {
        return fail("render", {ErrorCode::kInvalidArgument,
                               "the scene's camera is " + std::to_string(camera.width) + "x" +
                                   std::to_string(camera.height) + " but " + color_info.name +
                                   " is " + std::to_string(color_info.format.width) + "x" +
                                   std::to_string(color_info.format.height)});
    }

    render::RenderOptions render_options;
    render_options.max_depth = options.max_depth;
    render_options.samples_per_pixel = options.samples;
    auto method = shadowMethod(options.shadows);
    if (!method)
        return fail("render", method.status());
    render_options.soft_shadows = *method;
    auto depth_rays = depthRays(options.depth_rays);
    if (!depth_rays)
        return fail("render", depth_rays.status());
    render_options.depth_secondary = *depth_rays;
    render_options.shadow_samples = options.shadow_samples;
    render_options.threads = options.threads;
    render_options.keep_layers = options.layers;
    auto renderer = render::Renderer::create(*scene, render_options);
    if (!renderer)
        return fail("render", renderer.status());

    // From here on a signal stops the work (the frame in progress within a tile) and the video
    // is closed with the frames done, so it plays.
    InterruptFlag interrupt;
    const double fps = color_info.nominal_fps > 0 ? color_info.nominal_fps : 30.0;
    auto video = render::VideoWriter::create(options.output, color_info.format.width,
                                             color_info.format.height, fps);
    if (!video)
        return fail("render", video.status());
    if (!options.png_dir.empty())
        fs::create_directories(options.png_dir);

    // Marker poses come from tracking, which recordings do not carry yet: marker-bound objects
    // are placed at the world origin (the main marker's frame), and the user is told so.
    std::map<std::string, Eigen::Isometry3d> anchors;
    for (const auto& object : scene->objects) {
        if (object.anchor != "world" && !anchors.count(object.anchor)) {
            anchors[object.anchor] = Eigen::Isometry3d::Identity();
            std::fprintf(stderr,
                         "mixray render: no pose for %s in %s; placed at the world origin\n",
                         object.anchor.c_str(), options.session.c_str());
        }
    }
    for (const auto& light : scene->lights) {
        if (light.anchor != "world" && !anchors.count(light.anchor)) {
            anchors[light.anchor] = Eigen::Isometry3d::Identity();
        }
    }

    StatusLine status;
    auto depths = DepthFrames::create((*reader)->streams(), streams->depth);
    if (!depths)
        return fail("render", depths.status().withContext(options.session));
    uint64_t frames = 0;
    uint64_t frames_without_pose = 0;
    double render_seconds = 0;
    double worst_seconds = 0;
    render::RenderLayers layers;
    Status result;
    // Composites one colour frame; false (with `result` set) on an error.
    const auto composite = [&](const FrameRef& colour) -> bool {
        render::RenderInputs inputs;
        inputs.camera_image = colour.image();
        if (auto depth = depths->closestTo(colour.meta().host_stamp_ns)) {
            inputs.depth_mm = *depth;
            if (streams->registration)
                inputs.depth_registration = &*streams->registration;
        }
        inputs.camera = camera;
        inputs.T_world_cam = scene->camera->T_world_cam;
        if (poses) {
            const auto T_world_cam =
                poses->poseFor(color_info.name, colour.meta(), static_cast<int64_t>(0.5e9 / fps));
            if (!T_world_cam) {
                ++frames_without_pose;
                return true;
            }
            inputs.T_world_cam = *T_world_cam;
        }
        inputs.T_world_anchor = anchors;
        inputs.stop = interrupt.token();
        render::RenderStats stats;
        result = (*renderer)->render(inputs, layers, &stats);
        if (!result)
            return false;
        result = (*video)->write(layers.composite.view(), colour.meta().host_stamp_ns);
        if (!result)
            return false;
        if (!options.png_dir.empty() && frames % static_cast<uint64_t>(options.png_every) == 0) {
            char name[64];
            std::snprintf(name, sizeof name, "frame_%06llu",
                          static_cast<unsigned long long>(frames));
            const fs::path base = fs::path(options.png_dir) / name;
            result = render::writePng(layers.composite.view(), base.string() + ".png");
            if (result && options.layers) {
                result = render::writeExr(layers.mixed, base.string() + "_mixed.exr");
                if (result)
                    result = render::writeExr(layers.real_only, base.string() + "_real.exr");
                if (result)
                    result = render::writeExr(layers.mask, base.string() + "_mask.exr");
            }
            if (!result)
                return false;
        }
        ++frames;
        render_seconds += stats.seconds;
        worst_seconds = std::max(worst_seconds, stats.seconds);
        char line[160];
        std::snprintf(
            line, sizeof line, "frame %llu: %.1f ms, %.2f Mrays/s, %llu px traced",
            static_cast<unsigned long long>(frames), stats.seconds * 1e3,
            stats.seconds > 0 ? static_cast<double>(stats.rays()) / stats.seconds / 1e6 : 0,
            static_cast<unsigned long long>(stats.pixels_traced));
        status.update(line);
        return true;
    };
    // A colour frame waits for the next frame so that a depth map stamped with it (or nearer
    // to it than the previous one) but stored after it still occludes it.
    FrameRef pending;
    while (!interrupt.raised() && (options.max_frames == 0 || frames < options.max_frames)) {
        auto next = nextFrame(**reader);
        if (!next || !*next) {
            if (!next)
                result = next.status();
            break;
        }
        const FrameRef& frame = **next;
        if (frame.meta().stream == streams->depth) {
            result = depths->push(frame);
            if (!result)
                break;
            continue;
        }
        if (frame.meta().stream != streams->color)
            continue;
        if (pending && !composite(pending))
            break;
        pending = frame;
    }
    if (pending && result && !interrupt.raised() &&
        (options.max_frames == 0 || frames < options.max_frames))
        composite(pending);
    status.finish();
    Status closed = (*video)->close();
    // A signal also ends the frame in progress: the renderer drops it whole (kCancelled).
    const bool stopped = interrupt.raised();
    if (stopped && result.code() == ErrorCode::kCancelled)
        result = Status::ok();
    if (!result)
        return fail("render", result);
    if (!closed)
        return fail("render", closed);
    if (frames_without_pose > 0)
        std::fprintf(stderr, "mixray render: %llu colour frames skipped: no pose in %s\n",
                     static_cast<unsigned long long>(frames_without_pose), poses->stream.c_str());
    std::printf("%s: %llu frames composited (%s), mean %.1f ms, worst %.1f ms per frame\n",
                options.output.c_str(), static_cast<unsigned long long>(frames),
                std::string(render::toString((*video)->codec())).c_str(),
                frames ? render_seconds / static_cast<double>(frames) * 1e3 : 0.0,
                worst_seconds * 1e3);
    if (stopped) {
        // The planned count is known when --max-frames set it; the recording's own count would
        // take a pass over the whole file.
        const auto plural = [](uint64_t n) { return n == 1 ? " frame" : " frames"; };
        const uint64_t held = static_cast<uint64_t>((*video)->framesWritten());
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
    return kExitOk;
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
