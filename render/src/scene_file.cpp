// Scene file parsing: strict YAML (mixray/graph/yaml_reader.h; yaml-cpp exceptions caught here)
// walked into a SceneDescription, then SceneDescription::validate().
#include "mixray/render/scene_file.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <system_error>
#include <vector>

#include "mixray/calibration/camera_model_yaml.h"
#include "mixray/graph/yaml_reader.h"

namespace mixray::render {
namespace {

using yaml::Field;
using yaml::Fields;
using yaml::find;
using yaml::Item;

constexpr double kMaxLength = 1e4;     // metres: anything larger is a unit mistake
constexpr double kMaxScale = 1e6;      // mesh scale factor
constexpr double kMaxIntensity = 1e9;  // light intensity / irradiance
constexpr double kMaxShininess = 1e6;  // Blinn-Phong exponent
constexpr double kMaxIor = 10;         // no real dielectric comes close
constexpr int64_t kMaxMarkerId = 1 << 20;
constexpr size_t kMaxEntries = 10000;  // objects, lights, materials

bool isNameChar(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-';
}

constexpr std::string_view kNameRule = "a name of up to 64 letters, digits, '_' or '-'";

bool isValidName(std::string_view name) {
    return !name.empty() && name.size() <= 64 && std::all_of(name.begin(), name.end(), isNameChar);
}

// "world" or "marker:<id>" with a decimal id; the canonical spelling, or nullopt.
std::optional<std::string> canonicalAnchor(std::string_view anchor) {
    if (anchor == "world")
        return std::string(anchor);
    constexpr std::string_view kMarker = "marker:";
    if (anchor.substr(0, kMarker.size()) != kMarker)
        return std::nullopt;
    const std::string_view digits = anchor.substr(kMarker.size());
    if (digits.empty() || digits.size() > 7 ||
        !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) {
        return std::nullopt;
    }
    const int64_t id = std::stoll(std::string(digits));
    if (id > kMaxMarkerId)
        return std::nullopt;
    return "marker:" + std::to_string(id);
}

constexpr std::string_view kAnchorRule = "an anchor: world or marker:<id> (like marker:3)";

// ---------------------------------------------------------------------------------------------
// Schema

constexpr std::array<std::string_view, 10> kRootKeys = {
    "version",       "materials",    "objects",         "lights",   "camera",
    "depth_surface", "lens_effects", "camera_matching", "caustics", "estimated_lights"};
constexpr std::array<std::string_view, 1> kEstimatedLightKeys = {"shadow_map"};
constexpr std::array<std::string_view, 2> kCausticsKeys = {"photons", "radius_m"};
constexpr std::array<std::string_view, 2> kCameraMatchingKeys = {"noise", "motion_blur"};
constexpr std::array<std::string_view, 1> kMotionBlurKeys = {"exposure_ms"};
constexpr std::array<std::string_view, 1> kDepthSurfaceKeys = {"reflectance"};
constexpr std::array<std::string_view, 2> kLensEffectKeys = {"bloom", "glare"};
constexpr std::array<std::string_view, 3> kBloomKeys = {"threshold", "strength", "radius_px"};
constexpr std::array<std::string_view, 4> kGlareKeys = {"threshold", "strength", "passes",
                                                        "attenuation"};
constexpr std::array<std::string_view, 10> kMaterialKeys = {
    "type", "albedo", "albedo_texture", "specular",    "shininess",
    "f0",   "ior",    "transmission",   "reflectance", "reflectance_map"};
constexpr std::array<std::string_view, 6> kObjectKeys = {"name",     "role",   "shape",
                                                         "material", "anchor", "pose"};
constexpr std::array<std::string_view, 5> kShapeKeys = {"sphere", "box", "plane", "disk", "mesh"};
constexpr std::array<std::string_view, 2> kRotationKeys = {"rotation_deg", "quaternion"};
constexpr std::array<std::string_view, 13> kLightKeys = {"name",
                                                         "type",
                                                         "anchor",
                                                         "position",
                                                         "radius",
                                                         "intensity",
                                                         "direction",
                                                         "irradiance",
                                                         "file",
                                                         "scale",
                                                         "mirror_lower_hemisphere",
                                                         "rotation",
                                                         "shadow_map"};
constexpr std::array<std::string_view, 6> kShadowMapKeys = {
    "filter", "resolution", "kernel", "blur_texels", "bleeding_reduction", "storage"};
constexpr std::array<std::string_view, 3> kShadowMapFilters = {"hard", "pcf", "vsm"};
constexpr std::array<std::string_view, 3> kShadowMapStorages = {"float", "8bit", "rgba8"};
constexpr std::array<std::string_view, 3> kCameraKeys = {"pose", "model", "aperture"};
constexpr std::array<std::string_view, 3> kApertureKeys = {"f_number", "focal_length_mm",
                                                           "focus_distance_m"};

struct TypeKeys {
    std::string_view type;
    std::vector<std::string_view> keys;
};

const std::vector<TypeKeys>& materialTypes() {
    static const std::vector<TypeKeys> types = {
        {"diffuse", {"type", "albedo", "albedo_texture", "reflectance", "reflectance_map"}},
        {"phong",
         {"type", "albedo", "albedo_texture", "specular", "shininess", "reflectance",
          "reflectance_map"}},
        {"mirror", {"type", "reflectance"}},
        {"metal", {"type", "f0"}},
        {"glass", {"type", "ior", "transmission"}},
    };
    return types;
}

const std::vector<TypeKeys>& lightTypes() {
    static const std::vector<TypeKeys> types = {
        {"point", {"name", "type", "anchor", "position", "intensity", "shadow_map"}},
        {"sphere", {"name", "type", "anchor", "position", "radius", "intensity", "shadow_map"}},
        {"directional", {"name", "type", "anchor", "direction", "irradiance", "shadow_map"}},
        {"environment", {"name", "type", "file", "scale", "mirror_lower_hemisphere", "rotation"}},
    };
    return types;
}

class SceneParser {
public:
    SceneParser(std::string file, std::filesystem::path base)
        : r_(std::move(file)), base_(std::move(base)) {}

