// mixray bench track: marker tracking frames/s against OpenCV's bare detectMarkers on the same
// frames, and light estimation milliseconds per frame, on simulated tabletop frames at each size.
#include "bench_track.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "mixray/render/simulator.h"
#include "mixray/tracking/camera_environment.h"
#include "mixray/tracking/light_intensity.h"
#include "mixray/tracking/lights.h"
#include "mixray/tracking/markers.h"

namespace mixray::cli {
namespace {

using nlohmann::json;

struct BenchTrackOptions {
    std::string sizes = "640x480,1280x720";
    int frames = 12;
    int repeats = 3;
    bool json = false;
};

struct Size {
    int width = 0, height = 0;
};

Result<std::vector<Size>> parseSizes(const std::string& text) {
    std::vector<Size> sizes;
    std::stringstream list(text);
    std::string item;
    while (std::getline(list, item, ',')) {
        Size s;
        char x = 0;
        std::stringstream one(item);
        if (!(one >> s.width >> x >> s.height) || x != 'x' || !one.eof() || s.width < 64 ||
            s.height < 64 || s.width > 4096 || s.height > 4096)
            return Status(ErrorCode::kInvalidArgument,
                          "--size: '" + item + "' is not WIDTHxHEIGHT with sides in [64, 4096]");
        sizes.push_back(s);
    }
    if (sizes.empty())
        return Status(ErrorCode::kInvalidArgument, "--size: no sizes");
    return sizes;
}

// Best of `repeats` runs of `body` over all frames, in milliseconds per frame.
double bestMsPerFrame(int repeats, size_t frames, const std::function<void()>& body) {
    double best = std::numeric_limits<double>::infinity();
    for (int r = 0; r < repeats; ++r) {
        const auto start = std::chrono::steady_clock::now();
        body();
        const double ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count();
        best = std::min(best, ms / static_cast<double>(std::max<size_t>(frames, 1)));
    }
    return best;
}

constexpr int kCameraEnvironmentWidth = 128;  // mixray run's and demo's default

struct SizeResult {
    Size size;
    double opencv_ms = 0, detect_ms = 0, track_ms = 0;
    double probe_ms = 0, intensity_ms = 0, environment_ms = 0;
    // The environment built from the colour frames (the light node's, 128 wide, every frame
    // added and a map every 10th): adding a frame, and making the map.
    double camera_env_add_ms = 0, camera_env_map_ms = 0;
    int tracked = 0, frames = 0, env_frames = 0;
};

Result<SizeResult> benchSize(const Size& size, const BenchTrackOptions& options) {
    render::SimulatorOptions so;
    so.scenario = render::SimScenario::kTabletop;
    so.frames = options.frames;
    so.width = size.width;
    so.height = size.height;
    so.samples_per_pixel = 4;  // antialiased like a camera image (and the fixture)
    so.env_every = 4;
    auto sim = render::Simulator::create(so);
    if (!sim)
        return sim.status();
    const render::SimTruth& t = (*sim)->truth();
    std::vector<render::SimFrame> frames;
    std::fprintf(stderr, "bench track: rendering %d simulated frames at %dx%d ...\n",
                 (*sim)->frameCount(), size.width, size.height);
    for (int i = 0; i < (*sim)->frameCount(); ++i) {
        auto f = (*sim)->render(i);
        if (!f)
            return f.status();
        frames.push_back(std::move(f).value());
    }

    SizeResult r;
    r.size = size;
    r.frames = static_cast<int>(frames.size());
    // OpenCV's own detector, bare: colour to grey and detectMarkers, default parameters.
    const cv::Ptr<cv::aruco::Dictionary> dictionary =
        cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250);
    const cv::Ptr<cv::aruco::DetectorParameters> parameters =
        cv::aruco::DetectorParameters::create();
    size_t opencv_found = 0;
    r.opencv_ms = bestMsPerFrame(options.repeats, frames.size(), [&] {
        opencv_found = 0;
        for (const render::SimFrame& f : frames) {
            const ImageView v = f.color.view();
            const cv::Mat rgb(v.desc.height, v.desc.width, CV_8UC3, const_cast<uint8_t*>(v.data),
                              static_cast<size_t>(v.desc.stride_bytes));
            cv::Mat grey;
            cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
            std::vector<std::vector<cv::Point2f>> corners;
            std::vector<int> ids;
            cv::aruco::detectMarkers(grey, dictionary, corners, ids, parameters);
            opencv_found += ids.size();
        }
    });
    r.detect_ms = bestMsPerFrame(options.repeats, frames.size(), [&] {
        for (const render::SimFrame& f : frames)
            (void)tracking::detectMarkers(f.color.view(), t.marker_dictionary);
    });
    tracking::MarkerTarget marker;
    marker.name = "marker";
    marker.dictionary = t.marker_dictionary;
    marker.id = t.marker_id;
    marker.size_m = t.marker_size_m;
    marker.T_world_target = t.T_world_marker;
    auto tracker = tracking::MarkerTracker::create(t.color, {marker});
    if (!tracker)
        return tracker.status();
    Status failed;
    r.track_ms = bestMsPerFrame(options.repeats, frames.size(), [&] {
        (*tracker)->reset();
        r.tracked = 0;
        for (size_t i = 0; i < frames.size(); ++i) {
            auto track = (*tracker)->track(frames[i].color.view(), t.frames[i].stamp_ns);
            if (!track)
                failed = track.status();
            else if (track->state == tracking::TrackState::kTracking)
                ++r.tracked;
        }
    });
    MIXRAY_RETURN_IF_ERROR(failed);

