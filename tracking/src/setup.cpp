// Tracking setup files (docs/tracking.md#setup-files).
#include "mixray/tracking/setup.h"

#include <array>
#include <fstream>
#include <set>
#include <sstream>
#include <system_error>

#include "mixray/calibration/camera_model_yaml.h"
#include "mixray/graph/yaml_reader.h"
#include "mixray/graph/yaml_writer.h"

namespace mixray::tracking {
namespace {

using yaml::find;
using yaml::Item;

constexpr std::array<std::string_view, 7> kRootKeys = {
    "version", "camera", "targets", "tracker", "probes", "probe_options", "environment"};
constexpr std::array<std::string_view, 2> kCameraKeys = {"stream", "model"};
constexpr std::array<std::string_view, 10> kTargetKeys = {
    "name",    "type",     "dictionary",   "id",   "size_m",
    "squares", "square_m", "separation_m", "pose", "binds"};
constexpr std::array<std::string_view, 4> kTrackerKeys = {"max_rms_px", "reacquire_after_ms",
                                                          "refine_corners", "smoothing"};
constexpr std::array<std::string_view, 4> kSmoothingKeys = {"enabled", "min_cutoff_hz", "beta",
                                                            "d_cutoff_hz"};
constexpr std::array<std::string_view, 5> kProbeKeys = {"name", "material", "radius_m", "centre",
                                                        "albedo"};
constexpr std::array<std::string_view, 3> kProbeOptionKeys = {"domain", "sphere_samples",
                                                              "max_lights"};
constexpr std::array<std::string_view, 9> kEnvironmentKeys = {
    "stream",    "model",      "pose",        "room_radius_m", "exposure_scale",
    "threshold", "max_lights", "min_area_px", "map_width"};
constexpr double kMaxLength = 1e4;  // metres: anything larger is a unit mistake

std::string_view targetTypeName(TargetKind kind) {
    switch (kind) {
        case TargetKind::kMarker:
            return "marker";
        case TargetKind::kCharucoBoard:
            return "charuco";
        case TargetKind::kGridBoard:
            return "gridboard";
    }
    return "marker";
}

class SetupParser {
public:
    explicit SetupParser(std::string source) : r_(std::move(source)) {}

    Status parse(std::string_view text, TrackingSetup& setup);

private:
    Status parseCamera(const Item& item, TrackedCamera& camera);
    Status parseTarget(const Item& item, MarkerTarget& target);
    Status parseTracker(const Item& item, TrackerOptions& tracker);
    Status parseProbe(const Item& item, LightProbe& probe);
    Status parseProbeOptions(const Item& item, ProbeOptions& options);
    Status parseEnvironment(const Item& item, EnvironmentStream& environment);

    Result<double> number(const yaml::Fields& fields, std::string_view key, double lo, double hi,
                          double fallback, bool lo_exclusive = false) {
        const Item* item = find(fields, key);
        return item ? r_.number(*item, lo, hi, lo_exclusive) : Result<double>(fallback);
    }
    Result<int64_t> integer(const yaml::Fields& fields, std::string_view key, int64_t lo,
                            int64_t hi, int64_t fallback) {
        const Item* item = find(fields, key);
        return item ? r_.integer(*item, lo, hi) : Result<int64_t>(fallback);
    }
    Result<std::string> streamName(const Item& item) {
        auto text = r_.text(item);
        if (!text)
            return text.status();
        const size_t slash = text->find('/');
        if (slash == std::string::npos || slash == 0 || slash + 1 == text->size() ||
            text->find('/', slash + 1) != std::string::npos) {
            return r_.expected(item, "a stream name device/stream like kinect/color");
        }
        return text;
    }

    yaml::Reader r_;
};

#define MIXRAY_ASSIGN(lhs, expr)                \
    do {                                        \
        auto assign_value_ = (expr);            \
        if (!assign_value_)                     \
            return assign_value_.status();      \
        lhs = std::move(assign_value_).value(); \
    } while (false)

Status SetupParser::parseCamera(const Item& item, TrackedCamera& camera) {
    auto fields = r_.readMap(item, kCameraKeys, "a camera mapping with stream: and model:");
    if (!fields)
        return fields.status();
    MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, "model"));
    if (const Item* stream = find(*fields, "stream"))
        MIXRAY_ASSIGN(camera.stream, streamName(*stream));
    MIXRAY_ASSIGN(camera.model, calibration::readCameraModel(r_, *find(*fields, "model")));
    return Status::ok();
}

