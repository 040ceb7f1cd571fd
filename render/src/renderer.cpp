// The Renderer: one-pass differential rendering (Kán & Kaufmann) of virtual objects into camera
// frames with RT²AR's ghosts, shadows, reflection, refraction and depth occlusion on Embree.
#include "mixray/render/renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

#include "bare_trace.h"
#include "embree_scene.h"
#include "footprint.h"
#include "mixray/render/depth_occlusion.h"
#include "optics.h"

namespace mixray::render {

Status RenderOptions::validate() const {
    const auto bad = [](const std::string& what) {
        return Status(ErrorCode::kInvalidArgument, "render options: " + what);
    };
    if (max_depth < 0 || max_depth > 64)
        return bad("max_depth must be in [0, 64]");
    const int root = static_cast<int>(std::lround(std::sqrt(std::max(samples_per_pixel, 0))));
    if (samples_per_pixel < 1 || samples_per_pixel > 256 || root * root != samples_per_pixel)
        return bad("samples_per_pixel must be a square number in [1, 256]");
    if (shadow_samples < 1 || shadow_samples > 1024)
        return bad("shadow_samples must be in [1, 1024]");
    if (!(depth_ghost_agreement >= 0 && depth_ghost_agreement < 0.5f))
        return bad("depth_ghost_agreement must be in [0, 0.5)");
    if (!std::isfinite(depth_thickness_m) || depth_thickness_m <= 0)
        return bad("depth_thickness_m must be positive and finite");
    if (threads < 0)
        return bad("threads must be >= 0");
    if (tile_size < 1 || tile_size > 1024)
        return bad("tile_size must be in [1, 1024]");
    if (!embree_isa.empty() &&
        std::none_of(std::begin(detail::kEmbreeIsaNames), std::end(detail::kEmbreeIsaNames),
                     [&](const char* name) { return embree_isa == name; }))
        return bad("embree_isa '" + embree_isa +
                   "' is none of sse2, sse4.2, avx, avx2, avx512 (or empty: the best)");
    return Status::ok();
}

uint64_t RayLog::count(Kind kind) const {
    return static_cast<uint64_t>(
        std::count_if(rays.begin(), rays.end(), [kind](const Ray& r) { return r.kind == kind; }));
}

namespace {

using detail::EmbreeScene;
using detail::Hit;
using detail::LightData;
using detail::MaterialData;
using detail::ObjectData;
using Vec3 = Eigen::Vector3f;
using Vec2 = Eigen::Vector2f;

constexpr float kInf = std::numeric_limits<float>::infinity();
// How far secondary rays look for depth-camera surfaces when nothing in the scene is nearer;
// beyond any Kinect's range.
constexpr float kFarDepth_m = 20;
constexpr float kDepthStart_m = 0.01f;

// Which radiances a ray carries: both (paths made of real surfaces so far), mixed only (after a
// virtual surface, where the real scene has no counterpart), or real only (the scene without
// virtual objects, for the I_r of rays a virtual object intercepted).
enum class Mode : uint8_t { kBoth, kMixed, kReal };

struct Pair {
    Vec3 m = Vec3::Zero();
    Vec3 r = Vec3::Zero();
};

struct Counters {
    uint64_t secondary = 0;
    uint64_t shadow = 0;
};

using RayList = std::vector<RayLog::Ray>;

struct SampleState {
    optics::Rng rng;
    Counters* counters;
    RayList* log = nullptr;  // RenderInputs::ray_log was given
    bool penumbra = false;
};

void logRay(RayList* log, RayLog::Kind kind, RTCScene scene, RTCScene ghosts, const Vec3& origin,
            const Vec3& d, float t_far) {
    if (log != nullptr)
        log->push_back({{origin.x(), origin.y(), origin.z()},
                        {d.x(), d.y(), d.z()},
                        t_far,
                        kind,
                        scene == ghosts});
}

// What shading needs about a hit, in world coordinates.
struct Surface {
    Vec3 p;
    Vec3 n_geometric;  // unit, outward (as the mesh winds or the sphere bulges)
    Vec3 n_shading;    // unit, interpolated, same side as n_geometric
    Vec2 uv = Vec2::Zero();
    const ObjectData* object = nullptr;
    const MaterialData* material = nullptr;
};

struct SphereBound {
    Vec3 centre;
    float radius;
};

Status checkPose(const Eigen::Isometry3d& T, const std::string& what) {
    if (!T.matrix().allFinite())
        return {ErrorCode::kInvalidArgument, what + ": pose has non-finite entries"};
    const Eigen::Matrix3d R = T.linear();
    const bool orthonormal = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-5;
    const bool last_row = T.matrix().row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1));
    if (!orthonormal || std::abs(R.determinant() - 1) > 1e-5 || !last_row)
        return {ErrorCode::kInvalidArgument, what + ": pose is not a rigid transform"};
    return Status::ok();
}

bool sameModel(const calibration::CameraModel& a, const calibration::CameraModel& b) {
    return a.lens == b.lens && a.width == b.width && a.height == b.height && a.fx == b.fx &&
           a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.distortion == b.distortion;
}

uint64_t hashIndex(uint64_t seed, uint64_t a, uint64_t b) {
    optics::Rng rng(seed ^ (a * 0x9e3779b97f4a7c15ULL) ^ (b * 0xc2b2ae3d27d4eb4fULL));
    return rng.next();
}

// Distance from `c` to the segment a + s·(b - a), s in [0, s_max] (s_max = inf: a ray).
float distanceToSegment(const Vec3& c, const Vec3& a, const Vec3& dir, float length) {
    const float s = std::clamp((c - a).dot(dir), 0.f, length);
    return (a + s * dir - c).norm();
}

// R·v spelled out: GCC at -O2 leaves Eigen's fixed-size product as an out-of-line call, which
// showed up in profiles of the per-hit code.
inline Vec3 rotate(const Eigen::Matrix3f& R, const Vec3& v) {
    return R.col(0) * v.x() + R.col(1) * v.y() + R.col(2) * v.z();
}

float offsetFor(const Vec3& p) {
    return 1e-4f * (1.f + p.cwiseAbs().maxCoeff());
}

// Camera directions of every (sub)pixel sample, computed once per camera model through its
// unproject(), so rays follow the lens distortion exactly. NaN marks samples without a ray.
struct RayCache {
    calibration::CameraModel model;
    int samples = 0;
    uint64_t seed = 0;
    std::vector<Vec3> directions;         // ((y * width + x) * samples + s)
    std::vector<detail::TileCone> cones;  // per tile of options.tile_size
    // The z of the unit ray through each pixel's centre (y * width + x), exactly as
    // rayDistanceAt() computes it; NaN where it has none in front of the camera.
    std::vector<double> centre_cos;

    // rayDistanceAt(depth, x, y) for a depth image registered to `model`, from the cache:
    // the same value, without a lens unprojection per pixel per frame.
    std::optional<float> rayDistanceAt(const DepthView& depth, int x, int y) const {
        const std::optional<float> z = depth.zAt(x, y);
        if (!z)
            return std::nullopt;
        const double c = centre_cos[static_cast<size_t>(y) * model.width + x];
        if (!(c > 0))
            return std::nullopt;
        return static_cast<float>(*z / c);
    }
};

// Per-frame tracing context: read-only during the parallel loop.
struct Frame {
    const RenderInputs* inputs = nullptr;
    Eigen::Matrix3f R_world_cam;
    Vec3 t_world_cam;
    Eigen::Matrix3d R_cam_world;
    Eigen::Vector3d t_cam_world;
    std::vector<SphereBound> virtual_bounds;
    std::vector<const LightData*> lights;  // active direct lights
    std::vector<const LightData*> environments;
    std::optional<DepthView> depth;
    bool depth_mesh = false;  // the depth surface is in the BVH this frame (kMesh)
    std::array<float, 256> srgb_lut{};
    // The only active ghost is a plane or disk: no ray leaving it can meet a ghost again.
    bool lone_flat_ghost = false;
    detail::FootprintScene footprint;
};

// Per-pixel accumulators of one frame, kept between frames: only tiles marked dirty hold
// anything but zeros.
struct PixelBuffers {
    std::vector<Vec3> virtual_radiance;  // mean I_m over samples that hit virtual objects
    std::vector<Vec3> difference;        // mean I_m - I_r over the other samples
    std::vector<float> mask;             // M
    std::vector<uint8_t> flags;          // kTraced | kPenumbra
    std::vector<Vec3> mixed, real;       // keep_layers
    std::vector<uint8_t> tile_dirty;
    int width = 0, height = 0;
};
constexpr uint8_t kTraced = 1;
constexpr uint8_t kPenumbra = 2;

// A tile's primary hits and directions: reused by the thread, so the loop never allocates.
struct TileScratch {
    std::vector<Hit> hits;
    std::vector<Vec3> dirs;
    std::vector<Surface> surfaces;  // one pixel's samples, from the footprint test to shading
    std::vector<uint8_t> have_surface;
};

Result<std::vector<LightData>> loadLights(const std::filesystem::path& scene_source,
                                          const std::vector<Light>& scene_lights);

class EmbreeRenderer final : public Renderer {
public:
    EmbreeRenderer(RenderOptions options, std::vector<MaterialData> materials,
                   std::vector<ObjectData> objects, std::vector<LightData> lights,
                   std::filesystem::path scene_source)
        : options_(options),
          materials_(std::move(materials)),
          objects_(std::move(objects)),
          lights_(std::move(lights)),
          scene_source_(std::move(scene_source)) {}

    Status setLights(const std::vector<Light>& lights) override {
        SceneDescription check;  // the scene's own checks, on the lights alone
        check.lights = lights;
        MIXRAY_RETURN_IF_ERROR(check.validate());
        auto loaded = loadLights(scene_source_, lights);
        if (!loaded)
            return loaded.status();
        lights_ = std::move(loaded).value();
        return Status::ok();
    }

