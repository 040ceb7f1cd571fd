// Writing a simulated session: the Matroska recording, its truth file, TUM trajectory and the
// real scene as a scene file (docs/simulation.md).
#include <array>
#include <charconv>
#include <chrono>
#include <fstream>
#include <limits>
#include <sstream>

#include "mixray/calibration/camera_model_yaml.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/pose.h"
#include "mixray/graph/yaml_reader.h"
#include "mixray/tracking/setup.h"
#include "simulator_internal.h"

namespace mixray::render {
namespace {

namespace fs = std::filesystem;
using Eigen::Isometry3d;
using Eigen::Vector3d;

template <typename T>
std::string num(T v) {
    return yaml::shortest(v);
}

template <typename V>
std::string list(const V& v) {
    std::string s = "[";
    for (int i = 0; i < static_cast<int>(v.size()); ++i)
        s += (i ? ", " : "") + num(v[i]);
    return s + "]";
}

Eigen::Quaterniond quaternion(const Isometry3d& T) {
    Eigen::Quaterniond q(T.linear());
    q.normalize();
    if (q.w() < 0)
        q.coeffs() = -q.coeffs();
    return q;
}

// As scene files write poses: translation and a [w, x, y, z] quaternion.
std::string poseText(const Isometry3d& T) {
    const Eigen::Quaterniond q = quaternion(T);
    return "{translation: " + list(Vector3d(T.translation())) + ", quaternion: [" + num(q.w()) +
           ", " + num(q.x()) + ", " + num(q.y()) + ", " + num(q.z()) + "]}";
}

std::string materialTypeName(MaterialType t) {
    switch (t) {
        case MaterialType::kDiffuse:
            return "diffuse";
        case MaterialType::kPhong:
            return "phong";
        case MaterialType::kMirror:
            return "mirror";
        case MaterialType::kMetal:
            return "metal";
        case MaterialType::kGlass:
            return "glass";
    }
    return "diffuse";
}

// The real scene as a scene file (docs/scene-format.md): every object a ghost, the true lights
// and the environment map. Paths are the assets' file names (they lie beside it).
std::string sceneText(const SimTruth& t) {
    std::ostringstream o;
    o << "# The real scene of a simulated session (docs/simulation.md): every object is a ghost,\n"
         "# the lights are the simulator's. Add virtual objects to composite into the session.\n"
         "version: 1\nmaterials:\n";
    for (const auto& [name, m] : t.scene.materials) {
        o << "  " << name << ": {type: " << materialTypeName(m.type);
        if (m.type == MaterialType::kDiffuse || m.type == MaterialType::kPhong)
            o << ", albedo: " << list(m.albedo);
        if (!m.albedo_texture.empty())
            o << ", albedo_texture: " << m.albedo_texture.filename().string();
        if (m.type == MaterialType::kPhong)
            o << ", specular: " << list(m.specular) << ", shininess: " << num(m.shininess);
        if (m.type == MaterialType::kMirror)
            o << ", reflectance: " << num(m.reflectance);
        o << "}\n";
    }
    o << "objects:\n";
    for (const SceneObject& obj : t.scene.objects) {
        o << "  - {name: " << obj.name << ", role: ghost, shape: {";
        switch (obj.shape.type) {
            case ShapeType::kSphere:
                o << "sphere: {radius: " << num(obj.shape.radius) << "}";
                break;
            case ShapeType::kBox:
                o << "box: {size: " << list(obj.shape.size) << "}";
                break;
            case ShapeType::kPlane:
                o << "plane: {size: " << list(Eigen::Vector2f(obj.shape.size.head<2>())) << "}";
                break;
            case ShapeType::kDisk:
                o << "disk: {radius: " << num(obj.shape.radius) << "}";
                break;
            case ShapeType::kMesh:
                break;
        }
        o << "}, material: " << obj.material << ",\n      pose: " << poseText(obj.T_anchor_object)
          << "}\n";
    }
    o << "lights:\n";
    for (const Light& l : t.lights)
        o << "  - {name: " << l.name << ", type: directional, direction: " << list(l.direction)
          << ", irradiance: " << list(l.intensity) << "}\n";
    o << "  - {name: room, type: environment, file: " << t.environment_map.filename().string()
      << "}\n";
    return o.str();
}

// What a user of this rig would write to track it: the true calibration, the marker, the
// probes and the environment camera (docs/tracking.md#setup-files).
tracking::TrackingSetup trackingSetup(const SimTruth& t) {
    tracking::TrackingSetup s;
    s.camera.stream = "kinect/color";
    s.camera.model = t.color;
    tracking::MarkerTarget& marker = s.targets.emplace_back();
    marker.name = "marker";
    marker.kind = tracking::TargetKind::kMarker;
    marker.dictionary = t.marker_dictionary;
    marker.id = t.marker_id;
    marker.size_m = t.marker_size_m;
    marker.T_world_target = t.T_world_marker;
    for (const SimProbe& p : t.probes) {
        tracking::LightProbe& probe = s.probes.emplace_back();
        probe.name = p.name;
        probe.material = p.material == MaterialType::kMirror ? tracking::ProbeMaterial::kMirror
                                                             : tracking::ProbeMaterial::kDiffuse;
        probe.radius_m = p.radius_m;
        probe.centre_world = p.centre_world;
        if (p.material == MaterialType::kDiffuse)
            // Through its shortest text: the float albedo as the decimal it was written as.
            probe.albedo = std::stod(yaml::shortest(t.scene.materials.at("matte").albedo.x()));
    }
    tracking::EnvironmentStream& env = s.environment.emplace();
    env.stream = "env/color";
    env.camera.model = t.env;
    env.camera.T_world_env = t.T_world_env;
    return s;
}

std::string truthText(const SimTruth& t, const SimulatorOptions& options, const std::string& stem,
                      int env_every) {
    const bool calib = t.scenario == SimScenario::kCalibration;
    std::ostringstream o;
    o << "# Ground truth of a simulated mixray session (docs/simulation.md). Metres, radians\n"
         "# unless a suffix says otherwise; T_a_b maps points from frame b into frame a; poses\n"
         "# are {translation, quaternion: [w, x, y, z]}; camera frames +x right, +y down, +z\n"
         "# forward (docs/conventions.md). World = the marker's frame, +z up.\n";
    o << "version: 1\n";
    o << "scenario: " << toString(t.scenario) << "\n";
    o << "seed: " << t.seed << "\n";
    o << "recording: " << stem << ".mkv\n";
    o << "# Simulator::create(readSimulationOptions(this file)) renders the session again.\n"
      << "simulation: {scenario: " << toString(t.scenario) << ", frames: " << t.frames.size()
      << ", seed: " << t.seed << ", width: " << t.color.width << ", height: " << t.color.height
      << ", samples_per_pixel: " << options.samples_per_pixel << ", env_every: " << env_every
      << ", env_map_width: " << options.env_map_width
      << ", depth: " << (t.depth_registered ? "registered" : "raw") << "}\n";
    o << "frame_count: " << t.frames.size() << "\n";
    o << "fps: " << num(t.fps) << "\n";
    o << "cameras:\n";
    o << "  kinect/color:\n    model: " << calibration::cameraModelYaml(t.color)
      << "\n    pose: per frame (frames[].T_world_color, " << stem << ".tum, truth/pose)\n";
    if (t.depth_registered)
        o << "  kinect/depth:\n    registered_to: kinect/color\n    model: "
          << calibration::cameraModelYaml(t.color) << "\n";
    else
        o << "  kinect/depth:\n    aligned_with: kinect/ir\n    model: "
          << calibration::cameraModelYaml(t.ir) << "\n";
    o << "  kinect/ir:\n    model: " << calibration::cameraModelYaml(t.ir)
      << "\n    T_color_ir: " << poseText(t.T_color_ir)
      << "\n    recorded: " << (calib ? "true" : "false") << "\n";
    o << "  env/color:\n    model: " << calibration::cameraModelYaml(t.env)
      << "\n    T_world_env: " << poseText(t.T_world_env)
      << "\n    T_marker_env: " << poseText(t.T_world_marker.inverse() * t.T_world_env)
      << "\n    every_nth_frame: " << env_every << "\n";
    const KinectDepthModel& d = t.depth_model;
    o << "depth_model:\n"
         "  reference: Khoshelham & Elberink 2012, Sensors 12(2):1437-1454\n"
         "  disparity: focal_px * baseline_m / z_ir, Gaussian noise, quantised to steps\n"
      << "  focal_px: " << num(d.focal_px) << "\n  baseline_m: " << num(d.baseline_m)
      << "\n  projector_in_ir: " << list(Vector3d(d.baseline_m, 0, 0))
      << "\n  disparity_step_px: " << num(d.disparity_step_px)
      << "\n  disparity_noise_px: " << num(d.disparity_noise_px)
      << "\n  min_range_m: " << num(d.min_range_m) << "\n  max_range_m: " << num(d.max_range_m)
      << "\n  max_incidence_deg: " << num(d.max_incidence_deg)
      << "\n  edge_jump: " << num(d.edge_jump) << "\n";
    o << "marker:\n  dictionary: " << t.marker_dictionary << "\n  id: " << t.marker_id
      << "\n  size_m: " << num(t.marker_size_m)
      << "\n  T_world_marker: " << poseText(t.T_world_marker) << "\n  corners_world:\n";
    for (const Vector3d& c : t.markerCornersWorld())
        o << "    - " << list(c) << "\n";
    o << "table_z_m: " << num(t.table_z_m) << "\n";
    o << "probes:" << (t.probes.empty() ? " []\n" : "\n");
    for (const SimProbe& p : t.probes) {
        const Material& m =
            t.scene.materials.at(p.material == MaterialType::kMirror ? "chrome" : "matte");
        o << "  - {name: " << p.name << ", material: " << materialTypeName(p.material)
          << (p.material == MaterialType::kMirror ? ", reflectance: " + num(m.reflectance)
                                                  : ", albedo: " + list(m.albedo))
          << ", radius_m: " << num(p.radius_m) << ",\n     centre_world: " << list(p.centre_world)
          << ", centre_marker: " << list(Vector3d(t.T_world_marker.inverse() * p.centre_world))
          << "}\n";
    }
    o << "lights:\n";
    for (const Light& l : t.lights) {
        const Vector3d to_light = -l.direction.normalized();
        o << "  - {name: " << l.name
          << ", type: directional, direction_world: " << list(l.direction)
          << ",\n     to_light_world: " << list(to_light)
          << ", to_light_env: " << list(Vector3d(t.T_world_env.linear().transpose() * to_light))
          << ",\n     irradiance: " << list(l.intensity) << "}\n";
    }
    o << "environment:\n  file: " << t.environment_map.filename().string()
      << "\n  frame: world (T_world_environment = identity; mixray EnvironmentMap convention)\n"
         "  lights: one disc per light, 2 deg at full radiance fading to 0 at 4 deg, integrating"
         " to its irradiance\n";
    o << "scene_file: " << stem << ".scene.yaml\n";
    if (t.board) {
        const SimBoard& b = *t.board;
        o << "board:\n  type: charuco\n  dictionary: " << b.dictionary
          << "\n  squares_x: " << b.squares_x << "\n  squares_y: " << b.squares_y
          << "\n  square_m: " << num(b.square_m) << "\n  marker_m: " << num(b.marker_m)
          << "\n  frame: OpenCV CharucoBoard (origin top-left corner, +x right, +y down, +z into "
             "the board)\n";
    }
    o << "trajectory:\n  file: " << stem
      << ".tum\n  of: kinect/color\n  format: TUM (timestamp_s tx ty tz qx qy qz qw), "
         "T_world_color\n";
    o << "frames:\n";
    for (size_t i = 0; i < t.frames.size(); ++i) {
        const SimFrameTruth& f = t.frames[i];
        o << "  - {index: " << i << ", stamp_ns: " << f.stamp_ns
          << ", env: " << (f.env_frame ? "true" : "false")
          << ",\n     T_world_color: " << poseText(f.T_world_color);
        if (f.T_world_board)
            o << ",\n     T_world_board: " << poseText(*f.T_world_board)
              << ",\n     board_seen: {color: " << num(f.board_in_color)
              << ", ir: " << num(f.board_in_ir) << ", env: " << num(f.board_in_env)
              << "}, marker_seen: {color: " << num(f.marker_in_color) << "}";
        o << "}\n";
    }
    return o.str();
}

std::string tumText(const SimTruth& t) {
    std::ostringstream o;
    o << "# mixray simulated ground truth: T_world_color of kinect/color (world = marker frame)\n"
         "# timestamp tx ty tz qx qy qz qw\n";
    char line[256];
    for (const SimFrameTruth& f : t.frames) {
        const Eigen::Quaterniond q = quaternion(f.T_world_color);
        const Vector3d p = f.T_world_color.translation();
        std::snprintf(line, sizeof line, "%.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n",
                      static_cast<double>(f.stamp_ns) * 1e-9, p.x(), p.y(), p.z(), q.x(), q.y(),
                      q.z(), q.w());
        o << line;
    }
    return o.str();
}

Status writeText(const fs::path& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << text;
    out.close();
    if (!out)
        return {ErrorCode::kIoError, path.string() + ": cannot write"};
    return Status::ok();
}

StreamInfo imageStream(const std::string& name, StreamKind kind, PixelFormat format, int width,
                       int height, double fps, ClockDomainId domain) {
    StreamInfo s;
    s.name = name;
    s.device = name.substr(0, name.find('/'));
    s.kind = kind;
    s.format = ImageDesc::packed(format, width, height);
    s.nominal_fps = fps;
    s.clock_domain = domain;
    s.tags["simulated"] = "true";
    return s;
}

}  // namespace

Result<SimulatorOptions> readSimulationOptions(std::string_view truth_text,
                                               std::string_view source_name) {
    static constexpr std::array<std::string_view, 9> kKeys = {
        "scenario",          "frames",    "seed",          "width", "height",
        "samples_per_pixel", "env_every", "env_map_width", "depth"};
    try {
        yaml::Reader r{std::string(source_name)};
        auto root = r.load(truth_text, 64 << 20, 64, "a truth file");
        if (!root)
            return root.status();
        auto fields = r.readMap(*root, {}, "a truth file mapping");
        if (!fields)
            return fields.status();
        const yaml::Item* section = yaml::find(*fields, "simulation");
        if (!section)
            return r.fail(*root,
                          "no simulation: section (written by mixray simulate since the "
                          "truth file's options were recorded)");
        auto sim = r.readMap(*section, kKeys, "a mapping of simulator options");
        if (!sim)
            return sim.status();
        for (std::string_view key : kKeys)
            if (key != "depth")  // written since IR-aligned depth exists; older files: default
                MIXRAY_RETURN_IF_ERROR(r.require(*sim, *section, key));
        const auto integer = [&](std::string_view key, int64_t lo, int64_t hi) {
            return r.integer(*yaml::find(*sim, key), lo, hi);
        };
        SimulatorOptions o;
        const yaml::Item& scenario = *yaml::find(*sim, "scenario");
        auto name = r.text(scenario);
        if (!name)
            return name.status();
        auto parsed = simScenarioFromString(*name);
        if (!parsed)
            return r.expected(scenario, "tabletop or calibration");
        o.scenario = *parsed;
        struct IntField {
            std::string_view key;
            int* out;
            int64_t lo, hi;
        };
        for (const IntField& f :
             {IntField{"frames", &o.frames, 1, 100000}, IntField{"width", &o.width, 16, 4096},
              IntField{"height", &o.height, 16, 4096},
              IntField{"samples_per_pixel", &o.samples_per_pixel, 1, 4096},
              IntField{"env_every", &o.env_every, 1, 100000},
              IntField{"env_map_width", &o.env_map_width, 16, 8192}}) {
            auto v = integer(f.key, f.lo, f.hi);
            if (!v)
                return v.status();
            *f.out = static_cast<int>(*v);
        }
        auto seed = integer("seed", 0, std::numeric_limits<int64_t>::max());
        if (!seed)
            return seed.status();
        o.seed = static_cast<uint64_t>(*seed);
        if (const yaml::Item* depth = yaml::find(*sim, "depth")) {
            auto text = r.text(*depth);
            if (!text)
                return text.status();
            if (*text != "registered" && *text != "raw")
                return r.expected(*depth, "registered or raw");
            o.register_depth = *text == "registered";
        }
        MIXRAY_RETURN_IF_ERROR(o.validate());
        return o;
    } catch (const YAML::Exception& e) {
        return Status(ErrorCode::kCorruptData, std::string(source_name) + ": " + e.what());
    }
}

Result<SimulationSummary> simulateSession(const SimulatorOptions& options_in,
                                          const fs::path& recording,
                                          const std::function<void(int, int)>& progress) {
    const auto start = std::chrono::steady_clock::now();
    if (recording.extension() != ".mkv")
        return Status(ErrorCode::kInvalidArgument,
                      recording.string() + ": the recording must be a .mkv file");
    const std::string stem = recording.stem().string();
    const fs::path dir = recording.parent_path().empty() ? fs::path(".") : recording.parent_path();
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec)
        return Status(ErrorCode::kIoError, "cannot create " + dir.string() + ": " + ec.message());
    SimulatorOptions options = options_in;
    options.asset_dir = dir;
    options.asset_prefix = stem;
    auto sim = Simulator::create(options);
    if (!sim)
        return sim.status();
    const SimTruth& t = (*sim)->truth();
    const bool calib = t.scenario == SimScenario::kCalibration;
    const int env_every = t.env_every;

