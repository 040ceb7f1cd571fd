// The AR scene as plain data: virtual objects, ghost proxies of real objects, materials,
// lights. Parsed from scene files (scene_file.h) or built in code; turned into an Embree scene
// by the Renderer.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/rig.h"

namespace mixray::render {

struct TriangleMesh;  // assets.h

// Linear-light RGB (not sRGB-encoded).
using Rgb = Eigen::Vector3f;

enum class MaterialType : uint8_t {
    kDiffuse,  // Lambertian
    kPhong,    // Lambertian + Blinn-Phong specular highlight
    kMirror,   // perfect specular reflector (reflectance `reflectance`, default 1)
    kMetal,    // specular reflector with Schlick Fresnel from a coloured F0
    kGlass,    // dielectric: Schlick Fresnel split into reflection and refraction, per-channel IOR
};

// How a surface responds to light. Unused fields for a type are ignored. Plain value.
struct Material {
    std::string name;
    MaterialType type = MaterialType::kDiffuse;
    Rgb albedo{0.8f, 0.8f, 0.8f};          // diffuse reflectance
    std::filesystem::path albedo_texture;  // sRGB image over the object's uv; empty: none
    Rgb specular{0.04f, 0.04f, 0.04f};     // Blinn-Phong specular colour
    float shininess = 32;                  // Blinn-Phong exponent
    Rgb f0{0.95f, 0.64f, 0.54f};           // metal: reflectance at normal incidence
    Rgb ior{1.5f, 1.5f, 1.5f};             // glass: index of refraction per channel
    Rgb transmission{1, 1, 1};             // glass: colour kept per unit path (1 = clear)
    // RT²AR reflectance: how much a diffuse/Phong surface also mirrors, 0..1, optionally
    // modulated by a grey map over uv saying where it reflects.
    float reflectance = 0;
    std::filesystem::path reflectance_map;
    SourceLocation where;
};

enum class ShapeType : uint8_t { kMesh, kSphere, kBox, kPlane, kDisk };

// Geometry of one object in its own frame. Plain value.
struct Shape {
    ShapeType type = ShapeType::kSphere;
    std::filesystem::path mesh;  // kMesh: OBJ, PLY or glTF 2.0 file (loaded with assimp)
    // kMesh built in code (benchmarks, generated geometry): used instead of `mesh` when set.
    std::shared_ptr<const TriangleMesh> mesh_data;
    float scale = 1;       // kMesh: uniform scale applied to the file's coordinates
    float radius = 0.05f;  // kSphere, kDisk: metres; sphere centred at the origin
    Eigen::Vector3f size{0.1f, 0.1f, 0.1f};  // kBox: edge lengths, centred; kPlane: x, y extent
    // kPlane and kDisk lie in the object's z = 0 plane, normal +z.
};

enum class ObjectRole : uint8_t {
    kVirtual,  // rendered into the image
    kGhost,    // proxy of a real object: occludes, receives and casts shadows, reflects, but
               // primary rays that hit it show the camera pixel (differential rendering)
};

// One object. `anchor` names the frame it is attached to: "world", or "marker:<id>" for an
// object bound to a tracked marker. Plain value.
struct SceneObject {
    std::string name;
    ObjectRole role = ObjectRole::kVirtual;
    Shape shape;
    std::string material;  // name in SceneDescription::materials
    std::string anchor = "world";
    Eigen::Isometry3d T_anchor_object = Eigen::Isometry3d::Identity();
    SourceLocation where;
};

enum class LightType : uint8_t {
    kPoint,        // position, intensity (W/sr-like radiant intensity, linear RGB)
    kSphere,       // spherical area light: position, radius, intensity (soft shadows)
    kDirectional,  // direction the light travels, irradiance (the sun)
    kEnvironment,  // equirectangular environment map around the scene
};

// Castro et al. §IV: a light's shadows looked up in depth maps rendered from the light (one of
// the mixed scene, one of the real scene's ghosts) instead of traced per shading point. The map
// covers where the virtual objects can shadow; shading points outside it trace rays.
enum class ShadowMapFilter : uint8_t {
    kHard,  // the nearest texel's depth test
    kPcf,   // percentage-closer filtering: pcf_kernel² bilinear depth tests averaged
    kVsm,   // variance shadow map: blurred depth moments, Chebyshev's bound
};

enum class ShadowMapStorage : uint8_t {
    kFloat,       // 32-bit float per value
    kEightBit,    // their 8-bit path: z (and z² for kVsm) in 8 bits each over the depth range
    kPackedRgba8  // their bit-packed RGBA texel: z in 32 bits (kVsm: z and z² in 16 bits each)
};

struct ShadowMapSettings {
    ShadowMapFilter filter = ShadowMapFilter::kPcf;
    int resolution = 1024;            // texels on a side
    int pcf_kernel = 3;               // kPcf: taps on a side, 1..15
    float vsm_blur_texels = 2;        // kVsm: σ of the moments' separable Gaussian blur
    float bleeding_reduction = 0.2f;  // kVsm: bounds below this read as full shadow, [0, 1)
    ShadowMapStorage storage = ShadowMapStorage::kFloat;
    SourceLocation where;
};

struct Light {
    std::string name;
    LightType type = LightType::kPoint;
    std::string anchor = "world";
    Eigen::Vector3d position{0, 0, 1};    // in the anchor frame
    Eigen::Vector3d direction{0, 0, -1};  // kDirectional: travel direction, anchor frame
    float radius = 0.05f;                 // kSphere
    Rgb intensity{1, 1, 1};               // point/sphere: intensity; directional: irradiance
    std::filesystem::path environment;    // kEnvironment: .hdr or .exr equirectangular map
    // kEnvironment: a map in memory (linear RGB, equirectangular, as EnvironmentMap), used
    // instead of `environment` when set: maps estimated while running.
    std::shared_ptr<const FloatImage> environment_image;
    float environment_scale = 1;  // multiplies the map's radiance
    Eigen::Isometry3d T_world_environment = Eigen::Isometry3d::Identity();
    bool mirror_lower_hemisphere = false;  // fill the lower half from the upper (fish-eye maps)
    // Point, sphere and directional lights: shadows from a shadow map; empty: ray-traced
    // (RenderOptions::soft_shadows).
    std::optional<ShadowMapSettings> shadow_map;
    SourceLocation where;
};

// The real lens's aperture as it was set for the session (Kán & Kaufmann §3.1): virtual objects
// away from the focus distance blur as the camera blurs real ones. A thin lens of diameter
// focal_length / f_number; a point at distance d spreads over a circle of confusion
// fx · diameter · |1/d − 1/focus_distance| pixels across. Plain value.
struct LensAperture {
    float f_number = 2.8f;
    float focal_length_mm = 0;   // required: the lens's focal length (not the 35 mm equivalent)
    float focus_distance_m = 0;  // required: where the lens is focused
    SourceLocation where;

