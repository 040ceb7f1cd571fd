// Camera matching: the real camera's noise, measured on its own image as a function of
// brightness, and the same grain added to virtual pixels so that they do not look cleaner than
// the real ones around them. Internal to mixray::render.
#pragma once

#include <array>
#include <cstdint>

#include "mixray/graph/image.h"

namespace mixray::render::detail {

// Noise σ, in 8-bit code values, against the code value a pixel's neighbourhood has.
struct NoiseProfile {
    static constexpr int kBins = 16;  // of 16 code values each
    std::array<float, kBins> sigma{};
    std::array<uint32_t, kBins> samples{};  // pixel-channels measured in each bin

    // σ at `code`: linear between bin centres, bins with too few samples filled from their
    // neighbours; 0 when nothing could be measured.
    float at(float code) const;
};

// Immerkær's fast noise estimation (1996), per brightness bin: the response r of the mask
// [1 −2 1; −2 4 −2; 1 −2 1] cancels smooth shading (it is a difference of Laplacians) and has
// σ_r = 6σ on noise; σ = median|r| / (0.6745 · 6), the median so that the texture and edges
// left in a bin move it little. Pixels on strong edges (Sobel) are left out. Every `step`-th
// pixel in each direction, each channel on its own, binned by its 3x3 mean. `rgb8` is any size
// of at least 3x3.
NoiseProfile measureNoise(const ImageView& rgb8, int step = 3);

// The grain the composite adds to virtual pixels: the camera's noise this frame, times
// `strength`.
struct Grain {
    float strength = 1;
    uint64_t seed = 0;  // a new one every frame: grain changes as the camera's does
    NoiseProfile profile;
    std::array<float, 256> sigma{};  // strength · profile.at(code), per code value

    // Measures the camera image of the next frame.
    void update(const ImageView& camera_rgb8);
    // code + m · σ(code) · n, rounded and clamped; n a standard normal drawn from (seed, index),
    // m the pixel's virtual coverage: the grain goes where virtual light replaces the camera's,
    // which carries its own.
    uint8_t add(uint8_t code, float m, uint64_t index) const;
};

}  // namespace mixray::render::detail
