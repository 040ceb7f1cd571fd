// mixray demo: the whole pipeline on a bundled recording — replay, track the marker, estimate
// the real light, composite virtual objects by ray-traced differential rendering — and, for a
// simulated session, how close poses, lights and the composite come to the ground truth.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>
#include <thread>

#include "backends.h"
#include "cli.h"
#include "console.h"
#include "mixray/graph/mkv.h"
#include "mixray/render/ar_pipeline.h"
#include "mixray/render/output.h"
#include "mixray/render/renderer.h"
#include "mixray/render/scene_file.h"
#include "mixray/render/simulator.h"
#include "mixray/replay/open_recording.h"
#include "mixray/tracking/pipeline.h"
#include "test_data_paths.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;
using Eigen::Isometry3d;
using Eigen::Vector3d;
using nlohmann::json;
using tracking::TrackedFrame;

struct DemoOptions {
    std::string session = (sourceDir() / "fixtures/sessions/sim_tabletop.mkv").string();
    std::string objects = (sourceDir() / "fixtures/scenes/sim_tabletop_demo.yaml").string();
    std::string real_scene;  // default: the session's NAME.scene.yaml
    std::string setup;
    std::string output = "out/demo";
    int png_every = 9;
    int samples = 4;
    int threads = 0;
    uint64_t max_frames = 0;
    bool truth = true;
    bool depth = true;
    bool environment = true;  // estimate lights and the map from the fish-eye
    int camera_environment = kDefaultCameraEnvironmentWidth;
};

double angleDeg(const Vector3d& a, const Vector3d& b) {
    return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180 / M_PI;
}