    float diameter_m() const { return focal_length_mm * 1e-3f / f_number; }
};

// A fixed camera for rendering without tracking: the pose of the camera in the world and,
// optionally, its intrinsics (else the recording's calibration is used) and its aperture.
struct FixedCamera {
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    // False when a scene file's camera gave no pose: the pose then comes from the recording's
    // pose stream (mixray render).
    bool has_pose = true;
    std::optional<calibration::CameraModel> model;
    std::optional<LensAperture> aperture;  // none: a pinhole camera, everything in focus
};

// The real surfaces a depth camera measures, when the Renderer meshes its depth map
// (DepthSecondaryRays::kMesh): diffuse, with an albedo taken from the camera image (the camera
// pixel over the irradiance the scene's lights give there, so that the differential rendering
// reproduces the camera pixel and scales it by exactly the lighting ratio virtual objects
// cause). Only how much they also mirror is a setting. Plain value.
struct DepthSurface {
    float reflectance = 0;  // RT²AR reflectance 0..1: real surfaces that mirror virtual objects
    SourceLocation where;
};

// RT²AR §IV-F's lens effects, added to the composite from what the virtual content adds to
// each pixel (linear light): light above a luminance threshold spreads, so a bright virtual
// highlight glows past its edges like a real one through the lens. A frame with nothing virtual
// stays the camera image. Plain values.
struct Bloom {
    float threshold = 1;     // luminance that blooms (1: the camera's white)
    float strength = 0.25f;  // fraction of the light above the threshold spread around
    float radius_px = 6;     // the spread's Gaussian sigma, in pixels of the frame
    SourceLocation where;
};
struct Glare {
    float threshold = 1.5f;  // a little above bloom's, as RT²AR has it
    float strength = 0.15f;  // fraction of the light above the threshold spread into streaks
    // Passes of 4 samples s = 0..3, pass n taking them b = 4^(n−1) pixels apart with weights
    // a^(b·s): streaks 4^passes − 1 pixels long (63 for 3) along the four diagonals.
    int passes = 3;
    float attenuation = 0.9f;  // a (RT²AR: 0.85 to 0.95)
    SourceLocation where;
};
struct LensEffects {
    std::optional<Bloom> bloom;
    std::optional<Glare> glare;
    bool any() const { return bloom || glare; }
};

// Camera matching (beyond the papers): virtual pixels take the real camera's look, so they do
// not look cleaner than the real ones around them. Plain value.
struct CameraMatching {
    // The camera's noise, measured on each frame's image as a function of brightness, added to
    // the virtual pixels times this (1: as much as the camera has); none: off.
    std::optional<float> noise;
    // Motion blur over each frame's exposure, from the tracked camera's motion between frames:
    // the frames' own exposure time where they carry one, else this many milliseconds (0: only
    // where they carry one); none: off.
    std::optional<float> motion_blur_exposure_ms;
    SourceLocation where;
    bool any() const { return noise.has_value() || motion_blur_exposure_ms.has_value(); }
};

// Kán & Kaufmann §3.2: caustics by photon mapping. Photons are shot from the point, sphere
// (from its centre) and directional lights at the bounding spheres of the specular objects
// (mirror, metal, glass; virtual and ghosts alike) and gathered with a fixed Epanechnikov kernel
// of radius_m. Plain value.
struct CausticSettings {
    int photons = 150000;     // per frame, over all lights
    float radius_m = 0.005f;  // the kernel's bandwidth: narrow, sharp and noisier
    SourceLocation where;
};

// How the lights tracking estimates are rendered: in the AR pipeline they replace the scene's
// own lights (render::lightsFromEstimates), so settings a scene file gives its lights are given
// to them here. Plain value.
struct EstimatedLightSettings {
    // Point, sphere and directional estimates: shadows from a shadow map; none: ray-traced.
    std::optional<ShadowMapSettings> shadow_map;
    SourceLocation where;
};

// A whole scene. Plain value; reentrant.
struct SceneDescription {
    std::map<std::string, Material> materials;
    std::vector<SceneObject> objects;
    std::vector<Light> lights;
    std::optional<FixedCamera> camera;
    DepthSurface depth_surface;
    LensEffects lens_effects;
    CameraMatching camera_matching;
    std::optional<CausticSettings> caustics;  // none: no caustics
    EstimatedLightSettings estimated_lights;
    std::filesystem::path source_path;  // where it was loaded from, for messages

    // kCorruptData with the entry's location on the first problem: unknown material names,
    // non-positive sizes, IOR < 1, non-finite numbers, bad anchors, duplicate names.
    Status validate() const;
};

}  // namespace mixray::render
