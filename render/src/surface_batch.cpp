// Surfaces of a triangle mesh's hits in SIMD lanes (surface_batch.h). Highway compiles this file
// once per instruction set and picks one at run time; the render library is built with
// -ffp-contract=off, so no multiply and add below is fused and every lane's bits are those of
// the scalar DifferentialIntegrator::surfaceAt().
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "surface_batch.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// foreach_target.h re-includes this file once per target: what follows is compiled each time.
#include <hwy/highway.h>

#include <algorithm>

#include "integrator.h"
#include "simd_vec3-inl.h"
#include "surface_batch.h"

HWY_BEFORE_NAMESPACE();
namespace mixray::render::detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

namespace {

using namespace simd;  // NOLINT(google-build-using-namespace): this file's lane vocabulary

// One group of lanes' hits and rays, as structure of arrays; the meshes' vertices are gathered
// straight into SIMD registers.
struct alignas(64) HitLanes {
    int32_t prim[kMaxLanes];
    float u[kMaxLanes], v[kMaxLanes], t[kMaxLanes];
    Lanes3 o, d;
    Lanes3 p, ng, ns;
    float uv[2][kMaxLanes];
};

// Vertex `index` of a packed array of `width`-float vectors (Eigen's Vector3f, Vector2f), component
// `k` of each lane.
V gather(const float* base, VI index, int width, int k) {
    const DI di;
    return hn::GatherIndex(D(), base, hn::Add(hn::Mul(index, hn::Set(di, width)), hn::Set(di, k)));
}

V3 gather3(const std::vector<Vec3>& points, VI index) {
    const float* base = points.data()->data();
    return {gather(base, index, 3, 0), gather(base, index, 3, 1), gather(base, index, 3, 2)};
}

// (w·a + u·b) + v·c: the barycentric blend surfaceAt() writes as w*a + u*b + v*c.
V blend(V w, V u, V v, V a, V b, V c) {
    return hn::Add(hn::Add(hn::Mul(w, a), hn::Mul(u, b)), hn::Mul(v, c));
}

}  // namespace