    Status parse(std::string_view text, SceneDescription& scene);

private:
    Status parseMaterial(const Field& field, SceneDescription& scene);
    Status parseObject(const Item& item, SceneDescription& scene,
                       std::map<std::string, SourceLocation>& names);
    Result<Shape> parseShape(const Item& item);
    Status parseLight(const Item& item, SceneDescription& scene,
                      std::map<std::string, SourceLocation>& names);
    Result<ShadowMapSettings> parseShadowMap(const Item& item);
    Status parseCamera(const Item& item, SceneDescription& scene);
    Status parseLensEffects(const Item& item, SceneDescription& scene);

    // Refuses keys the chosen type does not use, naming the ones it does.
    Status checkTypeKeys(const Fields& fields, const TypeKeys& type, std::string_view what);
    Result<const TypeKeys*> chooseType(const Item& item, const std::vector<TypeKeys>& types);

    Result<std::string> name(const Item& item);
    Result<std::string> anchor(const Item& item);
    Result<float> scalar(const Item& item, double min, double max, bool min_exclusive);
    // Reads `key` of `fields` into `out` when it is there, in [min, max] (min excluded when
    // `min_exclusive`); `out` keeps its value when the key is absent.
    Status optionalScalar(const Fields& fields, std::string_view key, double min, double max,
                          bool min_exclusive, float& out);
    // The index in `names` of the item's word.
    Result<size_t> oneOf(const Item& item, std::span<const std::string_view> names);
    // A linear RGB colour: a number (grey) or [r, g, b], each in [min, max].
    Result<Rgb> colour(const Item& item, double min, double max);
    Result<Eigen::Vector3d> vector3(const Item& item, double limit) {
        return r_.vector3(item, limit);
    }
    Result<Eigen::Quaterniond> rotation(const Fields& fields) { return r_.rotation(fields); }
    Result<Eigen::Isometry3d> pose(const Item& item) { return r_.pose(item, kMaxLength); }
    Result<std::filesystem::path> path(const Item& item);

