// Embree prototypes (exact spheres, triangle meshes) instanced per object, posed each frame.
#include "embree_scene.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <map>

#include "mixray/render/renderer.h"

namespace mixray::render::detail {
namespace {

void onEmbreeError(void* user, RTCError code, const char* message) {
    auto* last = static_cast<std::string*>(user);
    *last = "embree error " + std::to_string(static_cast<int>(code)) + ": " +
            (message != nullptr ? message : "");
}

RTCGeometry sphereGeometry(RTCDevice device, float radius) {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    auto* point = static_cast<float*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), 1));
    if (point != nullptr) {
        point[0] = point[1] = point[2] = 0;
        point[3] = radius;
    }
    return geometry;
}

RTCGeometry triangleGeometry(RTCDevice device, const TriangleMesh& mesh) {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                3 * sizeof(float), mesh.positions.size()));
    auto* indices = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(uint32_t), mesh.triangles.size()));
    if (vertices != nullptr && indices != nullptr) {
        for (size_t i = 0; i < mesh.positions.size(); ++i)
            std::memcpy(vertices + 3 * i, mesh.positions[i].data(), 3 * sizeof(float));
        for (size_t i = 0; i < mesh.triangles.size(); ++i)
            std::memcpy(indices + 3 * i, mesh.triangles[i].data(), 3 * sizeof(uint32_t));
    }
    return geometry;
}

// Whether this CPU has what Embree's kernels of `isa` need (Embree's own ISA groups).
bool cpuRuns(const std::string& isa) {
    __builtin_cpu_init();
    if (isa == "sse2")
        return __builtin_cpu_supports("sse2");
    if (isa == "sse4.2")
        return __builtin_cpu_supports("sse4.2");
    if (isa == "avx")
        return __builtin_cpu_supports("avx");
    if (isa == "avx2")
        return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
               __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2");
    if (isa == "avx512")
        return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
               __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw") &&
               __builtin_cpu_supports("avx512vl");
    return false;
}

}  // namespace

EmbreeScene::~EmbreeScene() {
    for (RTCGeometry g : instances_all_)
        rtcReleaseGeometry(g);
    for (RTCGeometry g : instances_ghost_)
        if (g != nullptr)
            rtcReleaseGeometry(g);
    if (all_ != nullptr)
        rtcReleaseScene(all_);
    if (ghosts_ != nullptr)
        rtcReleaseScene(ghosts_);
    for (RTCScene s : prototypes_)
        rtcReleaseScene(s);
    depth_mesh_.reset();
    if (device_ != nullptr)
        rtcReleaseDevice(device_);
}

Status EmbreeScene::deviceStatus(const std::string& what) const {
    if (rtcGetDeviceError(device_) == RTC_ERROR_NONE && last_error_->empty())
        return Status::ok();
    return {ErrorCode::kInternal, what + ": " + *last_error_};
}

