// The differential integrator (integrator.h).
#include "integrator.h"

#include <array>
#include <cmath>
#include <utility>

#include "caustics.h"
#include "influence_batch.h"
#include "shadow_map.h"
#include "surface_batch.h"

namespace mixray::render::detail {
namespace {

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

}  // namespace

Surface DifferentialIntegrator::surfaceAt(const Hit& hit, const Vec3& origin, const Vec3& d) const {
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
    const TriangleMesh& mesh = (*object.meshes)[hit.mesh];
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

bool DifferentialIntegrator::outgrowsCache(const std::vector<ObjectData>& objects,
                                           std::optional<size_t> depth_object) {
    if (depth_object)
        return true;
    // Half of a core's L2 on the machines measured (docs/benchmarks.md): the teapot's 154 KB
    // stays cached, the 1.1M-triangle dragon's 40 MB does not.
    constexpr size_t kCachedBytes = 256 * 1024;
    for (const ObjectData& object : objects) {
        size_t bytes = 0;
        for (const TriangleMesh& mesh : *object.meshes)
            bytes += mesh.triangles.size() * sizeof(mesh.triangles[0]) +
                     mesh.positions.size() * sizeof(Vec3) + mesh.normals.size() * sizeof(Vec3);
        if (bytes > kCachedBytes)
            return true;
    }
    return false;
}

void DifferentialIntegrator::surfacesAt(const Hit* hits, const Vec3* origins, const Vec3* dirs,
                                        size_t count, Surface* out) const {
    SurfaceScratch scratch;
    surfacesAt(hits, origins, dirs, count, out, scratch);
}

void DifferentialIntegrator::surfacesAt(const Hit* hits, const Vec3* origins, const Vec3* dirs,
                                        size_t count, Surface* out, SurfaceScratch& scratch) const {
    if (prefetch_meshes_)
        prefetchMeshData(hits, count);
    // Hits on triangle meshes go to meshSurfaces() one mesh of one object at a time, in SIMD
    // lanes; a tile shows a few. Exact spheres, and meshes past the first kMaxGroups, one by one.
    struct Group {
        unsigned object = 0, mesh = 0;
        uint32_t count = 0, start = 0;
    };
    constexpr uint8_t kMaxGroups = 16, kNoGroup = 0xFF;
    std::array<Group, kMaxGroups> groups;
    uint8_t n_groups = 0, last = kNoGroup;
    scratch.group.resize(count);
    for (size_t i = 0; i < count; ++i) {
        uint8_t& group = scratch.group[i];
        group = kNoGroup;
        const Hit& hit = hits[i];
        if (!hit.valid)
            continue;
        if (objects_[hit.object].shape == ShapeType::kSphere) {
            out[i] = surfaceAt(hit, origins[i], dirs[i]);
            continue;
        }
        const auto same = [&](uint8_t g) {
            return groups[g].object == hit.object && groups[g].mesh == hit.mesh;
        };
        if (last == kNoGroup || !same(last)) {
            last = kNoGroup;
            for (uint8_t g = 0; g < n_groups; ++g)
                if (same(g))
                    last = g;
            if (last == kNoGroup && n_groups < kMaxGroups) {
                last = n_groups++;
                groups[last] = {hit.object, hit.mesh};
            }
        }
        if (last == kNoGroup) {
            out[i] = surfaceAt(hit, origins[i], dirs[i]);
            continue;
        }
        group = last;
        ++groups[last].count;
    }
    uint32_t start = 0;
    for (uint8_t g = 0; g < n_groups; ++g) {
        groups[g].start = start;
        start += groups[g].count;
        groups[g].count = 0;
    }
    scratch.order.resize(start);
    for (size_t i = 0; i < count; ++i)
        if (const uint8_t g = scratch.group[i]; g != kNoGroup)
            scratch.order[groups[g].start + groups[g].count++] = static_cast<uint32_t>(i);
    for (uint8_t g = 0; g < n_groups; ++g) {
        const ObjectData& object = objects_[groups[g].object];
        meshSurfaces({&object, &materials_[static_cast<size_t>(object.material)],
                      &(*object.meshes)[groups[g].mesh], hits, origins, dirs,
                      scratch.order.data() + groups[g].start, groups[g].count},
                     out);
    }
}

void DifferentialIntegrator::prefetchMeshData(const Hit* hits, size_t count) const {
    const auto meshOf = [&](const Hit& hit) -> const TriangleMesh* {
        const ObjectData& object = objects_[hit.object];
        return hit.valid && object.shape != ShapeType::kSphere ? &(*object.meshes)[hit.mesh]
                                                               : nullptr;
    };
    // First the triangles' vertex indices, then the vertices they name: on a 1.1M-triangle mesh
    // each is a miss to memory, which the computing loop would wait for hit by hit.
    for (size_t i = 0; i < count; ++i)
        if (const TriangleMesh* mesh = meshOf(hits[i]))
            __builtin_prefetch(&mesh->triangles[hits[i].prim]);
    for (size_t i = 0; i < count; ++i) {
        const TriangleMesh* mesh = meshOf(hits[i]);
        if (mesh == nullptr)
            continue;
        const bool normals = mesh->normals.size() == mesh->positions.size();
        for (const uint32_t v : mesh->triangles[hits[i].prim]) {
            __builtin_prefetch(&mesh->positions[v]);
            if (normals)
                __builtin_prefetch(&mesh->normals[v]);
        }
    }
}

Vec3 DifferentialIntegrator::environment(const Frame& f, const Vec3& d) const {
    Vec3 sum = Vec3::Zero();
    for (const LightData* light : f.environments)
        sum += light->light.environment_scale *
               light->environment.radiance((light->R_environment_world * d).normalized());
    return sum;
}

LightPath DifferentialIntegrator::lightPath(const LightData& light, const Surface& s, const Vec3& n,
                                            const Vec3& d, const Vec3& diffuse) {
    LightPath path;
    Vec3 irradiance;
    if (light.light.type == LightType::kDirectional) {
        path.wi = -light.direction_world;
        irradiance = light.light.intensity;
    } else {
        const Vec3 delta = light.position_world - s.p;
        path.dist = delta.norm();
        if (path.dist <= 0)
            return path;
        path.wi = delta / path.dist;
        irradiance = light.light.intensity / (path.dist * path.dist);
    }
    const float cos_theta = n.dot(path.wi);
    if (cos_theta <= 0)
        return path;
    const Material& mat = s.material->material;
    Vec3 brdf = diffuse;
    if (mat.type == MaterialType::kPhong) {
        const Vec3 h = (path.wi - d).normalized();
        const float lobe = std::pow(std::max(0.f, n.dot(h)), mat.shininess);
        brdf += mat.specular * ((mat.shininess + 8) / (8 * optics::kPi)) * lobe;
    }
    path.unshadowed = brdf.cwiseProduct(irradiance) * cos_theta;
    path.lit = true;
    return path;
}

// How much of `light` the point sees, from its shadow map where it has one that covers the point,
// else by shadow rays; real surfaces the depth map holds shadow virtual ones (in kMesh they are
// in the BVH). `traced`, when given, is what the rays found (a hard test traced elsewhere).
Pair DifferentialIntegrator::lightVisibility(const Frame& f, const LightData& light,
                                             const Surface& s, const Vec3& origin,
                                             const Vec3& n_facing, const LightPath& path, Mode mode,
                                             SampleState& st, bool* penumbra,
                                             const Pair* traced) const {
    std::optional<Pair> from_map;
    if (light.shadow_map && options_.shadows)
        from_map = light.shadow_map->visibility(s.p, n_facing, mode);
    Pair visible = from_map ? *from_map
                   : traced
                       ? *traced
                       : shadows_.visibility(light, origin, path.wi, path.dist, mode, st, penumbra);
    if (s.object->role == ObjectRole::kVirtual && visible.m.maxCoeff() > 0 &&
        shadows_.depthMapOccludes(f, origin, path.wi, path.dist)) {
        visible = {};
    }
    return visible;
}

void DifferentialIntegrator::addLight(const LightPath& path, const Pair& visible, bool penumbra,
                                      Pair& out, PrimaryDirect* record) {
    out.m += path.unshadowed.cwiseProduct(visible.m);
    out.r += path.unshadowed.cwiseProduct(visible.r);
    if (record != nullptr) {
        // Shadow rays give every channel one visible fraction.
        const float weight = path.unshadowed.sum();
        record->unshadowed += weight;
        record->visible_m += weight * visible.m.x();
        record->visible_r += weight * visible.r.x();
        record->dm_dvisible_m += path.unshadowed;
        record->dr_dvisible_r += path.unshadowed;
        record->penumbra |= penumbra;
    }
}

void DifferentialIntegrator::addCaustics(const Frame& f, const Surface& s, const Vec3& n_facing,
                                         const Vec3& diffuse, Mode mode, Pair& out) {
    // Caustic irradiance from the photon maps, reflected diffusely.
    const Pair e = f.caustics->irradiance(s.p, n_facing, mode);
    out.m += diffuse.cwiseProduct(e.m);
    out.r += diffuse.cwiseProduct(e.r);
}

// Direct light from point, spherical and directional lights: Lambert plus, for Phong, a
// normalised Blinn-Phong lobe; each light's shadow rays in the scenes the mode asks for.
Pair DifferentialIntegrator::direct(const Frame& f, const Surface& s, const Vec3& n, const Vec3& d,
                                    const Vec3& albedo, Mode mode, SampleState& st,
                                    PrimaryDirect* record) const {
    Pair out;
    const Vec3 n_facing = facingNormal(s, d);
    const Vec3 origin = s.p + offsetFor(s.p) * n_facing;
    const Vec3 diffuse = albedo / optics::kPi;
    for (const LightData* light : f.lights) {
        const LightPath path = lightPath(*light, s, n, d, diffuse);
        if (!path.lit)
            continue;
        bool penumbra = false;
        const Pair visible = lightVisibility(f, *light, s, origin, n_facing, path, mode, st,
                                             record != nullptr ? &penumbra : nullptr);
        addLight(path, visible, penumbra, out, record);
    }
    if (f.caustics)
        addCaustics(f, s, n_facing, diffuse, mode, out);
    return out;
}

void DifferentialIntegrator::directBatch(const Frame& f, DirectBatch& batch, Counters& counters,
                                         RayList* log) const {
    const size_t count = batch.count;
    batch.paths.resize(count);
    batch.traced.resize(count);
    batch.queries.resize(count);
    batch.answers.resize(count);
    // The vectors' data as plain pointers: the byte array's stores may alias anything.
    DirectBatch::Entry* const entries = batch.entries.data();
    LightPath* const paths = batch.paths.data();
    uint8_t* const traced = batch.traced.data();
    HardShadowQuery* const queries = batch.queries.data();
    Pair* const answers = batch.answers.data();
    for (size_t i = 0; i < count; ++i) {
        DirectBatch::Entry& e = entries[i];
        e.out = {};
        e.n_facing = facingNormal(*e.s, e.d);
        e.origin = e.s->p + offsetFor(e.s->p) * e.n_facing;
        e.diffuse = e.albedo / optics::kPi;
    }
    for (const LightData* light : f.lights) {
        // Each point's way to the light; then what blocks it: hard tests of all points traced
        // together as packets, the rest (shadow maps, soft shadows) point by point.
        const bool hard_rays = options_.shadows && !light->shadow_map;
        size_t n_queries = 0;
        for (size_t i = 0; i < count; ++i) {
            const DirectBatch::Entry& e = entries[i];
            const LightPath& path = paths[i] = lightPath(*light, *e.s, e.n, e.d, e.diffuse);
            traced[i] = path.lit && hard_rays && shadows_.hard(*light, path.dist);
            if (traced[i])
                queries[n_queries++] = shadows_.hardQuery(e.origin, path.wi, path.dist, e.mode);
        }
        shadows_.hardVisibilities(queries, n_queries, counters, log, answers);
        for (size_t i = 0, q = 0; i < count; ++i) {
            const LightPath& path = paths[i];
            if (!path.lit)
                continue;
            DirectBatch::Entry& e = entries[i];
            bool penumbra = false;
            const Pair visible = lightVisibility(
                f, *light, *e.s, e.origin, e.n_facing, path, e.mode, *e.st,
                e.record != nullptr ? &penumbra : nullptr, traced[i] ? &answers[q++] : nullptr);
            addLight(path, visible, penumbra, e.out, e.record);
        }
    }
    if (f.caustics)
        for (size_t i = 0; i < count; ++i) {
            DirectBatch::Entry& e = entries[i];
            addCaustics(f, *e.s, e.n_facing, e.diffuse, e.mode, e.out);
        }
}

Vec3 DifferentialIntegrator::albedoAt(const Surface& s) {
    Vec3 albedo = s.material->material.albedo;
    if (!s.material->albedo_texture.empty())
        albedo = albedo.cwiseProduct(s.material->albedo_texture.sample(s.uv));
    return albedo;
}

Pair DifferentialIntegrator::withReflection(const Frame& f, const Surface& s, const Vec3& d,
                                            int depth, Mode mode, SampleState& st,
                                            const Pair& local, PrimaryDirect* record) const {
    const float rho = std::clamp(s.material->material.reflectance * reflectanceMapAt(s), 0.f, 1.f);
    if (rho <= 0)
        return local;
    if (record != nullptr) {
        record->dm_dvisible_m *= 1 - rho;
        record->dm_dvisible_r *= 1 - rho;
        record->dr_dvisible_r *= 1 - rho;
    }
    return sum(scaled(local, Vec3::Constant(1 - rho)),
               scaled(reflected(f, s, d, depth, mode, st), Vec3::Constant(rho)));
}

Vec3 DifferentialIntegrator::cutPath(const Frame& f, const Vec3& p, const Vec3& d) const {
    if (!f.environments.empty())
        return environment(f, d);
    // No environment: a grey world lit by the direct lights, each as a hemisphere sky around
    // its direction, so the surface a ray along `d` would meet (facing back along it) gets
    // (1 - d·wi) / 2 of the light's irradiance: full looking away from the light, none
    // looking into it.
    Vec3 irradiance = Vec3::Zero();
    for (const LightData* light : f.lights) {
        Vec3 wi = -light->direction_world;
        Vec3 e = light->light.intensity;
        if (light->light.type != LightType::kDirectional) {
            const Vec3 delta = light->position_world - p;
            const float dist2 = delta.squaredNorm();
            if (!(dist2 > 0))
                continue;
            wi = delta / std::sqrt(dist2);
            e /= dist2;
        }
        irradiance += e * (0.5f * (1 - d.dot(wi)));
    }
    return irradiance * (kCutWorldAlbedo / optics::kPi);
}

Pair DifferentialIntegrator::onward(const Frame& f, const Vec3& origin, const Vec3& d, int depth,
                                    Mode mode, SampleState& st) const {
    if (depth < options_.max_depth)
        return trace(f, origin, d, depth + 1, mode, st);
    if (!options_.cut_paths_see_environment)
        return {};
    const Vec3 e = cutPath(f, origin, d);
    return {e, e};
}

Pair DifferentialIntegrator::reflected(const Frame& f, const Surface& s, const Vec3& d, int depth,
                                       Mode mode, SampleState& st) const {
    const HitSide side = sideOf(s, d);
    return onward(f, side.above, optics::reflect(d, side.n).normalized(), depth, mode, st);
}

Pair DifferentialIntegrator::shade(const Frame& f, const Surface& s, const Hit& hit, const Vec3& d,
                                   int depth, Mode mode, SampleState& st) const {
    // Only this call's own direct light is the primary hit's: not what its bounces see.
    PrimaryDirect* const record = std::exchange(st.primary_direct, nullptr);
    const Material& mat = s.material->material;
    const HitSide side = sideOf(s, d);
    const bool entering = side.entering;
    const Vec3& n = side.n;
    const Vec3 below = s.p - offsetFor(s.p) * side.n_geo;
    const auto reflectedRay = [&]() { return reflected(f, s, d, depth, mode, st); };
    const float map = reflectanceMapAt(s);

    switch (mat.type) {
        case MaterialType::kDiffuse:
        case MaterialType::kPhong: {
            const Pair local = s.material->albedo_from_camera
                                   ? cameraAlbedoDirect(f, s, n, d, st, record)
                                   : direct(f, s, n, d, albedoAt(s), mode, st, record);
            return withReflection(f, s, d, depth, mode, st, local, record);
        }
        case MaterialType::kMirror: {
            const float rho =
                std::clamp((mat.reflectance > 0 ? mat.reflectance : 1.f) * map, 0.f, 1.f);
            return scaled(reflectedRay(), Vec3::Constant(rho));
        }
        case MaterialType::kMetal: {
            const float cos_i = std::clamp(-d.dot(n), 0.f, 1.f);
            Vec3 fresnel;
            for (int c = 0; c < 3; ++c)
                fresnel[c] = optics::schlick(mat.f0[c], cos_i);
            return scaled(reflectedRay(), fresnel);
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
            if (reflectance.maxCoeff() > 0)
                result = scaled(reflectedRay(), reflectance);
            for (int c = 0; c < channels; ++c) {
                if (!refracted[c])
                    continue;
                Pair t = onward(f, below, *refracted[c], depth, mode, st);
                Vec3 weight = Vec3::Ones() - reflectance;
                if (dispersive) {
                    const float keep = weight[c];
                    weight = Vec3::Zero();
                    weight[c] = keep;
                }
                result = sum(result, scaled(t, weight));
            }
            return scaled(result, absorbed);
        }
    }
    return {};
}

// Direct light on the depth surface, whose albedo is the camera pixel over the irradiance the
// scene's lights give in the real scene: then I_r is the camera pixel itself and I_m is that
// pixel times E_mixed / E_real, so I_c + I_m − I_r scales the camera pixel by exactly the ratio
// of the lighting with and without the virtual objects, however the real lights are modelled.
// Where the model gives no light, nothing virtual can change it: both are the camera pixel.
Pair DifferentialIntegrator::cameraAlbedoDirect(const Frame& f, const Surface& s, const Vec3& n,
                                                const Vec3& d, SampleState& st,
                                                PrimaryDirect* record) const {
    const int w = f.inputs->camera.width, h = f.inputs->camera.height;
    const std::optional<Vec3> camera = cameraTexel(f, s.uv.x() * w - 0.5, s.uv.y() * h - 0.5);
    if (!camera)
        return {};
    PrimaryDirect light;
    const Pair irradiance =
        direct(f, s, n, d, Vec3::Ones(), Mode::kBoth, st, record != nullptr ? &light : nullptr);
    Pair out{*camera, *camera};
    for (int c = 0; c < 3; ++c)
        if (irradiance.r[c] > 0 && irradiance.m[c] != irradiance.r[c])
            out.m[c] = (*camera)[c] * irradiance.m[c] / irradiance.r[c];
    // I_m = camera · v_m / v_r for visible fractions v_m, v_r of one light; I_r is the camera.
    const float v_m = light.visibleFractionM(), v_r = light.visibleFractionR();
    if (record != nullptr && v_r > 0) {
        record->unshadowed += light.unshadowed;
        record->visible_m += light.visible_m;
        record->visible_r += light.visible_r;
        record->dm_dvisible_m += *camera / v_r;
        record->dm_dvisible_r -= *camera * (v_m / (v_r * v_r));
        record->penumbra |= light.penumbra;
    }
    return out;
}

// The surface a camera ray shows. Virtual objects are hidden exactly where the depth map puts a
// real surface nearer along the pixel's ray (rayDistanceAt), in every DepthSecondaryRays mode.
// With the depth mesh, the real surface such a pixel shows is traced too (the nearest of the
// ghosts and the mesh), so that virtual shadows and reflections on it are shaded.
// A primary ray's hit among the scene's objects (the depth mesh masked out), checked against the
// depth map: a real surface the depth camera measured in front hides what was hit.
Hit DifferentialIntegrator::finishPrimaryHit(const Frame& f, const Hit& hit, const Vec3& origin,
                                             const Vec3& d,
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
        !depthSurfaceInfluenced(f, origin + *depth_limit * d, 0.05f * *depth_limit)) {
        return hidden ? Hit{} : hit;
    }
    return EmbreeScene::intersect(scene_.ghosts(), origin, d, kInf);
}

// ghostInfluenced() for the depth surface at a point known to within `margin`: moving the point
// by up to `margin` moves its segments towards the lights by no more.
bool DifferentialIntegrator::depthSurfaceInfluenced(const Frame& f, const Vec3& p,
                                                    float margin) const {
    if (f.virtual_bounds.empty())
        return false;
    const MaterialData& surface =
        materials_[static_cast<size_t>(objects_[*depth_object_].material)];
    // The point is known only to within `margin`, wider than the caustic kernel: wherever there
    // are caustics, the tiles they reach are shaded whole.
    if (surface.material.reflectance > 0 || (f.caustics && f.caustics->landed()))
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
        for (const BoundSphere& b : f.virtual_bounds)
            if (distanceToSegment(b.centre, p, dir, length) <= b.radius + extra)
                return true;
    }
    return false;
}