    yaml::Reader r_;
    std::filesystem::path base_;
};

Result<std::string> SceneParser::name(const Item& item) {
    if (!item.node.IsScalar() || !isValidName(item.node.Scalar()))
        return r_.expected(item, kNameRule);
    return item.node.Scalar();
}

Result<std::string> SceneParser::anchor(const Item& item) {
    if (item.node.IsScalar()) {
        if (auto a = canonicalAnchor(item.node.Scalar()))
            return *a;
    }
    return r_.expected(item, kAnchorRule);
}

Result<float> SceneParser::scalar(const Item& item, double min, double max, bool min_exclusive) {
    auto v = r_.number(item, min, max, min_exclusive);
    if (!v)
        return v.status();
    return static_cast<float>(*v);
}

Status SceneParser::optionalScalar(const Fields& fields, std::string_view key, double min,
                                   double max, bool min_exclusive, float& out) {
    if (const Item* v = find(fields, key)) {
        auto x = scalar(*v, min, max, min_exclusive);
        if (!x)
            return x.status();
        out = *x;
    }
    return Status::ok();
}

Result<size_t> SceneParser::oneOf(const Item& item, std::span<const std::string_view> names) {
    if (item.node.IsScalar()) {
        for (size_t i = 0; i < names.size(); ++i)
            if (item.node.Scalar() == names[i])
                return i;
        std::string what = "expected one of " + yaml::joinNames(names);
        if (auto guess = yaml::closestName(item.node.Scalar(), names); !guess.empty())
            what += " (did you mean " + std::string(guess) + "?)";
        return r_.fail(item, what + ", got " + yaml::quote(item.node.Scalar()));
    }
    return r_.expected(item, "one of " + yaml::joinNames(names));
}

Result<Rgb> SceneParser::colour(const Item& item, double min, double max) {
    if (item.node.IsScalar()) {
        auto grey = scalar(item, min, max, false);
        if (!grey)
            return grey.status();
        return Rgb(Rgb::Constant(*grey));
    }
    auto elements = r_.readList(item, 3, 3, "a colour: a number (grey) or [r, g, b]");
    if (!elements)
        return elements.status();
    Rgb c;
    for (int i = 0; i < 3; ++i) {
        auto v = scalar((*elements)[i], min, max, false);
        if (!v)
            return v.status();
        c[i] = *v;
    }
    return c;
}

Result<std::filesystem::path> SceneParser::path(const Item& item) {
    auto written = r_.text(item);
    if (!written)
        return written.status();
    const std::filesystem::path p(*written);
    return p.is_absolute() ? p.lexically_normal() : (base_ / p).lexically_normal();
}

Result<const TypeKeys*> SceneParser::chooseType(const Item& item,
                                                const std::vector<TypeKeys>& types) {
    std::vector<std::string_view> names;
    for (const auto& t : types) {
        names.push_back(t.type);
        if (item.node.IsScalar() && item.node.Scalar() == t.type)
            return &t;
    }
    std::string what = "expected one of " + yaml::joinNames(names);
    if (item.node.IsScalar()) {
        if (auto guess = yaml::closestName(item.node.Scalar(), names); !guess.empty())
            what += " (did you mean " + std::string(guess) + "?)";
        return r_.fail(item, what + ", got " + yaml::quote(item.node.Scalar()));
    }
    return r_.expected(item, "one of " + yaml::joinNames(names));
}

Status SceneParser::checkTypeKeys(const Fields& fields, const TypeKeys& type,
                                  std::string_view what) {
    for (const auto& f : fields) {
        if (std::find(type.keys.begin(), type.keys.end(), f.key) == type.keys.end()) {
            return yaml::corrupt(f.key_where, f.item.path,
                                 "does not apply to a " + std::string(type.type) + " " +
                                     std::string(what) +
                                     " (its fields: " + yaml::joinNames(type.keys) + ")");
        }
    }
    return Status::ok();
}

Status SceneParser::parseMaterial(const Field& field, SceneDescription& scene) {
    if (!isValidName(field.key)) {
        return yaml::corrupt(field.key_where, field.item.path,
                             "a material name is " + std::string(kNameRule));
    }
    auto fields = r_.readMap(field.item, kMaterialKeys, "a material mapping with type:");
    if (!fields)
        return fields.status();
    Material m;
    m.name = field.key;
    m.where = field.key_where;
    const TypeKeys* type = &materialTypes()[0];
    if (const Item* t = find(*fields, "type")) {
        auto chosen = chooseType(*t, materialTypes());
        if (!chosen)
            return chosen.status();
        type = *chosen;
    }
    MIXRAY_RETURN_IF_ERROR(checkTypeKeys(*fields, *type, "material"));
    static constexpr std::array kTypes = {MaterialType::kDiffuse, MaterialType::kPhong,
                                          MaterialType::kMirror, MaterialType::kMetal,
                                          MaterialType::kGlass};
    m.type = kTypes[static_cast<size_t>(type - materialTypes().data())];
    if (m.type == MaterialType::kMirror)
        m.reflectance = 1;

    for (const auto& f : *fields) {
        const Item& v = f.item;
        if (f.key == "albedo" || f.key == "specular" || f.key == "f0" || f.key == "transmission") {
            auto c = colour(v, 0, 1);
            if (!c)
                return c.status();
            (f.key == "albedo"     ? m.albedo
             : f.key == "specular" ? m.specular
             : f.key == "f0"       ? m.f0
                                   : m.transmission) = *c;
        } else if (f.key == "ior") {
            auto c = colour(v, 1, kMaxIor);
            if (!c)
                return c.status();
            m.ior = *c;
        } else if (f.key == "shininess") {
            auto s = scalar(v, 0, kMaxShininess, true);
            if (!s)
                return s.status();
            m.shininess = *s;
        } else if (f.key == "reflectance") {
            auto s = scalar(v, 0, 1, false);
            if (!s)
                return s.status();
            m.reflectance = *s;
        } else if (f.key == "albedo_texture" || f.key == "reflectance_map") {
            auto p = path(v);
            if (!p)
                return p.status();
            (f.key == "albedo_texture" ? m.albedo_texture : m.reflectance_map) = *p;
        }
    }
    scene.materials.emplace(m.name, std::move(m));
    return Status::ok();
}

Result<Shape> SceneParser::parseShape(const Item& item) {
    auto fields = r_.readMap(item, kShapeKeys,
                             "a shape: one of sphere:, box:, plane:, disk: or mesh: with its "
                             "settings");
    if (!fields)
        return fields.status();
    if (fields->size() != 1) {
        return r_.fail(item, "give exactly one of sphere, box, plane, disk and mesh");
    }
    const Field& kind = fields->front();
    Shape shape;
    static constexpr std::array<std::string_view, 1> kRadius = {"radius"};
    static constexpr std::array<std::string_view, 1> kSize = {"size"};
    static constexpr std::array<std::string_view, 2> kMesh = {"file", "scale"};
    auto radius = [&](ShapeType type) -> Status {
        auto settings = r_.readMap(kind.item, kRadius, "a mapping with radius:");
        if (!settings)
            return settings.status();
        MIXRAY_RETURN_IF_ERROR(r_.require(*settings, kind.item, "radius"));
        auto value = scalar(*find(*settings, "radius"), 0, kMaxLength, true);
        if (!value)
            return value.status();
        shape.type = type;
        shape.radius = *value;
        return Status::ok();
    };
    if (kind.key == "sphere") {
        MIXRAY_RETURN_IF_ERROR(radius(ShapeType::kSphere));
    } else if (kind.key == "disk") {
        MIXRAY_RETURN_IF_ERROR(radius(ShapeType::kDisk));
    } else if (kind.key == "box" || kind.key == "plane") {
        const bool box = kind.key == "box";
        auto settings = r_.readMap(kind.item, kSize, "a mapping with size:");
        if (!settings)
            return settings.status();
        MIXRAY_RETURN_IF_ERROR(r_.require(*settings, kind.item, "size"));
        const Item& size = *find(*settings, "size");
        auto elements = r_.readList(size, box ? 3 : 2, box ? 3 : 2,
                                    box ? "edge lengths [x, y, z]" : "extents [x, y]");
        if (!elements)
            return elements.status();
        shape.type = box ? ShapeType::kBox : ShapeType::kPlane;
        shape.size = Eigen::Vector3f::Zero();
        for (size_t i = 0; i < elements->size(); ++i) {
            auto v = scalar((*elements)[i], 0, kMaxLength, true);
            if (!v)
                return v.status();
            shape.size[static_cast<int>(i)] = *v;
        }
    } else {
        auto settings = r_.readMap(kind.item, kMesh, "a mapping with file: and scale:");
        if (!settings)
            return settings.status();
        MIXRAY_RETURN_IF_ERROR(r_.require(*settings, kind.item, "file"));
        auto file = path(*find(*settings, "file"));
        if (!file)
            return file.status();
        shape.type = ShapeType::kMesh;
        shape.mesh = *file;
        if (const Item* s = find(*settings, "scale")) {
            auto scale = scalar(*s, 0, kMaxScale, true);
            if (!scale)
                return scale.status();
            shape.scale = *scale;
        }
    }
    return shape;
}

Status SceneParser::parseObject(const Item& item, SceneDescription& scene,
                                std::map<std::string, SourceLocation>& names) {
    auto fields =
        r_.readMap(item, kObjectKeys, "an object mapping with name:, shape: and material:");
    if (!fields)
        return fields.status();
    for (std::string_view key : {"name", "shape", "material"})
        MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, key));
    SceneObject object;
    object.where = item.where;

