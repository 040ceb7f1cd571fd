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

// What surfacesAt() sorts the hits of a batch by mesh in: kept by the thread, so that a tile
// allocates nothing.
struct SurfaceScratch {
    std::vector<uint8_t> group;
    std::vector<uint32_t> order;
};

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
    // The environment lights' radiance along `d`.
    Vec3 environment(const Frame& f, const Vec3& d) const;
    // Conservative: can virtual objects change the shading of this real point seen along `d`?
    bool ghostInfluenced(const Frame& f, const Surface& s, const Vec3& d) const;
    // ghostInfluenced() for the depth surface at a point known to within `margin`.
    bool depthSurfaceInfluenced(const Frame& f, const Vec3& p, float margin) const;

private:
    // `record`, when not null, receives the light's visibility (the primary hit's, for the
    // penumbra filter).
    Pair direct(const Frame& f, const Surface& s, const Vec3& n, const Vec3& d, const Vec3& albedo,
                Mode mode, SampleState& st, PrimaryDirect* record) const;
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