    Status init() {
        auto built = EmbreeScene::build(objects_, options_.embree_isa);
        if (!built)
            return built.status();
        scene_ = std::move(built).value();
        return Status::ok();
    }

    const RenderOptions& options() const override { return options_; }
    void setDepthObject(std::optional<size_t> index) { depth_object_ = index; }
    BareTraceTimes traceBare(const RayLog& log, int repeats) const override {
        return detail::traceBareEmbree(scene_->all(), scene_->ghosts(), log, options_.threads,
                                       repeats);
    }
    Status render(const RenderInputs& inputs, RenderLayers& out, RenderStats* stats) override;

    // The integrator (const: reentrant over tiles).
    Pair trace(const Frame& f, const Vec3& origin, const Vec3& d, int depth, Mode mode,
               SampleState& st) const;
    Pair shade(const Frame& f, const Surface& s, const Hit& hit, const Vec3& d, int depth,
               Mode mode, SampleState& st) const;
    Pair direct(const Frame& f, const Surface& s, const Vec3& n, const Vec3& d, const Vec3& albedo,
                Mode mode, SampleState& st) const;
    Pair lightVisibility(const LightData& light, const Vec3& origin, const Vec3& to_light,
                         float dist, Mode mode, SampleState& st) const;
    Hit finishPrimaryHit(const Frame& f, const Hit& hit, const Vec3& d,
                         std::optional<float> depth_limit) const;
    Pair cameraAlbedoDirect(const Frame& f, const Surface& s, const Vec3& n, const Vec3& d,
                            SampleState& st) const;
    bool depthMapShadows(const Frame& f, const Vec3& origin, const Vec3& wi, float dist) const;
    bool depthSurfaceInfluenced(const Frame& f, const Vec3& p, float margin) const;
    Surface surfaceAt(const Hit& hit, const Vec3& origin, const Vec3& d) const;
    Vec3 environment(const Frame& f, const Vec3& d) const;
    std::optional<Vec3> cameraRadianceAt(const Frame& f, const Surface& s, SampleState& st) const;
    bool ghostInfluenced(const Frame& f, const Surface& s, const Vec3& d) const;

private:
    Status checkInputs(const RenderInputs& inputs) const;
    Status prepareFrame(const RenderInputs& inputs, Frame& f);
    // The depth image in the camera: inputs.depth_mm itself, or registered into it.
    Result<ImageView> registeredDepth(const RenderInputs& inputs);
    void updateDepthMesh(Frame& f);
    void updateRayCache(const calibration::CameraModel& camera);
    void prepareFootprint(Frame& f) const;
    void depthRegions(const Frame& f, detail::FootprintScene& fp) const;
    void primaryHits(const Frame& f, int x0, int y0, int x1, int y1, TileScratch& scratch,
                     RayList* log) const;

    RenderOptions options_;
    std::vector<MaterialData> materials_;
    std::vector<ObjectData> objects_;
    std::vector<LightData> lights_;
    std::filesystem::path scene_source_;  // the scene file: light files resolve against it
    std::unique_ptr<EmbreeScene> scene_;
    RayCache rays_;
    std::optional<size_t> depth_object_;  // index in objects_ of the depth surface (kMesh)
    DepthMesher mesher_;
    // Registration of depth images from another camera: kept while the registration is the
    // same, so its scratch and the registered image are reused frame to frame.
    std::optional<calibration::Registrar> registrar_;
    Image registered_depth_;
    PixelBuffers buffers_;
    std::vector<uint8_t> tile_mask_;
    // One per thread slot of the render arena (tbb::this_task_arena::current_thread_index()).
    std::vector<TileScratch> scratch_;
};

Surface EmbreeRenderer::surfaceAt(const Hit& hit, const Vec3& origin, const Vec3& d) const {
    const ObjectData& object = objects_[hit.object];
    Surface s;
    s.object = &object;
    s.material = &materials_[static_cast<size_t>(object.material)];
    const Eigen::Matrix3f& R = object.R_world_object;
    if (object.shape == ShapeType::kSphere) {
        // Recompute the point on the exact sphere: less drift than origin + t·d.
        const Vec3 p_obj = R.transpose() * (origin + hit.t * d - object.t_world_object);
        const Vec3 n_obj = p_obj.normalized();
        s.n_geometric = s.n_shading = rotate(R, n_obj);
        s.p = rotate(R, n_obj * object.sphere_radius) + object.t_world_object;
        s.uv = {0.5f + std::atan2(n_obj.y(), n_obj.x()) / (2 * optics::kPi),
                std::acos(std::clamp(n_obj.z(), -1.f, 1.f)) / optics::kPi};
        return s;
    }
    const TriangleMesh& mesh = object.meshes[hit.mesh];
    const auto& tri = mesh.triangles[hit.prim];
    const float w = 1.f - hit.u - hit.v;
    const Vec3& a = mesh.positions[tri[0]];
    const Vec3& b = mesh.positions[tri[1]];
    const Vec3& c = mesh.positions[tri[2]];
    const Vec3 n_geo = (b - a).cross(c - a).normalized();
    s.n_geometric = rotate(R, n_geo);
    s.p = origin + hit.t * d;
    if (mesh.normals.size() == mesh.positions.size()) {
        Vec3 n =
            w * mesh.normals[tri[0]] + hit.u * mesh.normals[tri[1]] + hit.v * mesh.normals[tri[2]];
        if (n.squaredNorm() > 1e-12f) {
            n = rotate(R, n.normalized());
            s.n_shading = n.dot(s.n_geometric) >= 0 ? n : Vec3(-n);
        } else {
            s.n_shading = s.n_geometric;
        }
    } else {
        s.n_shading = s.n_geometric;
    }
    if (mesh.uvs.size() == mesh.positions.size())
        s.uv = w * mesh.uvs[tri[0]] + hit.u * mesh.uvs[tri[1]] + hit.v * mesh.uvs[tri[2]];
    return s;
}

Vec3 EmbreeRenderer::environment(const Frame& f, const Vec3& d) const {
    Vec3 sum = Vec3::Zero();
    for (const LightData* light : f.environments)
        sum += light->light.environment_scale *
               light->environment.radiance((light->R_environment_world * d).normalized());
    return sum;
}

// Fractions of a light's visible area seen from `origin` in the mixed and the real scene. Both
// use the same sample points, so they agree bit for bit where no virtual object interferes.
Pair EmbreeRenderer::lightVisibility(const LightData& light, const Vec3& origin,
                                     const Vec3& to_light, float dist, Mode mode,
                                     SampleState& st) const {
    if (!options_.shadows)
        return {Vec3::Ones(), Vec3::Ones()};
    const bool want_m = mode != Mode::kReal;
    const bool want_r = mode != Mode::kMixed;
    // One shadow ray towards `target` (a point, or a direction when dist is infinite).
    const auto test = [&](const Vec3& dir, float length, int& lit_m, int& lit_r) {
        bool occ_m = false;
        if (want_m) {
            ++st.counters->shadow;
            logRay(st.log, RayLog::Kind::kShadow, scene_->all(), scene_->ghosts(), origin, dir,
                   length);
            occ_m = EmbreeScene::occluded(scene_->all(), origin, dir, length);
            lit_m += occ_m ? 0 : 1;
        }
        if (want_r) {
            bool occ_r = false;
            if (!want_m || occ_m) {
                ++st.counters->shadow;
                logRay(st.log, RayLog::Kind::kShadow, scene_->ghosts(), scene_->ghosts(), origin,
                       dir, length);
                occ_r = EmbreeScene::occluded(scene_->ghosts(), origin, dir, length);
            }
            lit_r += occ_r ? 0 : 1;
        }
    };
    // Up to 16 shadow rays towards points on the light: one packet per scene.
    const auto testPacket = [&](const Vec3* dirs, const float* lengths, int count, int& lit_m,
                                int& lit_r) {
        std::array<bool, 16> occ_m{}, active{}, occ_r{};
        if (want_m) {
            for (int i = 0; i < count; ++i) {
                ++st.counters->shadow;
                logRay(st.log, RayLog::Kind::kShadow, scene_->all(), scene_->ghosts(), origin,
                       dirs[i], lengths[i]);
            }
            EmbreeScene::occluded16(scene_->all(), origin, dirs, lengths, nullptr, count,
                                    occ_m.data());
            for (int i = 0; i < count; ++i)
                lit_m += occ_m[i] ? 0 : 1;
        }
        if (want_r) {
            bool any = false;
            for (int i = 0; i < count; ++i) {
                active[i] = !want_m || occ_m[i];
                if (active[i]) {
                    any = true;
                    ++st.counters->shadow;
                    logRay(st.log, RayLog::Kind::kShadow, scene_->ghosts(), scene_->ghosts(),
                           origin, dirs[i], lengths[i]);
                }
            }
            if (any)
                EmbreeScene::occluded16(scene_->ghosts(), origin, dirs, lengths, active.data(),
                                        count, occ_r.data());
            for (int i = 0; i < count; ++i)
                lit_r += occ_r[i] ? 0 : 1;
        }
    };
    const float shorten = 1.f - 1e-4f;
    int lit_m = 0, lit_r = 0;
    const SoftShadowMethod method = options_.soft_shadows;
    if (light.light.type != LightType::kSphere || method == SoftShadowMethod::kHard ||
        dist <= light.light.radius) {
        test(to_light, std::isfinite(dist) ? dist * shorten : kInf, lit_m, lit_r);
        return {Vec3::Constant(static_cast<float>(lit_m)),
                Vec3::Constant(static_cast<float>(lit_r))};
    }
    // The disc of the sphere facing `origin` (RT²AR fig. 9), spanned by u and v.
    const Vec3 w = to_light;
    const Vec3 u = w.unitOrthogonal();
    const Vec3 v = w.cross(u);
    const Vec3 centre = origin + dist * w;
    const float radius = light.light.radius;
    std::array<Vec3, 16> dirs;
    std::array<float, 16> lengths;
    const auto aim = [&](int lane, const Vec3& target) {
        const Vec3 delta = target - origin;
        const float length = delta.norm();
        dirs[static_cast<size_t>(lane)] = delta / length;
        lengths[static_cast<size_t>(lane)] = length * shorten;
    };
    if (method == SoftShadowMethod::kAdaptive) {
        const std::array<Vec3, 5> points = {centre, centre + radius * u, centre - radius * u,
                                            centre + radius * v, centre - radius * v};
        for (int i = 0; i < 5; ++i)
            aim(i, points[static_cast<size_t>(i)]);
        // Five rays fill a third of a packet: measured slower than single rays.
        for (int i = 0; i < 5; ++i)
            test(dirs[static_cast<size_t>(i)], lengths[static_cast<size_t>(i)], lit_m, lit_r);
        const bool agree_m = !want_m || lit_m == 0 || lit_m == 5;
        const bool agree_r = !want_r || lit_r == 0 || lit_r == 5;
        if (agree_m && agree_r)
            return {Vec3::Constant(lit_m / 5.f), Vec3::Constant(lit_r / 5.f)};
        st.penumbra = true;
        lit_m = lit_r = 0;
    }
    const int n = options_.shadow_samples;
    const float rotation = st.rng.uniform() * 2 * optics::kPi;
    for (int k0 = 0; k0 < n; k0 += 16) {
        const int count = std::min(16, n - k0);
        for (int i = 0; i < count; ++i) {
            const Vec2 q = optics::discSample(k0 + i, n, st.rng.uniform(), rotation);
            aim(i, centre + radius * (q.x() * u + q.y() * v));
        }
        if (count >= 8) {
            testPacket(dirs.data(), lengths.data(), count, lit_m, lit_r);
        } else {
            for (int i = 0; i < count; ++i)
                test(dirs[static_cast<size_t>(i)], lengths[static_cast<size_t>(i)], lit_m, lit_r);
        }
    }
    return {Vec3::Constant(static_cast<float>(lit_m) / static_cast<float>(n)),
            Vec3::Constant(static_cast<float>(lit_r) / static_cast<float>(n))};
}