    const Item& name_item = *find(*fields, "name");
    auto object_name = name(name_item);
    if (!object_name)
        return object_name.status();
    if (auto [it, inserted] = names.emplace(*object_name, name_item.where); !inserted) {
        return r_.fail(name_item, "duplicate object name " + yaml::quote(*object_name) +
                                      " (first at " + it->second.toString() + ")");
    }
    object.name = *object_name;

    if (const Item* role = find(*fields, "role")) {
        if (role->node.IsScalar() && role->node.Scalar() == "virtual") {
            object.role = ObjectRole::kVirtual;
        } else if (role->node.IsScalar() && role->node.Scalar() == "ghost") {
            object.role = ObjectRole::kGhost;
        } else {
            return r_.expected(*role, "virtual or ghost");
        }
    }
    auto shape = parseShape(*find(*fields, "shape"));
    if (!shape)
        return shape.status();
    object.shape = *shape;

    const Item& material_item = *find(*fields, "material");
    auto material = name(material_item);
    if (!material)
        return material.status();
    if (!scene.materials.count(*material)) {
        std::vector<std::string_view> known;
        for (const auto& [key, value] : scene.materials)
            known.push_back(key);
        std::string what = "unknown material " + yaml::quote(*material);
        if (auto guess = yaml::closestName(*material, known); !guess.empty())
            what += " (did you mean " + std::string(guess) + "?)";
        what += known.empty() ? "; the file defines no materials:"
                              : "; materials: " + yaml::joinNames(known);
        return r_.fail(material_item, what);
    }
    object.material = *material;

    if (const Item* a = find(*fields, "anchor")) {
        auto value = anchor(*a);
        if (!value)
            return value.status();
        object.anchor = *value;
    }
    if (const Item* p = find(*fields, "pose")) {
        auto T = pose(*p);
        if (!T)
            return T.status();
        object.T_anchor_object = *T;
    }
    scene.objects.push_back(std::move(object));
    return Status::ok();
}

