// mixray track: the camera's pose and the real lights, frame by frame, from a recording.
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "backends.h"
#include "cli.h"
#include "console.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/pose.h"
#include "mixray/graph/record_codec.h"
#include "mixray/render/ar_pipeline.h"
#include "mixray/render/output.h"
#include "mixray/replay/open_recording.h"
#include "mixray/tracking/camera_environment.h"
#include "mixray/tracking/pipeline.h"
#include "overlay.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using tracking::TrackedFrame;

struct TrackCommandOptions {
    std::string session;
    std::string setup;
    std::string output = "out/track";
    bool video = true;
    bool record = true;
    bool probes = true;
    bool environment = true;
    uint64_t max_frames = 0;
    std::string rig;  // empty: the recording's rig.yaml attachment
    std::string utc;  // the first colour frame's UTC; empty: the recording's tag
    // Build an environment map from the colour camera's own tracked frames
    // (camera_environment.exr): the map's width, 0 for none.
    int camera_environment = 0;
    double camera_environment_radius_m = 0;  // its distance sphere; 0: at infinity
};

json vec(const Eigen::Vector3d& v) {
    return json::array({v.x(), v.y(), v.z()});
}

json poseJson(const Eigen::Isometry3d& T) {
    Eigen::Quaterniond q(T.linear());
    q.normalize();
    if (q.w() < 0)
        q.coeffs() = -q.coeffs();
    return {{"translation", vec(T.translation())},
            {"quaternion", json::array({q.w(), q.x(), q.y(), q.z()})}};
}

json lightJson(const tracking::EstimatedLight& l) {
    json j = {{"source", tracking::toString(l.source)},
              {"to_light_world", vec(l.to_light_world)},
              {"intensity", vec(l.intensity)},
              {"angular_radius_deg", l.angular_radius_rad * 180 / M_PI},
              {"weight", l.weight}};
    if (l.position_world)
        j["position_world"] = vec(*l.position_world);
    return j;
}

template <typename T>
json estimateHeader(const tracking::Estimate<T>& e) {
    json j = {{"stale", e.stale}, {"good_stamp_ns", e.good_stamp_ns}};
    if (!e.reason.empty())
        j["reason"] = e.reason;
    return j;
}

json frameJson(const TrackedFrame& f, const tracking::TrackingSetup& setup) {
    json j;
    j["frame"] = f.index;
    j["stamp_ns"] = f.color.meta().host_stamp_ns;
    j["sequence"] = f.color.meta().sequence;
    j["state"] = tracking::toString(f.track.state);
    j["reacquired"] = f.track.reacquired;
    json pose = estimateHeader(f.track.pose);
    if (f.track.pose.value)
        pose["T_world_camera"] = poseJson(*f.track.pose.value);
    if (f.track.raw_T_world_camera)
        pose["raw_T_world_camera"] = poseJson(*f.track.raw_T_world_camera);
    j["pose"] = pose;
    json targets = json::array();
    for (const auto& o : f.track.targets)
        targets.push_back({{"target", o.target},
                           {"T_camera_target", poseJson(o.T_camera_target)},
                           {"points", o.points},
                           {"rms_px", o.rms_px}});
    j["targets"] = targets;
    json markers = json::array();
    for (const auto& d : f.track.detections) {
        json corners = json::array();
        for (const auto& c : d.corners)
            corners.push_back({c.x(), c.y()});
        markers.push_back({{"dictionary", d.dictionary}, {"id", d.id}, {"corners", corners}});
    }
    j["markers"] = markers;
    json probes = json::array();
    for (size_t i = 0; i < f.probes.size(); ++i) {
        json p = estimateHeader(f.probes[i]);
        p["probe"] = setup.probes[i].name;
        if (f.probes[i].value) {
            json lights = json::array();
            for (const auto& l : f.probes[i].value->lights)
                lights.push_back(lightJson(l));
            p["lights"] = lights;
            p["outline"] = {{"centre_px",
                             {f.probes[i].value->outline.centre_px.x(),
                              f.probes[i].value->outline.centre_px.y()}},
                            {"radius_px", f.probes[i].value->outline.radius_px}};
        }
        probes.push_back(p);
    }
    j["probes"] = probes;
    if (setup.environment) {
        json e = estimateHeader(f.environment);
        if (f.environment.value) {
            json lights = json::array();
            for (const auto& l : f.environment.value->lights)
                lights.push_back(lightJson(l));
            e["lights"] = lights;
        }
        j["environment"] = e;
    }
    if (f.sun.value || !f.sun.reason.empty()) {
        json sun = estimateHeader(f.sun);
        if (f.sun.value)
            sun["light"] = lightJson(*f.sun.value);
        j["sun"] = sun;
    }
    if (f.intensities.value || !f.intensities.reason.empty()) {
        json i = estimateHeader(f.intensities);
        if (f.intensities.value) {
            json irradiance = json::array();
            for (const auto& e : f.intensities.value->irradiance)
                irradiance.push_back(vec(e));
            i["irradiance"] = irradiance;
            i["rms"] = f.intensities.value->rms;
        }
        j["light_intensities"] = i;
    }
    j["track_ms"] = f.track_ms;
    j["probe_ms"] = f.probe_ms;
    return j;
}