Result<std::unique_ptr<EmbreeScene>> EmbreeScene::build(std::vector<ObjectData>& objects,
                                                        const std::string& isa) {
    std::unique_ptr<EmbreeScene> scene(new EmbreeScene());
    if (!isa.empty()) {
        const std::vector<std::string> available = embreeIsas();
        if (std::find(available.begin(), available.end(), isa) == available.end()) {
            std::string names;
            for (const std::string& a : available)
                names += (names.empty() ? "" : ", ") + a;
            return Status(ErrorCode::kInvalidArgument,
                          "Embree ISA '" + isa +
                              "' is not available here (this CPU and Embree: " + names + ")");
        }
    }
    scene->device_ = rtcNewDevice(isa.empty() ? nullptr : ("isa=" + isa).c_str());
    if (scene->device_ == nullptr)
        return Status(ErrorCode::kInternal, "rtcNewDevice failed");
    rtcSetDeviceErrorFunction(scene->device_, onEmbreeError, scene->last_error_.get());
    scene->all_ = rtcNewScene(scene->device_);
    scene->ghosts_ = rtcNewScene(scene->device_);

    // Objects sharing their meshes (one file or one mesh in memory at one scale) share one
    // prototype: its BVH is built once and instanced at each object's pose.
    std::map<const std::vector<TriangleMesh>*, RTCScene> built;
    for (size_t i = 0; i < objects.size(); ++i) {
        ObjectData& object = objects[i];
        RTCScene prototype = nullptr;
        if (object.depth_surface) {
            // Its triangles arrive every frame through setDepthMesh().
            if (scene->depth_mesh_) {
                return Status(ErrorCode::kInternal,
                              "building object '" + object.name + "': a second depth surface");
            }
            scene->depth_mesh_ = std::make_unique<DepthMeshGeometry>(scene->device_);
            prototype = scene->depth_mesh_->scene();
        } else if (const auto it = built.find(object.meshes.get());
                   object.shape != ShapeType::kSphere && it != built.end()) {
            prototype = it->second;
        } else {
            prototype = rtcNewScene(scene->device_);
            scene->prototypes_.push_back(prototype);
            if (object.shape != ShapeType::kSphere)
                built[object.meshes.get()] = prototype;
            if (object.shape == ShapeType::kSphere) {
                RTCGeometry g = sphereGeometry(scene->device_, object.sphere_radius);
                rtcCommitGeometry(g);
                rtcAttachGeometryByID(prototype, g, 0);
                rtcReleaseGeometry(g);
            } else {
                for (size_t m = 0; m < object.meshes->size(); ++m) {
                    RTCGeometry g = triangleGeometry(scene->device_, (*object.meshes)[m]);
                    scene->triangles_built_ += (*object.meshes)[m].triangles.size();
                    rtcCommitGeometry(g);
                    rtcAttachGeometryByID(prototype, g, static_cast<unsigned>(m));
                    rtcReleaseGeometry(g);
                }
            }
            rtcCommitScene(prototype);
        }
        MIXRAY_RETURN_IF_ERROR(scene->deviceStatus("building object '" + object.name + "'"));

        const auto addInstance = [&](RTCScene top) {
            RTCGeometry instance = rtcNewGeometry(scene->device_, RTC_GEOMETRY_TYPE_INSTANCE);
            rtcSetGeometryInstancedScene(instance, prototype);
            rtcSetGeometryTimeStepCount(instance, 1);
            rtcSetGeometryMask(instance, object.depth_surface ? kDepthMeshMask : kObjectMask);
            rtcAttachGeometryByID(top, instance, static_cast<unsigned>(i));
            return instance;
        };
        scene->instances_all_.push_back(addInstance(scene->all_));
        scene->instances_ghost_.push_back(
            object.role == ObjectRole::kGhost ? addInstance(scene->ghosts_) : nullptr);
    }
    MIXRAY_RETURN_IF_ERROR(scene->deviceStatus("building instances"));
    return scene;
}

Status EmbreeScene::setPoses(const std::vector<ObjectData>& objects) {
    for (size_t i = 0; i < objects.size(); ++i) {
        const ObjectData& object = objects[i];
        Eigen::Matrix<float, 3, 4> xfm;  // column-major 3x4, as Embree wants
        xfm.leftCols<3>() = object.R_world_object;
        xfm.col(3) = object.t_world_object;
        for (RTCGeometry instance : {instances_all_[i], instances_ghost_[i]}) {
            if (instance == nullptr)
                continue;
            rtcSetGeometryTransform(instance, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xfm.data());
            if (object.active)
                rtcEnableGeometry(instance);
            else
                rtcDisableGeometry(instance);
            rtcCommitGeometry(instance);
        }
    }
    rtcCommitScene(all_);
    rtcCommitScene(ghosts_);
    return deviceStatus("posing objects");
}

bool EmbreeScene::setDepthMesh(const TriangleMesh& mesh) {
    return depth_mesh_ == nullptr || depth_mesh_->update(mesh);
}

