// The Renderer's Embree scene: one prototype BVH per object, instanced into a scene of all
// objects and a scene of ghosts only, so real-only rays never see virtual objects.
#pragma once

#include <embree3/rtcore.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "depth_mesh_geometry.h"
#include "mixray/graph/result.h"
#include "mixray/render/assets.h"
#include "mixray/render/scene.h"

namespace mixray::render::detail {

// A material with its textures loaded. Plain value.
struct MaterialData {
    Material material;
    Texture albedo_texture;   // empty: albedo only
    Texture reflectance_map;  // empty: uniform `material.reflectance`
    // The depth surface's material: diffuse, its albedo the camera pixel over the modelled
    // irradiance (DepthSurface in scene.h).
    bool albedo_from_camera = false;
};

// One scene object as the integrator needs it. `active` and the pose change per frame.
struct ObjectData {
    std::string name;
    ObjectRole role = ObjectRole::kVirtual;
    ShapeType shape = ShapeType::kSphere;
    float sphere_radius = 0;
    int material = 0;
    std::string anchor;
    Eigen::Isometry3f T_anchor_object = Eigen::Isometry3f::Identity();
    // The triangles in the object's frame, scaled; kSphere: none (traced exactly). Shared by the
    // objects that use one mesh file or one mesh in memory at one scale: loaded once, and
    // their BVH built once and instanced (EmbreeScene).
    std::shared_ptr<std::vector<TriangleMesh>> meshes =
        std::make_shared<std::vector<TriangleMesh>>();
    // The depth camera's surface (DepthSecondaryRays::kMesh): (*meshes)[0] is rebuilt every frame
    // in the camera frame and the object is posed at T_world_cam; a ghost.
    bool depth_surface = false;
    Eigen::Vector3f bound_centre = Eigen::Vector3f::Zero();  // bounding sphere, object frame
    float bound_radius = 0;

    bool active = false;
    Eigen::Matrix3f R_world_object = Eigen::Matrix3f::Identity();
    Eigen::Vector3f t_world_object = Eigen::Vector3f::Zero();
};

// Meshes one scene has loaded, by where they came from (a resolved file or a mesh in memory)
// and their scale, with what they were loaded with.
struct LoadedGeometry {
    std::shared_ptr<std::vector<TriangleMesh>> meshes;
    std::optional<MeshMaterialHint> hint;
    Eigen::Vector3f bound_centre = Eigen::Vector3f::Zero();
    float bound_radius = 0;
};
using MeshCache = std::map<std::pair<std::string, float>, LoadedGeometry>;

// A scene object's geometry loaded into an ObjectData (name, role, pose, meshes scaled and
// bounded; the material left to the caller): mesh files resolved against the scene file's
// folder. `hint`, when given, gets the mesh file's own material. With a `cache`, a mesh file
// or in-memory mesh another object already loaded at the same scale is shared, not loaded
// again. Errors name the object.
Result<ObjectData> loadObjectGeometry(const SceneDescription& scene, const SceneObject& object,
                                      std::optional<MeshMaterialHint>* hint = nullptr,
                                      MeshCache* cache = nullptr);

class ShadowMap;

struct LightData {
    Light light;
    EnvironmentMap environment;  // kEnvironment only
    bool active = false;
    Eigen::Vector3f position_world = Eigen::Vector3f::Zero();
    Eigen::Vector3f direction_world{0, 0, -1};  // unit, travel direction
    Eigen::Matrix3f R_environment_world = Eigen::Matrix3f::Identity();
    // Light::shadow_map: this frame's maps; null where they cannot cover the casters.
    std::shared_ptr<ShadowMap> shadow_map;
};

// Embree's `isa=` values RenderOptions::embree_isa may name, narrowest first.
constexpr const char* kEmbreeIsaNames[] = {"sse2", "sse4.2", "avx", "avx2", "avx512"};

// Context flags for rtcOccluded16 packets. Embree 3.13.5's AVX-512 coherent (frustum)
// occlusion traversal never returns on ordinary shadow packets on AMD Zen 4 (one origin, 16
// directions in a cone, tnear 0: 100 % CPU for minutes), while the same packets return at once
// traced incoherently or on the AVX2 kernels; incoherent is as fast on the soft-shadow bench
// (docs/benchmarks.md). No coherent occlusion packet anywhere: EmbreePacketTest runs every ISA.
constexpr RTCIntersectContextFlags kOcclusionPacketFlags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;

// Embree geometry masks: rays with kObjectMask see the scene's objects but not the depth mesh.
constexpr unsigned kObjectMask = 1u;
constexpr unsigned kDepthMeshMask = 2u;
constexpr unsigned kAnyMask = 0xFFFFFFFFu;

// A ray's nearest hit: which object, which of its meshes and triangles, Embree's barycentrics.
struct Hit {
    bool valid = false;
    float t = std::numeric_limits<float>::infinity();
    unsigned object = 0;
    unsigned mesh = 0;
    unsigned prim = 0;
    float u = 0, v = 0;
};

// Up to 16 rays gathered lane by lane into one rtcIntersect16 packet where they are made, each
// with the slot its hit goes to, so that nothing is copied between the rays and Embree's packet.
// Thread-bound: each thread keeps its own.
class IntersectPacket16 {
public:
    int size() const { return lanes_; }
    bool full() const { return lanes_ == 16; }
    uint32_t slot(int lane) const { return slot_[lane]; }
    [[gnu::always_inline]] void add(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                                    uint32_t slot) {
        const int i = lanes_++;
        rh_.ray.org_x[i] = origin.x();
        rh_.ray.org_y[i] = origin.y();
        rh_.ray.org_z[i] = origin.z();
        rh_.ray.dir_x[i] = direction.x();
        rh_.ray.dir_y[i] = direction.y();
        rh_.ray.dir_z[i] = direction.z();
        slot_[i] = slot;
    }
    // The nearest hits of the rays added, in [0, inf), as one coherent packet (camera rays),
    // through objects that `mask` sees: each ray's hit into hits[its slot]. Empties the packet.
    void trace(RTCScene scene, unsigned mask, Hit* hits);

private:
    alignas(64) RTCRayHit16 rh_;
    alignas(64) int valid_[16];
    uint32_t slot_[16];
    int lanes_ = 0;
};

// Up to 16 occlusion rays, each from its own origin, gathered lane by lane into one
// rtcOccluded16 packet (traced incoherently: kOcclusionPacketFlags), each with the slot its
// answer goes to. Thread-bound: each thread keeps its own.
class OcclusionPacket16 {
public:
    int size() const { return lanes_; }
    bool full() const { return lanes_ == 16; }
    [[gnu::always_inline]] void add(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                                    float t_far, uint32_t slot) {
        const int i = lanes_++;
        ray_.org_x[i] = origin.x();
        ray_.org_y[i] = origin.y();
        ray_.org_z[i] = origin.z();
        ray_.dir_x[i] = direction.x();
        ray_.dir_y[i] = direction.y();
        ray_.dir_z[i] = direction.z();
        ray_.tfar[i] = t_far;
        slot_[i] = slot;
    }
    // Traces the rays added through `scene` and calls on_ray(slot, occluded) for each, in the
    // order they were added; empties the packet first, so on_ray may add to it again.
    template <class OnRay>
    void trace(RTCScene scene, OnRay&& on_ray) {
        const int lanes = traceRays(scene);
        for (int i = 0; i < lanes; ++i)
            on_ray(answer_slot_[i], answer_[i]);
    }

private:
    // Traces the packet, moves its answers to answer_ and empties it; the lanes it had.
    int traceRays(RTCScene scene);

