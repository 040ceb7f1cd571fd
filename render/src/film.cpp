// The film (film.h).
#include "film.h"

#include <algorithm>
#include <cstring>

namespace mixray::render::detail {

void Film::beginFrame(int w, int h, int ts, bool keep_layers, bool filter_penumbra) {
    const size_t count = static_cast<size_t>(w) * h;
    if (width != w || height != h || tile_size != ts) {
        tile_size = ts;
        tiles_x = (w + ts - 1) / ts;
        const int tiles_y = (h + ts - 1) / ts;
        virtual_radiance.assign(count, Vec3::Zero());
        difference.assign(count, Vec3::Zero());
        mask.assign(count, 0.f);
        flags.assign(count, 0);
        tile_dirty.assign(static_cast<size_t>(tiles_x) * tiles_y, 0);
        glow.clear();
        glow_box = {};
        width = w;
        height = h;
    }
    if (keep_layers) {
        mixed.assign(count, Vec3::Zero());
        real.assign(count, Vec3::Zero());
    }
    // Read only where a pixel's kLit flag says this frame wrote them.
    if (filter_penumbra && visible_m.size() != count) {
        visible_m.resize(count);
        visible_r.resize(count);
        dvirtual_dvisible_m.resize(count);
        ddifference_dvisible_m.resize(count);
        ddifference_dvisible_r.resize(count);
    }
}

void Film::clearTile(int tile) {
    const int ts = tile_size;
    const int x0 = (tile % tiles_x) * ts, y0 = (tile / tiles_x) * ts;
    const int x1 = std::min(width, x0 + ts);
    for (int y = y0; y < std::min(height, y0 + ts); ++y) {
        const auto i = static_cast<std::ptrdiff_t>(static_cast<size_t>(y) * width + x0);
        const auto n = static_cast<std::ptrdiff_t>(x1 - x0);
        std::fill_n(virtual_radiance.begin() + i, n, Vec3::Zero());
        std::fill_n(difference.begin() + i, n, Vec3::Zero());
        std::fill_n(mask.begin() + i, n, 0.f);
        std::fill_n(flags.begin() + i, n, uint8_t{0});
    }
    tile_dirty[static_cast<size_t>(tile)] = 0;
}

// Only dirty tiles hold penumbra pixels; new values are applied after all are computed, so every
// mean reads unfiltered neighbours.
void Film::meanFilterPenumbra() {
    const int w = width, h = height, ts = tile_size;
    struct Filtered {
        size_t pixel;
        Vec3 virtual_radiance, difference;
    };
    std::vector<Filtered> filtered;
    for (size_t t = 0; t < tile_dirty.size(); ++t) {
        if (!tile_dirty[t])
            continue;
        const int x0 = static_cast<int>(t % tiles_x) * ts, y0 = static_cast<int>(t / tiles_x) * ts;
        for (int y = y0; y < std::min(h, y0 + ts); ++y)
            for (int x = x0; x < std::min(w, x0 + ts); ++x) {
                const size_t i = static_cast<size_t>(y) * w + x;
                if (!(flags[i] & kPenumbra))
                    continue;
                float sum_v = 0, sum_dm = 0, sum_dr = 0;
                int n_v = 0, n_d = 0;
                for (int yy = std::max(0, y - 1); yy <= std::min(h - 1, y + 1); ++yy)
                    for (int xx = std::max(0, x - 1); xx <= std::min(w - 1, x + 1); ++xx) {
                        const size_t j = static_cast<size_t>(yy) * w + xx;
                        if (!(flags[j] & kLit))
                            continue;
                        if (mask[j] > 0)
                            sum_v += visible_m[j], ++n_v;
                        if (mask[j] < 1)
                            sum_dm += visible_m[j], sum_dr += visible_r[j], ++n_d;
                    }
                Filtered out{i, virtual_radiance[i], difference[i]};
                if (mask[i] > 0 && n_v > 0)
                    out.virtual_radiance +=
                        dvirtual_dvisible_m[i] * (sum_v / static_cast<float>(n_v) - visible_m[i]);
                if (mask[i] < 1 && n_d > 0)
                    out.difference += ddifference_dvisible_m[i] *
                                          (sum_dm / static_cast<float>(n_d) - visible_m[i]) +
                                      ddifference_dvisible_r[i] *
                                          (sum_dr / static_cast<float>(n_d) - visible_r[i]);
                filtered.push_back(out);
            }
    }
    for (const Filtered& p : filtered) {
        virtual_radiance[p.pixel] = p.virtual_radiance;
        difference[p.pixel] = p.difference;
    }
}

void Film::compositeRow(int y, const ImageView& camera, const std::array<float, 256>& srgb_lut,
                        const Grain* grain, const MutableImageView& dst) const {
    const int w = width, ts = tile_size;
    const uint8_t* src_row = camera.row<uint8_t>(y);
    uint8_t* dst_row = dst.row<uint8_t>(y);
    const int tile_row = (y / ts) * tiles_x;
    const bool glow_row = !glow_box.empty() && y >= glow_box.y0 && y < glow_box.y1;
    for (int tx = 0; tx < tiles_x; ++tx) {
        const int x0 = tx * ts, x1 = std::min(w, x0 + ts);
        const bool glowing = glow_row && x1 > glow_box.x0 && x0 < glow_box.x1;
        if (!tile_dirty[static_cast<size_t>(tile_row + tx)] && !glowing) {
            std::memcpy(dst_row + 3 * x0, src_row + 3 * x0, 3 * static_cast<size_t>(x1 - x0));
            continue;
        }
        for (int x = x0; x < x1; ++x) {
            const size_t i = static_cast<size_t>(y) * w + x;
            const uint8_t* c = src_row + 3 * x;
            uint8_t* o = dst_row + 3 * x;
            const float m = mask[i];
            const Vec3 g = glowing && glow_box.contains(x, y) ? glow[i] : Vec3::Zero();
            if (m == 0 && difference[i] == Vec3::Zero() && g == Vec3::Zero()) {
                o[0] = c[0], o[1] = c[1], o[2] = c[2];
                continue;
            }
            for (int ch = 0; ch < 3; ++ch) {
                const float real_radiance = srgb_lut[c[ch]] + difference[i][ch];
                o[ch] = optics::encodeSrgb8(m * virtual_radiance[i][ch] + (1 - m) * real_radiance +
                                            g[ch]);
                if (grain != nullptr && m > 0)
                    o[ch] = grain->add(o[ch], m, 3 * i + static_cast<size_t>(ch));
            }
        }
    }
}

void Film::exportLayers(bool keep_layers, RenderLayers& out) const {
    if (!keep_layers) {
        out.mixed = out.real_only = out.mask = FloatImage{};
        return;
    }
    const size_t count = static_cast<size_t>(width) * height;
    const auto toImage = [&](const std::vector<Vec3>& src, FloatImage& img) {
        img = FloatImage{width, height, 3, std::vector<float>(count * 3)};
        for (size_t i = 0; i < count; ++i)
            for (int ch = 0; ch < 3; ++ch)
                img.pixels[3 * i + ch] = src[i][ch];
    };
    toImage(mixed, out.mixed);
    toImage(real, out.real_only);
    out.mask = FloatImage{width, height, 1, mask};
}

}  // namespace mixray::render::detail