    SimulationSummary summary;
    summary.files.push_back(recording);
    const fs::path truth_path = dir / (stem + ".truth.yaml");
    const fs::path tum_path = dir / (stem + ".tum");
    const fs::path scene_path = dir / (stem + ".scene.yaml");
    const std::string truth = truthText(t, options, stem, env_every);
    MIXRAY_RETURN_IF_ERROR(writeText(truth_path, truth));
    MIXRAY_RETURN_IF_ERROR(writeText(tum_path, tumText(t)));
    MIXRAY_RETURN_IF_ERROR(writeText(scene_path, sceneText(t)));
    const fs::path tracking_path = dir / (stem + ".tracking.yaml");
    const std::string tracking = tracking::trackingSetupYaml(trackingSetup(t));
    MIXRAY_RETURN_IF_ERROR(writeText(tracking_path, tracking));
    summary.files.insert(summary.files.end(),
                         {truth_path, tum_path, scene_path, tracking_path, t.environment_map});
    for (const auto& [name, m] : t.scene.materials)
        if (!m.albedo_texture.empty())
            summary.files.push_back(m.albedo_texture);

    // Streams: Kinect clock domain 1, environment camera 2.
    RecordingHeader header;
    const int w = t.color.width, h = t.color.height;
    header.streams.push_back(
        imageStream("kinect/color", StreamKind::kColor, PixelFormat::kRGB8, w, h, t.fps, 1));
    const calibration::CameraModel& depth_camera = t.depth_registered ? t.color : t.ir;
    header.streams.push_back(imageStream("kinect/depth", StreamKind::kDepth, PixelFormat::kDepth16,
                                         depth_camera.width, depth_camera.height, t.fps, 1));
    if (t.depth_registered)
        header.streams.back().tags["registered_to"] = "kinect/color";
    else
        header.streams.back().tags["aligned_with"] = "kinect/ir";
    header.streams.push_back(imageStream("env/color", StreamKind::kColor, PixelFormat::kRGB8,
                                         t.env.width, t.env.height, t.fps / env_every, 2));
    StreamInfo pose = makePoseStreamInfo("truth/pose", "kinect/color", t.fps, true);
    pose.clock_domain = 1;
    header.streams.push_back(pose);
    const StreamId kColor = 0, kDepth = 1, kEnv = 2, kPose = 3;
    StreamId kIr = kInvalidStream;
    if (calib) {
        kIr = static_cast<StreamId>(header.streams.size());
        header.streams.push_back(imageStream("kinect/ir", StreamKind::kInfrared, PixelFormat::kIR16,
                                             t.ir.width, t.ir.height, t.fps, 1));
    }
    header.attachments.push_back(
        {"truth.yaml", "application/x-yaml", std::vector<uint8_t>(truth.begin(), truth.end())});
    header.attachments.push_back({"tracking.yaml", "application/x-yaml",
                                  std::vector<uint8_t>(tracking.begin(), tracking.end())});
    header.tags["simulator"] = "mixray simulate";
    header.tags["scenario"] = std::string(toString(t.scenario));
    header.tags["seed"] = std::to_string(t.seed);
    MkvWriterOptions mkv;
    mkv.flush_every_frame = false;
    auto writer = createMkvWriter(recording, header, mkv);
    if (!writer)
        return writer.status();

