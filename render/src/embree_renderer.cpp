// The Renderer's frame loop (embree_renderer.h): the frame set up, its tiles traced in parallel
// (primary packets, the footprint test, the integrator per sample), the film filtered and
// composited.
#include "embree_renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>

#include "bare_trace.h"
#include "mixray/graph/thread_priority.h"
#include "shadow_map.h"

namespace mixray::render::detail {

namespace {
// The nice value each thread had before it joined a render arena (TBB calls entry and exit on
// the joining thread itself).
thread_local int nice_before_render = 0;
thread_local int render_arena_depth = 0;
}  // namespace

RenderThreadPriority::RenderThreadPriority(tbb::task_arena& arena)
    : tbb::task_scheduler_observer(arena) {
    observe(true);
}

RenderThreadPriority::~RenderThreadPriority() {
    observe(false);
}

void RenderThreadPriority::on_scheduler_entry(bool /*is_worker*/) {
    if (render_arena_depth++ == 0) {
        nice_before_render = currentNice();
        runAs(ThreadRole::kRenderer);
    }
}

void RenderThreadPriority::on_scheduler_exit(bool /*is_worker*/) {
    if (--render_arena_depth == 0)
        (void)setCurrentNice(nice_before_render);  // refused without privilege: see the header
}

EmbreeRenderer::EmbreeRenderer(RenderOptions options, std::vector<MaterialData> materials,
                               std::vector<ObjectData> objects, std::vector<LightData> lights,
                               std::filesystem::path scene_source,
                               std::optional<size_t> depth_object, const SceneEffects& effects)
    : options_(std::move(options)),
      materials_(std::move(materials)),
      objects_(std::move(objects)),
      lights_(std::move(lights)),
      scene_source_(std::move(scene_source)),
      depth_object_(depth_object),
      caustic_settings_(effects.caustics) {
    if (effects.lens_effects.any())
        lens_effects_.emplace(effects.lens_effects);
    if (effects.aperture)
        lens_ = {effects.aperture->diameter_m() / 2, effects.aperture->focus_distance_m};
    if (effects.camera_matching.noise) {
        grain_.emplace();
        grain_->strength = *effects.camera_matching.noise;
    }
}

Status EmbreeRenderer::init() {
    const auto start = std::chrono::steady_clock::now();
    auto built = EmbreeScene::build(objects_, options_.embree_isa);
    if (!built)
        return built.status();
    scene_ = std::move(built).value();
    creation_times_.bvh_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    creation_times_.triangles_built = scene_->trianglesBuilt();
    // One arena for the renderer's life: building one per frame cost its threads' start-up
    // (and the first tasks' cold caches) on every render().
    const int threads = options_.threads > 0 ? options_.threads : tbb::task_arena::automatic;
    arena_.emplace(threads);
    arena_->initialize();
    if (options_.yield_to_capture)
        thread_priority_.emplace(*arena_);
    scratch_.resize(static_cast<size_t>(arena_->max_concurrency()));
    integrator_.emplace(options_, materials_, objects_, *scene_, depth_object_);
    if (caustic_settings_) {
        caustics_.emplace(*caustic_settings_, objects_, materials_);
        if (!caustics_->any())
            caustics_.reset();  // no specular object: nothing to shoot at
    }
    return Status::ok();
}

Status EmbreeRenderer::setLights(const std::vector<Light>& lights) {
    SceneDescription check;  // the scene's own checks, on the lights alone
    check.lights = lights;
    MIXRAY_RETURN_IF_ERROR(check.validate());
    auto loaded = loadLights(scene_source_, lights);
    if (!loaded)
        return loaded.status();
    lights_ = std::move(loaded).value();
    return Status::ok();
}

void EmbreeRenderer::markCausticTiles(const calibration::CameraModel& camera, const Frame& f,
                                      int tiles_x, int ts) {
    const int tiles_y = static_cast<int>(tile_mask_.size()) / tiles_x;
    const float radius = caustic_settings_->radius_m;
    // Only photons one scene has and the other has not change pixels (CausticMaps::near()).
    // In parallel (150K photons project in several ms on one core); a tile is only ever set,
    // so relaxed atomic stores suffice.
    const std::vector<Photon>& photons = f.caustics->changed().photons();
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, photons.size(), 4096),
        [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i < r.end(); ++i) {
                const Eigen::Vector3d p_cam =
                    f.R_cam_world * photons[i].p.cast<double>() + f.t_cam_world;
                if (!(p_cam.z() > 0))
                    continue;
                const auto px = camera.project(p_cam);
                if (!px)
                    continue;
                const double reach = radius * camera.fx / p_cam.z() + 1;
                const int x0 = std::max(0, static_cast<int>((px->x() - reach) / ts));
                const int x1 = std::min(tiles_x - 1, static_cast<int>((px->x() + reach) / ts));
                const int y0 = std::max(0, static_cast<int>((px->y() - reach) / ts));
                const int y1 = std::min(tiles_y - 1, static_cast<int>((px->y() + reach) / ts));
                for (int y = y0; y <= y1; ++y)
                    for (int x = x0; x <= x1; ++x)
                        std::atomic_ref<uint8_t>(tile_mask_[static_cast<size_t>(y * tiles_x + x)])
                            .store(1, std::memory_order_relaxed);
            }
        });
}

