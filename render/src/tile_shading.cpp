// A tile's shading (embree_renderer.h): the footprint test on its primary hits, their shading
// with the direct light of diffuse and Phong hits in one batch, and the film.
#include "embree_renderer.h"

namespace mixray::render::detail {

uint64_t EmbreeRenderer::shadeTile(const Frame& f, const PixelBox& box, bool filter_penumbra,
                                   TileScratch& scratch, Counters& counters, RayList* log) {
    const DifferentialIntegrator& integrator = *integrator_;
    Film& b = film_;
    const int w = f.inputs->camera.width, spp = options_.samples_per_pixel;
    const bool keep = options_.keep_layers;
    const int tile_w = box.x1 - box.x0;
    const PrimarySamples& primaries = scratch.primaries;
    const Hit* const hits = primaries.hits.data();
    const Vec3* const dirs = primaries.dirs.data();
    const Vec3* const origins = primaries.origins.data();
    const Surface* const surfaces = scratch.surfaces.data();
    TileShading& sh = scratch.shading;

    // The footprint test: the pixels virtual content can touch, which are shaded. A pixel with
    // a virtual hit is; the ghost hits of the others are tested together, in SIMD lanes.
    // The vectors' data as plain pointers: the byte arrays' stores may alias anything, and would
    // make the compiler load every vector's pointer again after each.
    const int tile_pixels = tile_w * (box.y1 - box.y0);
    sh.has_virtual.assign(static_cast<size_t>(tile_pixels), 0);
    uint8_t* const has_virtual = sh.has_virtual.data();
    sh.ghost_hits.clear();
    for (int p = 0; p < tile_pixels; ++p) {
        const size_t first = static_cast<size_t>(p) * spp;
        for (int k = 0; k < spp; ++k)
            if (hits[first + k].valid &&
                objects_[hits[first + k].object].role == ObjectRole::kVirtual)
                has_virtual[p] = 1;
        if (has_virtual[p])
            continue;
        for (int k = 0; k < spp; ++k)
            if (hits[first + k].valid)
                sh.ghost_hits.push_back(static_cast<uint32_t>(first + k));
    }
    sh.ghost_influenced.resize(primaries.hits.size());
    const uint8_t* const ghost_influenced = sh.ghost_influenced.data();
    integrator.ghostsInfluenced(f, surfaces, dirs, sh.ghost_hits.data(), sh.ghost_hits.size(),
                                sh.ghost_influenced.data());
    sh.pixels.clear();
    for (int y = box.y0; y < box.y1; ++y)
        for (int x = box.x0; x < box.x1; ++x) {
            const auto p = static_cast<size_t>((y - box.y0) * tile_w + (x - box.x0));
            const size_t first = p * spp;
            bool influenced = has_virtual[p] != 0;
            for (int k = 0; k < spp && !influenced; ++k)
                influenced = hits[first + k].valid && ghost_influenced[first + k] != 0;
            if (!influenced && !keep && options_.only_virtual_footprint)
                continue;
            sh.pixels.push_back({static_cast<size_t>(y) * w + x, first, influenced});
        }

    // Every sample of those pixels. Diffuse and Phong hits have their direct light in one batch,
    // whose hard shadow rays go as packets; the rest are shaded at once. Each sample keeps its
    // own random numbers, used in the order shade() uses them: its direct light, then its bounces.
    const size_t count = sh.pixels.size() * static_cast<size_t>(spp);
    // Grown, never shrunk: every entry below [0, count) is written before it is read.
    if (sh.states.size() < count) {
        sh.states.resize(count);
        sh.light.resize(count);
        sh.radiance.resize(count);
        sh.is_virtual.resize(count);
        sh.batched.resize(count);
    }
    sh.batch.count = 0;
    const ShadedPixel* const pixels = sh.pixels.data();
    SampleState* const states = sh.states.data();
    PrimaryDirect* const lights = sh.light.data();
    Pair* const radiance = sh.radiance.data();
    uint8_t* const is_virtual = sh.is_virtual.data();
    std::pair<size_t, size_t>* const batched = sh.batched.data();
    const uint8_t* const live = primaries.live.data();
    // A shaded sample's radiance pair; a virtual hit's I_r is the scene without it (keep_layers).
    const auto finish = [&](size_t e, size_t i, const Pair& p, SampleState& st) {
        if (!is_virtual[e]) {
            radiance[e] = p;
            return;
        }
        radiance[e] = {p.m, keep ? integrator.trace(f, origins[i], dirs[i], 0, Mode::kReal, st).r
                                 : Vec3::Zero()};
    };
    for (size_t px = 0; px < sh.pixels.size(); ++px)
        for (int k = 0; k < spp; ++k) {
            const ShadedPixel& pixel = pixels[px];
            const size_t e = px * static_cast<size_t>(spp) + static_cast<size_t>(k);
            const size_t i = pixel.first + static_cast<size_t>(k);
            SampleState& st = states[e];
            st = {optics::Rng(hashIndex(options_.seed, pixel.index, k + 1)), &counters, log};
            PrimaryDirect* record = nullptr;
            if (filter_penumbra) {
                record = &lights[e];
                *record = {};
            }
            is_virtual[e] = 0;
            if (!hits[i].valid) {
                const Vec3 e_env = live[i] ? integrator.environment(f, dirs[i]) : Vec3::Zero();
                radiance[e] = {e_env, e_env};
                continue;
            }
            const Surface& s = surfaces[i];
            is_virtual[e] = s.object->role == ObjectRole::kVirtual;
            const Mode mode = is_virtual[e] ? Mode::kMixed : Mode::kBoth;
            const MaterialType type = s.material->material.type;
            if ((type == MaterialType::kDiffuse || type == MaterialType::kPhong) &&
                !s.material->albedo_from_camera) {
                batched[sh.batch.count] = {e, i};
                DirectBatch::Entry& entry = sh.batch.add();
                entry.s = &s;
                entry.n = s.n_geometric.dot(dirs[i]) < 0 ? s.n_shading : Vec3(-s.n_shading);
                entry.d = dirs[i];
                entry.albedo = DifferentialIntegrator::albedoAt(s);
                entry.mode = mode;
                entry.st = &st;
                entry.record = record;
                continue;
            }
            st.primary_direct = record;
            finish(e, i, integrator.shade(f, s, hits[i], dirs[i], 0, mode, st), st);
        }
    integrator.directBatch(f, sh.batch, counters, log);
    const DirectBatch::Entry* const entries = sh.batch.entries.data();
    for (size_t q = 0; q < sh.batch.count; ++q) {
        const DirectBatch::Entry& entry = entries[q];
        const auto [e, i] = batched[q];
        finish(e, i,
               integrator.withReflection(f, *entry.s, entry.d, 0, entry.mode, *entry.st, entry.out,
                                         entry.record),
               *entry.st);
    }

    // The film: each pixel's mean over its samples.
    Vec3* const virtual_radiance = b.virtual_radiance.data();
    Vec3* const difference = b.difference.data();
    float* const mask = b.mask.data();
    uint8_t* const flags = b.flags.data();
    for (size_t px = 0; px < sh.pixels.size(); ++px) {
        const size_t pixel = pixels[px].index;
        int n_virtual = 0;
        Vec3 vsum = Vec3::Zero(), dsum = Vec3::Zero(), msum = Vec3::Zero(), rsum = Vec3::Zero();
        PrimaryDirect light;  // over the pixel's samples, for the penumbra filter
        Vec3 dv_dm = Vec3::Zero(), dd_dm = Vec3::Zero(), dd_dr = Vec3::Zero();
        for (int k = 0; k < spp; ++k) {
            const size_t e = px * static_cast<size_t>(spp) + static_cast<size_t>(k);
            const Pair& p = radiance[e];
            if (is_virtual[e]) {
                ++n_virtual;
                vsum += p.m;
            } else {
                dsum += p.m - p.r;
            }
            if (keep) {
                msum += p.m;
                rsum += p.r;
            }
            if (!filter_penumbra)
                continue;
            const PrimaryDirect& sample_light = lights[e];
            light.unshadowed += sample_light.unshadowed;
            light.visible_m += sample_light.visible_m;
            light.visible_r += sample_light.visible_r;
            light.penumbra |= sample_light.penumbra;
            if (is_virtual[e]) {
                dv_dm += sample_light.dm_dvisible_m;
            } else {
                dd_dm += sample_light.dm_dvisible_m;
                dd_dr += sample_light.dm_dvisible_r - sample_light.dr_dvisible_r;
            }
        }
        if (n_virtual > 0)
            virtual_radiance[pixel] = vsum / static_cast<float>(n_virtual);
        if (n_virtual < spp)
            difference[pixel] = dsum / static_cast<float>(spp - n_virtual);
        mask[pixel] = static_cast<float>(n_virtual) / static_cast<float>(spp);
        flags[pixel] = kTraced;
        // Only pixels virtual content can touch take part in the filter, so that tracing the
        // others (only_virtual_footprint off) leaves the image as it is.
        if (filter_penumbra && pixels[px].influenced && light.unshadowed > 0) {
            flags[pixel] |= kLit | (light.penumbra ? kPenumbra : 0);
            b.visible_m[pixel] = light.visibleFractionM();
            b.visible_r[pixel] = light.visibleFractionR();
            // Only the penumbra's own pixels move: only they need the derivatives.
            if (light.penumbra && n_virtual > 0)
                b.dvirtual_dvisible_m[pixel] = dv_dm / static_cast<float>(n_virtual);
            if (light.penumbra && n_virtual < spp) {
                const auto n_real = static_cast<float>(spp - n_virtual);
                b.ddifference_dvisible_m[pixel] = dd_dm / n_real;
                b.ddifference_dvisible_r[pixel] = dd_dr / n_real;
            }
        }
        if (keep) {
            b.mixed[pixel] = msum / static_cast<float>(spp);
            b.real[pixel] = rsum / static_cast<float>(spp);
        }
    }
    return sh.pixels.size();
}

}  // namespace mixray::render::detail
