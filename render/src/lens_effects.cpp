// Bloom and glare (lens_effects.h).
#include "lens_effects.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace mixray::render::detail {
namespace {

PixelBox grown(const PixelBox& box, int margin, int w, int h) {
    return {std::max(0, box.x0 - margin), std::max(0, box.y0 - margin),
            std::min(w, box.x1 + margin), std::min(h, box.y1 + margin)};
}

PixelBox united(const PixelBox& a, const PixelBox& b) {
    if (a.empty())
        return b;
    if (b.empty())
        return a;
    return {std::min(a.x0, b.x0), std::min(a.y0, b.y0), std::max(a.x1, b.x1), std::max(a.y1, b.y1)};
}

void zero(std::vector<Vec3>& image, int w, const PixelBox& box) {
    for (int y = box.y0; y < box.y1; ++y)
        std::fill_n(
            image.begin() + static_cast<std::ptrdiff_t>(static_cast<size_t>(y) * w + box.x0),
            box.x1 - box.x0, Vec3::Zero());
}

// Rows [0, rows) in parallel.
template <typename F>
void forRows(int rows, F f) {
    tbb::parallel_for(tbb::blocked_range<int>(0, rows, 4), [&](const tbb::blocked_range<int>& r) {
        for (int y = r.begin(); y < r.end(); ++y)
            f(y);
    });
}

}  // namespace

void brightPass(const Film& film, std::span<BrightImage> images) {
    const int w = film.width, h = film.height, ts = film.tile_size;
    for (BrightImage& image : images) {
        if (image.width != w || image.height != h) {
            image.light.assign(static_cast<size_t>(w) * h, Vec3::Zero());
            image.width = w;
            image.height = h;
        } else {
            zero(image.light, w, image.box);
        }
        image.box = {w, h, 0, 0};
    }
    // Only dirty tiles hold anything virtual.
    for (size_t t = 0; t < film.tile_dirty.size(); ++t) {
        if (!film.tile_dirty[t])
            continue;
        const int x0 = static_cast<int>(t % film.tiles_x) * ts;
        const int y0 = static_cast<int>(t / film.tiles_x) * ts;
        for (int y = y0; y < std::min(h, y0 + ts); ++y)
            for (int x = x0; x < std::min(w, x0 + ts); ++x) {
                const size_t i = static_cast<size_t>(y) * w + x;
                const float m = film.mask[i];
                const Vec3 added =
                    m * film.virtual_radiance[i] + (1 - m) * film.difference[i].cwiseMax(0.f);
                const float y_lum = luminance(added);
                for (BrightImage& image : images) {
                    if (!(y_lum > image.threshold))
                        continue;
                    image.light[i] = added * ((y_lum - image.threshold) / y_lum);
                    image.box = united(image.box, {x, y, x + 1, y + 1});
                }
            }
    }
    for (BrightImage& image : images)
        if (image.box.empty())
            image.box = {};
}

PixelBox addBloom(const std::vector<Vec3>& bright, int w, int h, const PixelBox& box,
                  float radius_px, float strength, std::vector<Vec3>& glow) {
    if (box.empty() || strength <= 0)
        return {};
    // Blurring a quarter-size map is 16 times less work; a factor that leaves the Gaussian at
    // least 2 small pixels wide keeps the upscaled glow smooth.
    const int k = std::clamp(static_cast<int>(radius_px / 2), 1, 4);
    const float sigma = radius_px / static_cast<float>(k);
    const int reach = static_cast<int>(std::ceil(3 * sigma));
    // The small map's pixel (i, j) covers full pixels [k·(sx0 + i), k·(sx0 + i + 1)).
    const PixelBox out = grown(box, k * (reach + 1), w, h);
    const int sx0 = out.x0 / k, sy0 = out.y0 / k;
    const int sw = (out.x1 + k - 1) / k - sx0, sh = (out.y1 + k - 1) / k - sy0;
    std::vector<Vec3> small(static_cast<size_t>(sw) * sh, Vec3::Zero());
    const float area = 1.f / static_cast<float>(k * k);
    for (int y = box.y0; y < box.y1; ++y)
        for (int x = box.x0; x < box.x1; ++x) {
            const Vec3& b = bright[static_cast<size_t>(y) * w + x];
            if (b != Vec3::Zero())
                small[static_cast<size_t>(y / k - sy0) * sw + (x / k - sx0)] += area * b;
        }
    std::vector<float> kernel(static_cast<size_t>(2 * reach + 1));
    float total = 0;
    for (int i = -reach; i <= reach; ++i)
        total += kernel[static_cast<size_t>(i + reach)] = std::exp(-0.5f * i * i / (sigma * sigma));
    for (float& v : kernel)
        v /= total;
    // Separable Gaussian, zero beyond the map (which holds the whole spread).
    std::vector<Vec3> pass(small.size(), Vec3::Zero());
    forRows(sh, [&](int j) {
        for (int i = 0; i < sw; ++i) {
            Vec3 s = Vec3::Zero();
            for (int d = std::max(-reach, -i); d <= std::min(reach, sw - 1 - i); ++d)
                s += kernel[static_cast<size_t>(d + reach)] *
                     small[static_cast<size_t>(j) * sw + i + d];
            pass[static_cast<size_t>(j) * sw + i] = s;
        }
    });
    forRows(sh, [&](int j) {
        for (int i = 0; i < sw; ++i) {
            Vec3 s = Vec3::Zero();
            for (int d = std::max(-reach, -j); d <= std::min(reach, sh - 1 - j); ++d)
                s += kernel[static_cast<size_t>(d + reach)] *
                     pass[static_cast<size_t>(j + d) * sw + i];
            small[static_cast<size_t>(j) * sw + i] = s;
        }
    });
    // Bilinear back up: the small pixel centres sit at full-pixel k·(i + 1/2) − 1/2.
    const auto at = [&](int i, int j) {
        return i < 0 || j < 0 || i >= sw || j >= sh ? Vec3(Vec3::Zero())
                                                    : small[static_cast<size_t>(j) * sw + i];
    };
    forRows(out.y1 - out.y0, [&](int row) {
        const int y = out.y0 + row;
        const float v =
            (static_cast<float>(y) + 0.5f) / static_cast<float>(k) - 0.5f - static_cast<float>(sy0);
        const int j = static_cast<int>(std::floor(v));
        const float fy = v - static_cast<float>(j);
        for (int x = out.x0; x < out.x1; ++x) {
            const float u = (static_cast<float>(x) + 0.5f) / static_cast<float>(k) - 0.5f -
                            static_cast<float>(sx0);
            const int i = static_cast<int>(std::floor(u));
            const float fx = u - static_cast<float>(i);
            const Vec3 value = (1 - fy) * ((1 - fx) * at(i, j) + fx * at(i + 1, j)) +
                               fy * ((1 - fx) * at(i, j + 1) + fx * at(i + 1, j + 1));
            glow[static_cast<size_t>(y) * w + x] += strength * value;
        }
    });
    return out;
}