// Direct light from point, spherical and directional lights: Lambert plus, for Phong, a
// normalised Blinn-Phong lobe; each light's shadow rays in the scenes the mode asks for.
Pair EmbreeRenderer::direct(const Frame& f, const Surface& s, const Vec3& n, const Vec3& d,
                            const Vec3& albedo, Mode mode, SampleState& st) const {
    Pair out;
    const Material& mat = s.material->material;
    const Vec3 origin =
        s.p + offsetFor(s.p) * (s.n_geometric.dot(d) < 0 ? s.n_geometric : Vec3(-s.n_geometric));
    for (const LightData* light : f.lights) {
        Vec3 wi;
        float dist = kInf;
        Vec3 irradiance;
        if (light->light.type == LightType::kDirectional) {
            wi = -light->direction_world;
            irradiance = light->light.intensity;
        } else {
            const Vec3 delta = light->position_world - s.p;
            dist = delta.norm();
            if (dist <= 0)
                continue;
            wi = delta / dist;
            irradiance = light->light.intensity / (dist * dist);
        }
        const float cos_theta = n.dot(wi);
        if (cos_theta <= 0)
            continue;
        Vec3 brdf = albedo / optics::kPi;
        if (mat.type == MaterialType::kPhong) {
            const Vec3 h = (wi - d).normalized();
            const float lobe = std::pow(std::max(0.f, n.dot(h)), mat.shininess);
            brdf += mat.specular * ((mat.shininess + 8) / (8 * optics::kPi)) * lobe;
        }
        const Vec3 unshadowed = brdf.cwiseProduct(irradiance) * cos_theta;
        Pair visible = lightVisibility(*light, origin, wi, dist, mode, st);
        // Real surfaces the depth map holds shadow virtual ones (in kMesh they are in the BVH).
        if (s.object->role == ObjectRole::kVirtual && visible.m.maxCoeff() > 0 &&
            depthMapShadows(f, origin, wi, dist)) {
            visible = {};
        }
        out.m += unshadowed.cwiseProduct(visible.m);
        out.r += unshadowed.cwiseProduct(visible.r);
    }
    return out;
}

Pair scaled(const Pair& p, const Vec3& w) {
    return {p.m.cwiseProduct(w), p.r.cwiseProduct(w)};
}
Pair sum(const Pair& a, const Pair& b) {
    return {a.m + b.m, a.r + b.r};
}

Pair EmbreeRenderer::shade(const Frame& f, const Surface& s, const Hit& hit, const Vec3& d,
                           int depth, Mode mode, SampleState& st) const {
    const Material& mat = s.material->material;
    const bool entering = s.n_geometric.dot(d) < 0;
    const Vec3 n_geo = entering ? s.n_geometric : Vec3(-s.n_geometric);
    const Vec3 n = entering ? s.n_shading : Vec3(-s.n_shading);
    const float eps = offsetFor(s.p);
    const Vec3 above = s.p + eps * n_geo;
    const Vec3 below = s.p - eps * n_geo;
    const bool can_bounce = depth < options_.max_depth;
    const auto reflected = [&]() {
        return can_bounce ? trace(f, above, optics::reflect(d, n).normalized(), depth + 1, mode, st)
                          : Pair{};
    };
    float map = 1;
    if (!s.material->reflectance_map.empty())
        map = s.material->reflectance_map.sample(s.uv).mean();

    switch (mat.type) {
        case MaterialType::kDiffuse:
        case MaterialType::kPhong: {
            Vec3 albedo = mat.albedo;
            if (!s.material->albedo_texture.empty())
                albedo = albedo.cwiseProduct(s.material->albedo_texture.sample(s.uv));
            Pair local = s.material->albedo_from_camera ? cameraAlbedoDirect(f, s, n, d, st)
                                                        : direct(f, s, n, d, albedo, mode, st);
            const float rho = std::clamp(mat.reflectance * map, 0.f, 1.f);
            if (rho <= 0)
                return local;
            return sum(scaled(local, Vec3::Constant(1 - rho)),
                       scaled(reflected(), Vec3::Constant(rho)));
        }
        case MaterialType::kMirror: {
            const float rho =
                std::clamp((mat.reflectance > 0 ? mat.reflectance : 1.f) * map, 0.f, 1.f);
            return scaled(reflected(), Vec3::Constant(rho));
        }
        case MaterialType::kMetal: {
            const float cos_i = std::clamp(-d.dot(n), 0.f, 1.f);
            Vec3 fresnel;
            for (int c = 0; c < 3; ++c)
                fresnel[c] = optics::schlick(mat.f0[c], cos_i);
            return scaled(reflected(), fresnel);
        }
        case MaterialType::kGlass: {
            const float cos_i = std::clamp(-d.dot(n), 0.f, 1.f);
            // Beer-Lambert absorption along the segment just travelled inside the glass.
            Vec3 absorbed = Vec3::Ones();
            if (!entering)
                for (int c = 0; c < 3; ++c)
                    absorbed[c] = std::pow(std::max(mat.transmission[c], 0.f), hit.t);
            const bool dispersive = mat.ior.x() != mat.ior.y() || mat.ior.x() != mat.ior.z();
            const int channels = dispersive ? 3 : 1;
            Vec3 reflectance;
            std::array<std::optional<Vec3>, 3> refracted;
            for (int c = 0; c < channels; ++c) {
                const float n_from = entering ? 1.f : mat.ior[c];
                const float n_to = entering ? mat.ior[c] : 1.f;
                refracted[c] = optics::refract(d, n, n_from / n_to);
                reflectance[c] =
                    refracted[c] ? optics::dielectricReflectance(cos_i, n_from, n_to) : 1.f;
            }
            if (!dispersive)
                reflectance = Vec3::Constant(reflectance[0]);
            Pair result;
            if (can_bounce) {
                if (reflectance.maxCoeff() > 0)
                    result = scaled(reflected(), reflectance);
                for (int c = 0; c < channels; ++c) {
                    if (!refracted[c])
                        continue;
                    Pair t = trace(f, below, *refracted[c], depth + 1, mode, st);
                    Vec3 weight = Vec3::Ones() - reflectance;
                    if (dispersive) {
                        const float keep = weight[c];
                        weight = Vec3::Zero();
                        weight[c] = keep;
                    }
                    result = sum(result, scaled(t, weight));
                }
            }
            return scaled(result, absorbed);
        }
    }
    return {};
}

// The camera image at a pixel position (bilinear, linear light); nullopt outside.
std::optional<Vec3> cameraTexel(const Frame& f, double x, double y) {
    const RenderInputs& in = *f.inputs;
    const int w = in.camera.width, h = in.camera.height;
    if (!(x >= 0 && y >= 0 && x <= w - 1 && y <= h - 1))
        return std::nullopt;
    const int x0 = std::min(static_cast<int>(x), w - 1), y0 = std::min(static_cast<int>(y), h - 1);
    const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
    const float ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
    const auto texel = [&](int px, int py) {
        const uint8_t* rgb = in.camera_image.row<uint8_t>(py) + 3 * px;
        return Vec3(f.srgb_lut[rgb[0]], f.srgb_lut[rgb[1]], f.srgb_lut[rgb[2]]);
    };
    return (1 - ay) * ((1 - ax) * texel(x0, y0) + ax * texel(x1, y0)) +
           ay * ((1 - ax) * texel(x0, y1) + ax * texel(x1, y1));
}