double EmbreeRenderer::renderShadowMaps(const Frame& f) {
    const auto start = std::chrono::steady_clock::now();
    bool rendered = false;
    for (LightData& light : lights_) {
        // Last frame's map lends its memory to this frame's.
        std::unique_ptr<ShadowMap> recycled;
        if (light.shadow_map && light.shadow_map.use_count() == 1)
            recycled = std::make_unique<ShadowMap>(std::move(*light.shadow_map));
        light.shadow_map.reset();
        if (light.active && light.light.shadow_map && options_.shadows) {
            light.shadow_map = ShadowMap::render(*light.light.shadow_map, light, f.virtual_bounds,
                                                 *scene_, objects_, std::move(recycled));
            rendered = true;
        }
    }
    return rendered
               ? std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
               : 0.0;
}

bench::BareTraceTimes EmbreeRenderer::traceBare(const bench::RayLog& log, int repeats) const {
    return traceBareEmbree(scene_->all(), scene_->ghosts(), log, options_.threads, repeats);
}

Status frameCancelled() {
    return Status(ErrorCode::kCancelled, "render: stopped on request before the frame was done");
}

Status EmbreeRenderer::renderFrame(const RenderInputs& in, RenderLayers& out, RenderStats* stats,
                                   bench::RayLog* ray_log) {
    const auto start = std::chrono::steady_clock::now();
    MIXRAY_RETURN_IF_ERROR(checkInputs(in));
    if (in.stop.stop_requested())
        return frameCancelled();
    Frame f;
    MIXRAY_RETURN_IF_ERROR(prepareFrame(in, f));

    prepareFootprint(f);

    const int w = in.camera.width, h = in.camera.height;
    const int spp = options_.samples_per_pixel;
    const bool keep = options_.keep_layers;
    const int ts = options_.tile_size;
    const int tiles_x = (w + ts - 1) / ts, tiles_y = (h + ts - 1) / ts;
    const int tiles = tiles_x * tiles_y;
    Film& b = film_;
    const bool filter_penumbra =
        options_.soft_shadows == SoftShadowMethod::kAdaptive && options_.shadow_mean_filter;
    b.beginFrame(w, h, ts, keep, filter_penumbra);
    const bool use_mask = options_.screen_footprint && options_.only_virtual_footprint && !keep;

    std::atomic<uint64_t> traced{0}, primary{0}, secondary{0}, shadow{0};
    std::vector<RayList> tile_logs(ray_log != nullptr ? static_cast<size_t>(tiles) : 0);
    // Set by the first tile that sees the stop request; the tiles after it return at once. A
    // skipped tile keeps its last frame's pixels and dirty flag, so the next frame clears it.
    std::atomic<bool> stopped{false};
    const DifferentialIntegrator& integrator = *integrator_;
    const auto renderTile = [&](int tile) {
        if (stopped.load(std::memory_order_relaxed) || in.stop.stop_requested()) {
            stopped.store(true, std::memory_order_relaxed);
            return;
        }
        if (b.tile_dirty[static_cast<size_t>(tile)])
            b.clearTile(tile);
        if (use_mask && !tile_mask_[static_cast<size_t>(tile)])
            return;
        RayList* log = tile_logs.empty() ? nullptr : &tile_logs[static_cast<size_t>(tile)];
        const int x0 = (tile % tiles_x) * ts, y0 = (tile / tiles_x) * ts;
        const int x1 = std::min(w, x0 + ts), y1 = std::min(h, y0 + ts);
        TileScratch& scratch =
            scratch_[static_cast<size_t>(tbb::this_task_arena::current_thread_index())];
        // The tile in stages over all its samples: the primary hits, each checked against the
        // depth map; then every hit's surface in one batch (SIMD lanes, their fetches from
        // memory overlapped); then the footprint test, the shading and the film (shadeTile()).
        PrimarySamples& primaries = scratch.primaries;
        primaryHits(*scene_, rays_, f, x0, y0, x1, y1, primaries, log);
        const int tile_w = x1 - x0;
        const size_t samples = primaries.hits.size();
        Hit* const hits_all = primaries.hits.data();
        const Vec3* const dirs_all = primaries.dirs.data();
        const Vec3* const origins_all = primaries.origins.data();
        const uint8_t* const live = primaries.live.data();
        uint64_t tile_primary = 0;
        for (size_t i = 0; i < samples; ++i)
            tile_primary += live[i];
        // Without depth a primary hit stands as Embree found it (finishPrimaryHit() is the
        // identity there: no depth limit, no depth mesh).
        if (f.depth)
            for (int y = y0; y < y1; ++y)
                for (int x = x0; x < x1; ++x) {
                    const size_t first = (static_cast<size_t>(y - y0) * tile_w + (x - x0)) * spp;
                    const std::optional<float> depth_limit = rays_.rayDistanceAt(*f.depth, x, y);
                    for (int k = 0; k < spp; ++k) {
                        const size_t i = first + static_cast<size_t>(k);
                        if (live[i])
                            hits_all[i] = integrator.finishPrimaryHit(
                                f, hits_all[i], origins_all[i], dirs_all[i], depth_limit);
                    }
                }
        scratch.surfaces.resize(samples);
        integrator.surfacesAt(hits_all, origins_all, dirs_all, samples, scratch.surfaces.data(),
                              scratch.surface_sort);
        Counters counters;
        const uint64_t tile_traced =
            shadeTile(f, {x0, y0, x1, y1}, filter_penumbra, scratch, counters, log);
        // Once per tile, not per pixel: neighbouring tiles' flags share a cache line, which
        // the threads would take from each other at every pixel.
        if (tile_traced > 0)
            b.tile_dirty[static_cast<size_t>(tile)] = 1;
        traced += tile_traced;
        primary += tile_primary;
        secondary += counters.secondary;
        shadow += counters.shadow;
    };

    double shadow_map_seconds = 0;
    arena_->execute([&] {
        shadow_map_seconds = renderShadowMaps(f);
        if (caustics_) {
            caustics_->update(f, *scene_, *integrator_);
            f.caustics = &*caustics_;
        }
        if (use_mask) {
            footprintMask(f.footprint, rays_.cones, rays_.directions, w, h, spp, ts, tile_mask_);
            if (f.caustics)
                markCausticTiles(in.camera, f, tiles_x, ts);
            // The footprint is of the image pose's pinhole rays; through the lens content
            // spreads by up to half its circle of confusion, and over the exposure by how far
            // the camera moved.
            if (lens_.radius_m > 0 || f.shutter)
                dilateTileMask(tile_mask_, tiles_x, ts,
                               spreadRadiusPx(f, nearestInfluencedDepth(f)) + 1);
        }
        tbb::parallel_for(tbb::blocked_range<int>(0, tiles, 1),
                          [&](const tbb::blocked_range<int>& r) {
                              for (int t = r.begin(); t < r.end(); ++t)
                                  renderTile(t);
                          });
        if (stopped)
            return;
        if (!(out.composite.desc() == ImageDesc::packed(PixelFormat::kRGB8, w, h)))
            out.composite = Image(ImageDesc::packed(PixelFormat::kRGB8, w, h));
        const MutableImageView dst = out.composite.mutableView();
        if (filter_penumbra)
            b.meanFilterPenumbra();
        if (lens_effects_)
            lens_effects_->apply(b);
        if (grain_)
            grain_->update(in.camera_image);
        // Composite I_f = M·I_m + (1 − M)·(I_c + I_m − I_r); clean tiles are the camera image.
        tbb::parallel_for(tbb::blocked_range<int>(0, h, 8), [&](const tbb::blocked_range<int>& r) {
            for (int y = r.begin(); y < r.end(); ++y)
                b.compositeRow(y, in.camera_image, f.srgb_lut, grain_ ? &*grain_ : nullptr, dst);
        });
    });
    if (stopped)
        return frameCancelled();
    if (ray_log != nullptr) {
        ray_log->rays.clear();
        for (const RayList& l : tile_logs)
            ray_log->rays.insert(ray_log->rays.end(), l.begin(), l.end());
    }
    b.exportLayers(keep, out);
    if (stats != nullptr) {
        stats->pixels_traced = traced;
        stats->primary_rays = primary;
        stats->secondary_rays = secondary;
        stats->shadow_rays = shadow;
        stats->shadow_map_seconds = shadow_map_seconds;
        if (caustics_) {
            const CausticTimes& t = caustics_->times();
            stats->caustic_shoot_seconds = t.reshot ? t.shoot_s : 0;
            stats->caustic_build_seconds = t.reshot ? t.build_s : 0;
            stats->caustic_photons = t.stored_mixed + t.stored_real;
        }
        stats->seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    return Status::ok();
}

}  // namespace mixray::render::detail
