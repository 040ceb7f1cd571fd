// Checks of scene descriptions built in code or parsed from files.
#include "mixray/render/scene.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <string_view>

namespace mixray::render {
namespace {

Status corrupt(const SourceLocation& where, const std::string& path, const std::string& what) {
    std::string message = where.toString();
    if (!message.empty())
        message += ": ";
    return Status(ErrorCode::kCorruptData, message + path + ": " + what);
}

bool isValidName(std::string_view name) {
    return !name.empty() && name.size() <= 64 && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
               c == '_' || c == '-';
    });
}

bool isValidAnchor(std::string_view anchor) {
    if (anchor == "world")
        return true;
    constexpr std::string_view kMarker = "marker:";
    if (anchor.substr(0, kMarker.size()) != kMarker)
        return false;
    const std::string_view id = anchor.substr(kMarker.size());
    return !id.empty() && id.size() <= 7 &&
           std::all_of(id.begin(), id.end(), [](char c) { return c >= '0' && c <= '9'; }) &&
           std::stol(std::string(id)) <= (1 << 20);  // as scene_file.cpp accepts
}

bool finite(const Rgb& c) {
    return c.allFinite();
}
bool inRange(const Rgb& c, float lo, float hi) {
    return c.allFinite() && (c.array() >= lo).all() && (c.array() <= hi).all();
}