Status SceneParser::parseLight(const Item& item, SceneDescription& scene,
                               std::map<std::string, SourceLocation>& names) {
    auto fields = r_.readMap(item, kLightKeys, "a light mapping with type:");
    if (!fields)
        return fields.status();
    MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, "type"));
    auto type = chooseType(*find(*fields, "type"), lightTypes());
    if (!type)
        return type.status();
    MIXRAY_RETURN_IF_ERROR(checkTypeKeys(*fields, **type, "light"));
    static constexpr std::array kTypes = {LightType::kPoint, LightType::kSphere,
                                          LightType::kDirectional, LightType::kEnvironment};
    Light light;
    light.type = kTypes[static_cast<size_t>(*type - lightTypes().data())];
    light.where = item.where;
    switch (light.type) {
        case LightType::kPoint:
        case LightType::kSphere:
            MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, "position"));
            break;
        case LightType::kDirectional:
            MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, "direction"));
            break;
        case LightType::kEnvironment:
            MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, "file"));
            break;
    }
    if (light.type == LightType::kSphere)
        MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, "radius"));

    for (const auto& f : *fields) {
        const Item& v = f.item;
        if (f.key == "name") {
            auto n = name(v);
            if (!n)
                return n.status();
            if (auto [it, inserted] = names.emplace(*n, v.where); !inserted) {
                return r_.fail(v, "duplicate light name " + yaml::quote(*n) + " (first at " +
                                      it->second.toString() + ")");
            }
            light.name = *n;
        } else if (f.key == "anchor") {
            auto a = anchor(v);
            if (!a)
                return a.status();
            light.anchor = *a;
        } else if (f.key == "position") {
            auto p = vector3(v, kMaxLength);
            if (!p)
                return p.status();
            light.position = *p;
        } else if (f.key == "direction") {
            auto d = vector3(v, kMaxLength);
            if (!d)
                return d.status();
            if (d->norm() < 1e-9)
                return r_.fail(v, "a direction cannot be zero");
            light.direction = d->normalized();
        } else if (f.key == "radius") {
            auto rad = scalar(v, 0, kMaxLength, true);
            if (!rad)
                return rad.status();
            light.radius = *rad;
        } else if (f.key == "intensity" || f.key == "irradiance") {
            auto c = colour(v, 0, kMaxIntensity);
            if (!c)
                return c.status();
            light.intensity = *c;
        } else if (f.key == "file") {
            auto p = path(v);
            if (!p)
                return p.status();
            light.environment = *p;
        } else if (f.key == "scale") {
            auto s = scalar(v, 0, kMaxIntensity, false);
            if (!s)
                return s.status();
            light.environment_scale = *s;
        } else if (f.key == "mirror_lower_hemisphere") {
            auto b = r_.boolean(v);
            if (!b)
                return b.status();
            light.mirror_lower_hemisphere = *b;
        } else if (f.key == "rotation") {
            auto rot = r_.readMap(v, kRotationKeys,
                                  "a mapping with rotation_deg: [rx, ry, rz] or quaternion: "
                                  "[w, x, y, z]");
            if (!rot)
                return rot.status();
            auto q = rotation(*rot);
            if (!q)
                return q.status();
            light.T_world_environment.linear() = q->toRotationMatrix();
        } else if (f.key == "shadow_map") {
            auto m = parseShadowMap(v);
            if (!m)
                return m.status();
            light.shadow_map = *m;
        }
    }
    scene.lights.push_back(std::move(light));
    return Status::ok();
}

Result<ShadowMapSettings> SceneParser::parseShadowMap(const Item& item) {
    auto fields = r_.readMap(item, kShadowMapKeys,
                             "a shadow map mapping with filter: (hard, pcf or vsm) and its "
                             "settings");
    if (!fields)
        return fields.status();
    ShadowMapSettings m;
    m.where = item.where;
    for (const auto& f : *fields) {
        const Item& v = f.item;
        if (f.key == "filter" || f.key == "storage") {
            const bool filter = f.key == "filter";
            auto i =
                oneOf(v, filter ? std::span(kShadowMapFilters) : std::span(kShadowMapStorages));
            if (!i)
                return i.status();
            if (filter)
                m.filter = static_cast<ShadowMapFilter>(*i);
            else
                m.storage = static_cast<ShadowMapStorage>(*i);
        } else if (f.key == "resolution" || f.key == "kernel") {
            const bool resolution = f.key == "resolution";
            auto n = resolution ? r_.integer(v, 16, 8192) : r_.integer(v, 1, 15);
            if (!n)
                return n.status();
            (resolution ? m.resolution : m.pcf_kernel) = static_cast<int>(*n);
        } else {
            const bool blur = f.key == "blur_texels";
            auto x = blur ? scalar(v, 0, 32, false) : scalar(v, 0, 0.99, false);
            if (!x)
                return x.status();
            (blur ? m.vsm_blur_texels : m.bleeding_reduction) = *x;
        }
    }
    return m;
}