    std::vector<std::shared_ptr<BufferPool>> pools;
    for (const StreamInfo& s : header.streams) {
        BufferPoolOptions po;
        po.desc = s.format;
        po.buffer_count = 2;
        po.name = s.name;
        pools.push_back(BufferPool::create(po));
    }
    const auto write = [&](StreamId stream, const ImageView& view, uint64_t sequence,
                           int64_t stamp_ns) -> Status {
        FrameMetadata meta;
        meta.stream = stream;
        meta.sequence = sequence;
        meta.device_stamp_ns = stamp_ns;
        // Arrival a fixed 2 ms (Kinect) / 3 ms (USB fish-eye) after capture: deterministic.
        meta.host_stamp_ns = stamp_ns + (stream == kEnv ? 3'000'000 : 2'000'000);
        meta.clock_domain = header.streams[stream].clock_domain;
        FrameRef frame = copyIntoPool(*pools[stream], view, meta);
        if (!frame)
            return {ErrorCode::kInternal,
                    "simulator: no buffer for " + header.streams[stream].name};
        return (*writer)->write(frame);
    };

    uint64_t env_sequence = 0;
    summary.frames_planned = (*sim)->frameCount();
    for (int i = 0; i < (*sim)->frameCount(); ++i) {
        if (options.stop.stop_requested()) {
            summary.stopped = true;
            break;
        }
        auto frame = (*sim)->render(i);
        if (!frame && frame.status().code() == ErrorCode::kCancelled &&
            options.stop.stop_requested()) {
            summary.stopped = true;  // the frame in progress is dropped whole
            break;
        }
        if (!frame)
            return frame.status();
        const SimFrameTruth& f = t.frames[static_cast<size_t>(i)];
        PoseRecord record;
        record.frame_sequence = static_cast<uint64_t>(i);
        record.frame_device_stamp_ns = f.stamp_ns;
        record.anchor = "world";
        record.setTransform(f.T_world_color);
        record.error = 0;
        auto bytes = encodePoseRecord(record);
        if (!bytes)
            return bytes.status();
        const ImageView pose_view{header.streams[kPose].format, bytes->data(), bytes->size()};
        const auto seq = static_cast<uint64_t>(i);
        MIXRAY_RETURN_IF_ERROR(write(kPose, pose_view, seq, f.stamp_ns));
        MIXRAY_RETURN_IF_ERROR(write(kColor, frame->color.view(), seq, f.stamp_ns));
        MIXRAY_RETURN_IF_ERROR(write(kDepth, frame->depth.view(), seq, f.stamp_ns));
        if (kIr != kInvalidStream)
            MIXRAY_RETURN_IF_ERROR(write(kIr, frame->ir.view(), seq, f.stamp_ns));
        if (f.env_frame) {
            MIXRAY_RETURN_IF_ERROR(write(kEnv, frame->env.view(), env_sequence++, f.stamp_ns));
            ++summary.env_frames;
        }
        ++summary.frames;
        if (progress)
            progress(i + 1, (*sim)->frameCount());
    }
    MIXRAY_RETURN_IF_ERROR((*writer)->close());
    if (summary.frames == 0 && summary.stopped) {
        std::error_code removed;
        fs::remove(recording, removed);
        if (removed)
            return Status(ErrorCode::kIoError, "cannot remove " + recording.string() +
                                                   ", left without frames: " + removed.message());
        summary.recording_written = false;
        summary.files.erase(summary.files.begin());
    }
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return summary;
}

}  // namespace mixray::render
