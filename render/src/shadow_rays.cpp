// Shadow rays (shadow_rays.h).
#include "shadow_rays.h"

#include <array>
#include <cmath>

namespace mixray::render::detail {

Pair ShadowRays::visibility(const LightData& light, const Vec3& origin, const Vec3& to_light,
                            float dist, Mode mode, SampleState& st, bool* penumbra) const {
    if (!options_.shadows)
        return {Vec3::Ones(), Vec3::Ones()};
    const bool want_m = mode != Mode::kReal;
    const bool want_r = mode != Mode::kMixed;
    // One shadow ray towards `target` (a point, or a direction when dist is infinite).
    const auto test = [&](const Vec3& dir, float length, int& lit_m, int& lit_r) {
        bool occ_m = false;
        if (want_m) {
            ++st.counters->shadow;
            logRay(st.log, bench::RayLog::Kind::kShadow, scene_.all(), scene_.ghosts(), origin, dir,
                   length);
            occ_m = EmbreeScene::occluded(scene_.all(), origin, dir, length);
            lit_m += occ_m ? 0 : 1;
        }
        if (want_r) {
            bool occ_r = false;
            if (!want_m || occ_m) {
                ++st.counters->shadow;
                logRay(st.log, bench::RayLog::Kind::kShadow, scene_.ghosts(), scene_.ghosts(),
                       origin, dir, length);
                occ_r = EmbreeScene::occluded(scene_.ghosts(), origin, dir, length);
            }
            lit_r += occ_r ? 0 : 1;
        }
    };
    // Up to 16 shadow rays towards points on the light: one packet per scene, 8 lanes wide for up
    // to 8 rays (the adaptive test's 5, a light's last 4 of 20 samples), else 16.
    const auto testPacket = [&](const Vec3* dirs, const float* lengths, int count, int& lit_m,
                                int& lit_r) {
        const auto occludedN = count <= 8 ? &EmbreeScene::occluded8 : &EmbreeScene::occluded16;
        std::array<bool, 16> occ_m{}, active{}, occ_r{};
        if (want_m) {
            for (int i = 0; i < count; ++i) {
                ++st.counters->shadow;
                logRay(st.log, bench::RayLog::Kind::kShadow, scene_.all(), scene_.ghosts(), origin,
                       dirs[i], lengths[i]);
            }
            occludedN(scene_.all(), origin, dirs, lengths, nullptr, count, occ_m.data());
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
                    logRay(st.log, bench::RayLog::Kind::kShadow, scene_.ghosts(), scene_.ghosts(),
                           origin, dirs[i], lengths[i]);
                }
            }
            if (any)
                occludedN(scene_.ghosts(), origin, dirs, lengths, active.data(), count,
                          occ_r.data());
            for (int i = 0; i < count; ++i)
                lit_r += occ_r[i] ? 0 : 1;
        }
    };
    const float shorten = kShorten;
    int lit_m = 0, lit_r = 0;
    const SoftShadowMethod method = options_.soft_shadows;
    if (hard(light, dist)) {
        const HardShadowQuery q = hardQuery(origin, to_light, dist, mode);
        test(q.dir, q.length, lit_m, lit_r);
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
    const auto aim = [&](int lane, const Vec3& target) __attribute__((always_inline)) {
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
        testPacket(dirs.data(), lengths.data(), 5, lit_m, lit_r);
        const bool agree_m = !want_m || lit_m == 0 || lit_m == 5;
        const bool agree_r = !want_r || lit_r == 0 || lit_r == 5;
        if (agree_m && agree_r)
            return {Vec3::Constant(lit_m / 5.f), Vec3::Constant(lit_r / 5.f)};
        if (penumbra != nullptr)
            *penumbra = true;
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
        // 4 rays (20 samples' tail) measured faster as a packet; shorter tails stay single rays.
        if (count >= 4) {
            testPacket(dirs.data(), lengths.data(), count, lit_m, lit_r);
        } else {
            for (int i = 0; i < count; ++i)
                test(dirs[static_cast<size_t>(i)], lengths[static_cast<size_t>(i)], lit_m, lit_r);
        }
    }
    return {Vec3::Constant(static_cast<float>(lit_m) / static_cast<float>(n)),
            Vec3::Constant(static_cast<float>(lit_r) / static_cast<float>(n))};
}

void ShadowRays::hardVisibilities(const HardShadowQuery* queries, size_t count, Counters& counters,
                                  RayList* log, Pair* visible) const {
    OcclusionPacket16 mixed, real;
    // The real scene's ray of query i (visibility()'s test(): where the mixed one was blocked,
    // or alone in Mode::kReal).
    const auto traceReal = [&](uint32_t i) {
        const HardShadowQuery& q = queries[i];
        ++counters.shadow;
        logRay(log, bench::RayLog::Kind::kShadow, scene_.ghosts(), scene_.ghosts(), q.origin, q.dir,
               q.length);
        real.add(q.origin, q.dir, q.length, i);
        if (real.full())
            real.trace(scene_.ghosts(), [&](uint32_t j, bool occluded) {
                visible[j].r = Vec3::Constant(occluded ? 0.f : 1.f);
            });
    };
    const auto traceMixed = [&] {
        mixed.trace(scene_.all(), [&](uint32_t i, bool occluded) {
            visible[i].m = Vec3::Constant(occluded ? 0.f : 1.f);
            if (queries[i].mode == Mode::kMixed)
                return;
            if (occluded)
                traceReal(i);
            else
                visible[i].r = Vec3::Ones();
        });
    };
    for (size_t i = 0; i < count; ++i) {
        const HardShadowQuery& q = queries[i];
        visible[i] = {};
        const auto slot = static_cast<uint32_t>(i);
        if (q.mode == Mode::kReal) {
            traceReal(slot);
            continue;
        }
        ++counters.shadow;
        logRay(log, bench::RayLog::Kind::kShadow, scene_.all(), scene_.ghosts(), q.origin, q.dir,
               q.length);
        mixed.add(q.origin, q.dir, q.length, slot);
        if (mixed.full())
            traceMixed();
    }
    traceMixed();
    real.trace(scene_.ghosts(), [&](uint32_t j, bool occluded) {
        visible[j].r = Vec3::Constant(occluded ? 0.f : 1.f);
    });
}

// RT²AR's screen-space traversal for a shadow ray (kScreenSpace): whether the depth map's
// surface lies between `origin` and the light. The walk starts where trace()'s does, so that a
// point on a surface the depth camera also measured does not shadow itself.
bool ShadowRays::depthMapOccludes(const Frame& f, const Vec3& origin, const Vec3& wi,
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

}  // namespace mixray::render::detail