// The camera pixel a world point projects to (bilinear, linear light); nullopt outside.
std::optional<Vec3> cameraPixelAt(const Frame& f, const Vec3& p_world) {
    const Eigen::Vector3d p_cam = f.R_cam_world * p_world.cast<double>() + f.t_cam_world;
    const auto pixel = f.inputs->camera.project(p_cam);
    if (!pixel)
        return std::nullopt;
    return cameraTexel(f, pixel->x(), pixel->y());
}

// Direct light on the depth surface, whose albedo is the camera pixel over the irradiance the
// scene's lights give in the real scene: then I_r is the camera pixel itself and I_m is that
// pixel times E_mixed / E_real, so I_c + I_m − I_r scales the camera pixel by exactly the ratio
// of the lighting with and without the virtual objects, however the real lights are modelled.
// Where the model gives no light, nothing virtual can change it: both are the camera pixel.
Pair EmbreeRenderer::cameraAlbedoDirect(const Frame& f, const Surface& s, const Vec3& n,
                                        const Vec3& d, SampleState& st) const {
    const int w = f.inputs->camera.width, h = f.inputs->camera.height;
    const std::optional<Vec3> camera = cameraTexel(f, s.uv.x() * w - 0.5, s.uv.y() * h - 0.5);
    if (!camera)
        return {};
    const Pair irradiance = direct(f, s, n, d, Vec3::Ones(), Mode::kBoth, st);
    Pair out{*camera, *camera};
    for (int c = 0; c < 3; ++c)
        if (irradiance.r[c] > 0 && irradiance.m[c] != irradiance.r[c])
            out.m[c] = (*camera)[c] * irradiance.m[c] / irradiance.r[c];
    return out;
}

// RT²AR's screen-space traversal for a shadow ray (kScreenSpace): whether the depth map's
// surface lies between `origin` and the light. The walk starts where trace()'s does, so that a
// point on a surface the depth camera also measured does not shadow itself.
bool EmbreeRenderer::depthMapShadows(const Frame& f, const Vec3& origin, const Vec3& wi,
                                     float dist) const {
    if (!f.depth || options_.depth_secondary != DepthSecondaryRays::kScreenSpace)
        return false;
    const float t_max = std::min(dist, kFarDepth_m) - kDepthStart_m;
    if (!(t_max > 0))
        return false;
    const Vec3 start = origin + kDepthStart_m * wi;
    const Vec3 o_cam = (f.R_cam_world * start.cast<double>() + f.t_cam_world).cast<float>();
    const Vec3 d_cam = (f.R_cam_world * wi.cast<double>()).cast<float>();
    return traceDepthMap(*f.depth, o_cam, d_cam, t_max, options_.depth_thickness_m).has_value();
}

// The surface a camera ray shows. Virtual objects are hidden exactly where the depth map puts a
// real surface nearer along the pixel's ray (rayDistanceAt), in every DepthSecondaryRays mode.
// With the depth mesh, the real surface such a pixel shows is traced too (the nearest of the
// ghosts and the mesh), so that virtual shadows and reflections on it are shaded.
// A primary ray's hit among the scene's objects (the depth mesh masked out), checked against the
// depth map: a real surface the depth camera measured in front hides what was hit.
Hit EmbreeRenderer::finishPrimaryHit(const Frame& f, const Hit& hit, const Vec3& d,
                                     std::optional<float> depth_limit) const {
    const bool ghost = hit.valid && objects_[hit.object].role != ObjectRole::kVirtual;
    const bool hidden = hit.valid && depth_limit &&
                        *depth_limit < hit.t * (ghost ? 1 - options_.depth_ghost_agreement : 1.0f);
    if (!f.depth_mesh)
        return hidden ? Hit{} : hit;
    if (hit.valid && !hidden && objects_[hit.object].role == ObjectRole::kVirtual)
        return hit;
    // Most of the depth surface is out of reach of every virtual object: there it stays the
    // camera pixel, as without the mesh, and its triangles need not be traced. The mesh point
    // lies near the measured one; 5 % of the distance (the relative step the mesher still joins)
    // covers the difference.
    if (depth_limit &&
        !depthSurfaceInfluenced(f, f.t_world_cam + *depth_limit * d, 0.05f * *depth_limit)) {
        return hidden ? Hit{} : hit;
    }
    return EmbreeScene::intersect(scene_->ghosts(), f.t_world_cam, d, kInf);
}

// ghostInfluenced() for the depth surface at a point known to within `margin`: moving the point
// by up to `margin` moves its segments towards the lights by no more.
bool EmbreeRenderer::depthSurfaceInfluenced(const Frame& f, const Vec3& p, float margin) const {
    if (f.virtual_bounds.empty())
        return false;
    const MaterialData& surface =
        materials_[static_cast<size_t>(objects_[*depth_object_].material)];
    if (surface.material.reflectance > 0)
        return true;
    for (const LightData* light : f.lights) {
        Vec3 dir;
        float length = kInf;
        float extra = margin;
        if (light->light.type == LightType::kDirectional) {
            dir = -light->direction_world;
        } else {
            const Vec3 delta = light->position_world - p;
            length = delta.norm();
            dir = length > 0 ? Vec3(delta / length) : Vec3::UnitZ();
            if (light->light.type == LightType::kSphere)
                extra += light->light.radius;
        }
        for (const SphereBound& b : f.virtual_bounds)
            if (distanceToSegment(b.centre, p, dir, length) <= b.radius + extra)
                return true;
    }
    return false;
}

// The camera's own measurement of a real surface point (Kán & Kaufmann fig. 4): reproject it
// into the image; nullopt when it falls outside or something real hides it from the camera.
std::optional<Vec3> EmbreeRenderer::cameraRadianceAt(const Frame& f, const Surface& s,
                                                     SampleState& st) const {
    const Vec3 to_camera = f.t_world_cam - s.p;
    const float dist = to_camera.norm();
    const Vec3 dir = to_camera / dist;
    const Vec3 origin =
        s.p + offsetFor(s.p) * (s.n_geometric.dot(dir) > 0 ? s.n_geometric : Vec3(-s.n_geometric));
    ++st.counters->shadow;
    logRay(st.log, RayLog::Kind::kShadow, scene_->ghosts(), scene_->ghosts(), origin, dir,
           dist * 0.999f);
    if (EmbreeScene::occluded(scene_->ghosts(), origin, dir, dist * 0.999f))
        return std::nullopt;
    return cameraPixelAt(f, s.p);
}

Pair EmbreeRenderer::trace(const Frame& f, const Vec3& origin, const Vec3& d, int depth, Mode mode,
                           SampleState& st) const {
    ++st.counters->secondary;
    const RTCScene scene = mode == Mode::kReal ? scene_->ghosts() : scene_->all();
    logRay(st.log, RayLog::Kind::kSecondary, scene, scene_->ghosts(), origin, d, kInf);
    const Hit hit = EmbreeScene::intersect(scene, origin, d, kInf);
    if (f.depth && options_.depth_secondary == DepthSecondaryRays::kScreenSpace) {
        // RT²AR Algorithm 2: the depth camera's surfaces, found in screen space, are real and
        // seen by the camera, so the camera pixel is their radiance in both scenes.
        // The walk starts a little away from the origin so that a ray leaving a surface the
        // depth camera also measured does not find that surface again.
        const Vec3 start = origin + kDepthStart_m * d;
        const Vec3 o_cam = (f.R_cam_world * start.cast<double>() + f.t_cam_world).cast<float>();
        const Vec3 d_cam = (f.R_cam_world * d.cast<double>()).cast<float>();
        const float t_max = (hit.valid ? hit.t : kFarDepth_m) - kDepthStart_m;
        const auto t =
            t_max > 0 ? traceDepthMap(*f.depth, o_cam, d_cam, t_max, options_.depth_thickness_m)
                      : std::nullopt;
        if (t)
            if (const auto c = cameraPixelAt(f, start + *t * d))
                return {*c, *c};
    }
    if (!hit.valid) {
        const Vec3 e = environment(f, d);
        return {e, e};
    }
    const Surface s = surfaceAt(hit, origin, d);
    if (s.object->role == ObjectRole::kVirtual) {
        Pair out;
        out.m = shade(f, s, hit, d, depth, Mode::kMixed, st).m;
        if (mode == Mode::kBoth)
            out.r = trace(f, origin, d, depth, Mode::kReal, st).r;
        return out;
    }
    if (mode != Mode::kMixed)
        return shade(f, s, hit, d, depth, mode, st);
    // A real surface reached through a virtual one: the camera saw its radiance; add only what
    // the virtual objects change there.
    const Pair p = shade(f, s, hit, d, depth, Mode::kBoth, st);
    const MaterialType type = s.material->material.type;
    if (type == MaterialType::kDiffuse || type == MaterialType::kPhong) {
        if (const auto measured = cameraRadianceAt(f, s, st)) {
            const Vec3 m = (*measured + p.m - p.r).cwiseMax(0.f);
            return {m, m};
        }
    }
    return {p.m, p.m};
}

