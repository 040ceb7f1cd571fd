// The Embree ray tracer that composites virtual objects into camera frames by one-pass
// differential rendering (Kán & Kaufmann; RT²AR's ghosts, depth occlusion and shadows).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <memory>
#include <stop_token>
#include <string>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/depth_registration.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/render/scene.h"

namespace mixray::render {

using ::mixray::FloatImage;

enum class SoftShadowMethod : uint8_t {
    kHard,      // one shadow ray to each light's centre
    kUniform,   // `shadow_samples` rays spread over each spherical light
    kAdaptive,  // RT²AR: 5 rays (centre + 4 extremes of the visible hemisphere); all
                // `shadow_samples` only where they disagree (the penumbra), then a mean filter
                // of the primary hits' light visibility there
};

enum class DepthSecondaryRays : uint8_t {
    kNone,         // depth occludes primary rays only
    kScreenSpace,  // RT²AR Algorithm 2: march secondary rays through the depth image
    kMesh,         // a triangle mesh built from the depth image each frame (Embree), so real
                   // depth surfaces also have normals, reflect and receive shadows
};

struct RenderOptions {
    int max_depth = 3;  // secondary bounces after the primary hit
    // What a path whose bounces max_depth cut sees: true, the environment lights along it (with
    // none, a grey world lit by the scene's lights), the same in I_m and I_r, so that few
    // bounces never draw a mirror, metal or glass surface black; false, black, as POV-Ray's
    // max_trace_level does (for comparisons with it).
    bool cut_paths_see_environment = true;
    bool shadows = true;        // false: lights are never occluded (no shadow rays)
    int samples_per_pixel = 1;  // stratified jittered supersampling; a square number
    SoftShadowMethod soft_shadows = SoftShadowMethod::kAdaptive;
    int shadow_samples = 20;         // rays per spherical light for kUniform / penumbra pixels
    bool shadow_mean_filter = true;  // smooth adaptive penumbrae: RT²AR's 3x3 mean, of visibility
    DepthSecondaryRays depth_secondary = DepthSecondaryRays::kScreenSpace;
    // A ghost (modelled real surface) and the depth map describe the same surface where they
    // agree to this fraction of the distance (Kinect noise and disparity steps): the ghost is
    // shaded there (virtual shadows land on it); only a clearly nearer measurement hides it.
    // Virtual objects are hidden by any nearer measurement (RT²AR).
    float depth_ghost_agreement = 0.03f;
    float depth_thickness_m = 0.05f;  // how thick a depth sample is taken to be for rays
    // Trace only pixels whose rays can touch virtual content (the screen footprint of virtual
    // objects, their shadows and reflections on ghosts); the rest is the camera image as is.
    bool only_virtual_footprint = true;
    // With only_virtual_footprint: skip whole tiles whose rays provably cannot meet virtual
    // content (bounding spheres, their mirror images in flat reflective ghosts and the ghost
    // regions their shadows can reach), without tracing their primary rays. Same image.
    bool screen_footprint = true;
    bool keep_layers = false;  // also return I_m, I_r and M
    int threads = 0;           // 0: all hardware threads
    // Render on threads that run as ThreadRole::kRenderer (mixray/graph/thread_priority.h),
    // below capture, the recorder, the publishers and tracking: when the machine is short of
    // CPU, the composite waits, never a captured or recorded frame. The live compositor sets
    // it; offline renders keep normal priority. Same image either way.
    bool yield_to_capture = false;
    int tile_size = 16;  // pixels per tile side
    uint64_t seed = 1;   // sampling is deterministic for a given seed
    // Embree's instruction set: "" (default) the widest this CPU has, else one of
    // embreeIsas() ("sse2", "sse4.2", "avx", "avx2", "avx512"), Embree's `isa=` device option.
    // For tests and benchmarks that must cover every kernel, and as a way round a kernel that
    // misbehaves on one CPU.
    std::string embree_isa;