// A finite rigid transform: orthonormal rotation with determinant +1.
bool isRigid(const Eigen::Isometry3d& T) {
    if (!T.matrix().allFinite())
        return false;
    const Eigen::Matrix3d R = T.linear();
    return (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-6 &&
           std::abs(R.determinant() - 1.0) < 1e-6;
}

Status validateMaterial(const std::string& key, const Material& m) {
    const std::string path = "materials." + key;
    if (!isValidName(key) || m.name != key) {
        return corrupt(m.where, path,
                       "material name must be 1-64 letters, digits, '_' or '-' and match its key");
    }
    if (!inRange(m.albedo, 0, 1))
        return corrupt(m.where, path + ".albedo", "each channel must be in [0, 1]");
    if (!inRange(m.specular, 0, 1))
        return corrupt(m.where, path + ".specular", "each channel must be in [0, 1]");
    if (!inRange(m.f0, 0, 1))
        return corrupt(m.where, path + ".f0", "each channel must be in [0, 1]");
    if (!inRange(m.transmission, 0, 1))
        return corrupt(m.where, path + ".transmission", "each channel must be in [0, 1]");
    if (!finite(m.ior) || (m.ior.array() < 1).any())
        return corrupt(m.where, path + ".ior", "an index of refraction is at least 1");
    if (!(std::isfinite(m.shininess) && m.shininess > 0))
        return corrupt(m.where, path + ".shininess", "must be a finite number above 0");
    if (!(m.reflectance >= 0 && m.reflectance <= 1))
        return corrupt(m.where, path + ".reflectance", "must be in [0, 1]");
    return Status::ok();
}

Status validateShape(const SceneObject& o, const std::string& path) {
    const Shape& s = o.shape;
    switch (s.type) {
        case ShapeType::kSphere:
        case ShapeType::kDisk:
            if (!(std::isfinite(s.radius) && s.radius > 0))
                return corrupt(o.where, path + ".radius", "must be a finite number above 0");
            break;
        case ShapeType::kBox:
            if (!(s.size.allFinite() && (s.size.array() > 0).all()))
                return corrupt(o.where, path + ".size", "edge lengths must be finite and above 0");
            break;
        case ShapeType::kPlane:
            if (!(s.size.head<2>().allFinite() && (s.size.head<2>().array() > 0).all()))
                return corrupt(o.where, path + ".size", "extents must be finite and above 0");
            break;
        case ShapeType::kMesh:
            if (s.mesh.empty() && s.mesh_data == nullptr)
                return corrupt(o.where, path + ".file", "empty path");
            if (!(std::isfinite(s.scale) && s.scale > 0))
                return corrupt(o.where, path + ".scale", "must be a finite number above 0");
            break;
    }
    return Status::ok();
}

Status validateShadowMap(const ShadowMapSettings& m, const std::string& path) {
    if (m.resolution < 16 || m.resolution > 8192)
        return corrupt(m.where, path + ".resolution", "must be 16..8192 texels");
    if (m.pcf_kernel < 1 || m.pcf_kernel > 15)
        return corrupt(m.where, path + ".kernel", "must be 1..15 taps");
    if (!(std::isfinite(m.vsm_blur_texels) && m.vsm_blur_texels >= 0 && m.vsm_blur_texels <= 32))
        return corrupt(m.where, path + ".blur_texels", "must be 0..32");
    if (!(m.bleeding_reduction >= 0 && m.bleeding_reduction < 1))
        return corrupt(m.where, path + ".bleeding_reduction", "must be in [0, 1)");
    return Status::ok();
}

Status validateLight(const Light& l, const std::string& path) {
    if (!isValidAnchor(l.anchor))
        return corrupt(l.where, path + ".anchor", "expected world or marker:<id>");
    if (l.shadow_map) {
        if (l.type == LightType::kEnvironment)
            return corrupt(l.where, path + ".shadow_map", "an environment light has no shadow map");
        MIXRAY_RETURN_IF_ERROR(validateShadowMap(*l.shadow_map, path + ".shadow_map"));
    }
    switch (l.type) {
        case LightType::kSphere:
            if (!(std::isfinite(l.radius) && l.radius > 0))
                return corrupt(l.where, path + ".radius", "must be a finite number above 0");
            [[fallthrough]];
        case LightType::kPoint:
            if (!l.position.allFinite())
                return corrupt(l.where, path + ".position", "must be finite");
            if (!inRange(l.intensity, 0, 1e9))
                return corrupt(l.where, path + ".intensity", "must be finite and not negative");
            break;
        case LightType::kDirectional:
            if (!l.direction.allFinite() || l.direction.norm() < 1e-9)
                return corrupt(l.where, path + ".direction", "must be finite and not zero");
            if (!inRange(l.intensity, 0, 1e9))
                return corrupt(l.where, path + ".irradiance", "must be finite and not negative");
            break;
        case LightType::kEnvironment:
            if (l.environment.empty() && !l.environment_image)
                return corrupt(l.where, path + ".file", "empty path");
            if (l.environment_image &&
                (l.environment_image->width < 2 || l.environment_image->channels < 3 ||
                 l.environment_image->height * 2 != l.environment_image->width ||
                 l.environment_image->pixels.size() !=
                     static_cast<size_t>(l.environment_image->width) *
                         static_cast<size_t>(l.environment_image->height) *
                         static_cast<size_t>(l.environment_image->channels)))
                return corrupt(l.where, path,
                               "the environment image is not an equirectangular "
                               "RGB map of width = 2 x height");
            if (!(std::isfinite(l.environment_scale) && l.environment_scale >= 0))
                return corrupt(l.where, path + ".scale", "must be finite and not negative");
            if (!isRigid(l.T_world_environment) || !l.T_world_environment.translation().isZero())
                return corrupt(l.where, path + ".rotation", "must be a pure rotation");
            break;
    }
    return Status::ok();
}

Status validateCamera(const FixedCamera& c, const SourceLocation& where) {
    if (!isRigid(c.T_world_cam))
        return corrupt(where, "camera.pose", "must be a finite rigid transform");
    if (const auto& a = c.aperture) {
        if (!(a->f_number >= 0.5f && a->f_number <= 128))
            return corrupt(a->where, "camera.aperture.f_number", "must be in [0.5, 128]");
        if (!(a->focal_length_mm > 0 && a->focal_length_mm <= 2000))
            return corrupt(a->where, "camera.aperture.focal_length_mm", "must be in (0, 2000]");
        if (!(a->focus_distance_m > 0 && a->focus_distance_m <= 1e4f))
            return corrupt(a->where, "camera.aperture.focus_distance_m", "must be in (0, 1e4]");
    }
    if (!c.model)
        return Status::ok();
    const calibration::CameraModel& m = *c.model;
    if (m.width < 1 || m.height < 1)
        return corrupt(where, "camera.model", "image size must be above 0");
    if (!(std::isfinite(m.fx) && m.fx > 0 && std::isfinite(m.fy) && m.fy > 0))
        return corrupt(where, "camera.model", "focal lengths must be finite and above 0");
    if (!(std::isfinite(m.cx) && std::isfinite(m.cy)))
        return corrupt(where, "camera.model", "principal point must be finite");
    const size_t n = m.distortion.size();
    const bool count_ok = m.lens == calibration::LensModel::kFisheye
                              ? (n == 0 || n == 4)
                              : (n == 0 || n == 4 || n == 5 || n == 8);
    if (!count_ok)
        return corrupt(where, "camera.model.distortion", "wrong number of coefficients");
    for (double d : m.distortion) {
        if (!std::isfinite(d))
            return corrupt(where, "camera.model.distortion", "must be finite");
    }
    return Status::ok();
}

}  // namespace