Hit EmbreeScene::intersect(RTCScene scene, const Eigen::Vector3f& origin,
                           const Eigen::Vector3f& direction, float t_far, unsigned mask) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh{};
    rh.ray.org_x = origin.x();
    rh.ray.org_y = origin.y();
    rh.ray.org_z = origin.z();
    rh.ray.dir_x = direction.x();
    rh.ray.dir_y = direction.y();
    rh.ray.dir_z = direction.z();
    rh.ray.tnear = 0;
    rh.ray.tfar = t_far;
    rh.ray.mask = mask;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &context, &rh);
    Hit hit;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID || rh.hit.instID[0] == RTC_INVALID_GEOMETRY_ID)
        return hit;
    hit.valid = true;
    hit.t = rh.ray.tfar;
    hit.object = rh.hit.instID[0];
    hit.mesh = rh.hit.geomID;
    hit.prim = rh.hit.primID;
    hit.u = rh.hit.u;
    hit.v = rh.hit.v;
    return hit;
}

bool EmbreeScene::occluded(RTCScene scene, const Eigen::Vector3f& origin,
                           const Eigen::Vector3f& direction, float t_far) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay ray{};
    ray.org_x = origin.x();
    ray.org_y = origin.y();
    ray.org_z = origin.z();
    ray.dir_x = direction.x();
    ray.dir_y = direction.y();
    ray.dir_z = direction.z();
    ray.tnear = 0;
    ray.tfar = t_far;
    ray.mask = kAnyMask;
    rtcOccluded1(scene, &context, &ray);
    return ray.tfar < 0;
}

void EmbreeScene::intersect16(RTCScene scene, const Eigen::Vector3f& origin,
                              const Eigen::Vector3f* directions, int count, Hit* hits,
                              unsigned mask) {
    std::array<Eigen::Vector3f, 16> origins;
    origins.fill(origin);
    intersect16(scene, origins.data(), directions, count, hits, mask);
}

void EmbreeScene::intersect16(RTCScene scene, const Eigen::Vector3f* origins,
                              const Eigen::Vector3f* directions, int count, Hit* hits,
                              unsigned mask) {
    IntersectPacket16 packet;
    for (int i = 0; i < count; ++i)
        packet.add(origins[i], directions[i], static_cast<uint32_t>(i));
    packet.trace(scene, mask, hits);
}

void IntersectPacket16::trace(RTCScene scene, unsigned mask, Hit* hits) {
    if (lanes_ == 0)
        return;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    for (int i = 0; i < 16; ++i) {
        valid_[i] = i < lanes_ ? -1 : 0;
        rh_.ray.tnear[i] = 0;
        rh_.ray.tfar[i] = std::numeric_limits<float>::infinity();
        rh_.ray.time[i] = 0;
        rh_.ray.mask[i] = mask;
        rh_.ray.id[i] = static_cast<unsigned>(i);
        rh_.ray.flags[i] = 0;
        rh_.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
        rh_.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    }
    // Lanes not added are not traced (Embree reads only active rays); given a ray anyway, so
    // nothing uninitialised is ever loaded.
    for (int i = lanes_; i < 16; ++i) {
        rh_.ray.org_x[i] = rh_.ray.org_y[i] = rh_.ray.org_z[i] = 0;
        rh_.ray.dir_x[i] = rh_.ray.dir_y[i] = 0;
        rh_.ray.dir_z[i] = 1;
    }
    rtcIntersect16(valid_, scene, &context, &rh_);
    for (int i = 0; i < lanes_; ++i) {
        Hit& hit = hits[slot_[i]];
        hit = Hit{};
        if (rh_.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID ||
            rh_.hit.instID[0][i] == RTC_INVALID_GEOMETRY_ID)
            continue;
        hit.valid = true;
        hit.t = rh_.ray.tfar[i];
        hit.object = rh_.hit.instID[0][i];
        hit.mesh = rh_.hit.geomID[i];
        hit.prim = rh_.hit.primID[i];
        hit.u = rh_.hit.u[i];
        hit.v = rh_.hit.v[i];
    }
    lanes_ = 0;
}