Status SetupParser::parseTarget(const Item& item, MarkerTarget& t) {
    auto fields = r_.readMap(item, kTargetKeys, "a target mapping with name:, type:, ...");
    if (!fields)
        return fields.status();
    MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, "name"));
    MIXRAY_ASSIGN(t.name, r_.text(*find(*fields, "name")));
    if (const Item* type = find(*fields, "type")) {
        auto name = r_.text(*type);
        if (!name)
            return name.status();
        if (*name == "marker")
            t.kind = TargetKind::kMarker;
        else if (*name == "charuco")
            t.kind = TargetKind::kCharucoBoard;
        else if (*name == "gridboard")
            t.kind = TargetKind::kGridBoard;
        else
            return r_.expected(*type, "marker, charuco or gridboard");
    }
    if (const Item* d = find(*fields, "dictionary")) {
        MIXRAY_ASSIGN(t.dictionary, r_.text(*d));
        if (!isKnownDictionary(t.dictionary))
            return r_.expected(*d, "an OpenCV dictionary like DICT_6X6_250 or apriltag:tag36h11");
    }
    int64_t id = 0;
    MIXRAY_ASSIGN(id, integer(*fields, "id", 0, 1 << 20, 0));
    t.id = static_cast<int>(id);
    MIXRAY_ASSIGN(t.size_m, number(*fields, "size_m", 0, 100, t.size_m, true));
    if (const Item* squares = find(*fields, "squares")) {
        auto xy = r_.readList(*squares, 2, 2, "[columns, rows]");
        if (!xy)
            return xy.status();
        int64_t x = 0, y = 0;
        MIXRAY_ASSIGN(x, r_.integer((*xy)[0], 1, 1000));
        MIXRAY_ASSIGN(y, r_.integer((*xy)[1], 1, 1000));
        t.squares_x = static_cast<int>(x);
        t.squares_y = static_cast<int>(y);
    }
    MIXRAY_ASSIGN(t.square_m, number(*fields, "square_m", 0, 100, t.square_m));
    MIXRAY_ASSIGN(t.separation_m, number(*fields, "separation_m", 0, 100, t.separation_m));
    if (const Item* pose = find(*fields, "pose"))
        MIXRAY_ASSIGN(t.T_world_target, r_.pose(*pose, kMaxLength));
    if (const Item* binds = find(*fields, "binds")) {
        auto names = r_.readList(*binds, 0, 10000, "a list of scene object names");
        if (!names)
            return names.status();
        for (const Item& n : *names) {
            std::string name;
            MIXRAY_ASSIGN(name, r_.text(n));
            t.bound_objects.push_back(std::move(name));
        }
    }
    if (Status s = t.validate(); !s)
        return r_.fail(item, s.message());
    return Status::ok();
}

Status SetupParser::parseTracker(const Item& item, TrackerOptions& o) {
    auto fields = r_.readMap(item, kTrackerKeys, "a tracker options mapping");
    if (!fields)
        return fields.status();
    MIXRAY_ASSIGN(o.max_rms_px, number(*fields, "max_rms_px", 0, 1e3, o.max_rms_px, true));
    double reacquire_ms = 0;
    MIXRAY_ASSIGN(reacquire_ms, number(*fields, "reacquire_after_ms", 0, 3.6e6,
                                       static_cast<double>(o.reacquire_after_ns) * 1e-6));
    o.reacquire_after_ns = static_cast<int64_t>(reacquire_ms * 1e6);
    if (const Item* refine = find(*fields, "refine_corners"))
        MIXRAY_ASSIGN(o.detector.refine_corners, r_.boolean(*refine));
    if (const Item* smoothing = find(*fields, "smoothing")) {
        auto s = r_.readMap(*smoothing, kSmoothingKeys, "a smoothing mapping");
        if (!s)
            return s.status();
        SmoothingOptions& sm = o.smoothing;
        if (const Item* enabled = find(*s, "enabled"))
            MIXRAY_ASSIGN(sm.enabled, r_.boolean(*enabled));
        MIXRAY_ASSIGN(sm.min_cutoff_hz,
                      number(*s, "min_cutoff_hz", 0, 1e4, sm.min_cutoff_hz, true));
        MIXRAY_ASSIGN(sm.beta, number(*s, "beta", 0, 1e6, sm.beta));
        MIXRAY_ASSIGN(sm.d_cutoff_hz, number(*s, "d_cutoff_hz", 0, 1e4, sm.d_cutoff_hz, true));
    }
    if (Status s = o.validate(); !s)
        return r_.fail(item, s.message());
    return Status::ok();
}

