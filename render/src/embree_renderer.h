// The Renderer as mixray builds it: Embree's BVH (embree_scene.h), the camera's rays
// (camera_rays.h), the differential integrator (integrator.h) and the film (film.h), driven
// tile by tile in a TBB arena. Internal to mixray::render; Renderer::create() makes one.
#pragma once

#include <tbb/task_arena.h>
#include <tbb/task_scheduler_observer.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "camera_rays.h"
#include "caustics.h"
#include "film.h"
#include "frame_context.h"
#include "integrator.h"
#include "lens_effects.h"
#include "mixray/calibration/depth_registration.h"
#include "mixray/render/bench_seam.h"

namespace mixray::render::detail {

// The lights' render data: environment maps loaded (files resolved against the scene file's
// folder) or taken from memory.
Result<std::vector<LightData>> loadLights(const std::filesystem::path& scene_source,
                                          const std::vector<Light>& scene_lights);

// kCancelled: RenderInputs::stop was requested before the frame was done.
Status frameCancelled();

// What a scene sets beyond its objects and lights: the camera's lens and look, and the light
// transport the renderer adds (SceneDescription's fields of the same names).
struct SceneEffects {
    LensEffects lens_effects;
    std::optional<LensAperture> aperture;
    CameraMatching camera_matching;
    std::optional<CausticSettings> caustics;
};

// A pixel of a tile that shadeTile() shades: its index in the frame, its first sample in the
// tile's arrays, and whether virtual content can touch it (the footprint test).
struct ShadedPixel {
    size_t index = 0;
    size_t first = 0;
    bool influenced = false;
};

// shadeTile()'s samples: each shaded pixel's spp in a row, their state, primary direct light
// (for the penumbra filter), radiance and kind; the batch of diffuse and Phong hits' direct light
// and where each of its entries goes (sample, tile sample).
struct TileShading {
    std::vector<uint8_t> has_virtual;       // per pixel of the tile: a sample hit a virtual object
    std::vector<uint32_t> ghost_hits;       // the others' samples on ghosts, for the footprint
    std::vector<uint8_t> ghost_influenced;  // per sample: their footprint test
    std::vector<ShadedPixel> pixels;
    std::vector<SampleState> states;
    std::vector<PrimaryDirect> light;
    std::vector<Pair> radiance;
    std::vector<uint8_t> is_virtual;
    DirectBatch batch;
    std::vector<std::pair<size_t, size_t>> batched;
};

// A tile's primary samples and their surfaces: reused by the thread, so the loop never allocates.
struct TileScratch {
    PrimarySamples primaries;
    std::vector<Surface> surfaces;  // at the tile's valid hits, from the footprint test to shading
    SurfaceScratch surface_sort;
    TileShading shading;
};

// Lowers every thread that joins a renderer's arena (its TBB workers and the thread that calls
// render()) to ThreadRole::kRenderer's nice value while it renders, and gives each back its
// own on leaving. TBB's workers serve every arena in the process; an unprivileged process may
// not raise a thread's priority again, so there a worker keeps the renderer's nice value for
// the other TBB work it picks up (OpenCV's and Embree's loops), which also yields to capture.
class RenderThreadPriority final : public tbb::task_scheduler_observer {
public:
    explicit RenderThreadPriority(tbb::task_arena& arena);
    ~RenderThreadPriority() override;
    RenderThreadPriority(const RenderThreadPriority&) = delete;
    RenderThreadPriority& operator=(const RenderThreadPriority&) = delete;

    void on_scheduler_entry(bool is_worker) override;
    void on_scheduler_exit(bool is_worker) override;
};

class EmbreeRenderer final : public Renderer {
public:
    EmbreeRenderer(RenderOptions options, std::vector<MaterialData> materials,
                   std::vector<ObjectData> objects, std::vector<LightData> lights,
                   std::filesystem::path scene_source, std::optional<size_t> depth_object,
                   const SceneEffects& effects);

    // Builds the BVH.
    Status init();

