// RT²AR §IV-F's lens effects as a post-process on the film: bloom (a thresholded luminance map,
// downscaled, blurred and added back) and glare (streaks along the four diagonals by repeated
// passes of 4 samples b = 4^(n−1) pixels apart, weighted a^(b·s)). Both start from what the
// virtual content adds to each pixel, so a frame with nothing virtual stays the camera image.
// Internal to mixray::render.
#pragma once

#include <span>
#include <vector>

#include "film.h"
#include "mixray/render/scene.h"

namespace mixray::render::detail {

// Rec. 709 luminance of linear RGB.
inline float luminance(const Vec3& c) {
    return 0.2126f * c.x() + 0.7152f * c.y() + 0.0722f * c.z();
}

// The light above one luminance threshold in what the virtual content adds to each pixel, kept
// between frames so that the next frame clears only the box this one lit.
struct BrightImage {
    explicit BrightImage(float luminance_threshold) : threshold(luminance_threshold) {}

    float threshold;
    int width = 0, height = 0;  // of `light`
    std::vector<Vec3> light;    // width x height, zero outside `box`
    PixelBox box;               // empty when nothing passes the threshold
};

// Fills each of `images` with the film's light above its threshold (the virtual radiance where
// M > 0, what virtual objects add to real surfaces elsewhere) in one scan of the film's dirty
// tiles; an image of another size than the film starts afresh.
void brightPass(const Film& film, std::span<BrightImage> images);

// Adds `strength` times `bright` (w x h, nonzero only inside `box`) blurred by a Gaussian of
// sigma `radius_px` to `glow`: box-downscaled by up to 4, blurred, bilinearly upscaled, so the
// light added is `strength` times the light in `bright`, less what leaves the frame. Returns the
// box it added to.
PixelBox addBloom(const std::vector<Vec3>& bright, int w, int h, const PixelBox& box,
                  float radius_px, float strength, std::vector<Vec3>& glow);

// The two images a streak's passes ping-pong between, kept so that a frame neither allocates
// nor clears them.
struct StreakBuffers {
    std::vector<Vec3> a, b;
};

// Adds `scale` times one streak of `in` to `out`: `passes` gathers, pass n taking
// out(p) = Σ_s a^(b·s) in(p + b·s·(dx, dy)) over s = 0..3, b = 4^(n−1), divided by Σ_s a^(b·s)
// (so a pass moves light and keeps it). `in` and `out` are images `w` wide; only `box` (which
// must hold the streak) is read and written.
void addGlareStreak(const std::vector<Vec3>& in, int w, const PixelBox& box, int dx, int dy,
                    int passes, float attenuation, float scale, std::vector<Vec3>& out,
                    StreakBuffers& buffers);

// Adds `strength` times the mean of the four diagonal streaks of `bright` to `glow`; returns
// the box it added to.
PixelBox addGlare(const std::vector<Vec3>& bright, int w, int h, const PixelBox& box,
                  const Glare& glare, std::vector<Vec3>& glow, StreakBuffers& buffers);

// The lens effects of one renderer, with their buffers kept between frames.
class LensEffectsPass {
public:
    explicit LensEffectsPass(LensEffects effects);

    // Fills film.glow and film.glow_box from the film's layers (clearing last frame's glow).
    void apply(Film& film);

private:
    LensEffects effects_;
    std::vector<BrightImage> bright_;  // bloom's, then glare's, of the effects that are on
    StreakBuffers streaks_;
};

}  // namespace mixray::render::detail