// Conservative: can virtual objects change the shading of this real point seen along `d`? True
// for glass and reflective ghosts (when the only ghost is flat: where the mirrored ray passes a
// virtual bounding sphere), and where a bounding sphere meets the way to a light.
bool EmbreeRenderer::ghostInfluenced(const Frame& f, const Surface& s, const Vec3& d) const {
    if (f.virtual_bounds.empty())
        return false;
    const Material& mat = s.material->material;
    const bool lambert = mat.type == MaterialType::kDiffuse || mat.type == MaterialType::kPhong;
    if (mat.type == MaterialType::kGlass)
        return true;
    if (!lambert || mat.reflectance > 0) {
        // Off the only, flat, ghost a mirrored ray never meets a ghost again, so it changes
        // the pixel only if it passes a virtual bounding sphere (the ray starts offset).
        if (!f.lone_flat_ghost)
            return true;
        const Vec3 n = s.n_geometric.dot(d) < 0 ? s.n_shading : Vec3(-s.n_shading);
        const Vec3 r = optics::reflect(d, n).normalized();
        const float slack = 2 * offsetFor(s.p);
        for (const SphereBound& b : f.virtual_bounds)
            if (distanceToSegment(b.centre, s.p, r, kInf) <= b.radius + slack)
                return true;
        if (!lambert)
            return false;
    }
    if (!options_.shadows)
        return false;
    for (const LightData* light : f.lights) {
        Vec3 dir;
        float length = kInf;
        float extra = 0;
        if (light->light.type == LightType::kDirectional) {
            dir = -light->direction_world;
        } else {
            const Vec3 delta = light->position_world - s.p;
            length = delta.norm();
            dir = length > 0 ? Vec3(delta / length) : Vec3::UnitZ();
            if (light->light.type == LightType::kSphere)
                extra = light->light.radius;
        }
        // Shadow rays to a spherical light fan out from s.p to its radius at the light.
        for (const SphereBound& b : f.virtual_bounds)
            if (detail::nearTaperedSegment(b.centre, s.p, dir, length, b.radius, b.radius + extra))
                return true;
    }
    return false;
}

Status EmbreeRenderer::checkInputs(const RenderInputs& in) const {
    const auto bad = [](const std::string& what) {
        return Status(ErrorCode::kInvalidArgument, "render inputs: " + what);
    };
    MIXRAY_RETURN_IF_ERROR(in.camera.validate().withContext("render inputs: camera model"));
    const ImageDesc& c = in.camera_image.desc;
    if (c.format != PixelFormat::kRGB8)
        return bad("camera image must be rgb8, got " + std::string(toString(c.format)));
    if (c.width != in.camera.width || c.height != in.camera.height)
        return bad("camera image is " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                   ", the camera model " + std::to_string(in.camera.width) + "x" +
                   std::to_string(in.camera.height));
    if (in.camera_image.data == nullptr || c.stride_bytes < 3 * c.width ||
        in.camera_image.size_bytes <
            static_cast<size_t>(c.stride_bytes) * static_cast<size_t>(c.height - 1) +
                3 * static_cast<size_t>(c.width))
        return bad("camera image buffer is too small for its size");
    const ImageDesc& dd = in.depth_mm.desc;
    const calibration::DepthRegistration* reg = in.depth_registration;
    // The registration itself is validated once, when its Registrar is made (registeredDepth).
    if (reg) {
        if (!sameModel(reg->color, in.camera))
            return bad("the depth registration's colour camera is not the camera model");
    }
    if (in.depth_mm.data != nullptr || dd.width != 0 || dd.height != 0) {
        if (dd.format != PixelFormat::kDepth16)
            return bad("depth image must be depth16, got " + std::string(toString(dd.format)));
        if (reg && !reg->isIdentity()) {
            if (dd.width != reg->depth.width || dd.height != reg->depth.height)
                return bad("depth image is " + std::to_string(dd.width) + "x" +
                           std::to_string(dd.height) + ", the registration's depth camera " +
                           std::to_string(reg->depth.width) + "x" +
                           std::to_string(reg->depth.height));
        } else if (dd.width != c.width || dd.height != c.height) {
            return bad("depth image size differs from the camera image");
        }
        if (in.depth_mm.data == nullptr || dd.stride_bytes < 2 * dd.width ||
            in.depth_mm.size_bytes <
                static_cast<size_t>(dd.stride_bytes) * static_cast<size_t>(dd.height - 1) +
                    2 * static_cast<size_t>(dd.width))
            return bad("depth image buffer is too small for its size");
    }
    MIXRAY_RETURN_IF_ERROR(checkPose(in.T_world_cam, "render inputs: T_world_cam"));
    for (const auto& [name, T] : in.T_world_anchor)
        MIXRAY_RETURN_IF_ERROR(checkPose(T, "render inputs: T_world_anchor[" + name + "]"));
    return Status::ok();
}

void EmbreeRenderer::updateRayCache(const calibration::CameraModel& camera) {
    const int spp = options_.samples_per_pixel;
    if (!rays_.directions.empty() && sameModel(rays_.model, camera) && rays_.samples == spp &&
        rays_.seed == options_.seed)
        return;
    rays_ = {camera, spp, options_.seed, {}, {}, {}};
    const int n = static_cast<int>(std::lround(std::sqrt(spp)));
    const int w = camera.width;
    rays_.directions.resize(static_cast<size_t>(w) * camera.height * spp);
    rays_.centre_cos.resize(static_cast<size_t>(w) * camera.height);
    tbb::parallel_for(0, camera.height, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const size_t pixel = static_cast<size_t>(y) * w + x;
            const auto centre = camera.unproject(Eigen::Vector2d(x, y));
            rays_.centre_cos[pixel] = centre ? centre->z() : NAN;
            optics::Rng rng(hashIndex(options_.seed, pixel, 0x5eed));
            for (int k = 0; k < spp; ++k) {
                // Stratified jitter; one sample sits exactly on the pixel centre.
                double dx = 0, dy = 0;
                if (spp > 1) {
                    dx = ((k % n) + rng.uniform()) / n - 0.5;
                    dy = ((k / n) + rng.uniform()) / n - 0.5;
                }
                const auto dir = camera.unproject({x + dx, y + dy});
                rays_.directions[pixel * spp + k] =
                    dir ? Vec3(dir->cast<float>().normalized()) : Vec3::Constant(NAN);
            }
        }
    });
    rays_.cones = detail::tileCones(camera, rays_.directions, spp, options_.tile_size);
}

// What the screen footprint needs of this frame, and whether the lone-flat-ghost shortcut of
// ghostInfluenced() holds.
void EmbreeRenderer::prepareFootprint(Frame& f) const {
    int ghosts = 0;
    bool flat = false;
    for (const ObjectData& o : objects_)
        if (o.active && o.role == ObjectRole::kGhost) {
            ++ghosts;
            flat = o.shape == ShapeType::kPlane || o.shape == ShapeType::kDisk;
        }
    f.lone_flat_ghost = ghosts == 1 && flat;
    detail::FootprintScene& fp = f.footprint;
    fp.R_world_cam = f.R_world_cam;
    fp.t_world_cam = f.t_world_cam;
    for (const SphereBound& b : f.virtual_bounds)
        fp.virtual_bounds.push_back({b.centre, b.radius});
    if (options_.shadows)
        for (const LightData* light : f.lights)
            fp.lights.push_back(
                {light->light.type == LightType::kDirectional, light->position_world,
                 light->direction_world,
                 light->light.type == LightType::kSphere ? light->light.radius : 0.f});
    for (size_t i = 0; i < objects_.size(); ++i) {
        const ObjectData& o = objects_[i];
        if (!o.active || o.role != ObjectRole::kGhost || i == depth_object_)
            continue;
        detail::FootprintGhost g;
        g.bound = {o.R_world_object * o.bound_centre + o.t_world_object,
                   o.bound_radius * 1.001f + 1e-4f};
        g.flat = o.shape == ShapeType::kPlane || o.shape == ShapeType::kDisk;
        g.plane_point = o.t_world_object;
        g.plane_normal = o.R_world_object.col(2);
        const Material& mat = materials_[static_cast<size_t>(o.material)].material;
        const bool lambert = mat.type == MaterialType::kDiffuse || mat.type == MaterialType::kPhong;
        const bool reflects = !lambert || mat.reflectance > 0;
        g.always = mat.type == MaterialType::kGlass || (reflects && !f.lone_flat_ghost);
        g.receives = lambert;
        if (reflects && !g.always) {
            // ghostInfluenced()'s slack for hit points anywhere on the ghost.
            const float slack = 2e-4f * (1 + g.bound.centre.cwiseAbs().maxCoeff() + g.bound.radius);
            for (const SphereBound& b : f.virtual_bounds)
                fp.mirrored_bounds.push_back(
                    {b.centre - 2 * g.plane_normal.dot(b.centre - g.plane_point) * g.plane_normal,
                     b.radius + slack});
        }
        fp.ghosts.push_back(g);
    }
    if (f.depth_mesh)
        depthRegions(f, fp);
}

// The footprint of the depth mesh: finishPrimaryHit() traces it where depthSurfaceInfluenced()
// holds for the measured point, with a margin of 5 % of its distance; each tile's sphere holds
// every such point and its margin.
void EmbreeRenderer::depthRegions(const Frame& f, detail::FootprintScene& fp) const {
    const int w = f.inputs->camera.width, h = f.inputs->camera.height;
    const int spp = options_.samples_per_pixel, ts = options_.tile_size;
    const int tiles_x = (w + ts - 1) / ts, tiles_y = (h + ts - 1) / ts;
    fp.depth_reflects =
        materials_[static_cast<size_t>(objects_[*depth_object_].material)].material.reflectance > 0;
    fp.depth_regions.assign(static_cast<size_t>(tiles_x) * tiles_y, {Vec3::Zero(), -1.f});
    for (int ty = 0; ty < tiles_y; ++ty)
        for (int tx = 0; tx < tiles_x; ++tx) {
            Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);
            float margin = 0;
            for (int y = ty * ts; y < std::min(h, (ty + 1) * ts); ++y)
                for (int x = tx * ts; x < std::min(w, (tx + 1) * ts); ++x) {
                    const std::optional<float> dist = rays_.rayDistanceAt(*f.depth, x, y);
                    if (!dist)
                        continue;
                    for (int k = 0; k < spp; ++k) {
                        const Vec3& d =
                            rays_.directions[(static_cast<size_t>(y) * w + x) * spp + k];
                        if (!d.allFinite())
                            continue;
                        const Vec3 p = *dist * d;
                        lo = lo.cwiseMin(p);
                        hi = hi.cwiseMax(p);
                        margin = std::max(margin, 0.05f * *dist);
                    }
                }
            if (!(lo.array() <= hi.array()).all())
                continue;
            const Vec3 centre_cam = 0.5f * (lo + hi);
            fp.depth_regions[static_cast<size_t>(ty) * tiles_x + tx] = {
                rotate(f.R_world_cam, centre_cam) + f.t_world_cam,
                0.5f * (hi - lo).norm() + margin};
        }
}