void addGlareStreak(const std::vector<Vec3>& in, int w, const PixelBox& box, int dx, int dy,
                    int passes, float attenuation, float scale, std::vector<Vec3>& out,
                    StreakBuffers& buffers) {
    const int bw = box.x1 - box.x0, bh = box.y1 - box.y0;
    // Every pixel of the box is written before it is read, so old contents do no harm.
    std::vector<Vec3>& a = buffers.a;
    std::vector<Vec3>& b = buffers.b;
    a.resize(std::max(a.size(), static_cast<size_t>(bw) * bh));
    b.resize(a.size());
    for (int y = 0; y < bh; ++y)
        std::copy_n(
            in.begin() + static_cast<std::ptrdiff_t>(static_cast<size_t>(box.y0 + y) * w + box.x0),
            bw, a.begin() + static_cast<std::ptrdiff_t>(static_cast<size_t>(y) * bw));
    int step = 1;  // b = 4^(n−1)
    for (int n = 0; n < passes; ++n, step *= 4) {
        std::array<float, 4> weight;
        float total = 0;
        for (int s = 0; s < 4; ++s)
            total += weight[static_cast<size_t>(s)] = std::pow(attenuation, step * s);
        for (float& v : weight)
            v /= total;
        forRows(bh, [&](int y) {
            for (int x = 0; x < bw; ++x) {
                Vec3 sum = Vec3::Zero();
                for (int s = 0; s < 4; ++s) {
                    const int xs = x + step * s * dx, ys = y + step * s * dy;
                    if (xs < 0 || ys < 0 || xs >= bw || ys >= bh)
                        break;  // further samples lie further out
                    sum += weight[static_cast<size_t>(s)] * a[static_cast<size_t>(ys) * bw + xs];
                }
                b[static_cast<size_t>(y) * bw + x] = sum;
            }
        });
        std::swap(a, b);
    }
    forRows(bh, [&](int y) {
        const size_t first = static_cast<size_t>(box.y0 + y) * w + box.x0;
        for (int x = 0; x < bw; ++x)
            out[first + x] += scale * a[static_cast<size_t>(y) * bw + x];
    });
}

PixelBox addGlare(const std::vector<Vec3>& bright, int w, int h, const PixelBox& box,
                  const Glare& glare, std::vector<Vec3>& glow, StreakBuffers& buffers) {
    if (box.empty() || glare.strength <= 0)
        return {};
    const int length = (1 << (2 * glare.passes)) - 1;  // 4^passes − 1
    const PixelBox out = grown(box, length, w, h);
    for (const auto& [dx, dy] : {std::pair{1, 1}, {-1, 1}, {1, -1}, {-1, -1}})
        addGlareStreak(bright, w, out, dx, dy, glare.passes, glare.attenuation, glare.strength / 4,
                       glow, buffers);
    return out;
}

LensEffectsPass::LensEffectsPass(LensEffects effects) : effects_(std::move(effects)) {
    if (effects_.bloom)
        bright_.emplace_back(effects_.bloom->threshold);
    if (effects_.glare)
        bright_.emplace_back(effects_.glare->threshold);
}

void LensEffectsPass::apply(Film& film) {
    const int w = film.width, h = film.height;
    // Film::beginFrame() empties the glow when the frame's size changes.
    if (film.glow.size() != static_cast<size_t>(w) * h) {
        film.glow.assign(static_cast<size_t>(w) * h, Vec3::Zero());
    } else {
        zero(film.glow, w, film.glow_box);
    }
    film.glow_box = {};
    brightPass(film, bright_);
    auto bright = bright_.begin();
    if (effects_.bloom) {
        const Bloom& b = *effects_.bloom;
        film.glow_box = united(film.glow_box, addBloom(bright->light, w, h, bright->box,
                                                       b.radius_px, b.strength, film.glow));
        ++bright;
    }
    if (effects_.glare)
        film.glow_box = united(film.glow_box, addGlare(bright->light, w, h, bright->box,
                                                       *effects_.glare, film.glow, streaks_));
}

}  // namespace mixray::render::detail
