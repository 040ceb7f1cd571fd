// Bare Embree over a bench::RayLog: rays converted up front, each method timed on fresh copies (a
// traced RTCRayHit has a shortened tfar, which would flatter a second run).
#include "bare_trace.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <limits>
#include <vector>

#include "embree_scene.h"

namespace mixray::render::detail {
namespace {

struct alignas(64) Valid16 {
    int lanes[16];
};

struct Packet16 {
    std::vector<RTCRayHit16> rays;
    std::vector<Valid16> valid;
};

RTCRay toRay(const bench::RayLog::Ray& r) {
    RTCRay ray{};
    ray.org_x = r.origin[0];
    ray.org_y = r.origin[1];
    ray.org_z = r.origin[2];
    ray.dir_x = r.direction[0];
    ray.dir_y = r.direction[1];
    ray.dir_z = r.direction[2];
    ray.tnear = 0;
    ray.tfar = r.t_far;
    ray.mask = 0xFFFFFFFFu;
    return ray;
}

RTCRayHit toRayHit(const bench::RayLog::Ray& r) {
    RTCRayHit rh{};
    rh.ray = toRay(r);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return rh;
}

Packet16 toPackets(const std::vector<const bench::RayLog::Ray*>& rays) {
    Packet16 p;
    p.rays.resize((rays.size() + 15) / 16);
    p.valid.resize(p.rays.size());
    for (size_t i = 0; i < p.rays.size() * 16; ++i) {
        RTCRayHit16& rh = p.rays[i / 16];
        const size_t lane = i % 16;
        const bool on = i < rays.size();
        p.valid[i / 16].lanes[lane] = on ? -1 : 0;
        const RTCRay ray = on ? toRay(*rays[i]) : RTCRay{};
        rh.ray.org_x[lane] = ray.org_x;
        rh.ray.org_y[lane] = ray.org_y;
        rh.ray.org_z[lane] = ray.org_z;
        rh.ray.dir_x[lane] = on ? ray.dir_x : 0;
        rh.ray.dir_y[lane] = on ? ray.dir_y : 0;
        rh.ray.dir_z[lane] = on ? ray.dir_z : 1;
        rh.ray.tnear[lane] = 0;
        rh.ray.tfar[lane] = on ? ray.tfar : 0;
        rh.ray.time[lane] = 0;
        rh.ray.mask[lane] = 0xFFFFFFFFu;
        rh.ray.id[lane] = static_cast<unsigned>(lane);
        rh.ray.flags[lane] = 0;
        rh.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0][lane] = RTC_INVALID_GEOMETRY_ID;
    }
    return p;
}

double processCpuSeconds() {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

struct Seconds {
    double wall = 0, cpu = 0;
    Seconds& operator+=(const Seconds& o) {
        wall += o.wall;
        cpu += o.cpu;
        return *this;
    }
};

// Wall and CPU seconds of the fastest of `repeats` runs of `trace(first, count)` over chunks
// of `work`, each run on a fresh copy of `pristine`.
template <class T, class Trace>
Seconds bestTime(tbb::task_arena& arena, const std::vector<T>& pristine, size_t grain, int repeats,
                 const Trace& trace) {
    if (pristine.empty())
        return {};
    std::vector<T> work;
    constexpr double kInf = std::numeric_limits<double>::infinity();
    Seconds best{kInf, kInf};
    for (int r = 0; r < repeats; ++r) {
        work = pristine;
        const double cpu_start = processCpuSeconds();
        const auto start = std::chrono::steady_clock::now();
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<size_t>(0, work.size(), grain),
                              [&](const tbb::blocked_range<size_t>& range) {
                                  trace(work.data() + range.begin(), range.size(), range.begin());
                              });
        });
        best.wall = std::min(
            best.wall,
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        best.cpu = std::min(best.cpu, processCpuSeconds() - cpu_start);
    }
    return best;
}

struct KindRays {
    std::vector<const bench::RayLog::Ray*> scene[2];  // [0] all, [1] ghosts only
};

}  // namespace