    // Light estimation on the true poses: every probe, the diffuse probe's intensity fit, and
    // the environment frames (lights and environment map).
    std::vector<tracking::LightProbe> probes;
    for (const render::SimProbe& p : t.probes) {
        tracking::LightProbe probe;
        probe.name = p.name;
        probe.material = p.material == render::MaterialType::kMirror
                             ? tracking::ProbeMaterial::kMirror
                             : tracking::ProbeMaterial::kDiffuse;
        probe.radius_m = p.radius_m;
        probe.centre_world = p.centre_world;
        probes.push_back(probe);
    }
    std::vector<Eigen::Vector3d> to_light;
    for (const render::Light& l : t.lights)
        to_light.push_back(-l.direction.normalized());
    r.probe_ms = bestMsPerFrame(options.repeats, frames.size(), [&] {
        for (size_t i = 0; i < frames.size(); ++i)
            for (const tracking::LightProbe& p : probes)
                (void)tracking::estimateProbeLights(frames[i].color.view(), t.color,
                                                    t.frames[i].T_world_color, p);
    });
    r.intensity_ms = bestMsPerFrame(options.repeats, frames.size(), [&] {
        for (size_t i = 0; i < frames.size(); ++i)
            for (const tracking::LightProbe& p : probes)
                if (p.material == tracking::ProbeMaterial::kDiffuse)
                    (void)tracking::fitLightIntensities(frames[i].color.view(), t.color,
                                                        t.frames[i].T_world_color, p, to_light);
    });
    tracking::EnvironmentCamera env;
    env.model = t.env;
    env.T_world_env = t.T_world_env;
    std::vector<const Image*> env_images;
    for (const render::SimFrame& f : frames)
        if (f.env.view().desc.width > 0)
            env_images.push_back(&f.env);
    r.env_frames = static_cast<int>(env_images.size());
    if (!env_images.empty())
        r.environment_ms = bestMsPerFrame(options.repeats, env_images.size(), [&] {
            for (const Image* image : env_images) {
                (void)tracking::estimateEnvironmentLights(image->view(), env);
                (void)tracking::environmentMapFromFisheye(image->view(), env);
            }
        });
    auto camera_env = tracking::CameraEnvironment::create({.width = kCameraEnvironmentWidth});
    if (!camera_env)
        return camera_env.status();
    r.camera_env_add_ms = bestMsPerFrame(options.repeats, frames.size(), [&] {
        for (size_t i = 0; i < frames.size(); ++i)
            if (Status s =
                    camera_env->add(frames[i].color.view(), t.color, t.frames[i].T_world_color);
                !s)
                failed = s;
    });
    MIXRAY_RETURN_IF_ERROR(failed);
    r.camera_env_map_ms = bestMsPerFrame(options.repeats, 1, [&] { (void)camera_env->map(); });
    if (opencv_found == 0)
        std::fprintf(stderr, "bench track: OpenCV found no marker at %dx%d\n", size.width,
                     size.height);
    return r;
}

int runBenchTrack(const BenchTrackOptions& options) {
    auto sizes = parseSizes(options.sizes);
    if (!sizes)
        return fail("bench track", sizes.status());
    std::vector<SizeResult> results;
    for (const Size& s : *sizes) {
        auto r = benchSize(s, options);
        if (!r)
            return fail("bench track", r.status());
        results.push_back(*r);
    }
    if (options.json) {
        json out = json::array();
        for (const SizeResult& r : results)
            out.push_back({{"width", r.size.width},
                           {"height", r.size.height},
                           {"frames", r.frames},
                           {"tracked", r.tracked},
                           {"opencv_detect_markers_ms", r.opencv_ms},
                           {"mixray_detect_ms", r.detect_ms},
                           {"mixray_track_ms", r.track_ms},
                           {"mixray_track_fps", 1e3 / r.track_ms},
                           {"opencv_detect_markers_fps", 1e3 / r.opencv_ms},
                           {"probe_lights_ms", r.probe_ms},
                           {"probe_intensity_fit_ms", r.intensity_ms},
                           {"environment_ms", r.environment_ms},
                           {"environment_frames", r.env_frames},
                           {"camera_environment_add_ms", r.camera_env_add_ms},
                           {"camera_environment_map_ms", r.camera_env_map_ms}});
        std::printf("%s\n", out.dump(2).c_str());
        return kExitOk;
    }
    std::printf(
        "Marker tracking on simulated tabletop frames (one 100 mm DICT_6X6_250 marker), "
        "best of %d runs:\n",
        options.repeats);
    std::printf("  %-10s %20s %16s %22s %9s\n", "size", "OpenCV detectMarkers", "mixray detect",
                "mixray track (ratio)", "tracked");
    for (const SizeResult& r : results) {
        char size[32];
        std::snprintf(size, sizeof size, "%dx%d", r.size.width, r.size.height);
        std::printf("  %-10s %13.1f fps   %9.1f fps   %9.1f fps (%.2fx)   %3d/%-3d\n", size,
                    1e3 / r.opencv_ms, 1e3 / r.detect_ms, 1e3 / r.track_ms,
                    r.opencv_ms / r.track_ms, r.tracked, r.frames);
    }
    std::printf("Light estimation, milliseconds per frame (true poses):\n");
    std::printf("  %-10s %18s %20s %28s %34s\n", "size", "probes (2 spheres)", "diffuse-probe fit",
                "environment (lights + map)", "camera environment: add / map");
    for (const SizeResult& r : results) {
        char size[32];
        std::snprintf(size, sizeof size, "%dx%d", r.size.width, r.size.height);
        std::printf(
            "  %-10s %15.2f ms %17.2f ms %19.2f ms (%d frames) %12.2f ms / %.2f ms "
            "(%.2fx the probes per frame)\n",
            size, r.probe_ms, r.intensity_ms, r.environment_ms, r.env_frames, r.camera_env_add_ms,
            r.camera_env_map_ms, (r.camera_env_add_ms + r.camera_env_map_ms / 10) / r.probe_ms);
    }
    std::printf(
        "  (camera environment: %d texels wide, a map every 10th frame as the light node "
        "makes it)\n",
        kCameraEnvironmentWidth);
    return kExitOk;
}

}  // namespace

void registerBenchTrack(CLI::App& bench, Commands& commands) {
    auto* track = bench.add_subcommand(
        "track",
        "Marker tracking frames/s against OpenCV's bare detectMarkers on the same simulated "
        "frames, and light estimation (probes, environment camera) milliseconds per frame");
    auto options = std::make_shared<BenchTrackOptions>();
    track->add_option("--size", options->sizes, "Image sizes, WIDTHxHEIGHT[,WIDTHxHEIGHT...]")
        ->capture_default_str();
    track->add_option("--frames", options->frames, "Simulated frames per size")
        ->check(CLI::Range(1, 1000))
        ->capture_default_str();
    track->add_option("--repeats", options->repeats, "Timed runs; the best counts")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    track->add_flag("--json", options->json, "Print the figures as JSON");
    commands.push_back({track, [options] { return runBenchTrack(*options); }});
}

}  // namespace mixray::cli