Status SetupParser::parseProbe(const Item& item, LightProbe& p) {
    auto fields = r_.readMap(item, kProbeKeys, "a probe mapping with name:, material:, ...");
    if (!fields)
        return fields.status();
    for (std::string_view key : {"name", "radius_m", "centre"})
        MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, key));
    MIXRAY_ASSIGN(p.name, r_.text(*find(*fields, "name")));
    if (const Item* m = find(*fields, "material")) {
        auto name = r_.text(*m);
        if (!name)
            return name.status();
        if (*name == "mirror")
            p.material = ProbeMaterial::kMirror;
        else if (*name == "diffuse")
            p.material = ProbeMaterial::kDiffuse;
        else
            return r_.expected(*m, "mirror or diffuse");
    }
    MIXRAY_ASSIGN(p.radius_m, number(*fields, "radius_m", 0, 100, 0, true));
    MIXRAY_ASSIGN(p.centre_world, r_.vector3(*find(*fields, "centre"), kMaxLength));
    MIXRAY_ASSIGN(p.albedo, number(*fields, "albedo", 0, 1, p.albedo, true));
    if (Status s = p.validate(); !s)
        return r_.fail(item, s.message());
    return Status::ok();
}

Status SetupParser::parseProbeOptions(const Item& item, ProbeOptions& o) {
    auto fields = r_.readMap(item, kProbeOptionKeys, "a probe options mapping");
    if (!fields)
        return fields.status();
    if (const Item* d = find(*fields, "domain")) {
        auto name = r_.text(*d);
        if (!name)
            return name.status();
        if (*name == "image")
            o.domain = ProbeDomain::kImage;
        else if (*name == "sphere")
            o.domain = ProbeDomain::kSphere;
        else
            return r_.expected(*d, "image or sphere");
    }
    int64_t v = 0;
    MIXRAY_ASSIGN(v, integer(*fields, "sphere_samples", 4, 4096, o.sphere_samples));
    o.sphere_samples = static_cast<int>(v);
    MIXRAY_ASSIGN(v, integer(*fields, "max_lights", 1, 64, o.max_lights));
    o.max_lights = static_cast<int>(v);
    if (Status s = o.validate(); !s)
        return r_.fail(item, s.message());
    return Status::ok();
}

Status SetupParser::parseEnvironment(const Item& item, EnvironmentStream& e) {
    auto fields = r_.readMap(item, kEnvironmentKeys, "an environment camera mapping");
    if (!fields)
        return fields.status();
    for (std::string_view key : {"model", "pose"})
        MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, key));
    if (const Item* stream = find(*fields, "stream"))
        MIXRAY_ASSIGN(e.stream, streamName(*stream));
    MIXRAY_ASSIGN(e.camera.model, calibration::readCameraModel(r_, *find(*fields, "model")));
    MIXRAY_ASSIGN(e.camera.T_world_env, r_.pose(*find(*fields, "pose"), kMaxLength));
    MIXRAY_ASSIGN(e.camera.room_radius_m, number(*fields, "room_radius_m", 0, kMaxLength, 0));
    MIXRAY_ASSIGN(e.camera.exposure_scale,
                  number(*fields, "exposure_scale", 0, 1e9, e.camera.exposure_scale, true));
    MIXRAY_ASSIGN(e.lights.threshold, number(*fields, "threshold", 0, 1, e.lights.threshold, true));
    int64_t v = 0;
    MIXRAY_ASSIGN(v, integer(*fields, "max_lights", 1, 64, e.lights.max_lights));
    e.lights.max_lights = static_cast<int>(v);
    MIXRAY_ASSIGN(e.lights.min_area_px,
                  number(*fields, "min_area_px", 0, 1e9, e.lights.min_area_px));
    MIXRAY_ASSIGN(v, integer(*fields, "map_width", 16, 8192, e.map_width));
    if (v % 2 != 0)
        return r_.expected(*find(*fields, "map_width"), "an even width");
    e.map_width = static_cast<int>(v);
    if (Status s = e.camera.validate(); !s)
        return r_.fail(item, s.message());
    if (Status s = e.lights.validate(); !s)
        return r_.fail(item, s.message());
    return Status::ok();
}