// The primary hits of the tile [x0, x1) x [y0, y1) in 16-ray packets of 4x4-pixel blocks,
// logged in that order.
void EmbreeRenderer::primaryHits(const Frame& f, int x0, int y0, int x1, int y1,
                                 TileScratch& scratch, RayList* log) const {
    const int spp = options_.samples_per_pixel;
    const int w = f.inputs->camera.width, tw = x1 - x0;
    const size_t n = static_cast<size_t>(tw) * (y1 - y0) * spp;
    scratch.hits.assign(n, Hit{});
    scratch.dirs.resize(n);
    std::array<size_t, 16> lane_index;
    std::array<Vec3, 16> lane_dir;
    std::array<Hit, 16> lane_hit;
    // The depth mesh is resolved per pixel in finishPrimaryHit().
    const unsigned object_mask = f.depth_mesh ? detail::kObjectMask : detail::kAnyMask;
    int lanes = 0;
    const auto flush = [&] {
        if (lanes == 0)
            return;
        EmbreeScene::intersect16(scene_->all(), f.t_world_cam, lane_dir.data(), lanes,
                                 lane_hit.data(), object_mask);
        for (int i = 0; i < lanes; ++i) {
            scratch.hits[lane_index[i]] = lane_hit[i];
            logRay(log, RayLog::Kind::kPrimary, scene_->all(), scene_->ghosts(), f.t_world_cam,
                   lane_dir[i], kInf);
        }
        lanes = 0;
    };
    for (int by = y0; by < y1; by += 4)
        for (int bx = x0; bx < x1; bx += 4) {
            for (int y = by; y < std::min(y1, by + 4); ++y)
                for (int x = bx; x < std::min(x1, bx + 4); ++x)
                    for (int k = 0; k < spp; ++k) {
                        const size_t i = (static_cast<size_t>(y - y0) * tw + (x - x0)) * spp + k;
                        const Vec3& dir_cam =
                            rays_.directions[(static_cast<size_t>(y) * w + x) * spp + k];
                        if (!dir_cam.allFinite())
                            continue;
                        scratch.dirs[i] = rotate(f.R_world_cam, dir_cam);
                        lane_index[lanes] = i;
                        lane_dir[lanes] = scratch.dirs[i];
                        if (++lanes == 16)
                            flush();
                    }
            flush();
        }
}

bool sameRegistration(const calibration::DepthRegistration& a,
                      const calibration::DepthRegistration& b) {
    return sameModel(a.depth, b.depth) && sameModel(a.color, b.color) &&
           a.T_color_depth.matrix() == b.T_color_depth.matrix() &&
           a.correction.scale == b.correction.scale &&
           a.correction.offset_m == b.correction.offset_m &&
           a.correction.alpha0 == b.correction.alpha0 &&
           a.correction.alpha1 == b.correction.alpha1 &&
           a.correction.distortion == b.correction.distortion;
}

Result<ImageView> EmbreeRenderer::registeredDepth(const RenderInputs& in) {
    const calibration::DepthRegistration* reg = in.depth_registration;
    if (!reg || reg->isIdentity())
        return in.depth_mm;
    if (!registrar_ || !sameRegistration(registrar_->registration(), *reg)) {
        auto created = calibration::Registrar::create(*reg);
        if (!created)
            return created.status().withContext("render inputs: depth registration");
        registrar_.emplace(std::move(created).value());
    }
    const ImageDesc desc =
        ImageDesc::packed(PixelFormat::kDepth16, in.camera.width, in.camera.height);
    if (!(registered_depth_.desc() == desc))
        registered_depth_ = Image(desc);
    MIXRAY_RETURN_IF_ERROR(registrar_->registerDepth(in.depth_mm, registered_depth_.mutableView()));
    return registered_depth_.view();
}

Status EmbreeRenderer::prepareFrame(const RenderInputs& in, Frame& f) {
    f.inputs = &in;
    f.R_world_cam = in.T_world_cam.linear().cast<float>();
    f.t_world_cam = in.T_world_cam.translation().cast<float>();
    const Eigen::Isometry3d T_cam_world = in.T_world_cam.inverse();
    f.R_cam_world = T_cam_world.linear();
    f.t_cam_world = T_cam_world.translation();
    for (int i = 0; i < 256; ++i)
        f.srgb_lut[i] = optics::srgbToLinear(i / 255.f);

    const auto anchorPose = [&](const std::string& anchor) -> std::optional<Eigen::Isometry3d> {
        if (anchor == "world")
            return Eigen::Isometry3d::Identity();
        const auto it = in.T_world_anchor.find(anchor);
        if (it == in.T_world_anchor.end())
            return std::nullopt;
        return it->second;
    };
    if (in.depth_mm.data != nullptr) {
        auto depth = registeredDepth(in);
        if (!depth)
            return depth.status();
        f.depth = DepthView{*depth, in.camera};
    }
    updateDepthMesh(f);
    for (ObjectData& object : objects_) {
        if (object.depth_surface)
            continue;  // posed by updateDepthMesh
        const auto T_world_anchor = anchorPose(object.anchor);
        object.active = T_world_anchor.has_value();
        if (!object.active)
            continue;
        const Eigen::Isometry3f T = T_world_anchor->cast<float>() * object.T_anchor_object;
        object.R_world_object = T.linear();
        object.t_world_object = T.translation();
        if (object.role == ObjectRole::kVirtual)
            f.virtual_bounds.push_back(
                {object.R_world_object * object.bound_centre + object.t_world_object,
                 object.bound_radius * 1.001f + 1e-4f});
    }
    MIXRAY_RETURN_IF_ERROR(scene_->setPoses(objects_));
    for (LightData& light : lights_) {
        const auto T_world_anchor = anchorPose(light.light.anchor);
        light.active = T_world_anchor.has_value();
        if (!light.active)
            continue;
        const Eigen::Isometry3d T = *T_world_anchor;
        light.position_world = (T * light.light.position).cast<float>();
        light.direction_world = (T.linear() * light.light.direction).normalized().cast<float>();
        if (light.light.type == LightType::kEnvironment) {
            light.R_environment_world =
                (T * light.light.T_world_environment).inverse().linear().cast<float>();
            f.environments.push_back(&light);
        } else {
            f.lights.push_back(&light);
        }
    }
    updateRayCache(in.camera);
    return Status::ok();
}

// kMesh: the depth map as a mesh in the camera frame, instanced at T_world_cam.
void EmbreeRenderer::updateDepthMesh(Frame& f) {
    if (!depth_object_)
        return;
    ObjectData& object = objects_[*depth_object_];
    TriangleMesh& mesh = object.meshes.front();
    if (f.depth) {
        mesher_.build(*f.depth, DepthMeshOptions{}, mesh);
    } else {
        mesh.positions.clear();
        mesh.normals.clear();
        mesh.uvs.clear();
        mesh.triangles.clear();
    }
    scene_->setDepthMesh(mesh);
    object.active = !mesh.empty();
    object.R_world_object = f.R_world_cam;
    object.t_world_object = f.t_world_cam;
    f.depth_mesh = object.active;
}

// RT²AR's post-process: a 3x3 mean over penumbra pixels, each layer averaged only over
// neighbours that carry it (virtual radiance where M > 0, the difference where M < 1).
// Only dirty tiles hold penumbra pixels; new values are applied after all are computed, so every
// mean reads unfiltered neighbours.
void meanFilterPenumbra(int w, int h, int ts, PixelBuffers& b) {
    struct Filtered {
        size_t pixel;
        Vec3 virtual_radiance, difference;
    };
    std::vector<Filtered> filtered;
    const std::vector<Vec3>& vr = b.virtual_radiance;
    const std::vector<Vec3>& diff = b.difference;
    const int tiles_x = (w + ts - 1) / ts;
    for (size_t t = 0; t < b.tile_dirty.size(); ++t) {
        if (!b.tile_dirty[t])
            continue;
        const int x0 = static_cast<int>(t % tiles_x) * ts, y0 = static_cast<int>(t / tiles_x) * ts;
        for (int y = y0; y < std::min(h, y0 + ts); ++y)
            for (int x = x0; x < std::min(w, x0 + ts); ++x) {
                const size_t i = static_cast<size_t>(y) * w + x;
                if (!(b.flags[i] & kPenumbra))
                    continue;
                Vec3 sv = Vec3::Zero(), sd = Vec3::Zero();
                int nv = 0, nd = 0;
                for (int yy = std::max(0, y - 1); yy <= std::min(h - 1, y + 1); ++yy)
                    for (int xx = std::max(0, x - 1); xx <= std::min(w - 1, x + 1); ++xx) {
                        const size_t j = static_cast<size_t>(yy) * w + xx;
                        if (b.mask[j] > 0)
                            sv += vr[j], ++nv;
                        if (b.mask[j] < 1)
                            sd += diff[j], ++nd;
                    }
                Filtered out{i, vr[i], diff[i]};
                if (b.mask[i] > 0 && nv > 0)
                    out.virtual_radiance = sv / static_cast<float>(nv);
                if (b.mask[i] < 1 && nd > 0)
                    out.difference = sd / static_cast<float>(nd);
                filtered.push_back(out);
            }
    }
    for (const Filtered& p : filtered) {
        b.virtual_radiance[p.pixel] = p.virtual_radiance;
        b.difference[p.pixel] = p.difference;
    }
}