int OcclusionPacket16::traceRays(RTCScene scene) {
    const int lanes = lanes_;
    if (lanes == 0)
        return 0;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = kOcclusionPacketFlags;
    for (int i = 0; i < 16; ++i) {
        valid_[i] = i < lanes ? -1 : 0;
        ray_.tnear[i] = 0;
        ray_.time[i] = 0;
        ray_.mask[i] = kAnyMask;
        ray_.id[i] = static_cast<unsigned>(i);
        ray_.flags[i] = 0;
    }
    // Lanes not added are not traced; given a ray anyway, so nothing uninitialised is loaded.
    for (int i = lanes; i < 16; ++i) {
        ray_.org_x[i] = ray_.org_y[i] = ray_.org_z[i] = 0;
        ray_.dir_x[i] = ray_.dir_y[i] = 0;
        ray_.dir_z[i] = 1;
        ray_.tfar[i] = 0;
    }
    rtcOccluded16(valid_, scene, &context, &ray_);
    for (int i = 0; i < lanes; ++i) {
        answer_slot_[i] = slot_[i];
        answer_[i] = ray_.tfar[i] < 0;
    }
    lanes_ = 0;
    return lanes;
}

namespace {

// RTCRayN of width N for rtcOccludedN.
template <int N>
struct OcclusionPacket;
template <>
struct OcclusionPacket<8> {
    using Ray = RTCRay8;
    static void occluded(const int* valid, RTCScene scene, RTCIntersectContext* context, Ray* ray) {
        rtcOccluded8(valid, scene, context, ray);
    }
};
template <>
struct OcclusionPacket<16> {
    using Ray = RTCRay16;
    static void occluded(const int* valid, RTCScene scene, RTCIntersectContext* context, Ray* ray) {
        rtcOccluded16(valid, scene, context, ray);
    }
};

template <int N>
void occludedPacket(RTCScene scene, const Eigen::Vector3f& origin,
                    const Eigen::Vector3f* directions, const float* t_far, const bool* active,
                    int count, bool* occluded) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = kOcclusionPacketFlags;
    alignas(64) int valid[N];
    alignas(64) typename OcclusionPacket<N>::Ray ray;
    for (int i = 0; i < N; ++i) {
        const bool on = i < count && (active == nullptr || active[i]);
        valid[i] = on ? -1 : 0;
        const Eigen::Vector3f d = on ? directions[i] : Eigen::Vector3f::UnitZ();
        ray.org_x[i] = origin.x();
        ray.org_y[i] = origin.y();
        ray.org_z[i] = origin.z();
        ray.dir_x[i] = d.x();
        ray.dir_y[i] = d.y();
        ray.dir_z[i] = d.z();
        ray.tnear[i] = 0;
        ray.tfar[i] = on ? t_far[i] : 0;
        ray.time[i] = 0;
        ray.mask[i] = 0xFFFFFFFFu;
        ray.id[i] = static_cast<unsigned>(i);
        ray.flags[i] = 0;
    }
    OcclusionPacket<N>::occluded(valid, scene, &context, &ray);
    for (int i = 0; i < count; ++i)
        occluded[i] = valid[i] != 0 && ray.tfar[i] < 0;
}

}  // namespace

void EmbreeScene::occluded8(RTCScene scene, const Eigen::Vector3f& origin,
                            const Eigen::Vector3f* directions, const float* t_far,
                            const bool* active, int count, bool* occluded) {
    occludedPacket<8>(scene, origin, directions, t_far, active, count, occluded);
}

void EmbreeScene::occluded16(RTCScene scene, const Eigen::Vector3f& origin,
                             const Eigen::Vector3f* directions, const float* t_far,
                             const bool* active, int count, bool* occluded) {
    occludedPacket<16>(scene, origin, directions, t_far, active, count, occluded);
}

}  // namespace mixray::render::detail

namespace mixray::render {

std::vector<std::string> embreeIsas() {
    static const std::vector<std::string> isas = [] {
        std::vector<std::string> found;
        for (const char* isa : detail::kEmbreeIsaNames) {
            if (!detail::cpuRuns(isa))
                continue;
            RTCDevice device = rtcNewDevice((std::string("isa=") + isa).c_str());
            if (device == nullptr)
                continue;
            rtcReleaseDevice(device);
            found.push_back(isa);
        }
        return found;
    }();
    return isas;
}

}  // namespace mixray::render