Status SetupParser::parse(std::string_view text, TrackingSetup& setup) {
    auto root = r_.load(text, kMaxTrackingSetupBytes, 32, "a tracking setup file");
    if (!root)
        return root.status();
    auto fields = r_.readMap(*root, kRootKeys, "a tracking setup mapping");
    if (!fields)
        return fields.status();
    for (std::string_view key : {"camera", "targets"})
        MIXRAY_RETURN_IF_ERROR(r_.require(*fields, *root, key));
    if (const Item* version = find(*fields, "version")) {
        auto v = r_.integer(*version, 1, 1);
        if (!v)
            return r_.expected(*version, "1 (the only version)");
    }
    MIXRAY_RETURN_IF_ERROR(parseCamera(*find(*fields, "camera"), setup.camera));
    const Item& targets = *find(*fields, "targets");
    auto target_items = r_.readList(targets, 1, 1000, "a list of one or more targets");
    if (!target_items)
        return target_items.status();
    std::set<std::string> names;
    for (const Item& t : *target_items) {
        MIXRAY_RETURN_IF_ERROR(parseTarget(t, setup.targets.emplace_back()));
        if (!names.insert(setup.targets.back().name).second)
            return r_.fail(t, "a second target named \"" + setup.targets.back().name + "\"");
    }
    if (const Item* tracker = find(*fields, "tracker"))
        MIXRAY_RETURN_IF_ERROR(parseTracker(*tracker, setup.tracker));
    if (const Item* probes = find(*fields, "probes")) {
        auto items = r_.readList(*probes, 0, 100, "a list of light probes");
        if (!items)
            return items.status();
        for (const Item& p : *items) {
            MIXRAY_RETURN_IF_ERROR(parseProbe(p, setup.probes.emplace_back()));
            if (!names.insert(setup.probes.back().name).second)
                return r_.fail(p, "the name \"" + setup.probes.back().name + "\" is taken");
        }
    }
    if (const Item* options = find(*fields, "probe_options"))
        MIXRAY_RETURN_IF_ERROR(parseProbeOptions(*options, setup.probe_options));
    if (const Item* environment = find(*fields, "environment"))
        MIXRAY_RETURN_IF_ERROR(parseEnvironment(*environment, setup.environment.emplace()));
    if (Status s = setup.camera.model.validate(); !s)
        return r_.fail(*find(*fields, "camera"), s.message());
    return Status::ok();
}

#undef MIXRAY_ASSIGN

std::string num(double v) {
    return yaml::shortest(v);
}

std::string vec(const Eigen::Vector3d& v) {
    return "[" + num(v.x()) + ", " + num(v.y()) + ", " + num(v.z()) + "]";
}

std::string pose(const Eigen::Isometry3d& T) {
    Eigen::Quaterniond q(T.linear());
    q.normalize();
    if (q.w() < 0)
        q.coeffs() = -q.coeffs();
    return "{translation: " + vec(T.translation()) + ", quaternion: [" + num(q.w()) + ", " +
           num(q.x()) + ", " + num(q.y()) + ", " + num(q.z()) + "]}";
}

}  // namespace

Status TrackingSetup::validate() const {
    const auto bad = [](const std::string& what) {
        return Status(ErrorCode::kInvalidArgument, "tracking setup: " + what);
    };
    if (version != 1)
        return bad("version must be 1");
    if (Status s = camera.model.validate(); !s)
        return bad("camera.model: " + s.message());
    if (targets.empty())
        return bad("no targets: at least one marker or board places the camera");
    std::set<std::string> names;
    for (const MarkerTarget& t : targets) {
        if (Status s = t.validate(); !s)
            return bad("target " + t.name + ": " + s.message());
        if (!names.insert(t.name).second)
            return bad("two targets named " + t.name);
    }
    for (const LightProbe& p : probes) {
        if (Status s = p.validate(); !s)
            return bad("probe " + p.name + ": " + s.message());
        if (!names.insert(p.name).second)
            return bad("the name " + p.name + " is used twice");
    }
    MIXRAY_RETURN_IF_ERROR(tracker.validate());
    MIXRAY_RETURN_IF_ERROR(probe_options.validate());
    if (environment) {
        MIXRAY_RETURN_IF_ERROR(environment->camera.validate());
        MIXRAY_RETURN_IF_ERROR(environment->lights.validate());
        if (environment->map_width < 16 || environment->map_width % 2 != 0)
            return bad("environment.map_width must be even and >= 16");
    }
    return Status::ok();
}

