// RT²AR §IV-F's lens effects as a post-process on the film: bloom (a thresholded luminance map,
// downscaled, blurred and added back) and glare (streaks along the four diagonals by repeated
// passes of 4 samples b = 4^(n−1) pixels apart, weighted a^(b·s)). Both start from what the
// virtual content adds to each pixel, so a frame with nothing virtual stays the camera image.
// Internal to mixray::render.
#pragma once

#include <vector>

#include "film.h"
#include "mixray/render/scene.h"

namespace mixray::render::detail {

// Rec. 709 luminance of linear RGB.
inline float luminance(const Vec3& c) {
    return 0.2126f * c.x() + 0.7152f * c.y() + 0.0722f * c.z();
}

// The light above `threshold` luminance in what the virtual content adds to each pixel (the
// virtual radiance where M > 0, what virtual objects add to real surfaces elsewhere), in `out`
// (the film's size, zero elsewhere); the box of the pixels that have any. `out` holds the last
// call's result, nonzero only in `last` (the box it returned), or is the wrong size.
PixelBox brightPass(const Film& film, float threshold, const PixelBox& last,
                    std::vector<Vec3>& out);

// Adds `strength` times `bright` (w x h, nonzero only inside `box`) blurred by a Gaussian of
// sigma `radius_px` to `glow`: box-downscaled by up to 4, blurred, bilinearly upscaled, so the
// light added is `strength` times the light in `bright`, less what leaves the frame. Returns the
// box it added to.
PixelBox addBloom(const std::vector<Vec3>& bright, int w, int h, const PixelBox& box,
                  float radius_px, float strength, std::vector<Vec3>& glow);

// Adds `scale` times one streak of `in` to `out`: `passes` gathers, pass n taking
// out(p) = Σ_s a^(b·s) in(p + b·s·(dx, dy)) over s = 0..3, b = 4^(n−1), divided by Σ_s a^(b·s)
// (so a pass moves light and keeps it). `in` and `out` are images `w` wide; only `box` (which
// must hold the streak) is read and written.
void addGlareStreak(const std::vector<Vec3>& in, int w, const PixelBox& box, int dx, int dy,
                    int passes, float attenuation, float scale, std::vector<Vec3>& out);

// Adds `strength` times the mean of the four diagonal streaks of `bright` to `glow`; returns
// the box it added to.
PixelBox addGlare(const std::vector<Vec3>& bright, int w, int h, const PixelBox& box,
                  const Glare& glare, std::vector<Vec3>& glow);

// The lens effects of one renderer, with their buffers kept between frames.
class LensEffectsPass {
public:
    explicit LensEffectsPass(LensEffects effects) : effects_(std::move(effects)) {}

    // Fills film.glow and film.glow_box from the film's layers (clearing last frame's glow).
    void apply(Film& film);

private:
    LensEffects effects_;
    // Each effect's bright pass, and the box of its light last frame.
    std::vector<Vec3> bloom_bright_, glare_bright_;
    PixelBox bloom_box_, glare_box_;
    int width_ = 0, height_ = 0;  // the frames they are of
};

}  // namespace mixray::render::detail