Status writeText(const fs::path& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary);
    out << text;
    out.close();
    if (!out)
        return Status(ErrorCode::kIoError, "cannot write " + path.string());
    return Status::ok();
}

int runTrack(const TrackCommandOptions& options) {
    setFfmpegLogging(false);
    registerRecordingFormats();
    auto reader = replay::openRecording(options.session);
    if (!reader)
        return fail("track", reader.status());
    auto setup = tracking::findTrackingSetup(options.session, **reader, options.setup);
    if (!setup)
        return fail("track", setup.status());
    render::ArPipelineOptions ar;
    ar.setup = *setup;
    ar.tracking.probes = options.probes;
    ar.tracking.environment = options.environment;
    auto site = tracking::findRigSite(**reader, options.rig);
    if (!site)
        return fail("track", site.status());
    ar.tracking.site = *site;
    if (!options.utc.empty()) {
        auto utc = tracking::parseUtc(options.utc);
        if (!utc)
            return fail("track", utc.status());
        ar.tracking.utc_first_frame_ns = *utc;
    } else {
        auto offset = tracking::recordingUtcOffset(**reader);
        if (!offset)
            return fail("track", offset.status());
        ar.tracking.utc_minus_host_ns = *offset;
    }
    const StreamInfo* color = nullptr;
    for (const StreamInfo& s : (*reader)->streams())
        if (s.name == setup->camera.stream)
            color = &s;
    if (!color) {
        std::string names;
        for (const StreamInfo& s : (*reader)->streams())
            names += (names.empty() ? "" : ", ") + s.name;
        return fail("track", {ErrorCode::kNotFound,
                              options.session + ": the recording has no stream " +
                                  setup->camera.stream + " to track (it has: " + names + ")"});
    }

    const fs::path out_dir = options.output;
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec)
        return fail("track", {ErrorCode::kIoError,
                              "cannot create " + out_dir.string() + ": " + ec.message()});
    std::unique_ptr<render::VideoWriter> video;
    if (options.video) {
        auto v = render::VideoWriter::create(out_dir / "overlay.mp4", color->format.width,
                                             color->format.height,
                                             color->nominal_fps > 0 ? color->nominal_fps : 30);
        if (!v)
            return fail("track", v.status());
        video = std::move(v).value();
    }
    // The recording again, with the camera's pose, the lights and the environment maps as
    // streams of their own.
    if (options.record) {
        ar.record = out_dir / "tracked.mkv";
        ar.record_attachments = (*reader)->attachments();
        ar.record_tags = (*reader)->tags();
    }
    reader->reset();

    std::optional<tracking::CameraEnvironment> camera_environment;
    if (options.camera_environment > 0) {
        auto created =
            tracking::CameraEnvironment::create({.width = options.camera_environment,
                                                 .radius_m = options.camera_environment_radius_m,
                                                 .centre = Eigen::Vector3d::Zero()});
        if (!created)
            return fail("track", created.status());
        camera_environment.emplace(std::move(created).value());
    }
    std::string poses_csv =
        "frame,stamp_ns,state,stale,reacquired,targets,markers,rms_px,tx,ty,tz,qw,qx,qy,qz\n";
    std::string lights_csv =
        "frame,stamp_ns,source,name,stale,index,lx,ly,lz,r,g,b,angular_radius_deg,weight\n";
    json frames = json::array();
    InterruptFlag interrupt;
    StatusLine status;
    uint64_t tracked = 0, lost = 0;
    double track_ms = 0, probe_ms = 0;
    Status result;
    // Everything written for one tracked colour frame; false (with `result` set) on an error.
    const auto handle = [&](const TrackedFrame& f) -> bool {
        frames.push_back(frameJson(f, *setup));
        track_ms += f.track_ms;
        probe_ms += f.probe_ms;
        (f.track.state == tracking::TrackState::kTracking ? tracked : lost)++;
        const int64_t stamp = f.color.meta().host_stamp_ns;
        char row[512];
        const Eigen::Isometry3d T = f.track.pose.value.value_or(Eigen::Isometry3d::Identity());
        Eigen::Quaterniond q(T.linear());
        q.normalize();
        if (q.w() < 0)
            q.coeffs() = -q.coeffs();
        std::snprintf(
            row, sizeof row, "%llu,%lld,%s,%d,%d,%zu,%zu,%.4f,%s\n",
            static_cast<unsigned long long>(f.index), static_cast<long long>(stamp),
            std::string(tracking::toString(f.track.state)).c_str(), f.track.pose.stale ? 1 : 0,
            f.track.reacquired ? 1 : 0, f.track.targets.size(), f.track.detections.size(),
            f.track.targets.empty() ? -1.0 : f.track.targets.front().rms_px,
            f.track.pose.value
                ? (std::to_string(T.translation().x()) + "," + std::to_string(T.translation().y()) +
                   "," + std::to_string(T.translation().z()) + "," + std::to_string(q.w()) + "," +
                   std::to_string(q.x()) + "," + std::to_string(q.y()) + "," +
                   std::to_string(q.z()))
                      .c_str()
                : ",,,,,,");
        poses_csv += row;
        const auto addLights = [&](const std::string& name, bool stale,
                                   const std::vector<tracking::EstimatedLight>& lights) {
            for (size_t i = 0; i < lights.size(); ++i) {
                const auto& l = lights[i];
                std::snprintf(row, sizeof row,
                              "%llu,%lld,%s,%s,%d,%zu,%.6f,%.6f,%.6f,%.6g,%.6g,%.6g,%.4f,%.1f\n",
                              static_cast<unsigned long long>(f.index),
                              static_cast<long long>(stamp),
                              std::string(tracking::toString(l.source)).c_str(), name.c_str(),
                              stale ? 1 : 0, i, l.to_light_world.x(), l.to_light_world.y(),
                              l.to_light_world.z(), l.intensity.x(), l.intensity.y(),
                              l.intensity.z(), l.angular_radius_rad * 180 / M_PI, l.weight);
                lights_csv += row;
            }
        };
        for (size_t i = 0; i < f.probes.size(); ++i)
            if (f.probes[i].value)
                addLights(setup->probes[i].name, f.probes[i].stale, f.probes[i].value->lights);
        if (f.environment.value)
            addLights(setup->environment->stream, f.environment.stale, f.environment.value->lights);
        if (f.sun.value)
            addLights("sun", f.sun.stale, {*f.sun.value});
        // Only frames with a fresh pose: a stale one would smear the map.
        if (camera_environment && f.track.state == tracking::TrackState::kTracking &&
            f.track.pose.value && !f.track.pose.stale &&
            !(result = camera_environment->add(f.color.image(), setup->camera.model, T)))
            return false;
        if (video) {
            const Image overlay = drawTrackingOverlay(f, *setup);
            if (!(result = video->write(overlay.view(), stamp)))
                return false;
        }
        char line[200];
        std::snprintf(line, sizeof line, "frame %llu: %s, %.1f ms markers, %.1f ms probes",
                      static_cast<unsigned long long>(f.index),
                      std::string(tracking::toString(f.track.state)).c_str(), f.track_ms,
                      f.probe_ms);
        status.update(line);
        return true;
    };
    std::atomic<bool> enough{false};
    std::atomic<bool> failed{false};  // `result` holds an error (written by the callback)
    ar.on_tracked = [&](const TrackedFrame& f) {
        if (!result || enough)
            return;
        if (!handle(f)) {
            failed = true;
            return;
        }
        if (options.max_frames > 0 && frames.size() >= options.max_frames)
            enough = true;
    };
    ar.max_color_frames = options.max_frames;
    auto pipeline = recordingPipeline(options.session, std::move(ar));
    if (!pipeline)
        return fail("track", pipeline.status());
    const Status ran =
        runPipeline(**pipeline, [&] { return interrupt.raised() || enough || failed; });
    status.finish();
    if (result)
        result = ran;
    if (video) {
        Status closed = video->close();
        if (result)
            result = closed;
    }
    if (!result)
        return fail("track", result);
    json doc = {{"session", options.session},
                {"setup", setup->source_path},
                {"camera_stream", setup->camera.stream},
                {"frames", frames}};
    const render::ArPipelineStats pipeline_stats = (*pipeline)->stats();
    doc["input"] = {{"complete", pipeline_stats.input.isOk()}};
    if (!pipeline_stats.input)
        doc["input"]["damage"] = pipeline_stats.input.message();
    for (const auto& [name, text] : {std::pair<std::string, std::string>{"poses.csv", poses_csv},
                                     {"lights.csv", lights_csv},
                                     {"track.json", doc.dump(1)}}) {
        if (Status s = writeText(out_dir / name, text); !s)
            return fail("track", s);
    }
    if (camera_environment) {
        const FloatImage map = camera_environment->map();
        if (Status s = render::writeExr(map, out_dir / "camera_environment.exr"); !s)
            return fail("track", s);
        // A picture of it, as the camera would show it.
        auto preview = render::toSrgb8(map);
        if (!preview)
            return fail("track", preview.status());
        if (Status s = render::writePng(preview->view(), out_dir / "camera_environment.png"); !s)
            return fail("track", s);
        std::printf(
            "camera environment: %llu frames, %.1f %% of the sphere seen (the rest filled); "
            "use it as a scene's environment light: { type: environment, file: %s }\n",
            static_cast<unsigned long long>(camera_environment->frames()),
            100 * camera_environment->coverage(),
            (out_dir / "camera_environment.exr").string().c_str());
    }
    const double n = static_cast<double>(frames.size());
    std::printf(
        "%s: %zu colour frames, %llu tracked, %llu without a fresh pose; mean %.1f ms "
        "markers, %.1f ms probes per frame\n",
        options.session.c_str(), frames.size(), static_cast<unsigned long long>(tracked),
        static_cast<unsigned long long>(lost), n > 0 ? track_ms / n : 0, n > 0 ? probe_ms / n : 0);
    std::printf("wrote %s/{poses.csv, lights.csv, track.json%s%s}\n", out_dir.string().c_str(),
                video ? ", overlay.mp4" : "",
                options.record ? ", tracked.mkv (+ tracking/pose, tracking/lights)" : "");
    const int code = finishPipelineRun("track", pipeline_stats);
    if (!interrupt.raised())
        return code;
    std::fprintf(stderr,
                 "mixray track: stopped by %s after %zu colour frames; the files hold them\n",
                 interrupt.signalName().c_str(), frames.size());
    return interrupt.exitCode();
}

}  // namespace

void registerTrackCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "track",
        "Track the camera (markers) and estimate the real lights (probes, fish-eye environment "
        "camera) in every colour frame of a recording; write poses and lights as CSV and JSON, an "
        "overlay video, and the recording with the pose as a stream");
    auto o = std::make_shared<TrackCommandOptions>();
    sub->add_option("SESSION", o->session, "Recording (.mkv, TUM or PCL TIFF folder)")->required();
    sub->add_option("--setup", o->setup,
                    "Tracking setup (docs/tracking.md#setup-files); default: the recording's "
                    "tracking.yaml attachment, else SESSION's NAME.tracking.yaml");
    sub->add_option("-o,--output", o->output, "Folder for the results")->capture_default_str();
    sub->add_flag("!--no-video", o->video, "Do not write overlay.mp4");
    sub->add_flag("!--no-record", o->record, "Do not write tracked.mkv");
    sub->add_flag("!--no-probes", o->probes, "Do not estimate lights from light probes");
    sub->add_flag("!--no-environment", o->environment,
                  "Do not estimate lights from the environment camera");
    sub->add_option("--max-frames", o->max_frames, "Stop after this many colour frames (0: all)");
    sub->add_option("--camera-environment", o->camera_environment,
                    "Also build an environment map of this width from the colour camera's own "
                    "tracked frames (camera_environment.exr and .png), for scenes without a "
                    "fish-eye camera or an HDR map")
        ->check(CLI::Range(16, 8192));
    sub->add_option("--camera-environment-radius", o->camera_environment_radius_m,
                    "Distance in metres from the world origin (the marker) to the surroundings "
                    "the camera sees; 0: at infinity")
        ->check(CLI::Range(0.0, 1e4))
        ->capture_default_str();
    sub->add_option("--rig", o->rig,
                    "Rig file whose site: (latitude, longitude, heading) gives the sun's "
                    "direction; default: the recording's rig.yaml attachment");
    sub->add_option("--utc", o->utc,
                    "UTC of the first colour frame, like 2026-06-21T12:00:00Z; default: the "
                    "recording's utc_minus_host_ns tag (mixray record sets it)");
    commands.push_back({sub, [o] { return runTrack(*o); }});
}

}  // namespace mixray::cli