    Status validate() const;
};

// The Embree instruction sets this CPU runs and this Embree accepts, narrowest first; the
// values RenderOptions::embree_isa takes besides "".
std::vector<std::string> embreeIsas();

// One frame to composite into.
struct RenderInputs {
    ImageView camera_image;  // I_c: rgb8, sRGB-encoded, camera.width x camera.height
    // Optional depth16: registered to the camera image, or, with depth_registration, the depth
    // camera's own image; empty: none.
    ImageView depth_mm;
    calibration::CameraModel camera;
    // When set and not an identity (DepthRegistration::isIdentity()), depth_mm is the depth
    // camera's image (depth_registration->depth's size) and is registered into the camera
    // (calibration::Registrar: its correction, occlusion by a z-buffer) before it occludes;
    // depth_registration->color must be `camera`. Not owned.
    const calibration::DepthRegistration* depth_registration = nullptr;
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    // Motion blur (camera matching): the camera's poses when the shutter opened and closed, the
    // image's T_world_cam between them; each sample takes a time in the exposure, stratified,
    // and the pose interpolated at it. Unset: a still camera.
    struct ShutterPoses {
        Eigen::Isometry3d T_world_cam_open = Eigen::Isometry3d::Identity();
        Eigen::Isometry3d T_world_cam_close = Eigen::Isometry3d::Identity();
    };
    std::optional<ShutterPoses> shutter;
    // Poses of the anchors objects are bound to, this frame ("marker:3" -> T_world_marker).
    // "world" is implicit. Objects whose anchor is missing are not drawn this frame.
    std::map<std::string, Eigen::Isometry3d> T_world_anchor;
    // Cancels this frame: render() checks it before each tile, so a stop requested from another
    // thread (or a signal watcher) ends the frame within about one tile's time. Default: never.
    std::stop_token stop;
};

// The shutter's poses for a camera moving at constant velocity from T_world_cam_before (a frame
// `frame_interval_s` earlier) to T_world_cam, whose image is taken mid-exposure over
// `exposure_s`: the motion between the frames, scaled to the exposure either side of the image.
RenderInputs::ShutterPoses shutterFromMotion(const Eigen::Isometry3d& T_world_cam_before,
                                             const Eigen::Isometry3d& T_world_cam,
                                             double frame_interval_s, double exposure_s);

struct RenderLayers {
    Image composite;       // I_f as rgb8 sRGB, the size of the camera image
    FloatImage mixed;      // I_m (keep_layers), linear
    FloatImage real_only;  // I_r (keep_layers), linear
    FloatImage mask;       // M in [0,1], one channel (keep_layers)
};

struct RenderStats {
    uint64_t pixels_traced = 0;
    uint64_t primary_rays = 0;
    uint64_t secondary_rays = 0;
    uint64_t shadow_rays = 0;  // occlusion rays: towards lights, and towards the camera for
                               // real surfaces seen through virtual ones
    double seconds = 0;
    double shadow_map_seconds = 0;  // of `seconds`: rendering the lights' shadow maps
    // Of `seconds`, caustics (SceneDescription::caustics): shooting the photons (t_p) and
    // sorting them into their grids (t_b); both 0 on a frame that reused the last frame's.
    double caustic_shoot_seconds = 0;
    double caustic_build_seconds = 0;
    uint64_t caustic_photons = 0;  // stored this frame, both scenes
    uint64_t rays() const { return primary_rays + secondary_rays + shadow_rays; }
};

// Holds the scene's Embree BVH and renders frames into it. Thread-safety: render() is called
// from one thread at a time; it parallelises internally over tiles.
class Renderer {
public:
    // Loads meshes, textures and environment maps and builds the BVH. Errors name the file or
    // the scene entry.
    static Result<std::unique_ptr<Renderer>> create(const SceneDescription& scene,
                                                    const RenderOptions& options);
    virtual ~Renderer() = default;

    // Composites the scene into inputs.camera_image. kInvalidArgument for images of the wrong
    // size or format, non-finite or non-rigid poses, invalid camera models. kCancelled when
    // inputs.stop was requested before the frame was done: the frame is dropped whole (`out`
    // and `stats` are left as they were, never half a frame) and the next render() is exact.
    virtual Status render(const RenderInputs& inputs, RenderLayers& out,
                          RenderStats* stats = nullptr) = 0;

    // Replaces the scene's lights from the next frame on (estimated light that changes while
    // the geometry does not); anchors and files as in the scene. kInvalidArgument /
    // kCorruptData naming a bad light (the old lights stay).
    virtual Status setLights(const std::vector<Light>& lights) = 0;

    virtual const RenderOptions& options() const = 0;
};

}  // namespace mixray::render