double median(std::vector<double> v) {
    if (v.empty())
        return std::nan("");
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double maximum(const std::vector<double>& v) {
    return v.empty() ? std::nan("") : *std::max_element(v.begin(), v.end());
}

double mean(const std::vector<double>& v) {
    return v.empty() ? std::nan("") : std::accumulate(v.begin(), v.end(), 0.0) / v.size();
}

// PSNR of two rgb8 images over all pixels, and over the pixels where `truth` differs from
// `camera` (what the virtual objects change: themselves, their shadows and reflections).
struct Psnr {
    double full = 0;
    double region = 0;
    size_t region_pixels = 0;
};

double psnrFrom(double squared, size_t count) {
    if (count == 0)
        return std::nan("");
    const double mse = squared / static_cast<double>(count);
    return mse <= 0 ? 99.0 : 10 * std::log10(255.0 * 255.0 / mse);
}

Psnr psnr(const ImageView& ours, const ImageView& truth, const ImageView& camera) {
    double all = 0, inside = 0;
    size_t inside_count = 0;
    const int w = truth.desc.width, h = truth.desc.height;
    for (int y = 0; y < h; ++y) {
        const uint8_t* a = ours.row<uint8_t>(y);
        const uint8_t* b = truth.row<uint8_t>(y);
        const uint8_t* c = camera.row<uint8_t>(y);
        for (int x = 0; x < w * 3; x += 3) {
            double e = 0;
            bool changed = false;
            for (int k = 0; k < 3; ++k) {
                const double d = static_cast<double>(a[x + k]) - b[x + k];
                e += d * d;
                changed |= std::abs(static_cast<int>(b[x + k]) - c[x + k]) > 3;
            }
            all += e;
            if (changed) {
                inside += e;
                inside_count += 3;
            }
        }
    }
    return {psnrFrom(all, static_cast<size_t>(w) * h * 3), psnrFrom(inside, inside_count),
            inside_count / 3};
}

// |ours − truth| × 4, for looking at where they differ.
Image differenceImage(const ImageView& ours, const ImageView& truth) {
    Image out(ImageDesc::packed(PixelFormat::kRGB8, truth.desc.width, truth.desc.height));
    MutableImageView m = out.mutableView();
    for (int y = 0; y < truth.desc.height; ++y) {
        const uint8_t* a = ours.row<uint8_t>(y);
        const uint8_t* b = truth.row<uint8_t>(y);
        uint8_t* o = m.data + static_cast<size_t>(y) * m.desc.stride_bytes;
        for (int x = 0; x < truth.desc.width * 3; ++x)
            o[x] = static_cast<uint8_t>(std::min(255, 4 * std::abs(a[x] - b[x])));
    }
    return out;
}

// Errors of one light-estimation method against the true lights, per frame.
struct LightErrors {
    std::vector<double> key_deg, fill_deg;
};

void addLightErrors(LightErrors& errors, const std::vector<tracking::EstimatedLight>& estimated,
                    const std::vector<render::Light>& truth) {
    if (estimated.empty() || truth.empty())
        return;
    for (size_t k = 0; k < truth.size() && k < 2; ++k) {
        const Vector3d to_light = -truth[k].direction.normalized();
        double best = 180;
        for (const auto& e : estimated)
            best = std::min(best, angleDeg(e.to_light_world, to_light));
        (k == 0 ? errors.key_deg : errors.fill_deg).push_back(best);
    }
}

json statsJson(const std::vector<double>& v) {
    return {{"median", median(v)}, {"mean", mean(v)}, {"max", maximum(v)}, {"count", v.size()}};
}

int runDemo(const DemoOptions& options) {
    setFfmpegLogging(false);
    const auto started = std::chrono::steady_clock::now();
    registerRecordingFormats();
    auto reader = replay::openRecording(options.session);
    if (!reader)
        return fail("demo", reader.status());
    auto setup = tracking::findTrackingSetup(options.session, **reader, options.setup);
    if (!setup)
        return fail("demo", setup.status());
    render::ArPipelineOptions ar;
    auto site = tracking::findRigSite(**reader, "");
    if (!site)
        return fail("demo", site.status());
    ar.tracking.site = *site;
    auto utc_offset = tracking::recordingUtcOffset(**reader);
    if (!utc_offset)
        return fail("demo", utc_offset.status());
    ar.tracking.utc_minus_host_ns = *utc_offset;
    ar.setup = *setup;
    ar.use_depth = options.depth;
    ar.tracking.environment = options.environment;
    if (options.camera_environment > 0)
        ar.tracking.camera_environment =
            tracking::CameraEnvironmentOptions{.width = options.camera_environment};

    fs::path real_scene = options.real_scene;
    if (real_scene.empty()) {
        real_scene = options.session;
        real_scene.replace_extension(".scene.yaml");
    }
    auto composed = render::composeArScene(real_scene, options.objects);
    if (!composed)
        return fail("demo", composed.status());
    for (const std::string& note : composed->notes)
        std::fprintf(stderr, "mixray demo: %s\n", note.c_str());
    const render::SceneDescription inserted = composed->inserted;
    ar.scene = std::move(composed->scene);
    ar.render.samples_per_pixel = options.samples;
    ar.render.max_depth = 3;
    ar.render.soft_shadows = render::SoftShadowMethod::kAdaptive;
    ar.render.depth_secondary = render::DepthSecondaryRays::kNone;
    ar.render.threads = options.threads;

    // Ground truth: the simulator renders the session again with the virtual objects real.
    std::unique_ptr<render::Simulator> truth_sim;
    if (options.truth) {
        for (const Attachment& a : (*reader)->attachments()) {
            if (a.name != "truth.yaml")
                continue;
            auto sim_options = render::readSimulationOptions(
                std::string(a.data.begin(), a.data.end()), options.session + ":truth.yaml");
            if (!sim_options)
                return fail("demo", sim_options.status());
            sim_options->inserted = inserted;
            sim_options->threads = options.threads;
            auto sim = render::Simulator::create(*sim_options);
            if (!sim)
                return fail("demo", sim.status().withContext("ground truth"));
            truth_sim = std::move(sim).value();
        }
        if (!truth_sim)
            std::fprintf(stderr,
                         "mixray demo: %s carries no simulator truth: no accuracy "
                         "summary, only the composite\n",
                         options.session.c_str());
    }
    const StreamInfo* color_info = nullptr;
    for (const StreamInfo& s : (*reader)->streams())
        if (s.name == setup->camera.stream)
            color_info = &s;
    if (!color_info)
        return fail("demo", {ErrorCode::kNotFound, options.session + " has no stream " +
                                                       setup->camera.stream + " to track"});
    const int width = color_info->format.width, height = color_info->format.height;
    const double fps = color_info->nominal_fps > 0 ? color_info->nominal_fps : 30;

    const fs::path out = options.output;
    std::error_code ec;
    fs::create_directories(out / "frames", ec);
    if (ec)
        return fail("demo", {ErrorCode::kIoError, "cannot create " + out.string()});
    // From here on a signal stops the work and the video is closed with the frames done.
    InterruptFlag interrupt;
    auto video = render::VideoWriter::create(out / "composite.mp4", width, height, fps);
    if (!video)
        return fail("demo", video.status());

    std::vector<double> t_err_mm, r_err_deg, marker_t_err_mm, psnr_full, psnr_region;
    std::vector<double> track_ms, light_ms, render_ms, truth_ms, latency_ms;
    std::map<std::string, LightErrors> light_errors;
    std::vector<double> key_irradiance_ratio;
    uint64_t frames = 0, stale_frames = 0, no_pose = 0;
    StatusLine status;

    // Tracked frames wait here (by colour sequence) for their composite.
    std::mutex tracked_mutex;
    std::map<uint64_t, TrackedFrame> tracked;
    ar.on_tracked = [&](const TrackedFrame& f) {
        std::lock_guard lock(tracked_mutex);
        tracked[f.color.meta().sequence] = f;
    };

    const auto process = [&](const TrackedFrame& f, const render::CompositeFrame& c) -> Status {
        light_ms.push_back(f.probe_ms);
        track_ms.push_back(f.track_ms);
        latency_ms.push_back(c.latency_ms);
        const ImageView camera_image = f.color.image();
        const ImageView composite = c.composite.image();
        if (c.rendered) {
            if (f.track.pose.stale)
                ++stale_frames;
            render_ms.push_back(c.stats.seconds * 1e3);
        } else {
            ++no_pose;
        }
        MIXRAY_RETURN_IF_ERROR((*video)->write(composite, f.color.meta().host_stamp_ns));
        const bool png = frames % static_cast<uint64_t>(options.png_every) == 0;
        char name[64];
        std::snprintf(name, sizeof name, "frame_%04llu", static_cast<unsigned long long>(frames));
        if (png)
            MIXRAY_RETURN_IF_ERROR(
                render::writePng(composite, out / "frames" / (std::string(name) + ".png")));
        if (truth_sim) {
            const int index = static_cast<int>(f.color.meta().sequence);
            const render::SimTruth& t = truth_sim->truth();
            if (index < 0 || index >= truth_sim->frameCount())
                return Status(ErrorCode::kCorruptData,
                              "colour frame " + std::to_string(index) + " has no truth");
            const Isometry3d& T_true = t.frames[static_cast<size_t>(index)].T_world_color;
            if (f.track.pose.value && !f.track.pose.stale) {
                const Isometry3d& T = *f.track.pose.value;
                t_err_mm.push_back((T.translation() - T_true.translation()).norm() * 1e3);
                r_err_deg.push_back(
                    Eigen::AngleAxisd(T.linear().transpose() * T_true.linear()).angle() * 180 /
                    M_PI);
                marker_t_err_mm.push_back(((T.inverse() * t.T_world_marker).translation() -
                                           (T_true.inverse() * t.T_world_marker).translation())
                                              .norm() *
                                          1e3);
            }
            for (size_t i = 0; i < f.probes.size(); ++i)
                if (f.probes[i].value && !f.probes[i].stale)
                    addLightErrors(light_errors[setup->probes[i].name], f.probes[i].value->lights,
                                   t.lights);
            if (f.environment.value && !f.environment.stale && f.environment.good_stamp_ns > 0)
                addLightErrors(light_errors["environment"], f.environment.value->lights, t.lights);
            if (f.intensities.value && !f.intensities.value->irradiance.empty() &&
                !t.lights.empty()) {
                // The fitted light nearest the key light, against the key's irradiance.
                const auto directions = f.environment.value
                                            ? f.environment.value->lights
                                            : std::vector<tracking::EstimatedLight>{};
                const Vector3d key_to_light = -t.lights[0].direction.normalized();
                double best = 180;
                size_t best_i = 0;
                for (size_t i = 0;
                     i < directions.size() && i < f.intensities.value->irradiance.size(); ++i) {
                    const double a = angleDeg(directions[i].to_light_world, key_to_light);
                    if (a < best) {
                        best = a;
                        best_i = i;
                    }
                }
                if (best < 10)
                    key_irradiance_ratio.push_back(f.intensities.value->irradiance[best_i].mean() /
                                                   t.lights[0].intensity.cast<double>().mean());
            }
            const auto truth_start = std::chrono::steady_clock::now();
            auto truth_image = truth_sim->renderColor(index);
            if (!truth_image)
                return truth_image.status();
            truth_ms.push_back(std::chrono::duration<double, std::milli>(
                                   std::chrono::steady_clock::now() - truth_start)
                                   .count());
            const Psnr p = psnr(composite, truth_image->view(), camera_image);
            psnr_full.push_back(p.full);
            if (p.region_pixels > 0)
                psnr_region.push_back(p.region);
            if (png) {
                MIXRAY_RETURN_IF_ERROR(render::writePng(
                    truth_image->view(), out / "frames" / (std::string(name) + "_truth.png")));
                MIXRAY_RETURN_IF_ERROR(
                    render::writePng(differenceImage(composite, truth_image->view()).view(),
                                     out / "frames" / (std::string(name) + "_diff4x.png")));
            }
        }
        ++frames;
        char line[200];
        std::snprintf(
            line, sizeof line, "frame %llu: %s, %.1f ms track, %.1f ms render%s",
            static_cast<unsigned long long>(frames),
            std::string(tracking::toString(f.track.state)).c_str(), f.track_ms,
            render_ms.empty() ? 0.0 : render_ms.back(),
            psnr_full.empty()
                ? ""
                : (", PSNR " + std::to_string(psnr_full.back()).substr(0, 5) + " dB").c_str());
        status.update(line);
        return Status::ok();
    };

    Status result;
    std::atomic<bool> enough{false};
    std::atomic<bool> failed{false};  // `result` holds an error (written by the callback)
    ar.on_composite = [&](const render::CompositeFrame& c) {
        if (!result || enough)
            return;
        std::optional<TrackedFrame> f;
        {
            std::lock_guard lock(tracked_mutex);
            auto found = tracked.find(c.color.meta().sequence);
            if (found != tracked.end()) {
                f = std::move(found->second);
                tracked.erase(tracked.begin(), std::next(found));
            }
        }
        if (!f) {
            result = Status(ErrorCode::kInternal, "composite of colour frame " +
                                                      std::to_string(c.color.meta().sequence) +
                                                      " without its tracked frame");
            failed = true;
            return;
        }
        result = process(*f, c);
        failed = !result;
        if (options.max_frames > 0 && frames >= options.max_frames)
            enough = true;
    };

    auto pipeline = recordingPipeline(options.session, std::move(ar));
    if (!pipeline)
        return fail("demo", pipeline.status());
    const Status ran =
        runPipeline(**pipeline, [&] { return interrupt.raised() || enough || failed; });
    status.finish();
    if (result)
        result = ran;
    Status closed = (*video)->close();
    if (result)
        result = closed;
    if (!result)
        return fail("demo", result);
    const render::ArPipelineStats pipeline_stats = (*pipeline)->stats();

    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    json summary = {{"session", options.session},
                    {"objects", options.objects},
                    {"frames", frames},
                    {"frames_with_stale_pose", stale_frames},
                    {"frames_without_pose", no_pose},
                    {"ms_per_frame",
                     {{"tracking", statsJson(track_ms)},
                      {"light_estimation", statsJson(light_ms)},
                      {"render", statsJson(render_ms)}}},
                    {"seconds", seconds}};
    // Latency from each colour frame's entry into the graph to its composite's publication:
    // at this (fast) pace it includes the wait behind frames ahead of it.
    summary["latency_ms"] = statsJson(latency_ms);
    summary["pipeline"] = json::parse(pipeline_stats.json());
    std::printf("\n== mixray demo: %llu frames of %s\n", static_cast<unsigned long long>(frames),
                options.session.c_str());
    std::printf(
        "   per frame: tracking %.1f ms, light estimation %.1f ms, rendering %.1f ms "
        "(median; %d samples/pixel, %dx%d)\n",
        median(track_ms), median(light_ms), median(render_ms), options.samples, width, height);
    {
        std::vector<double> sorted = latency_ms;
        std::sort(sorted.begin(), sorted.end());
        const auto at = [&](double p) {
            return sorted.empty() ? std::nan("")
                                  : sorted[std::min(sorted.size() - 1,
                                                    static_cast<size_t>(p * sorted.size()))];
        };
        summary["latency_ms"]["p50"] = at(0.5);
        summary["latency_ms"]["p95"] = at(0.95);
        summary["latency_ms"]["p99"] = at(0.99);
        std::printf("   latency capture -> composite: p50 %.0f ms, p95 %.0f ms, p99 %.0f ms\n",
                    at(0.5), at(0.95), at(0.99));
    }
    if (stale_frames || no_pose)
        std::printf("   %llu frames used a stale pose, %llu had none (see overlay/track)\n",
                    static_cast<unsigned long long>(stale_frames),
                    static_cast<unsigned long long>(no_pose));
    if (truth_sim) {
        json accuracy;
        accuracy["camera_position_error_mm"] = statsJson(t_err_mm);
        accuracy["camera_rotation_error_deg"] = statsJson(r_err_deg);
        accuracy["marker_position_in_camera_error_mm"] = statsJson(marker_t_err_mm);
        std::printf(
            "   pose vs truth: camera position %.2f mm median (max %.2f), rotation %.3f° "
            "median (max %.3f); marker in camera %.2f mm median\n",
            median(t_err_mm), maximum(t_err_mm), median(r_err_deg), maximum(r_err_deg),
            median(marker_t_err_mm));
        json lights;
        for (const auto& [method, e] : light_errors) {
            lights[method] = {{"key_light_error_deg", statsJson(e.key_deg)},
                              {"fill_light_error_deg", statsJson(e.fill_deg)}};
            std::printf("   light direction (%s): key %.2f° median (max %.2f), fill %.2f° median\n",
                        method.c_str(), median(e.key_deg), maximum(e.key_deg), median(e.fill_deg));
        }
        accuracy["light_direction"] = lights;
        if (!key_irradiance_ratio.empty()) {
            accuracy["key_irradiance_ratio"] = statsJson(key_irradiance_ratio);
            std::printf("   key light irradiance: %.3f x the truth (median)\n",
                        median(key_irradiance_ratio));
        }
        accuracy["psnr_db"] = statsJson(psnr_full);
        accuracy["psnr_changed_region_db"] = statsJson(psnr_region);
        std::printf(
            "   composite vs ground truth: PSNR %.2f dB mean (min %.2f); %.2f dB where the "
            "virtual objects change the image\n",
            mean(psnr_full),
            psnr_full.empty() ? std::nan("")
                              : *std::min_element(psnr_full.begin(), psnr_full.end()),
            mean(psnr_region));
        summary["accuracy"] = accuracy;
        summary["ms_per_frame"]["ground_truth_render"] = statsJson(truth_ms);
    }
    std::ofstream(out / "summary.json") << summary.dump(2) << "\n";
    std::printf("   wrote %s/composite.mp4, %s/frames/*.png%s, %s/summary.json (%.1f s)\n",
                out.string().c_str(), out.string().c_str(),
                truth_sim ? " (with _truth and _diff4x)" : "", out.string().c_str(), seconds);
    const int code = finishPipelineRun("demo", pipeline_stats);
    if (interrupt.raised()) {
        std::fprintf(stderr, "mixray demo: stopped by %s after %llu frames; %s holds them\n",
                     interrupt.signalName().c_str(), static_cast<unsigned long long>(frames),
                     (out / "composite.mp4").string().c_str());
        return interrupt.exitCode();
    }
    return code;
}

}  // namespace

void registerDemoCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "demo",
        "The main job on the bundled simulated session: replay, track the marker, estimate the "
        "real light (probes, fish-eye), composite a glass sphere, a metal teapot and a clay box, "
        "and measure poses, lights and the composite against the simulator's ground truth");
    sub->footer(signalHelp("OUTPUT/composite.mp4"));
    auto o = std::make_shared<DemoOptions>();
    sub->add_option("--session", o->session, "Recording")->capture_default_str();
    sub->add_option("--objects", o->objects, "Scene file with the virtual objects")
        ->capture_default_str();
    sub->add_option("--real-scene", o->real_scene,
                    "Scene file modelling the real scene (ghosts); default: SESSION's "
                    "NAME.scene.yaml");
    sub->add_option("--setup", o->setup,
                    "Tracking setup; default: the recording's tracking.yaml attachment");
    sub->add_option("-o,--output", o->output, "Folder for the results")->capture_default_str();
    sub->add_option("--png-every", o->png_every, "Frames between PNGs")
        ->check(CLI::Range(1, 1000000))
        ->capture_default_str();
    sub->add_option("--samples", o->samples, "Samples per pixel (a square number)")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    sub->add_option("--threads", o->threads, "Render threads (0: all cores)")
        ->check(CLI::Range(0, 1024));
    sub->add_option("--max-frames", o->max_frames, "Stop after this many frames (0: all)");
    sub->add_flag("!--no-truth", o->truth, "Skip the ground-truth comparison");
    sub->add_flag("!--no-depth", o->depth, "Do not hide virtual objects behind Kinect depth");
    sub->add_flag("!--no-environment", o->environment,
                  "Leave the fish-eye environment camera out (the environment the colour camera "
                  "builds stands in)");
    addCameraEnvironmentOption(*sub, o->camera_environment);
    commands.push_back({sub, [o] { return runDemo(*o); }});
}

}  // namespace mixray::cli