Status SceneParser::parseCamera(const Item& item, SceneDescription& scene) {
    auto fields =
        r_.readMap(item, kCameraKeys, "a camera mapping with pose:, model: and aperture:");
    if (!fields)
        return fields.status();
    // Filled in place: moving an optional<CameraModel> trips GCC's maybe-uninitialized.
    FixedCamera& camera = scene.camera.emplace();
    camera.has_pose = find(*fields, "pose") != nullptr;
    if (const Item* p = find(*fields, "pose")) {
        auto T = pose(*p);
        if (!T)
            return T.status();
        camera.T_world_cam = *T;
    }
    if (const Item* m = find(*fields, "model")) {
        auto model = calibration::readCameraModel(r_, *m);
        if (!model)
            return model.status();
        camera.model = std::move(model).value();
    }
    if (const Item* a = find(*fields, "aperture")) {
        auto aperture_fields =
            r_.readMap(*a, kApertureKeys,
                       "an aperture mapping with f_number:, focal_length_mm: and "
                       "focus_distance_m:");
        if (!aperture_fields)
            return aperture_fields.status();
        LensAperture aperture;
        aperture.where = a->where;
        for (const std::string_view key : {"focal_length_mm", "focus_distance_m"})
            if (!find(*aperture_fields, key))
                return r_.fail(*a, "aperture." + std::string(key) + " is required");
        MIXRAY_RETURN_IF_ERROR(
            optionalScalar(*aperture_fields, "f_number", 0.5, 128, false, aperture.f_number));
        MIXRAY_RETURN_IF_ERROR(optionalScalar(*aperture_fields, "focal_length_mm", 0, 2000, true,
                                              aperture.focal_length_mm));
        MIXRAY_RETURN_IF_ERROR(optionalScalar(*aperture_fields, "focus_distance_m", 0, 1e4, true,
                                              aperture.focus_distance_m));
        camera.aperture = aperture;
    }
    return Status::ok();
}

Status SceneParser::parse(std::string_view text, SceneDescription& scene) {
    auto root = r_.load(text, kMaxSceneFileBytes, kMaxSceneNesting, "a scene file");
    if (!root)
        return root.status();
    if (root->node.IsNull()) {
        return r_.fail(*root,
                       "the file is empty; expected a mapping with materials:, objects: "
                       "and lights:");
    }
    auto fields =
        r_.readMap(*root, kRootKeys, "a mapping with materials:, objects: and lights: at the top");
    if (!fields)
        return fields.status();
    if (const Item* version = find(*fields, "version")) {
        auto v = r_.integer(*version, 1, INT32_MAX);
        if (!v)
            return v.status();
        if (*v != 1) {
            return r_.fail(*version, "unsupported scene format version " + std::to_string(*v) +
                                         "; this mixray reads version 1");
        }
    }
    // Materials first, whatever the order in the file: objects refer to them.
    if (const Item* materials = find(*fields, "materials")) {
        auto entries = r_.readMap(*materials, {}, "a mapping of material name to settings");
        if (!entries)
            return entries.status();
        if (entries->size() > kMaxEntries)
            return r_.fail(*materials, "too many materials");
        for (const Field& f : *entries)
            MIXRAY_RETURN_IF_ERROR(parseMaterial(f, scene));
    }
    if (const Item* objects = find(*fields, "objects")) {
        auto elements = r_.readList(*objects, 0, kMaxEntries, "a list of objects");
        if (!elements)
            return elements.status();
        std::map<std::string, SourceLocation> names;
        for (const Item& e : *elements)
            MIXRAY_RETURN_IF_ERROR(parseObject(e, scene, names));
    }
    if (const Item* lights = find(*fields, "lights")) {
        auto elements = r_.readList(*lights, 0, kMaxEntries, "a list of lights");
        if (!elements)
            return elements.status();
        std::map<std::string, SourceLocation> names;
        for (const Item& e : *elements)
            MIXRAY_RETURN_IF_ERROR(parseLight(e, scene, names));
    }
    if (const Item* c = find(*fields, "caustics")) {
        auto settings =
            r_.readMap(*c, kCausticsKeys, "a caustics mapping with photons: and radius_m:");
        if (!settings)
            return settings.status();
        CausticSettings& caustics = scene.caustics.emplace();
        caustics.where = c->where;
        if (const Item* n = find(*settings, "photons")) {
            auto v = r_.integer(*n, 1000, 100'000'000);
            if (!v)
                return v.status();
            caustics.photons = static_cast<int>(*v);
        }
        MIXRAY_RETURN_IF_ERROR(
            optionalScalar(*settings, "radius_m", 0, 1, true, caustics.radius_m));
    }
    if (const Item* estimated = find(*fields, "estimated_lights")) {
        auto settings = r_.readMap(*estimated, kEstimatedLightKeys,
                                   "an estimated_lights mapping with shadow_map:");
        if (!settings)
            return settings.status();
        scene.estimated_lights.where = estimated->where;
        if (const Item* m = find(*settings, "shadow_map")) {
            auto map = parseShadowMap(*m);
            if (!map)
                return map.status();
            scene.estimated_lights.shadow_map = *map;
        }
    }
    if (const Item* camera = find(*fields, "camera"))
        MIXRAY_RETURN_IF_ERROR(parseCamera(*camera, scene));
    if (const Item* depth = find(*fields, "depth_surface")) {
        auto depth_fields =
            r_.readMap(*depth, kDepthSurfaceKeys, "a depth_surface mapping with reflectance:");
        if (!depth_fields)
            return depth_fields.status();
        scene.depth_surface.where = depth->where;
        MIXRAY_RETURN_IF_ERROR(optionalScalar(*depth_fields, "reflectance", 0, 1, false,
                                              scene.depth_surface.reflectance));
    }
    if (const Item* lens = find(*fields, "lens_effects"))
        MIXRAY_RETURN_IF_ERROR(parseLensEffects(*lens, scene));
    if (const Item* matching = find(*fields, "camera_matching")) {
        auto matching_fields = r_.readMap(*matching, kCameraMatchingKeys,
                                          "a camera_matching mapping with noise: and motion_blur:");
        if (!matching_fields)
            return matching_fields.status();
        scene.camera_matching.where = matching->where;
        if (find(*matching_fields, "noise")) {
            float strength = 0;
            MIXRAY_RETURN_IF_ERROR(
                optionalScalar(*matching_fields, "noise", 0, 10, false, strength));
            scene.camera_matching.noise = strength;
        }
        if (const Item* blur = find(*matching_fields, "motion_blur")) {
            auto blur_fields =
                r_.readMap(*blur, kMotionBlurKeys, "a motion_blur mapping with exposure_ms:");
            if (!blur_fields)
                return blur_fields.status();
            float exposure_ms = 0;
            MIXRAY_RETURN_IF_ERROR(
                optionalScalar(*blur_fields, "exposure_ms", 0, 1000, false, exposure_ms));
            scene.camera_matching.motion_blur_exposure_ms = exposure_ms;
        }
    }
    return Status::ok();
}