// The camera's own measurement of a real surface point (Kán & Kaufmann fig. 4): reproject it
// into the image; nullopt when it falls outside or something real hides it from the camera.
std::optional<Vec3> DifferentialIntegrator::cameraRadianceAt(const Frame& f, const Surface& s,
                                                             SampleState& st) const {
    const Vec3 to_camera = f.t_world_cam - s.p;
    const float dist = to_camera.norm();
    const Vec3 dir = to_camera / dist;
    const Vec3 origin =
        s.p + offsetFor(s.p) * (s.n_geometric.dot(dir) > 0 ? s.n_geometric : Vec3(-s.n_geometric));
    ++st.counters->shadow;
    logRay(st.log, bench::RayLog::Kind::kShadow, scene_.ghosts(), scene_.ghosts(), origin, dir,
           dist * 0.999f);
    if (EmbreeScene::occluded(scene_.ghosts(), origin, dir, dist * 0.999f))
        return std::nullopt;
    return cameraPixelAt(f, s.p);
}

Pair DifferentialIntegrator::trace(const Frame& f, const Vec3& origin, const Vec3& d, int depth,
                                   Mode mode, SampleState& st) const {
    ++st.counters->secondary;
    const RTCScene scene = mode == Mode::kReal ? scene_.ghosts() : scene_.all();
    logRay(st.log, bench::RayLog::Kind::kSecondary, scene, scene_.ghosts(), origin, d, kInf);
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

void DifferentialIntegrator::ghostsInfluenced(const Frame& f, const Surface* surfaces,
                                              const Vec3* dirs, const uint32_t* samples,
                                              size_t count, uint8_t* influenced) const {
    if (f.virtual_bounds.empty() || f.caustics) {
        // Nothing virtual (no lanes needed), or caustics, which CausticMaps::near() tests hit by
        // hit.
        for (size_t k = 0; k < count; ++k)
            influenced[samples[k]] =
                ghostInfluenced(f, surfaces[samples[k]], dirs[samples[k]]) ? 1 : 0;
        return;
    }
    detail::ghostsInfluenced({&f, options_.shadows, surfaces, dirs, samples, count}, influenced);
}

// Conservative: can virtual objects change the shading of this real point seen along `d`? True
// for glass and reflective ghosts (when the only ghost is flat: where the mirrored ray passes a
// virtual bounding sphere), and where a bounding sphere meets the way to a light.
bool DifferentialIntegrator::ghostInfluenced(const Frame& f, const Surface& s,
                                             const Vec3& d) const {
    if (f.virtual_bounds.empty())
        return false;
    if (f.caustics && f.caustics->near(s.p))
        return true;
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
        for (const BoundSphere& b : f.virtual_bounds)
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
        for (const BoundSphere& b : f.virtual_bounds)
            if (nearTaperedSegment(b.centre, s.p, dir, length, b.radius, b.radius + extra))
                return true;
    }
    return false;
}

}  // namespace mixray::render::detail