Status EmbreeRenderer::render(const RenderInputs& in, RenderLayers& out, RenderStats* stats) {
    const auto start = std::chrono::steady_clock::now();
    MIXRAY_RETURN_IF_ERROR(checkInputs(in));
    const auto cancelled = [] {
        return Status(ErrorCode::kCancelled,
                      "render: stopped on request before the frame was done");
    };
    if (in.stop.stop_requested())
        return cancelled();
    Frame f;
    MIXRAY_RETURN_IF_ERROR(prepareFrame(in, f));

    prepareFootprint(f);

    const int w = in.camera.width, h = in.camera.height;
    const size_t count = static_cast<size_t>(w) * h;
    const int spp = options_.samples_per_pixel;
    const bool keep = options_.keep_layers;
    const int ts = options_.tile_size;
    const int tiles_x = (w + ts - 1) / ts, tiles_y = (h + ts - 1) / ts;
    const int tiles = tiles_x * tiles_y;
    PixelBuffers& b = buffers_;
    if (b.width != w || b.height != h) {
        b.virtual_radiance.assign(count, Vec3::Zero());
        b.difference.assign(count, Vec3::Zero());
        b.mask.assign(count, 0.f);
        b.flags.assign(count, 0);
        b.tile_dirty.assign(static_cast<size_t>(tiles), 0);
        b.width = w;
        b.height = h;
    }
    if (keep) {
        b.mixed.assign(count, Vec3::Zero());
        b.real.assign(count, Vec3::Zero());
    }
    const auto clearTile = [&](int tile) {
        const int x0 = (tile % tiles_x) * ts, y0 = (tile / tiles_x) * ts;
        const int x1 = std::min(w, x0 + ts);
        for (int y = y0; y < std::min(h, y0 + ts); ++y) {
            const size_t i = static_cast<size_t>(y) * w + x0;
            const auto n = static_cast<std::ptrdiff_t>(x1 - x0);
            std::fill_n(b.virtual_radiance.begin() + static_cast<std::ptrdiff_t>(i), n,
                        Vec3::Zero());
            std::fill_n(b.difference.begin() + static_cast<std::ptrdiff_t>(i), n, Vec3::Zero());
            std::fill_n(b.mask.begin() + static_cast<std::ptrdiff_t>(i), n, 0.f);
            std::fill_n(b.flags.begin() + static_cast<std::ptrdiff_t>(i), n, uint8_t{0});
        }
        b.tile_dirty[static_cast<size_t>(tile)] = 0;
    };
    const bool use_mask = options_.screen_footprint && options_.only_virtual_footprint && !keep;

    std::atomic<uint64_t> traced{0}, primary{0}, secondary{0}, shadow{0};
    std::vector<RayList> tile_logs(in.ray_log != nullptr ? static_cast<size_t>(tiles) : 0);
    // Set by the first tile that sees the stop request; the tiles after it return at once. A
    // skipped tile keeps its last frame's pixels and dirty flag, so the next frame clears it.
    std::atomic<bool> stopped{false};
    const auto renderTile = [&](int tile) {
        if (stopped.load(std::memory_order_relaxed) || in.stop.stop_requested()) {
            stopped.store(true, std::memory_order_relaxed);
            return;
        }
        if (b.tile_dirty[static_cast<size_t>(tile)])
            clearTile(tile);
        if (use_mask && !tile_mask_[static_cast<size_t>(tile)])
            return;
        RayList* log = tile_logs.empty() ? nullptr : &tile_logs[static_cast<size_t>(tile)];
        const int x0 = (tile % tiles_x) * ts, y0 = (tile / tiles_x) * ts;
        const int x1 = std::min(w, x0 + ts), y1 = std::min(h, y0 + ts);
        TileScratch& scratch =
            scratch_[static_cast<size_t>(tbb::this_task_arena::current_thread_index())];
        scratch.surfaces.resize(static_cast<size_t>(spp));
        scratch.have_surface.resize(static_cast<size_t>(spp));
        primaryHits(f, x0, y0, x1, y1, scratch, log);
        Counters counters;
        uint64_t tile_traced = 0, tile_primary = 0;
        for (int y = y0; y < y1; ++y)
            for (int x = x0; x < x1; ++x) {
                const size_t pixel = static_cast<size_t>(y) * w + x;
                Hit* hits = scratch.hits.data() +
                            (static_cast<size_t>(y - y0) * (x1 - x0) + (x - x0)) * spp;
                const Vec3* dirs = scratch.dirs.data() + (hits - scratch.hits.data());
                const std::optional<float> depth_limit =
                    f.depth ? rays_.rayDistanceAt(*f.depth, x, y) : std::nullopt;
                // Whether virtual content can touch this pixel.
                bool influenced = false;
                std::fill(scratch.have_surface.begin(), scratch.have_surface.end(), 0);
                for (int k = 0; k < spp; ++k) {
                    if (!rays_.directions[pixel * spp + k].allFinite())
                        continue;
                    ++tile_primary;
                    hits[k] = finishPrimaryHit(f, hits[k], dirs[k], depth_limit);
                    if (!hits[k].valid || influenced)
                        continue;
                    if (objects_[hits[k].object].role == ObjectRole::kVirtual) {
                        influenced = true;
                        continue;
                    }
                    const Surface& s = scratch.surfaces[static_cast<size_t>(k)] =
                        surfaceAt(hits[k], f.t_world_cam, dirs[k]);
                    scratch.have_surface[static_cast<size_t>(k)] = 1;
                    influenced = ghostInfluenced(f, s, dirs[k]);
                }
                if (!influenced && !keep && options_.only_virtual_footprint)
                    continue;
                // Shade.
                ++tile_traced;
                int n_virtual = 0;
                Vec3 vsum = Vec3::Zero(), dsum = Vec3::Zero(), msum = Vec3::Zero(),
                     rsum = Vec3::Zero();
                bool penumbra = false;
                for (int k = 0; k < spp; ++k) {
                    SampleState st{optics::Rng(hashIndex(options_.seed, pixel, k + 1)), &counters,
                                   log};
                    Pair p;
                    bool is_virtual = false;
                    if (!hits[k].valid) {
                        if (rays_.directions[pixel * spp + k].allFinite())
                            p.m = p.r = environment(f, dirs[k]);
                    } else {
                        const Surface s = scratch.have_surface[static_cast<size_t>(k)]
                                              ? scratch.surfaces[static_cast<size_t>(k)]
                                              : surfaceAt(hits[k], f.t_world_cam, dirs[k]);
                        is_virtual = s.object->role == ObjectRole::kVirtual;
                        if (is_virtual) {
                            p.m = shade(f, s, hits[k], dirs[k], 0, Mode::kMixed, st).m;
                            if (keep)
                                p.r = trace(f, f.t_world_cam, dirs[k], 0, Mode::kReal, st).r;
                        } else {
                            p = shade(f, s, hits[k], dirs[k], 0, Mode::kBoth, st);
                        }
                    }
                    penumbra |= st.penumbra;
                    if (is_virtual) {
                        ++n_virtual;
                        vsum += p.m;
                    } else {
                        dsum += p.m - p.r;
                    }
                    msum += p.m;
                    rsum += p.r;
                }
                if (n_virtual > 0)
                    b.virtual_radiance[pixel] = vsum / static_cast<float>(n_virtual);
                if (n_virtual < spp)
                    b.difference[pixel] = dsum / static_cast<float>(spp - n_virtual);
                b.mask[pixel] = static_cast<float>(n_virtual) / static_cast<float>(spp);
                b.flags[pixel] = kTraced | ((penumbra && influenced) ? kPenumbra : 0);
                b.tile_dirty[static_cast<size_t>(tile)] = 1;
                if (keep) {
                    b.mixed[pixel] = msum / static_cast<float>(spp);
                    b.real[pixel] = rsum / static_cast<float>(spp);
                }
            }
        traced += tile_traced;
        primary += tile_primary;
        secondary += counters.secondary;
        shadow += counters.shadow;
    };

    // Composite I_f = M·I_m + (1 − M)·(I_c + I_m − I_r); clean tiles are the camera image.
    MutableImageView dst;  // out.composite's, once every tile is done
    const auto compositeRow = [&](int y) {
        const uint8_t* src_row = in.camera_image.row<uint8_t>(y);
        uint8_t* dst_row = dst.row<uint8_t>(y);
        const int tile_row = (y / ts) * tiles_x;
        for (int tx = 0; tx < tiles_x; ++tx) {
            const int x0 = tx * ts, x1 = std::min(w, x0 + ts);
            if (!b.tile_dirty[static_cast<size_t>(tile_row + tx)]) {
                std::memcpy(dst_row + 3 * x0, src_row + 3 * x0, 3 * static_cast<size_t>(x1 - x0));
                continue;
            }
            for (int x = x0; x < x1; ++x) {
                const size_t i = static_cast<size_t>(y) * w + x;
                const uint8_t* c = src_row + 3 * x;
                uint8_t* o = dst_row + 3 * x;
                const float mask = b.mask[i];
                if (mask == 0 && b.difference[i] == Vec3::Zero()) {
                    o[0] = c[0], o[1] = c[1], o[2] = c[2];
                    continue;
                }
                for (int ch = 0; ch < 3; ++ch) {
                    const float real = f.srgb_lut[c[ch]] + b.difference[i][ch];
                    o[ch] =
                        optics::encodeSrgb8(mask * b.virtual_radiance[i][ch] + (1 - mask) * real);
                }
            }
        }
    };

    tbb::task_arena arena(options_.threads > 0 ? options_.threads : tbb::task_arena::automatic);
    arena.initialize();
    if (scratch_.size() < static_cast<size_t>(arena.max_concurrency()))
        scratch_.resize(static_cast<size_t>(arena.max_concurrency()));
    arena.execute([&] {
        if (use_mask)
            detail::footprintMask(f.footprint, rays_.cones, rays_.directions, w, h, spp, ts,
                                  tile_mask_);
        tbb::parallel_for(tbb::blocked_range<int>(0, tiles, 1),
                          [&](const tbb::blocked_range<int>& r) {
                              for (int t = r.begin(); t < r.end(); ++t)
                                  renderTile(t);
                          });
        if (stopped)
            return;
        if (!(out.composite.desc() == ImageDesc::packed(PixelFormat::kRGB8, w, h)))
            out.composite = Image(ImageDesc::packed(PixelFormat::kRGB8, w, h));
        dst = out.composite.mutableView();
        if (options_.soft_shadows == SoftShadowMethod::kAdaptive && options_.shadow_mean_filter)
            meanFilterPenumbra(w, h, ts, b);
        tbb::parallel_for(tbb::blocked_range<int>(0, h, 8), [&](const tbb::blocked_range<int>& r) {
            for (int y = r.begin(); y < r.end(); ++y)
                compositeRow(y);
        });
    });
    if (stopped)
        return cancelled();
    if (in.ray_log != nullptr) {
        in.ray_log->rays.clear();
        for (const RayList& l : tile_logs)
            in.ray_log->rays.insert(in.ray_log->rays.end(), l.begin(), l.end());
    }
    if (keep) {
        const auto toImage = [&](const std::vector<Vec3>& src, FloatImage& img) {
            img = FloatImage{w, h, 3, std::vector<float>(count * 3)};
            for (size_t i = 0; i < count; ++i)
                for (int ch = 0; ch < 3; ++ch)
                    img.pixels[3 * i + ch] = src[i][ch];
        };
        toImage(b.mixed, out.mixed);
        toImage(b.real, out.real_only);
        out.mask = FloatImage{w, h, 1, b.mask};
    } else {
        out.mixed = out.real_only = out.mask = FloatImage{};
    }
    if (stats != nullptr) {
        stats->pixels_traced = traced;
        stats->primary_rays = primary;
        stats->secondary_rays = secondary;
        stats->shadow_rays = shadow;
        stats->seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    return Status::ok();
}

std::filesystem::path resolve(const SceneDescription& scene, const std::filesystem::path& p) {
    if (p.empty() || p.is_absolute() || scene.source_path.empty())
        return p;
    return scene.source_path.parent_path() / p;
}

Result<Texture> loadTexture(const SceneDescription& scene, const std::filesystem::path& path,
                            const std::string& what) {
    auto texture = Texture::load(resolve(scene, path));
    if (!texture)
        return texture.status().withContext(what);
    return texture;
}

void boundMeshes(ObjectData& object) {
    Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);
    for (const TriangleMesh& mesh : object.meshes)
        for (const Vec3& p : mesh.positions) {
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
    object.bound_centre = 0.5f * (lo + hi);
    object.bound_radius = 0;
    for (const TriangleMesh& mesh : object.meshes)
        for (const Vec3& p : mesh.positions)
            object.bound_radius = std::max(object.bound_radius, (p - object.bound_centre).norm());
}

// The lights' render data: environment maps loaded (files resolved against the scene file's
// folder) or taken from memory.
Result<std::vector<LightData>> loadLights(const std::filesystem::path& scene_source,
                                          const std::vector<Light>& scene_lights) {
    std::vector<LightData> lights;
    for (const Light& light : scene_lights) {
        LightData data;
        data.light = light;
        if (light.type == LightType::kEnvironment) {
            if (light.environment_image) {
                const FloatImage& image = *light.environment_image;
                std::vector<Rgb> texels(static_cast<size_t>(image.width) * image.height);
                for (int y = 0; y < image.height; ++y)
                    for (int x = 0; x < image.width; ++x) {
                        const float* p = image.at(x, y);
                        texels[static_cast<size_t>(y) * image.width + x] = Rgb(p[0], p[1], p[2]);
                    }
                data.environment = EnvironmentMap(Texture(image.width, image.height, texels));
                data.light.environment_image.reset();  // the texture holds it now
            } else {
                SceneDescription where;
                where.source_path = scene_source;
                auto map = EnvironmentMap::load(resolve(where, light.environment));
                if (!map)
                    return map.status().withContext("light '" + light.name + "' (" +
                                                    light.where.toString() + ")");
                data.environment = std::move(map).value();
            }
            if (light.mirror_lower_hemisphere)
                data.environment.mirrorUpperIntoLower();
        }
        lights.push_back(std::move(data));
    }
    return lights;
}

}  // namespace

