// The footprint test of ghost hits in SIMD lanes (influence_batch.h): ghostInfluenced()'s
// branches become masks, its sums and roots the same operations in the same order
// (simd_vec3-inl.h), so each lane gives its answer. Highway compiles this file once per
// instruction set and picks one at run time.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "influence_batch.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// foreach_target.h re-includes this file once per target: what follows is compiled each time.
#include <hwy/highway.h>

#include <algorithm>

#include "influence_batch.h"
#include "integrator.h"
#include "simd_vec3-inl.h"

HWY_BEFORE_NAMESPACE();
namespace mixray::render::detail::HWY_NAMESPACE {

namespace {

using namespace simd;  // NOLINT(google-build-using-namespace): this file's lane vocabulary

struct alignas(64) GhostLanes {
    Lanes3 p, ng, ns, d;
    int32_t glass[kMaxLanes], lambert[kMaxLanes], reflects[kMaxLanes];
};

// distanceToSegment(c, a, dir, kInf) (frame_context.h): |a + clamp((c − a)·dir, 0, ∞)·dir − c|.
V distanceToRay(const V3& c, const V3& a, const V3& dir) {
    const D d;
    const V s = stdClamp(dot3(sub3(c, a), dir), hn::Zero(d), hn::Set(d, kInf));
    return norm3(sub3(add3(a, scale3(s, dir)), c));
}

// nearTaperedSegment(c, a, dir, length, tol_a, tol_b) (footprint.h), lane by lane.
M nearTaperedSegment(const V3& c, const V3& a, const V3& dir, V length, V tol_a, V tol_b) {
    const D d;
    const V3 q = sub3(c, a);
    const V along = dot3(q, dir);
    // A ray: its tolerance stays tol_a.
    const M infinite = hn::Not(hn::IsFinite(length));
    const M near_ray =
        hn::Le(norm3(sub3(add3(a, scale3(stdMax(hn::Zero(d), along), dir)), c)), tol_a);
    const V k = hn::Div(hn::Sub(tol_b, tol_a), length);
    const M steep = hn::Not(hn::Lt(hn::Abs(k), hn::Set(d, 0.999f)));
    const V h = hn::Sqrt(stdMax(hn::Zero(d), hn::Sub(dot3(q, q), hn::Mul(along, along))));
    const V t = stdClamp(
        hn::Add(along, hn::Div(hn::Mul(k, h), hn::Sqrt(hn::Sub(hn::Set(d, 1.f), hn::Mul(k, k))))),
        hn::Zero(d), length);
    const M near_segment =
        hn::Le(norm3(sub3(add3(a, scale3(t, dir)), c)), hn::Add(tol_a, hn::Mul(k, t)));
    return hn::Or(hn::And(infinite, near_ray), hn::AndNot(infinite, hn::Or(steep, near_segment)));
}

}  // namespace

void GhostsInfluencedImpl(const GhostHits& hits, uint8_t* influenced) {
    const D d;
    const DI di;
    const size_t lanes = hn::Lanes(d);
    HWY_DASSERT(lanes <= kMaxLanes);
    const Frame& f = *hits.f;
    GhostLanes g;
    for (size_t first = 0; first < hits.count; first += lanes) {
        const size_t n = std::min(lanes, hits.count - first);
        // Lanes past the last hit repeat it.
        for (size_t l = 0; l < lanes; ++l) {
            const uint32_t sample = hits.samples[first + std::min(l, n - 1)];
            const Surface& s = hits.surfaces[sample];
            const Vec3& dir = hits.dirs[sample];
            for (int k = 0; k < 3; ++k) {
                g.p[k][l] = s.p[k];
                g.ng[k][l] = s.n_geometric[k];
                g.ns[k][l] = s.n_shading[k];
                g.d[k][l] = dir[k];
            }
            const Material& mat = s.material->material;
            g.glass[l] = mat.type == MaterialType::kGlass ? -1 : 0;
            g.lambert[l] =
                mat.type == MaterialType::kDiffuse || mat.type == MaterialType::kPhong ? -1 : 0;
            g.reflects[l] = mat.reflectance > 0 ? -1 : 0;
        }
        const V3 p = load3(g.p), dir = load3(g.d);
        const M glass = hn::RebindMask(d, hn::Ne(hn::Load(di, g.glass), hn::Zero(di)));
        const M lambert = hn::RebindMask(d, hn::Ne(hn::Load(di, g.lambert), hn::Zero(di)));
        const M reflects = hn::RebindMask(d, hn::Ne(hn::Load(di, g.reflects), hn::Zero(di)));
        M result = glass;
        // Mirrors, and Lambert surfaces that also reflect: off the only, flat, ghost a mirrored
        // ray changes the pixel only where it passes a virtual bound.
        const M mirrors = hn::AndNot(glass, hn::Or(hn::Not(lambert), reflects));
        if (!f.lone_flat_ghost) {
            result = hn::Or(result, mirrors);
        } else if (!hn::AllFalse(d, mirrors)) {
            const V3 ng = load3(g.ng), ns = load3(g.ns);
            const V3 normal = select3(hn::Lt(dot3(ng, dir), hn::Zero(d)), ns, neg3(ns));
            // optics::reflect(d, n) = d − (2·(d·n))·n, normalized.
            const V two_dn = hn::Mul(hn::Set(d, 2.f), dot3(dir, normal));
            const V3 r = normalized3(sub3(dir, scale3(two_dn, normal)));
            // 2·offsetFor(p): 2·(1e-4·(1 + max|p_i|)), Eigen's maxCoeff() as max(x, max(y, z)).
            const V largest = stdMax(hn::Abs(p.x), stdMax(hn::Abs(p.y), hn::Abs(p.z)));
            const V slack = hn::Mul(hn::Set(d, 2.f),
                                    hn::Mul(hn::Set(d, 1e-4f), hn::Add(hn::Set(d, 1.f), largest)));
            M mirrored = hn::FirstN(d, 0);
            for (const BoundSphere& b : f.virtual_bounds)
                mirrored = hn::Or(mirrored, hn::Le(distanceToRay(set3(b.centre), p, r),
                                                   hn::Add(hn::Set(d, b.radius), slack)));
            result = hn::Or(result, hn::And(mirrors, mirrored));
        }
        // Lambert surfaces: where a bound meets the way to a light.
        const M shaded = hn::AndNot(glass, lambert);
        if (hits.shadows && !hn::AllFalse(d, hn::AndNot(result, shaded))) {
            for (const LightData* light : f.lights) {
                V3 to_light;
                V length = hn::Set(d, kInf);
                float extra = 0;
                if (light->light.type == LightType::kDirectional) {
                    to_light = set3(-light->direction_world);
                } else {
                    const V3 delta = sub3(set3(light->position_world), p);
                    length = norm3(delta);
                    const M positive = hn::Gt(length, hn::Zero(d));
                    to_light = select3(positive,
                                       {hn::Div(delta.x, length), hn::Div(delta.y, length),
                                        hn::Div(delta.z, length)},
                                       set3(Vec3::UnitZ()));
                    if (light->light.type == LightType::kSphere)
                        extra = light->light.radius;
                }
                for (const BoundSphere& b : f.virtual_bounds)
                    result = hn::Or(
                        result, hn::And(shaded, nearTaperedSegment(set3(b.centre), p, to_light,
                                                                   length, hn::Set(d, b.radius),
                                                                   hn::Set(d, b.radius + extra))));
            }
        }
        alignas(64) int32_t answer[kMaxLanes];
        hn::Store(hn::VecFromMask(di, hn::RebindMask(di, result)), di, answer);
        for (size_t l = 0; l < n; ++l)
            influenced[hits.samples[first + l]] = answer[l] != 0;
    }
}

// NOLINTNEXTLINE(google-readability-namespace-comments)
}  // namespace mixray::render::detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace mixray::render::detail {

HWY_EXPORT(GhostsInfluencedImpl);

void ghostsInfluenced(const GhostHits& hits, uint8_t* influenced) {
    if (hits.count > 0)
        HWY_DYNAMIC_DISPATCH(GhostsInfluencedImpl)(hits, influenced);
}

}  // namespace mixray::render::detail
#endif  // HWY_ONCE
