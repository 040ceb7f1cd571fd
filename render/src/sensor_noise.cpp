// The camera's noise, measured and matched (sensor_noise.h).
#include "sensor_noise.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "optics.h"

namespace mixray::render::detail {
namespace {

// A bin needs this many pixel-channels for its median to hold within a few percent.
constexpr uint32_t kMinSamples = 200;
// |r| is kept to this in the per-bin histograms; noise of σ 40 codes stays below it.
constexpr int kMaxResponse = 1023;
// Sobel |gx| + |gy| above this is an edge, not noise: on noise alone it averages about 5.5σ,
// so this keeps every pixel of noise up to σ ≈ 10 and leaves out the edges of real content.
constexpr int kEdgeGradient = 96;

}  // namespace

float NoiseProfile::at(float code) const {
    // Bins with enough samples; the others take the nearest measured bins' values.
    std::array<float, kBins> filled{};
    std::array<bool, kBins> known{};
    bool any = false;
    for (int b = 0; b < kBins; ++b) {
        known[static_cast<size_t>(b)] = samples[static_cast<size_t>(b)] >= kMinSamples;
        any |= known[static_cast<size_t>(b)];
    }
    if (!any)
        return 0;
    for (int b = 0; b < kBins; ++b) {
        if (known[static_cast<size_t>(b)]) {
            filled[static_cast<size_t>(b)] = sigma[static_cast<size_t>(b)];
            continue;
        }
        int lo = b - 1, hi = b + 1;
        while (lo >= 0 && !known[static_cast<size_t>(lo)])
            --lo;
        while (hi < kBins && !known[static_cast<size_t>(hi)])
            ++hi;
        if (lo < 0)
            filled[static_cast<size_t>(b)] = sigma[static_cast<size_t>(hi)];
        else if (hi >= kBins)
            filled[static_cast<size_t>(b)] = sigma[static_cast<size_t>(lo)];
        else
            filled[static_cast<size_t>(b)] =
                sigma[static_cast<size_t>(lo)] +
                (sigma[static_cast<size_t>(hi)] - sigma[static_cast<size_t>(lo)]) *
                    static_cast<float>(b - lo) / static_cast<float>(hi - lo);
    }
    // Bin b's centre is code 16·b + 7.5.
    const float u = std::clamp((code - 7.5f) / 16.f, 0.f, static_cast<float>(kBins - 1));
    const int b = std::min(static_cast<int>(u), kBins - 2);
    const float t = u - static_cast<float>(b);
    return (1 - t) * filled[static_cast<size_t>(b)] + t * filled[static_cast<size_t>(b + 1)];
}

NoiseProfile measureNoise(const ImageView& rgb8, int step) {
    NoiseProfile profile;
    const int w = rgb8.desc.width, h = rgb8.desc.height;
    if (w < 3 || h < 3)
        return profile;
    step = std::max(1, step);
    std::vector<std::vector<uint32_t>> histograms(
        NoiseProfile::kBins, std::vector<uint32_t>(static_cast<size_t>(kMaxResponse) + 1, 0));
    for (int y = 1; y < h - 1; y += step) {
        const uint8_t* rows[3] = {rgb8.row<uint8_t>(y - 1), rgb8.row<uint8_t>(y),
                                  rgb8.row<uint8_t>(y + 1)};
        for (int x = 1; x < w - 1; x += step)
            for (int ch = 0; ch < 3; ++ch) {
                const auto v = [&](int dx, int dy) {
                    return static_cast<int>(rows[dy + 1][3 * (x + dx) + ch]);
                };
                const int corners = v(-1, -1) + v(1, -1) + v(-1, 1) + v(1, 1);
                const int sides = v(0, -1) + v(-1, 0) + v(1, 0) + v(0, 1);
                const int centre = v(0, 0);
                const int gx =
                    (v(1, -1) + 2 * v(1, 0) + v(1, 1)) - (v(-1, -1) + 2 * v(-1, 0) + v(-1, 1));
                const int gy =
                    (v(-1, 1) + 2 * v(0, 1) + v(1, 1)) - (v(-1, -1) + 2 * v(0, -1) + v(1, -1));
                if (std::abs(gx) + std::abs(gy) > kEdgeGradient)
                    continue;
                const int r = std::abs(corners - 2 * sides + 4 * centre);
                const int mean = (corners + sides + centre + 4) / 9;
                const int bin = std::min(mean / 16, NoiseProfile::kBins - 1);
                ++histograms[static_cast<size_t>(bin)]
                            [static_cast<size_t>(std::min(r, kMaxResponse))];
                ++profile.samples[static_cast<size_t>(bin)];
            }
    }
    for (int b = 0; b < NoiseProfile::kBins; ++b) {
        const uint32_t n = profile.samples[static_cast<size_t>(b)];
        if (n == 0)
            continue;
        // The median of |r|, read between the integer responses it falls between.
        const double half = 0.5 * n;
        double below = 0;
        double median = 0;
        for (int r = 0; r <= kMaxResponse; ++r) {
            const double count = histograms[static_cast<size_t>(b)][static_cast<size_t>(r)];
            if (below + count >= half) {
                // |r| is an integer: spread each value's count over [r − 1/2, r + 1/2).
                median = std::max(0.0, r - 0.5 + (half - below) / count);
                break;
            }
            below += count;
        }
        profile.sigma[static_cast<size_t>(b)] = static_cast<float>(median / (0.6745 * 6));
    }
    return profile;
}

namespace {

// Quantiles of the standard normal at (i + 1/2) / n: drawing one at random is a normal draw
// without a logarithm per pixel.
constexpr int kNormals = 4096;
const std::array<float, kNormals>& normalQuantiles() {
    static const std::array<float, kNormals> table = [] {
        std::array<float, kNormals> q{};
        for (int i = 0; i < kNormals; ++i) {
            const double p = (i + 0.5) / kNormals;
            // Φ(x) = erfc(−x/√2)/2 is increasing: bisect for Φ(x) = p.
            double lo = -6, hi = 6;
            for (int k = 0; k < 60; ++k) {
                const double mid = 0.5 * (lo + hi);
                (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
            }
            q[static_cast<size_t>(i)] = static_cast<float>(0.5 * (lo + hi));
        }
        return q;
    }();
    return table;
}

}  // namespace

void Grain::update(const ImageView& camera_rgb8) {
    profile = measureNoise(camera_rgb8);
    for (int code = 0; code < 256; ++code)
        sigma[static_cast<size_t>(code)] = strength * profile.at(static_cast<float>(code));
    ++seed;
}

uint8_t Grain::add(uint8_t code, float m, uint64_t index) const {
    const float s = m * sigma[code];
    if (!(s > 0))
        return code;
    optics::Rng rng(seed ^ (index * 0x9e3779b97f4a7c15ULL));
    const float n = normalQuantiles()[static_cast<size_t>(rng.next() % kNormals)];
    return static_cast<uint8_t>(std::clamp(std::lround(code + s * n), 0L, 255L));
}

}  // namespace mixray::render::detail