bench::BareTraceTimes traceBareEmbree(RTCScene all, RTCScene ghosts, const bench::RayLog& log,
                                      int threads, int repeats) {
    tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
    KindRays kinds[3];
    for (const bench::RayLog::Ray& r : log.rays)
        kinds[static_cast<int>(r.kind)].scene[r.ghosts_only ? 1 : 0].push_back(&r);
    const RTCScene scenes[2] = {all, ghosts};
    constexpr size_t kGrain = 256;

    const auto intersect1 = [&](const KindRays& k, bool coherent) {
        Seconds sum;
        for (int s = 0; s < 2; ++s) {
            std::vector<RTCRayHit> rays;
            for (const bench::RayLog::Ray* r : k.scene[s])
                rays.push_back(toRayHit(*r));
            sum += bestTime(arena, rays, kGrain, repeats, [&](RTCRayHit* first, size_t n, size_t) {
                RTCIntersectContext context;
                rtcInitIntersectContext(&context);
                if (coherent)
                    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
                for (size_t i = 0; i < n; ++i)
                    rtcIntersect1(scenes[s], &context, first + i);
            });
        }
        return sum;
    };
    const auto intersect1M = [&](const KindRays& k) {
        Seconds sum;
        for (int s = 0; s < 2; ++s) {
            std::vector<RTCRayHit> rays;
            for (const bench::RayLog::Ray* r : k.scene[s])
                rays.push_back(toRayHit(*r));
            sum += bestTime(arena, rays, kGrain, repeats, [&](RTCRayHit* first, size_t n, size_t) {
                RTCIntersectContext context;
                rtcInitIntersectContext(&context);
                rtcIntersect1M(scenes[s], &context, first, static_cast<unsigned>(n),
                               sizeof(RTCRayHit));
            });
        }
        return sum;
    };
    const auto intersect16 = [&](const KindRays& k) {
        Seconds sum;
        for (int s = 0; s < 2; ++s) {
            const Packet16 packets = toPackets(k.scene[s]);
            sum += bestTime(arena, packets.rays, kGrain / 16, repeats,
                            [&](RTCRayHit16* first, size_t n, size_t offset) {
                                RTCIntersectContext context;
                                rtcInitIntersectContext(&context);
                                context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
                                for (size_t i = 0; i < n; ++i)
                                    rtcIntersect16(packets.valid[offset + i].lanes, scenes[s],
                                                   &context, first + i);
                            });
        }
        return sum;
    };
    const auto occluded = [&](const KindRays& k, bool stream) {
        Seconds sum;
        for (int s = 0; s < 2; ++s) {
            std::vector<RTCRay> rays;
            for (const bench::RayLog::Ray* r : k.scene[s])
                rays.push_back(toRay(*r));
            sum += bestTime(arena, rays, kGrain, repeats, [&](RTCRay* first, size_t n, size_t) {
                RTCIntersectContext context;
                rtcInitIntersectContext(&context);
                if (stream) {
                    rtcOccluded1M(scenes[s], &context, first, static_cast<unsigned>(n),
                                  sizeof(RTCRay));
                } else {
                    for (size_t i = 0; i < n; ++i)
                        rtcOccluded1(scenes[s], &context, first + i);
                }
            });
        }
        return sum;
    };
    const auto occluded16 = [&](const KindRays& k) {
        Seconds sum;
        for (int s = 0; s < 2; ++s) {
            const Packet16 packets = toPackets(k.scene[s]);
            sum += bestTime(arena, packets.rays, kGrain / 16, repeats,
                            [&](RTCRayHit16* first, size_t n, size_t offset) {
                                RTCIntersectContext context;
                                rtcInitIntersectContext(&context);
                                context.flags = kOcclusionPacketFlags;
                                for (size_t i = 0; i < n; ++i)
                                    rtcOccluded16(packets.valid[offset + i].lanes, scenes[s],
                                                  &context, &first[i].ray);
                            });
        }
        return sum;
    };
    bench::BareTraceTimes times;
    const auto best = [&](bench::RayLog::Kind kind, double& seconds, double& cpu_seconds,
                          std::string& method,
                          std::initializer_list<std::pair<Seconds, const char*>> tries) {
        seconds = std::numeric_limits<double>::infinity();
        for (const auto& [s, name] : tries) {
            times.tried.push_back({.kind = kind, .name = name, .wall_s = s.wall, .cpu_s = s.cpu});
            if (s.wall < seconds) {
                seconds = s.wall;
                cpu_seconds = s.cpu;
                method = name;
            }
        }
    };

    const KindRays& primary = kinds[static_cast<int>(bench::RayLog::Kind::kPrimary)];
    const KindRays& secondary = kinds[static_cast<int>(bench::RayLog::Kind::kSecondary)];
    const KindRays& shadow = kinds[static_cast<int>(bench::RayLog::Kind::kShadow)];
    best(bench::RayLog::Kind::kPrimary, times.primary_s, times.primary_cpu_s, times.primary_method,
         {{intersect1(primary, true), "rtcIntersect1"}, {intersect16(primary), "rtcIntersect16"}});
    best(bench::RayLog::Kind::kSecondary, times.secondary_s, times.secondary_cpu_s,
         times.secondary_method,
         {{intersect1(secondary, false), "rtcIntersect1"},
          {intersect1M(secondary), "rtcIntersect1M"},
          {intersect16(secondary), "rtcIntersect16"}});
    best(bench::RayLog::Kind::kShadow, times.shadow_s, times.shadow_cpu_s, times.shadow_method,
         {{occluded(shadow, false), "rtcOccluded1"},
          {occluded(shadow, true), "rtcOccluded1M"},
          {occluded16(shadow), "rtcOccluded16"}});
    return times;
}

}  // namespace mixray::render::detail