    Status render(const RenderInputs& inputs, RenderLayers& out, RenderStats* stats) override {
        return renderFrame(inputs, out, stats, nullptr);
    }
    Status setLights(const std::vector<Light>& lights) override;
    const RenderOptions& options() const override { return options_; }

    // render(), appending every ray to `log` when it is not null (bench_seam.h).
    Status renderFrame(const RenderInputs& inputs, RenderLayers& out, RenderStats* stats,
                       bench::RayLog* log);
    bench::BareTraceTimes traceBare(const bench::RayLog& log, int repeats) const;
    // The loading's seconds come from Renderer::create(), the BVH's from init().
    void setLoadSeconds(double seconds) { creation_times_.load_s = seconds; }
    const bench::CreationTimes& creationTimes() const { return creation_times_; }

private:
    // frame_setup.cpp: the frame's inputs checked, its poses, depth, lights and rays set up.
    Status checkInputs(const RenderInputs& inputs) const;
    Status prepareFrame(const RenderInputs& inputs, Frame& f);
    // The depth image in the camera: inputs.depth_mm itself, or registered into it.
    Result<ImageView> registeredDepth(const RenderInputs& inputs);
    void updateDepthMesh(Frame& f);
    void prepareFootprint(Frame& f) const;
    void depthRegions(const Frame& f, FootprintScene& fp) const;
    // With a lens or motion blur: the nearest depth, in the camera, of anything virtual content
    // can touch, and how far in pixels a point at least that deep spreads from where the frame's
    // pinhole image shows it.
    float nearestInfluencedDepth(const Frame& f) const;
    float spreadRadiusPx(const Frame& f, float nearest_m) const;
    // tile_shading.cpp: the footprint test, shading and film of the tile `box`, whose primary
    // samples and surfaces `scratch` holds; the pixels it shaded.
    uint64_t shadeTile(const Frame& f, const PixelBox& box, bool filter_penumbra,
                       TileScratch& scratch, Counters& counters, RayList* log);
    // The lights' shadow maps for this frame (Light::shadow_map), inside the render arena; the
    // seconds they took, 0 when no light asks for one.
    double renderShadowMaps(const Frame& f);
    // Marks the tiles a caustic photon (of either scene) lands in, with the kernel around it.
    void markCausticTiles(const calibration::CameraModel& camera, const Frame& f, int tiles_x,
                          int ts);

    RenderOptions options_;
    std::vector<MaterialData> materials_;
    std::vector<ObjectData> objects_;
    std::vector<LightData> lights_;
    std::filesystem::path scene_source_;  // the scene file: light files resolve against it
    std::optional<size_t> depth_object_;  // index in objects_ of the depth surface (kMesh)
    std::unique_ptr<EmbreeScene> scene_;
    bench::CreationTimes creation_times_;
    std::optional<DifferentialIntegrator> integrator_;  // once the BVH is built
    ThinLens lens_;  // the scene camera's aperture; radius 0: a pinhole
    RayCache rays_;
    DepthMesher mesher_;
    // Registration of depth images from another camera: kept while the registration is the
    // same, so its scratch and the registered image are reused frame to frame.
    std::optional<calibration::Registrar> registrar_;
    Image registered_depth_;
    Film film_;
    std::optional<LensEffectsPass> lens_effects_;  // the scene has some
    std::optional<Grain> grain_;                   // the scene matches the camera's noise
    std::optional<CausticSettings> caustic_settings_;
    std::optional<CausticMaps> caustics_;  // once the BVH is built, with caustic_settings_
    std::vector<uint8_t> tile_mask_;
    // The threads every frame runs on (RenderOptions::threads), made with the BVH.
    std::optional<tbb::task_arena> arena_;
    // With RenderOptions::yield_to_capture: the arena's threads run as ThreadRole::kRenderer
    // while in it. Declared after arena_, so it stops observing before the arena goes.
    std::optional<RenderThreadPriority> thread_priority_;
    // One per thread slot of arena_ (tbb::this_task_arena::current_thread_index()).
    std::vector<TileScratch> scratch_;
};

}  // namespace mixray::render::detail