Status SceneDescription::validate() const {
    const SourceLocation file_where{source_path.string(), 0, 0};
    for (const auto& [key, material] : materials)
        MIXRAY_RETURN_IF_ERROR(validateMaterial(key, material));

    std::set<std::string_view> object_names;
    for (size_t i = 0; i < objects.size(); ++i) {
        const SceneObject& o = objects[i];
        const std::string path = "objects[" + std::to_string(i) + "]";
        if (!isValidName(o.name))
            return corrupt(o.where, path + ".name", "must be 1-64 letters, digits, '_' or '-'");
        if (!object_names.insert(o.name).second)
            return corrupt(o.where, path + ".name", "duplicate object name \"" + o.name + "\"");
        if (!materials.count(o.material))
            return corrupt(o.where, path + ".material", "unknown material \"" + o.material + "\"");
        if (!isValidAnchor(o.anchor))
            return corrupt(o.where, path + ".anchor", "expected world or marker:<id>");
        if (!isRigid(o.T_anchor_object))
            return corrupt(o.where, path + ".pose", "must be a finite rigid transform");
        MIXRAY_RETURN_IF_ERROR(validateShape(o, path + ".shape"));
    }

    std::set<std::string_view> light_names;
    for (size_t i = 0; i < lights.size(); ++i) {
        const Light& l = lights[i];
        const std::string path = "lights[" + std::to_string(i) + "]";
        if (!l.name.empty() && !isValidName(l.name))
            return corrupt(l.where, path + ".name", "must be 1-64 letters, digits, '_' or '-'");
        if (!l.name.empty() && !light_names.insert(l.name).second)
            return corrupt(l.where, path + ".name", "duplicate light name \"" + l.name + "\"");
        MIXRAY_RETURN_IF_ERROR(validateLight(l, path));
    }
    if (estimated_lights.shadow_map)
        MIXRAY_RETURN_IF_ERROR(
            validateShadowMap(*estimated_lights.shadow_map, "estimated_lights.shadow_map"));
    if (camera)
        MIXRAY_RETURN_IF_ERROR(validateCamera(*camera, file_where));
    if (!(depth_surface.reflectance >= 0 && depth_surface.reflectance <= 1))
        return corrupt(depth_surface.where, "depth_surface.reflectance", "must be in [0, 1]");
    if (const auto& b = lens_effects.bloom) {
        if (!(b->threshold > 0 && b->threshold <= 1e6f))
            return corrupt(b->where, "lens_effects.bloom.threshold", "must be in (0, 1e6]");
        if (!(b->strength >= 0 && b->strength <= 10))
            return corrupt(b->where, "lens_effects.bloom.strength", "must be in [0, 10]");
        if (!(b->radius_px >= 0.5f && b->radius_px <= 64))
            return corrupt(b->where, "lens_effects.bloom.radius_px", "must be in [0.5, 64]");
    }
    if (camera_matching.noise && !(*camera_matching.noise >= 0 && *camera_matching.noise <= 10))
        return corrupt(camera_matching.where, "camera_matching.noise", "must be in [0, 10]");
    if (const auto& e = camera_matching.motion_blur_exposure_ms; e && !(*e >= 0 && *e <= 1000))
        return corrupt(camera_matching.where, "camera_matching.motion_blur.exposure_ms",
                       "must be in [0, 1000]");
    if (const auto& g = lens_effects.glare) {
        if (!(g->threshold > 0 && g->threshold <= 1e6f))
            return corrupt(g->where, "lens_effects.glare.threshold", "must be in (0, 1e6]");
        if (!(g->strength >= 0 && g->strength <= 10))
            return corrupt(g->where, "lens_effects.glare.strength", "must be in [0, 10]");
        if (g->passes < 1 || g->passes > 4)
            return corrupt(g->where, "lens_effects.glare.passes", "must be 1, 2, 3 or 4");
        if (!(g->attenuation > 0 && g->attenuation < 1))
            return corrupt(g->where, "lens_effects.glare.attenuation", "must be in (0, 1)");
    }
    if (caustics) {
        if (caustics->photons < 1000 || caustics->photons > 100'000'000)
            return corrupt(caustics->where, "caustics.photons", "must be 1000..100000000");
        if (!(caustics->radius_m > 0 && caustics->radius_m <= 1))
            return corrupt(caustics->where, "caustics.radius_m", "must be in (0, 1] metres");
    }
    return Status::ok();
}

}  // namespace mixray::render
