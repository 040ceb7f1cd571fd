// The film: per-pixel accumulators of one-pass differential rendering, kept between frames
// (only tiles marked dirty hold anything but zeros), RT²AR's penumbra filter, and the composite
// I_f = M·I_m + (1 − M)·(I_c + I_m − I_r). Internal to mixray::render.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "frame_context.h"
#include "sensor_noise.h"

namespace mixray::render::detail {

// Pixels [x0, x1) x [y0, y1); empty when x0 >= x1 or y0 >= y1.
struct PixelBox {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    bool empty() const { return x0 >= x1 || y0 >= y1; }
    bool contains(int x, int y) const { return x >= x0 && x < x1 && y >= y0 && y < y1; }
};

constexpr uint8_t kTraced = 1;
constexpr uint8_t kPenumbra = 2;  // the penumbra filter smooths this pixel's light visibility
constexpr uint8_t kLit = 4;       // the primary hits get direct light: visible_m/r hold its share

struct Film {
    std::vector<Vec3> virtual_radiance;  // mean I_m over samples that hit virtual objects
    std::vector<Vec3> difference;        // mean I_m - I_r over the other samples
    std::vector<float> mask;             // M
    std::vector<uint8_t> flags;          // kTraced | kPenumbra | kLit
    // The penumbra filter's (kLit pixels): the visible fraction of the primary hits' direct light
    // in the mixed and in the real scene, and how the layers above change with each.
    std::vector<float> visible_m, visible_r;
    std::vector<Vec3> dvirtual_dvisible_m, ddifference_dvisible_m, ddifference_dvisible_r;
    std::vector<Vec3> mixed, real;  // keep_layers
    std::vector<uint8_t> tile_dirty;
    int width = 0, height = 0;
    int tile_size = 16, tiles_x = 0;
    // Light the lens effects add this frame (lens_effects.h), zero outside glow_box.
    std::vector<Vec3> glow;
    PixelBox glow_box;

    // For frames of w x h in tiles of `tile_size`: keeps what it holds when nothing changed;
    // `keep_layers` zeroes the I_m and I_r layers; `filter_penumbra` sizes the filter's.
    void beginFrame(int w, int h, int tile_size, bool keep_layers, bool filter_penumbra);
    // Zeroes a tile the last frame wrote to.
    void clearTile(int tile);
    // RT²AR's post-process: a 3x3 mean over penumbra pixels, of the visible fraction of their
    // direct light (not of their radiance, which would blur textures and reflections), each
    // layer's over the lit neighbours that carry it (virtual radiance where M > 0, the
    // difference where M < 1); each layer then moves by its derivative times the change.
    void meanFilterPenumbra();
    // Row y of the composite over `camera` (rgb8 sRGB; `srgb_lut` decodes it), plus the glow,
    // into `dst`, with `grain` (may be null) on what is virtual; tiles neither dirty nor glowing
    // are the camera image.
    void compositeRow(int y, const ImageView& camera, const std::array<float, 256>& srgb_lut,
                      const Grain* grain, const MutableImageView& dst) const;
    // keep_layers: I_m, I_r and M into `out`; otherwise clears them there.
    void exportLayers(bool keep_layers, RenderLayers& out) const;
};

}  // namespace mixray::render::detail