Status SceneParser::parseLensEffects(const Item& item, SceneDescription& scene) {
    auto fields =
        r_.readMap(item, kLensEffectKeys, "a lens_effects mapping with bloom: and glare:");
    if (!fields)
        return fields.status();
    if (const Item* b = find(*fields, "bloom")) {
        auto bloom_fields =
            r_.readMap(*b, kBloomKeys, "a bloom mapping with threshold:, strength:, radius_px:");
        if (!bloom_fields)
            return bloom_fields.status();
        Bloom bloom;
        bloom.where = b->where;
        MIXRAY_RETURN_IF_ERROR(
            optionalScalar(*bloom_fields, "threshold", 0, 1e6, true, bloom.threshold));
        MIXRAY_RETURN_IF_ERROR(
            optionalScalar(*bloom_fields, "strength", 0, 10, false, bloom.strength));
        MIXRAY_RETURN_IF_ERROR(
            optionalScalar(*bloom_fields, "radius_px", 0.5, 64, false, bloom.radius_px));
        scene.lens_effects.bloom = bloom;
    }
    if (const Item* g = find(*fields, "glare")) {
        auto glare_fields = r_.readMap(
            *g, kGlareKeys, "a glare mapping with threshold:, strength:, passes:, attenuation:");
        if (!glare_fields)
            return glare_fields.status();
        Glare glare;
        glare.where = g->where;
        MIXRAY_RETURN_IF_ERROR(
            optionalScalar(*glare_fields, "threshold", 0, 1e6, true, glare.threshold));
        MIXRAY_RETURN_IF_ERROR(
            optionalScalar(*glare_fields, "strength", 0, 10, false, glare.strength));
        MIXRAY_RETURN_IF_ERROR(
            optionalScalar(*glare_fields, "attenuation", 0, 1, true, glare.attenuation));
        if (const Item* v = find(*glare_fields, "passes")) {
            auto n = scalar(*v, 1, 4, false);
            if (!n)
                return n.status();
            if (*n != std::floor(*n))
                return r_.expected(*v, "a whole number of passes, 1 to 4");
            glare.passes = static_cast<int>(*n);
        }
        scene.lens_effects.glare = glare;
    }
    return Status::ok();
}