Result<TrackingSetup> parseTrackingSetup(std::string_view text, std::string_view source_name) {
    TrackingSetup setup;
    setup.source_path = std::string(source_name);
    try {
        SetupParser parser{std::string(source_name)};
        MIXRAY_RETURN_IF_ERROR(parser.parse(text, setup));
    } catch (const YAML::Exception& e) {
        return Status(ErrorCode::kCorruptData, std::string(source_name) + ": " + e.what());
    }
    // Cross-entry problems are the file's content too.
    if (Status s = setup.validate(); !s)
        return Status(ErrorCode::kCorruptData, std::string(source_name) + ": " + s.message());
    return setup;
}

Result<TrackingSetup> loadTrackingSetup(const std::filesystem::path& path) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec))
        return Status(ErrorCode::kNotFound, "tracking setup " + path.string() + " does not exist");
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    if (!in && !in.eof())
        return Status(ErrorCode::kIoError, "cannot read tracking setup " + path.string());
    return parseTrackingSetup(text.str(), path.string());
}

std::string trackingSetupYaml(const TrackingSetup& s) {
    std::ostringstream o;
    o << "# mixray tracking setup (docs/tracking.md#setup-files). World = the marker frame, +z "
         "up;\n# poses T_world_x as {translation, quaternion: [w, x, y, z]}.\n";
    o << "version: 1\n";
    o << "camera:\n  stream: " << s.camera.stream
      << "\n  model: " << calibration::cameraModelYaml(s.camera.model) << "\n";
    o << "targets:\n";
    for (const MarkerTarget& t : s.targets) {
        o << "  - name: " << yaml::doubleQuoted(t.name) << "\n    type: " << targetTypeName(t.kind)
          << "\n    dictionary: " << yaml::doubleQuoted(t.dictionary) << "\n    id: " << t.id
          << "\n    size_m: " << num(t.size_m) << "\n";
        if (t.kind != TargetKind::kMarker) {
            o << "    squares: [" << t.squares_x << ", " << t.squares_y << "]\n";
            if (t.kind == TargetKind::kCharucoBoard)
                o << "    square_m: " << num(t.square_m) << "\n";
            else
                o << "    separation_m: " << num(t.separation_m) << "\n";
        }
        o << "    pose: " << pose(t.T_world_target) << "\n";
        if (!t.bound_objects.empty()) {
            o << "    binds: [";
            for (size_t i = 0; i < t.bound_objects.size(); ++i)
                o << (i ? ", " : "") << yaml::doubleQuoted(t.bound_objects[i]);
            o << "]\n";
        }
    }
    const TrackerOptions& tr = s.tracker;
    o << "tracker:\n  max_rms_px: " << num(tr.max_rms_px)
      << "\n  reacquire_after_ms: " << num(static_cast<double>(tr.reacquire_after_ns) * 1e-6)
      << "\n  refine_corners: " << (tr.detector.refine_corners ? "true" : "false")
      << "\n  smoothing: {enabled: " << (tr.smoothing.enabled ? "true" : "false")
      << ", min_cutoff_hz: " << num(tr.smoothing.min_cutoff_hz)
      << ", beta: " << num(tr.smoothing.beta) << ", d_cutoff_hz: " << num(tr.smoothing.d_cutoff_hz)
      << "}\n";
    if (!s.probes.empty()) {
        o << "probes:\n";
        for (const LightProbe& p : s.probes) {
            o << "  - {name: " << yaml::doubleQuoted(p.name)
              << ", material: " << (p.material == ProbeMaterial::kMirror ? "mirror" : "diffuse")
              << ", radius_m: " << num(p.radius_m) << ", centre: " << vec(p.centre_world)
              << ", albedo: " << num(p.albedo) << "}\n";
        }
    }
    const ProbeOptions& po = s.probe_options;
    o << "probe_options: {domain: " << (po.domain == ProbeDomain::kImage ? "image" : "sphere")
      << ", sphere_samples: " << po.sphere_samples << ", max_lights: " << po.max_lights << "}\n";
    if (s.environment) {
        const EnvironmentStream& e = *s.environment;
        o << "environment:\n  stream: " << e.stream
          << "\n  model: " << calibration::cameraModelYaml(e.camera.model)
          << "\n  pose: " << pose(e.camera.T_world_env)
          << "\n  room_radius_m: " << num(e.camera.room_radius_m)
          << "\n  exposure_scale: " << num(e.camera.exposure_scale)
          << "\n  threshold: " << num(e.lights.threshold)
          << "\n  max_lights: " << e.lights.max_lights
          << "\n  min_area_px: " << num(e.lights.min_area_px) << "\n  map_width: " << e.map_width
          << "\n";
    }
    return o.str();
}

}  // namespace mixray::tracking
