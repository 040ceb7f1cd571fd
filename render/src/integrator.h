// The integrator of one-pass differential rendering (Kán & Kaufmann §3): every path carries its
// radiance in the scene with the virtual objects (I_m) and without them (I_r), through RT²AR's
// ghosts, depth occlusion and depth-surface secondary rays, with Whitted-style reflection and
// refraction and direct light from the scene's lights. Internal to mixray::render.
#pragma once

#include <optional>
#include <vector>

#include "frame_context.h"
#include "shadow_rays.h"

namespace mixray::render::detail {

// What shading needs about a hit, in world coordinates.
struct Surface {
    Vec3 p;
    Vec3 n_geometric;  // unit, outward (as the mesh winds or the sphere bulges)
    Vec3 n_shading;    // unit, interpolated, same side as n_geometric
    Vec2 uv = Vec2::Zero();
    const ObjectData* object = nullptr;
    const MaterialData* material = nullptr;
};

// Which side of a surface a ray along `d` sees, and the points just off it that rays leave from.
struct HitSide {
    bool entering = false;  // the ray meets the outside (d · n_geometric < 0)
    Vec3 n_geo;             // the geometric normal on the ray's side
    Vec3 n;                 // the shading normal on the same side
    Vec3 above;             // s.p moved off the surface along n_geo, where reflected rays start
};

[[gnu::always_inline]] inline Vec3 facingNormal(const Surface& s, const Vec3& d) {
    return s.n_geometric.dot(d) < 0 ? s.n_geometric : Vec3(-s.n_geometric);
}

[[gnu::always_inline]] inline HitSide sideOf(const Surface& s, const Vec3& d) {
    HitSide side;
    side.entering = s.n_geometric.dot(d) < 0;
    side.n_geo = side.entering ? s.n_geometric : Vec3(-s.n_geometric);
    side.n = side.entering ? s.n_shading : Vec3(-s.n_shading);
    side.above = s.p + offsetFor(s.p) * side.n_geo;
    return side;
}

// One light's direct light at a shaded point before shadows: the way to it and what it gives
// unoccluded; `lit` false where it gives nothing (behind the surface, or at the point itself).
struct LightPath {
    Vec3 wi = Vec3::Zero();  // unit, towards the light
    float dist = kInf;       // to it; infinite for directional lights
    Vec3 unshadowed = Vec3::Zero();
    bool lit = false;
};

// The direct light of many diffuse or Phong primary hits at once (DifferentialIntegrator::
// directBatch): each entry's inputs, and `out`, what direct() gives for it. Kept by the thread
// with the scratch the batch needs, so that a tile allocates nothing.
struct DirectBatch {
    struct Entry {
        const Surface* s = nullptr;
        Vec3 n;       // the shading normal on the side the ray came from
        Vec3 d;       // the ray's direction
        Vec3 albedo;  // textured
        Mode mode = Mode::kBoth;
        SampleState* st = nullptr;
        PrimaryDirect* record = nullptr;  // the penumbra filter's, or null
        Pair out;
        // Set by directBatch().
        Vec3 n_facing, origin, diffuse;
    };
    // entries[0, count) are the batch; the vector only grows, so a tile constructs nothing.
    std::vector<Entry> entries;
    size_t count = 0;
    Entry& add() {
        if (count == entries.size())
            entries.resize(std::max<size_t>(64, 2 * entries.size()));
        return entries[count++];
    }
    std::vector<LightPath> paths;
    std::vector<uint8_t> traced;  // the light's hard test of the entry is among the queries
    std::vector<HardShadowQuery> queries;
    std::vector<Pair> answers;
};

// What surfacesAt() sorts the hits of a batch by mesh in: kept by the thread, so that a tile
// allocates nothing.
struct SurfaceScratch {
    std::vector<uint8_t> group;
    std::vector<uint32_t> order;
};

// The albedo of the grey world a path cut at max_depth sees where the scene has no environment
// light (DifferentialIntegrator::cutPath): a middling real room's.
constexpr float kCutWorldAlbedo = 0.5f;

// Const, so reentrant over tiles. Keeps every argument by reference: they must outlive it; the
// objects' poses change between frames, not during one.
class DifferentialIntegrator {
public:
    DifferentialIntegrator(const RenderOptions& options, const std::vector<MaterialData>& materials,
                           const std::vector<ObjectData>& objects, const EmbreeScene& scene,
                           std::optional<size_t> depth_object)
        : options_(options),
          materials_(materials),
          objects_(objects),
          scene_(scene),
          depth_object_(depth_object),
          prefetch_meshes_(outgrowsCache(objects, depth_object)),
          shadows_(options, scene) {}

    // The radiance pair a ray from `origin` along `d` brings back, `depth` bounces deep.
    Pair trace(const Frame& f, const Vec3& origin, const Vec3& d, int depth, Mode mode,
               SampleState& st) const;
    // The radiance pair leaving surface `s` (hit by a ray along `d`) back along the ray.
    Pair shade(const Frame& f, const Surface& s, const Hit& hit, const Vec3& d, int depth,
               Mode mode, SampleState& st) const;