Result<SceneDescription> parseSceneAt(std::string_view text, std::string source_name,
                                      std::filesystem::path base) {
    SceneDescription scene;
    SceneParser parser(source_name, std::move(base));
    try {
        MIXRAY_RETURN_IF_ERROR(parser.parse(text, scene));
    } catch (const YAML::Exception& e) {
        SourceLocation where{source_name, 0, 0};
        if (!e.mark.is_null() && e.mark.line >= 0) {
            where.line = e.mark.line + 1;
            where.column = e.mark.column + 1;
        }
        return yaml::corrupt(where, "", "YAML syntax error: " + e.msg);
    } catch (const std::exception& e) {
        return Status(ErrorCode::kInternal, source_name + ": parsing failed: " + e.what());
    }
    scene.source_path = source_name;
    MIXRAY_RETURN_IF_ERROR(scene.validate());
    return scene;
}

}  // namespace

Result<SceneDescription> parseScene(std::string_view text, std::string_view source_name) {
    std::string name(source_name);
    std::filesystem::path base = std::filesystem::path(name).parent_path();
    return parseSceneAt(text, std::move(name), std::move(base));
}

Result<SceneDescription> loadScene(const std::filesystem::path& path) {
    const std::string name = path.string();
    std::error_code ec;
    const auto status = std::filesystem::status(path, ec);
    if (ec && ec != std::errc::no_such_file_or_directory)
        return Status(ErrorCode::kIoError, name + ": " + ec.message());
    if (!std::filesystem::exists(status))
        return Status(ErrorCode::kNotFound, name + ": no such scene file");
    if (std::filesystem::is_directory(status))
        return Status(ErrorCode::kInvalidArgument, name + ": is a directory, not a scene file");
    std::ifstream in(path, std::ios::binary);
    if (!in)
        return Status(ErrorCode::kIoError, name + ": cannot open for reading");
    // At most one byte past the limit: enough to tell a file is too large.
    std::string text;
    std::array<char, 64 * 1024> chunk{};
    while (text.size() <= kMaxSceneFileBytes && in) {
        in.read(chunk.data(), chunk.size());
        text.append(chunk.data(), static_cast<size_t>(in.gcount()));
    }
    if (in.bad())
        return Status(ErrorCode::kIoError, name + ": read failed");
    const std::filesystem::path absolute = std::filesystem::absolute(path, ec);
    std::filesystem::path base = (ec ? path : absolute).parent_path().lexically_normal();
    return parseSceneAt(text, name, std::move(base));
}

Result<ComposedArScene> composeArScene(const std::filesystem::path& real_scene_path,
                                       const std::filesystem::path& objects_path) {
    namespace fs = std::filesystem;
    auto real = loadScene(real_scene_path);
    if (!real)
        return real.status();
    auto objects = loadScene(objects_path);
    if (!objects)
        return objects.status();
    ComposedArScene out;
    SceneDescription& scene = out.scene;
    scene.source_path = real->source_path;
    scene.materials = real->materials;
    // Lights and a fixed camera only from the objects file: the real scene's are what tracking
    // and light estimation measure.
    scene.lights = objects->lights;
    scene.camera = objects->camera;
    scene.lens_effects = objects->lens_effects;  // how the virtual objects pass the lens
    scene.camera_matching = objects->camera_matching;
    scene.caustics = objects->caustics;  // the virtual objects' caustics on the real scene
    scene.estimated_lights = objects->estimated_lights;
    for (SceneObject o : real->objects) {
        o.role = ObjectRole::kGhost;
        scene.objects.push_back(std::move(o));
    }
    // The composed scene's relative paths would resolve against the real scene's folder; make
    // the real scene's textures absolute so the objects file's folder never matters for them.
    for (auto& [name, m] : real->materials)
        if (!m.albedo_texture.empty() && m.albedo_texture.is_relative())
            scene.materials[name].albedo_texture =
                fs::absolute(real->source_path.parent_path() / m.albedo_texture);
    for (const auto& [name, m] : objects->materials) {
        if (scene.materials.count(name))
            return Status(ErrorCode::kInvalidArgument, objects_path.string() + ": material " +
                                                           name + " is also defined in " +
                                                           real_scene_path.string());
        scene.materials[name] = m;
        out.inserted.materials[name] = m;
    }
    for (SceneObject o : objects->objects) {
        o.role = ObjectRole::kVirtual;
        if (o.shape.type == ShapeType::kMesh && !o.shape.mesh.empty()) {
            fs::path file = o.shape.mesh;
            if (file.is_relative())
                file = objects->source_path.parent_path() / file;
            std::error_code ec;
            if (!fs::exists(file, ec)) {
                out.notes.push_back(file.string() + " not found (the shared data is not here); a " +
                                    "sphere of its material stands in for " + o.name);
                o.shape = Shape{};
                o.shape.type = ShapeType::kSphere;
                o.shape.radius = 0.04f;
                o.T_anchor_object.translation().z() += 0.04;
            } else {
                o.shape.mesh = fs::absolute(file);
            }
        }
        out.inserted.objects.push_back(o);
        scene.objects.push_back(std::move(o));
    }
    MIXRAY_RETURN_IF_ERROR(scene.validate());
    return out;
}

}  // namespace mixray::render