Result<std::unique_ptr<Renderer>> Renderer::create(const SceneDescription& scene,
                                                   const RenderOptions& options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    MIXRAY_RETURN_IF_ERROR(scene.validate());

    std::vector<MaterialData> materials;
    std::map<std::string, int> material_index;
    for (const auto& [name, material] : scene.materials) {
        MaterialData data{material, {}, {}};
        const std::string where = "material '" + name + "' (" + material.where.toString() + ")";
        if (!material.albedo_texture.empty()) {
            auto texture = loadTexture(scene, material.albedo_texture, where);
            if (!texture)
                return texture.status();
            data.albedo_texture = std::move(texture).value();
        }
        if (!material.reflectance_map.empty()) {
            auto texture = loadTexture(scene, material.reflectance_map, where);
            if (!texture)
                return texture.status();
            data.reflectance_map = std::move(texture).value();
        }
        material_index[name] = static_cast<int>(materials.size());
        materials.push_back(std::move(data));
    }

    std::vector<ObjectData> objects;
    for (const SceneObject& obj : scene.objects) {
        const std::string where = "object '" + obj.name + "' (" + obj.where.toString() + ")";
        ObjectData data;
        data.name = obj.name;
        data.role = obj.role;
        data.shape = obj.shape.type;
        data.anchor = obj.anchor;
        data.T_anchor_object = obj.T_anchor_object.cast<float>();
        std::optional<MeshMaterialHint> hint;
        if (obj.shape.type == ShapeType::kSphere) {
            data.sphere_radius = obj.shape.radius;
            data.bound_radius = obj.shape.radius;
        } else if (obj.shape.type == ShapeType::kMesh && obj.shape.mesh_data != nullptr) {
            data.meshes.push_back(*obj.shape.mesh_data);
            for (Vec3& p : data.meshes.back().positions)
                p *= obj.shape.scale;
            boundMeshes(data);
        } else if (obj.shape.type == ShapeType::kMesh) {
            auto loaded = loadMeshFile(resolve(scene, obj.shape.mesh), obj.shape.scale);
            if (!loaded)
                return loaded.status().withContext(where);
            for (LoadedMesh& mesh : loaded.value()) {
                if (!hint)
                    hint = mesh.material;
                data.meshes.push_back(std::move(mesh.mesh));
            }
            boundMeshes(data);
        } else {
            data.meshes.push_back(makeShapeMesh(obj.shape));
            boundMeshes(data);
        }
        if (obj.shape.type != ShapeType::kSphere &&
            std::all_of(data.meshes.begin(), data.meshes.end(),
                        [](const TriangleMesh& m) { return m.empty(); }))
            return Status(ErrorCode::kCorruptData, where + ": shape has no triangles");
        if (const auto it = material_index.find(obj.material); it != material_index.end()) {
            data.material = it->second;
        } else if (obj.material.empty()) {
            // No scene material: what the mesh file says, else the default diffuse grey.
            MaterialData fallback;
            if (hint) {
                fallback.material.albedo = hint->base_color;
                if (!hint->base_color_texture.empty()) {
                    auto texture = loadTexture(scene, hint->base_color_texture, where);
                    if (!texture)
                        return texture.status();
                    fallback.albedo_texture = std::move(texture).value();
                }
            }
            data.material = static_cast<int>(materials.size());
            materials.push_back(std::move(fallback));
        } else {
            return Status(ErrorCode::kCorruptData,
                          where + ": unknown material '" + obj.material + "'");
        }
        objects.push_back(std::move(data));
    }

    auto lights = loadLights(scene.source_path, scene.lights);
    if (!lights)
        return lights.status();

    std::optional<size_t> depth_object;
    if (options.depth_secondary == DepthSecondaryRays::kMesh) {
        MaterialData surface;
        surface.material.name = "depth surface";
        surface.material.reflectance = scene.depth_surface.reflectance;
        surface.albedo_from_camera = true;
        ObjectData data;
        data.name = "depth surface";
        data.role = ObjectRole::kGhost;
        data.shape = ShapeType::kMesh;
        data.depth_surface = true;
        data.meshes.emplace_back();
        data.material = static_cast<int>(materials.size());
        materials.push_back(std::move(surface));
        depth_object = objects.size();
        objects.push_back(std::move(data));
    }

    auto renderer =
        std::make_unique<EmbreeRenderer>(options, std::move(materials), std::move(objects),
                                         std::move(lights).value(), scene.source_path);
    renderer->setDepthObject(depth_object);
    MIXRAY_RETURN_IF_ERROR(renderer->init());
    return std::unique_ptr<Renderer>(std::move(renderer));
}

}  // namespace mixray::render