    alignas(64) RTCRay16 ray_;
    alignas(64) int valid_[16];
    uint32_t slot_[16];
    int lanes_ = 0;
    uint32_t answer_slot_[16];
    bool answer_[16];
};

// Owns the Embree device and scenes. Thread-safety: intersect/occluded are reentrant once
// setPoses() returned; setPoses() must not run concurrently with them.
class EmbreeScene {
public:
    ~EmbreeScene();

    // Builds prototypes and instances for `objects` (which keep their meshes afterwards) on a
    // device of instruction set `isa` ("": the widest the CPU has; else one of embreeIsas()).
    static Result<std::unique_ptr<EmbreeScene>> build(std::vector<ObjectData>& objects,
                                                      const std::string& isa = "");

    // Moves each object's instances to its pose, disables inactive ones, recommits.
    Status setPoses(const std::vector<ObjectData>& objects);

    // Rebuilds the depth surface's BVH from `mesh` (camera frame); call before setPoses().
    // Without a depth_surface object, nothing. True when its buffers were reused.
    bool setDepthMesh(const TriangleMesh& mesh);

    RTCScene all() const { return all_; }
    RTCScene ghosts() const { return ghosts_; }
    // Triangles whose BVH build() built: a mesh instanced by several objects counts once.
    uint64_t trianglesBuilt() const { return triangles_built_; }

    static Hit intersect(RTCScene scene, const Eigen::Vector3f& origin,
                         const Eigen::Vector3f& direction, float t_far, unsigned mask = kAnyMask);
    static bool occluded(RTCScene scene, const Eigen::Vector3f& origin,
                         const Eigen::Vector3f& direction, float t_far);
    // Nearest hits of up to 16 coherent rays from one origin (camera rays), as one packet.
    static void intersect16(RTCScene scene, const Eigen::Vector3f& origin,
                            const Eigen::Vector3f* directions, int count, Hit* hits,
                            unsigned mask = kAnyMask);
    // The same from an origin per ray (camera rays through a thin lens's aperture).
    static void intersect16(RTCScene scene, const Eigen::Vector3f* origins,
                            const Eigen::Vector3f* directions, int count, Hit* hits,
                            unsigned mask = kAnyMask);
    // occluded() of up to 16 rays from one origin (soft-shadow samples) as one packet; lanes
    // with active[i] false (active may be null: all) are not traced and false. Traced as an
    // incoherent packet: see kOcclusionPacketFlags.
    static void occluded16(RTCScene scene, const Eigen::Vector3f& origin,
                           const Eigen::Vector3f* directions, const float* t_far,
                           const bool* active, int count, bool* occluded);
    // The same for up to 8 rays.
    static void occluded8(RTCScene scene, const Eigen::Vector3f& origin,
                          const Eigen::Vector3f* directions, const float* t_far, const bool* active,
                          int count, bool* occluded);

private:
    EmbreeScene() = default;
    Status deviceStatus(const std::string& what) const;

    RTCDevice device_ = nullptr;
    RTCScene all_ = nullptr;
    RTCScene ghosts_ = nullptr;
    std::vector<RTCScene> prototypes_;
    uint64_t triangles_built_ = 0;
    std::vector<RTCGeometry> instances_all_;
    std::vector<RTCGeometry> instances_ghost_;  // nullptr for virtual objects
    std::unique_ptr<DepthMeshGeometry> depth_mesh_;
    std::unique_ptr<std::string> last_error_ = std::make_unique<std::string>();
};

}  // namespace mixray::render::detail