void MeshSurfacesImpl(const MeshHits& job, Surface* out) {
    const D d;
    const size_t lanes = hn::Lanes(d);
    HWY_DASSERT(lanes <= kMaxLanes);
    const TriangleMesh& mesh = *job.mesh;
    const bool normals = mesh.normals.size() == mesh.positions.size();
    const bool uvs = mesh.uvs.size() == mesh.positions.size();
    const Eigen::Matrix3f& R = job.object->R_world_object;
    HitLanes g{};  // zeroed once: the compiler cannot see that uv is read only where written
    // A triangle's three vertex indices, packed (std::array<uint32_t, 3>); below 2^31.
    const auto* corners = reinterpret_cast<const int32_t*>(mesh.triangles.data());
    const DI di;
    for (size_t first = 0; first < job.count; first += lanes) {
        const size_t n = std::min(lanes, job.count - first);
        // Lanes past the last hit repeat it, so that every lane computes on real values.
        for (size_t l = 0; l < lanes; ++l) {
            const uint32_t sample = job.samples[first + std::min(l, n - 1)];
            const Hit& hit = job.hits[sample];
            g.prim[l] = static_cast<int32_t>(hit.prim);
            g.u[l] = hit.u;
            g.v[l] = hit.v;
            g.t[l] = hit.t;
            for (int k = 0; k < 3; ++k) {
                g.o[k][l] = job.origins[sample][k];
                g.d[k][l] = job.dirs[sample][k];
            }
        }
        const VI triangle = hn::Mul(hn::Load(di, g.prim), hn::Set(di, 3));
        const VI i0 = hn::GatherIndex(di, corners, triangle);
        const VI i1 = hn::GatherIndex(di, corners, hn::Add(triangle, hn::Set(di, 1)));
        const VI i2 = hn::GatherIndex(di, corners, hn::Add(triangle, hn::Set(di, 2)));
        const auto u = hn::Load(d, g.u), v = hn::Load(d, g.v), t = hn::Load(d, g.t);
        const auto w = hn::Sub(hn::Sub(hn::Set(d, 1.f), u), v);
        const V3 a = gather3(mesh.positions, i0), b = gather3(mesh.positions, i1),
                 c = gather3(mesh.positions, i2);
        const V3 e1{hn::Sub(b.x, a.x), hn::Sub(b.y, a.y), hn::Sub(b.z, a.z)};
        const V3 e2{hn::Sub(c.x, a.x), hn::Sub(c.y, a.y), hn::Sub(c.z, a.z)};
        // Eigen's cross(): (e1y·e2z − e1z·e2y, e1z·e2x − e1x·e2z, e1x·e2y − e1y·e2x).
        const V3 cross{hn::Sub(hn::Mul(e1.y, e2.z), hn::Mul(e1.z, e2.y)),
                       hn::Sub(hn::Mul(e1.z, e2.x), hn::Mul(e1.x, e2.z)),
                       hn::Sub(hn::Mul(e1.x, e2.y), hn::Mul(e1.y, e2.x))};
        const V3 ng = rotate3(R, normalized3(cross));
        store3(ng, g.ng);
        const V3 o = load3(g.o), dir = load3(g.d);
        store3({hn::Add(o.x, hn::Mul(t, dir.x)), hn::Add(o.y, hn::Mul(t, dir.y)),
                hn::Add(o.z, hn::Mul(t, dir.z))},
               g.p);
        if (normals) {
            const V3 n0 = gather3(mesh.normals, i0), n1 = gather3(mesh.normals, i1),
                     n2 = gather3(mesh.normals, i2);
            const V3 blended{blend(w, u, v, n0.x, n1.x, n2.x), blend(w, u, v, n0.y, n1.y, n2.y),
                             blend(w, u, v, n0.z, n1.z, n2.z)};
            const auto usable = hn::Gt(dot3(blended, blended), hn::Set(d, 1e-12f));
            const V3 ns = rotate3(R, normalized3(blended));
            const auto facing = hn::Ge(dot3(ns, ng), hn::Zero(d));
            const auto side = [&](V n_k, V ng_k) {
                return hn::IfThenElse(usable, hn::IfThenElse(facing, n_k, hn::Neg(n_k)), ng_k);
            };
            store3({side(ns.x, ng.x), side(ns.y, ng.y), side(ns.z, ng.z)}, g.ns);
        } else {
            store3(ng, g.ns);
        }
        if (uvs) {
            const float* base = mesh.uvs.data()->data();
            for (int k = 0; k < 2; ++k)
                hn::Store(blend(w, u, v, gather(base, i0, 2, k), gather(base, i1, 2, k),
                                gather(base, i2, 2, k)),
                          d, g.uv[k]);
        }
        for (size_t l = 0; l < n; ++l) {
            Surface& s = out[job.samples[first + l]];
            s.object = job.object;
            s.material = job.material;
            s.p = {g.p[0][l], g.p[1][l], g.p[2][l]};
            s.n_geometric = {g.ng[0][l], g.ng[1][l], g.ng[2][l]};
            s.n_shading = {g.ns[0][l], g.ns[1][l], g.ns[2][l]};
            s.uv = uvs ? Vec2(g.uv[0][l], g.uv[1][l]) : Vec2::Zero();
        }
    }
}

// NOLINTNEXTLINE(google-readability-namespace-comments)
}  // namespace mixray::render::detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace mixray::render::detail {

HWY_EXPORT(MeshSurfacesImpl);

void meshSurfaces(const MeshHits& hits, Surface* out) {
    if (hits.count > 0)
        HWY_DYNAMIC_DISPATCH(MeshSurfacesImpl)(hits, out);
}

}  // namespace mixray::render::detail
#endif  // HWY_ONCE
