// 3-vectors in SIMD lanes for the renderer's batches (surface_batch.cpp, influence_batch.cpp):
// Eigen's operations on Vector3f spelled out in the order Eigen evaluates them, so that each
// lane gives the scalar code's bits (the render library is built with -ffp-contract=off).
// Included once per Highway target, after hwy/foreach_target.h.

// Highway's per-target include guard: toggled with HWY_TARGET_TOGGLE for each target.
#if defined(MIXRAY_RENDER_SIMD_VEC3_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef MIXRAY_RENDER_SIMD_VEC3_INL_H_
#undef MIXRAY_RENDER_SIMD_VEC3_INL_H_
#else
#define MIXRAY_RENDER_SIMD_VEC3_INL_H_
#endif

#include <hwy/highway.h>

#include <Eigen/Core>
#include <cstddef>

HWY_BEFORE_NAMESPACE();
namespace mixray::render::detail::HWY_NAMESPACE {
namespace simd {
namespace hn = hwy::HWY_NAMESPACE;

constexpr size_t kMaxLanes = 16;  // AVX-512's floats: the widest x86 target

using D = hn::ScalableTag<float>;
using V = hn::Vec<D>;
using M = hn::Mask<D>;
using DI = hn::RebindToSigned<D>;
using VI = hn::Vec<DI>;

// A 3-vector in each lane.
struct V3 {
    V x, y, z;
};

// Lanes of 3-vectors as structure of arrays, aligned for Load and Store.
using Lanes3 = float[3][kMaxLanes];

inline V3 load3(const Lanes3& src) {
    const D d;
    return {hn::Load(d, src[0]), hn::Load(d, src[1]), hn::Load(d, src[2])};
}

inline void store3(const V3& v, Lanes3& dst) {
    const D d;
    hn::Store(v.x, d, dst[0]);
    hn::Store(v.y, d, dst[1]);
    hn::Store(v.z, d, dst[2]);
}

// The same vector in every lane.
inline V3 set3(const Eigen::Vector3f& v) {
    const D d;
    return {hn::Set(d, v.x()), hn::Set(d, v.y()), hn::Set(d, v.z())};
}

inline V3 add3(const V3& a, const V3& b) {
    return {hn::Add(a.x, b.x), hn::Add(a.y, b.y), hn::Add(a.z, b.z)};
}

inline V3 sub3(const V3& a, const V3& b) {
    return {hn::Sub(a.x, b.x), hn::Sub(a.y, b.y), hn::Sub(a.z, b.z)};
}

inline V3 scale3(V s, const V3& v) {
    return {hn::Mul(s, v.x), hn::Mul(s, v.y), hn::Mul(s, v.z)};
}

inline V3 neg3(const V3& v) {
    return {hn::Neg(v.x), hn::Neg(v.y), hn::Neg(v.z)};
}

inline V3 select3(M m, const V3& yes, const V3& no) {
    return {hn::IfThenElse(m, yes.x, no.x), hn::IfThenElse(m, yes.y, no.y),
            hn::IfThenElse(m, yes.z, no.z)};
}

// Eigen's squaredNorm() and dot() of 3-vectors: x·x' + (y·y' + z·z').
inline V dot3(const V3& a, const V3& b) {
    return hn::Add(hn::Mul(a.x, b.x), hn::Add(hn::Mul(a.y, b.y), hn::Mul(a.z, b.z)));
}

inline V norm3(const V3& v) {
    return hn::Sqrt(dot3(v, v));
}

// Eigen's normalized(): v / sqrt(|v|²) where |v|² > 0, else v.
inline V3 normalized3(const V3& v) {
    const D d;
    const V n2 = dot3(v, v);
    const M positive = hn::Gt(n2, hn::Zero(d));
    const V len = hn::Sqrt(n2);
    return select3(positive, {hn::Div(v.x, len), hn::Div(v.y, len), hn::Div(v.z, len)}, v);
}

// rotate(R, v) (frame_context.h): row i is (R(i,0)·x + R(i,1)·y) + R(i,2)·z.
inline V3 rotate3(const Eigen::Matrix3f& R, const V3& v) {
    const D d;
    const auto row = [&](int i) {
        return hn::Add(
            hn::Add(hn::Mul(hn::Set(d, R(i, 0)), v.x), hn::Mul(hn::Set(d, R(i, 1)), v.y)),
            hn::Mul(hn::Set(d, R(i, 2)), v.z));
    };
    return {row(0), row(1), row(2)};
}

// std::max(a, b) and std::clamp(v, lo, hi), NaN where they give it: (a < b) ? b : a, and
// (v < lo) ? lo : (hi < v) ? hi : v.
inline V stdMax(V a, V b) {
    return hn::IfThenElse(hn::Lt(a, b), b, a);
}

inline V stdClamp(V v, V lo, V hi) {
    return hn::IfThenElse(hn::Lt(v, lo), lo, hn::IfThenElse(hn::Lt(hi, v), hi, v));
}

}  // namespace simd
// NOLINTNEXTLINE(google-readability-namespace-comments)
}  // namespace mixray::render::detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // MIXRAY_RENDER_SIMD_VEC3_INL_H_