    // A primary ray's hit among the scene's objects (the depth mesh masked out), checked against
    // the depth map (`depth_limit`: the measured distance along the pixel's ray).
    Hit finishPrimaryHit(const Frame& f, const Hit& hit, const Vec3& origin, const Vec3& d,
                         std::optional<float> depth_limit) const;
    Surface surfaceAt(const Hit& hit, const Vec3& origin, const Vec3& d) const;
    // surfaceAt() for `count` hits at once (invalid ones skipped): the same surfaces, bit for
    // bit, those on triangle meshes computed in SIMD lanes a mesh at a time (surface_batch.h).
    // Where meshes outgrow the cache, their triangles, positions and normals are fetched from
    // memory for all hits before any is computed, so that the misses overlap instead of
    // queueing one by one.
    void surfacesAt(const Hit* hits, const Vec3* origins, const Vec3* dirs, size_t count,
                    Surface* out, SurfaceScratch& scratch) const;
    // The same with scratch of its own.
    void surfacesAt(const Hit* hits, const Vec3* origins, const Vec3* dirs, size_t count,
                    Surface* out) const;
    // direct() for every entry of `batch`, into its `out`: the same light, each entry's hard
    // shadow rays traced with the others' as occlusion packets (ShadowRays::hardVisibilities).
    // Counts its shadow rays in `counters` and logs them in `log` (may be null).
    void directBatch(const Frame& f, DirectBatch& batch, Counters& counters, RayList* log) const;
    // A diffuse or Phong surface's albedo, textured.
    static Vec3 albedoAt(const Surface& s);
    // What shade() gives a diffuse or Phong surface with direct light `local`: `local` and,
    // where the material reflects, the mirrored ray's radiance (RT²AR's reflectance).
    Pair withReflection(const Frame& f, const Surface& s, const Vec3& d, int depth, Mode mode,
                        SampleState& st, const Pair& local, PrimaryDirect* record) const;
    // The environment lights' radiance along `d`.
    Vec3 environment(const Frame& f, const Vec3& d) const;
    // Conservative: can virtual objects change the shading of this real point seen along `d`?
    bool ghostInfluenced(const Frame& f, const Surface& s, const Vec3& d) const;
    // ghostInfluenced() of the ghost hits surfaces[samples[k]], seen along dirs[samples[k]], for
    // k < count: into influenced[samples[k]], in SIMD lanes (influence_batch.h).
    void ghostsInfluenced(const Frame& f, const Surface* surfaces, const Vec3* dirs,
                          const uint32_t* samples, size_t count, uint8_t* influenced) const;
    // ghostInfluenced() for the depth surface at a point known to within `margin`.
    bool depthSurfaceInfluenced(const Frame& f, const Vec3& p, float margin) const;

private:
    // `record`, when not null, receives the light's visibility (the primary hit's, for the
    // penumbra filter).
    Pair direct(const Frame& f, const Surface& s, const Vec3& n, const Vec3& d, const Vec3& albedo,
                Mode mode, SampleState& st, PrimaryDirect* record) const;
    // `light`'s path to the point (`diffuse`: the albedo over π) for direct().
    static LightPath lightPath(const LightData& light, const Surface& s, const Vec3& n,
                               const Vec3& d, const Vec3& diffuse);
    Pair lightVisibility(const Frame& f, const LightData& light, const Surface& s,
                         const Vec3& origin, const Vec3& n_facing, const LightPath& path, Mode mode,
                         SampleState& st, bool* penumbra, const Pair* traced = nullptr) const;
    static void addLight(const LightPath& path, const Pair& visible, bool penumbra, Pair& out,
                         PrimaryDirect* record);
    static void addCaustics(const Frame& f, const Surface& s, const Vec3& n_facing,
                            const Vec3& diffuse, Mode mode, Pair& out);
    // What a path cut at max_depth sees from `p` along `d`, the same in both scenes: the
    // environment lights' radiance, or without any, a grey world (kCutWorldAlbedo) lit by the
    // direct lights. So a mirror, metal or glass surface on a low rung of the quality ladder
    // shows its surroundings' light, not black.
    Vec3 cutPath(const Frame& f, const Vec3& p, const Vec3& d) const;
    // The radiance pair a ray leaving a surface hit `depth` bounces deep brings back: traced
    // while bounces are left, else cutPath().
    Pair onward(const Frame& f, const Vec3& origin, const Vec3& d, int depth, Mode mode,
                SampleState& st) const;
    // The radiance of the ray mirrored off `s` (seen along `d`), onward().
    Pair reflected(const Frame& f, const Surface& s, const Vec3& d, int depth, Mode mode,
                   SampleState& st) const;
    static float reflectanceMapAt(const Surface& s) {
        return s.material->reflectance_map.empty()
                   ? 1.f
                   : s.material->reflectance_map.sample(s.uv).mean();
    }
    Pair cameraAlbedoDirect(const Frame& f, const Surface& s, const Vec3& n, const Vec3& d,
                            SampleState& st, PrimaryDirect* record) const;
    std::optional<Vec3> cameraRadianceAt(const Frame& f, const Surface& s, SampleState& st) const;

    const RenderOptions& options_;
    const std::vector<MaterialData>& materials_;
    const std::vector<ObjectData>& objects_;
    const EmbreeScene& scene_;
    // Whether any object's mesh data is big enough (or, the depth surface, rebuilt every frame)
    // that its hits miss the cache, where surfacesAt() prefetches; small meshes stay cached and
    // the prefetch passes would only cost instructions.
    static bool outgrowsCache(const std::vector<ObjectData>& objects,
                              std::optional<size_t> depth_object);
    // The triangles, positions and normals the valid hits name, prefetched.
    void prefetchMeshData(const Hit* hits, size_t count) const;

    std::optional<size_t> depth_object_;  // index in objects_ of the depth surface (kMesh)
    bool prefetch_meshes_;
    ShadowRays shadows_;
};

}  // namespace mixray::render::detail
