// Shadow maps (shadow_map.h).
#include "shadow_map.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <utility>

namespace mixray::render::detail {
namespace {

// Directional maps start their rays this far before the casters' bounds towards the light, so
// that real surfaces between them and the light (a ceiling in the depth mesh) still occlude.
constexpr float kDirectionalLead_m = 100;
// Lookups move along the normal by this many texels (normal-offset shadows): a surface never
// shadows itself at grazing light, where a constant depth bias would have to be large.
constexpr float kNormalOffsetTexels = 1.5f;

// One value of a stored texel, normalised to [0, 1], in the storage's precision.
struct Codec {
    ShadowMapStorage storage;
    int components;

    size_t bytesPerTexel() const {
        switch (storage) {
            case ShadowMapStorage::kFloat:
                return 0;
            case ShadowMapStorage::kEightBit:
                return static_cast<size_t>(components);
            case ShadowMapStorage::kPackedRgba8:
                return 4;
        }
        return 0;
    }
    // Steps of one stored value over [0, 1].
    double levels() const {
        switch (storage) {
            case ShadowMapStorage::kFloat:
                return 0;
            case ShadowMapStorage::kEightBit:
                return 255;
            case ShadowMapStorage::kPackedRgba8:
                return components == 1 ? 4294967295.0 : 65535.0;
        }
        return 0;
    }
};

}  // namespace

std::unique_ptr<ShadowMap> ShadowMap::render(const ShadowMapSettings& settings,
                                             const LightData& light,
                                             const std::vector<BoundSphere>& casters,
                                             const EmbreeScene& scene,
                                             const std::vector<ObjectData>& objects,
                                             std::unique_ptr<ShadowMap> recycled) {
    if (casters.empty() || light.light.type == LightType::kEnvironment)
        return nullptr;
    // One sphere around every caster.
    Vec3 centre = Vec3::Zero();
    for (const BoundSphere& b : casters)
        centre += b.centre;
    centre /= static_cast<float>(casters.size());
    float radius = 0;
    for (const BoundSphere& b : casters)
        radius = std::max(radius, (b.centre - centre).norm() + b.radius);

    std::unique_ptr<ShadowMap> map =
        recycled ? std::move(recycled) : std::unique_ptr<ShadowMap>(new ShadowMap(settings));
    ShadowMap& m = *map;
    m.settings_ = settings;
    m.res_ = settings.resolution;
    // The map reaches past the casters' outline by what its filter reads around a texel, so
    // that penumbrae at the outline are filtered as inside.
    float reach_texels = 2;
    if (settings.filter == ShadowMapFilter::kPcf)
        reach_texels += 0.5f * static_cast<float>(settings.pcf_kernel);
    else if (settings.filter == ShadowMapFilter::kVsm)
        reach_texels += 3 * settings.vsm_blur_texels;
    const float grow =
        static_cast<float>(m.res_) / std::max(1.f, static_cast<float>(m.res_) - 2 * reach_texels);
    m.components_ = settings.filter == ShadowMapFilter::kVsm ? 2 : 1;
    if (light.light.type == LightType::kDirectional) {
        m.orthographic_ = true;
        m.w_ = light.direction_world.normalized();
        m.origin_ = centre - (radius + kDirectionalLead_m) * m.w_;
        m.half_extent_ = radius * grow;
    } else {
        const Vec3 to_centre = centre - light.position_world;
        const float distance = to_centre.norm();
        if (!(distance > radius * 1.0001f))
            return nullptr;  // the light is among the casters: a cube map's job
        m.orthographic_ = false;
        m.w_ = to_centre / distance;
        m.origin_ = light.position_world;
        const float sin_half = radius / distance;
        m.half_extent_ = grow * sin_half / std::sqrt(1 - sin_half * sin_half);
    }
    m.u_ = m.w_.unitOrthogonal();
    m.v_ = m.w_.cross(m.u_);

    // Depths along each texel's ray in both scenes; misses are infinite.
    const int res = m.res_;
    const size_t texels = static_cast<size_t>(res) * static_cast<size_t>(res);
    // Scratch kept from frame to frame: fresh pages for megabytes of texels cost more than the
    // rays.
    std::vector<float>& depth_mixed = m.depth_mixed_;
    std::vector<float>& depth_real = m.depth_real_;
    depth_mixed.resize(texels);
    depth_real.resize(texels);
    tbb::parallel_for(tbb::blocked_range<int>(0, res, 4), [&](const tbb::blocked_range<int>& r) {
        std::array<Vec3, 16> origins, dirs;
        std::array<Hit, 16> hits;
        std::array<int, 16> lanes;
        // Parallel rays from the map's plane, or rays from the light's centre.
        const auto trace = [&](RTCScene target, int count) {
            if (m.orthographic_)
                EmbreeScene::intersect16(target, origins.data(), dirs.data(), count, hits.data());
            else
                EmbreeScene::intersect16(target, m.origin_, dirs.data(), count, hits.data());
        };
        for (int y = r.begin(); y < r.end(); ++y) {
            for (int x0 = 0; x0 < res; x0 += 16) {
                const int count = std::min(16, res - x0);
                for (int i = 0; i < count; ++i)
                    m.texelRay(static_cast<float>(x0 + i), static_cast<float>(y),
                               origins[static_cast<size_t>(i)], dirs[static_cast<size_t>(i)]);
                // The mixed scene first; its hits on real surfaces are the real scene's too
                // (the ghosts are in both), so only rays that met a virtual object go again.
                const size_t row =
                    static_cast<size_t>(y) * static_cast<size_t>(res) + static_cast<size_t>(x0);
                trace(scene.all(), count);
                int again = 0;
                for (int i = 0; i < count; ++i) {
                    const Hit& hit = hits[static_cast<size_t>(i)];
                    const float t = hit.valid ? hit.t : kInf;
                    depth_mixed[row + static_cast<size_t>(i)] = t;
                    depth_real[row + static_cast<size_t>(i)] = t;
                    if (hit.valid && objects[hit.object].role == ObjectRole::kVirtual) {
                        origins[static_cast<size_t>(again)] = origins[static_cast<size_t>(i)];
                        dirs[static_cast<size_t>(again)] = dirs[static_cast<size_t>(i)];
                        lanes[static_cast<size_t>(again++)] = i;
                    }
                }
                if (again == 0)
                    continue;
                trace(scene.ghosts(), again);
                for (int i = 0; i < again; ++i) {
                    const Hit& hit = hits[static_cast<size_t>(i)];
                    depth_real[row + static_cast<size_t>(lanes[static_cast<size_t>(i)])] =
                        hit.valid ? hit.t : kInf;
                }
            }
        }
    });
    using Range = std::pair<float, float>;
    const auto [lo, hi] = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, texels, 16384), Range{kInf, -kInf},
        [&](const tbb::blocked_range<size_t>& r, Range range) {
            for (const std::vector<float>* depths : {&depth_mixed, &depth_real})
                for (size_t i = r.begin(); i < r.end(); ++i)
                    if (const float t = (*depths)[i]; std::isfinite(t)) {
                        range.first = std::min(range.first, t);
                        range.second = std::max(range.second, t);
                    }
            return range;
        },
        [](Range a, Range b) {
            return Range{std::min(a.first, b.first), std::max(a.second, b.second)};
        });
    if (!std::isfinite(lo))
        return nullptr;  // nothing under the light there
    m.near_ = std::max(0.f, lo - 1e-3f);
    m.far_ = hi + 0.01f * (hi - lo) + 1e-3f;

    const float range = m.far_ - m.near_;
    std::vector<float>& values = m.values_;
    for (int layer = 0; layer < 2; ++layer) {
        values.resize(texels * static_cast<size_t>(m.components_));
        const std::vector<float>& depths = layer == 0 ? depth_mixed : depth_real;
        tbb::parallel_for(
            tbb::blocked_range<size_t>(0, texels, 16384), [&](const tbb::blocked_range<size_t>& r) {
                for (size_t i = r.begin(); i < r.end(); ++i) {
                    const float z = std::isfinite(depths[i])
                                        ? std::clamp((depths[i] - m.near_) / range, 0.f, 1.f)
                                        : 1.f;
                    if (m.components_ == 1) {
                        values[i] = z;
                    } else {
                        values[2 * i] = z;
                        values[2 * i + 1] = z * z;
                    }
                }
            });
        if (m.components_ == 2 && settings.vsm_blur_texels > 0) {
            // Separable Gaussian blur of the moments, clamped at the map's edges.
            const float sigma = settings.vsm_blur_texels;
            const int reach = static_cast<int>(std::ceil(3 * sigma));
            std::vector<float> weights(static_cast<size_t>(2 * reach + 1));
            float total = 0;
            for (int k = -reach; k <= reach; ++k) {
                const float wk = std::exp(-0.5f * static_cast<float>(k * k) / (sigma * sigma));
                weights[static_cast<size_t>(k + reach)] = wk;
                total += wk;
            }
            for (float& wk : weights)
                wk /= total;
            m.pass_.resize(values.size());
            const size_t row = 2 * static_cast<size_t>(res);
            // Along x: the clamped taps only within `reach` of the edges.
            tbb::parallel_for(
                tbb::blocked_range<int>(0, res, 8), [&](const tbb::blocked_range<int>& r) {
                    for (int y = r.begin(); y < r.end(); ++y) {
                        const float* src = values.data() + static_cast<size_t>(y) * row;
                        float* dst = m.pass_.data() + static_cast<size_t>(y) * row;
                        for (int x = 0; x < res; ++x) {
                            float s1 = 0, s2 = 0;
                            const bool inside = x >= reach && x < res - reach;
                            for (int k = -reach; k <= reach; ++k) {
                                const int xx = inside ? x + k : std::clamp(x + k, 0, res - 1);
                                const float wk = weights[static_cast<size_t>(k + reach)];
                                s1 += wk * src[2 * xx];
                                s2 += wk * src[2 * xx + 1];
                            }
                            dst[2 * x] = s1;
                            dst[2 * x + 1] = s2;
                        }
                    }
                });
            // Along y: whole rows weighted and summed, in memory order.
            tbb::parallel_for(
                tbb::blocked_range<int>(0, res, 8), [&](const tbb::blocked_range<int>& r) {
                    for (int y = r.begin(); y < r.end(); ++y) {
                        float* dst = values.data() + static_cast<size_t>(y) * row;
                        std::fill(dst, dst + row, 0.f);
                        for (int k = -reach; k <= reach; ++k) {
                            const float* src =
                                m.pass_.data() +
                                static_cast<size_t>(std::clamp(y + k, 0, res - 1)) * row;
                            const float wk = weights[static_cast<size_t>(k + reach)];
                            for (size_t x = 0; x < row; ++x)
                                dst[x] += wk * src[x];
                        }
                    }
                });
        }
        m.store(layer == 0 ? m.mixed_ : m.real_, values);
    }
    return map;
}

void ShadowMap::texelRay(float x, float y, Vec3& origin, Vec3& direction) const {
    const float a = ((x + 0.5f) / static_cast<float>(res_) * 2 - 1) * half_extent_;
    const float b = ((y + 0.5f) / static_cast<float>(res_) * 2 - 1) * half_extent_;
    if (orthographic_) {
        origin = origin_ + a * u_ + b * v_;
        direction = w_;
    } else {
        origin = origin_;
        direction = (w_ + a * u_ + b * v_).normalized();
    }
}

ShadowMap::LightSpace ShadowMap::toLight(const Vec3& p) const {
    const Vec3 d = p - origin_;
    float a, b, depth;
    if (orthographic_) {
        a = d.dot(u_);
        b = d.dot(v_);
        depth = d.dot(w_);
    } else {
        const float z = d.dot(w_);
        if (!(z > 0))
            return {-kInf, -kInf, 0};
        a = d.dot(u_) / z;
        b = d.dot(v_) / z;
        depth = d.norm();
    }
    const float scale = static_cast<float>(res_) / (2 * half_extent_);
    return {(a + half_extent_) * scale - 0.5f, (b + half_extent_) * scale - 0.5f, depth};
}

float ShadowMap::texelSize(const Vec3& p) const {
    const float texel = 2 * half_extent_ / static_cast<float>(res_);
    return orthographic_ ? texel : texel * std::max(0.f, (p - origin_).dot(w_));
}

float ShadowMap::depthStep_m() const {
    const double levels = Codec{settings_.storage, components_}.levels();
    return levels > 0 ? static_cast<float>((far_ - near_) / levels) : 0.f;
}

float ShadowMap::storedDepth_m(int x, int y) const {
    const size_t texel =
        static_cast<size_t>(std::clamp(y, 0, res_ - 1)) * static_cast<size_t>(res_) +
        static_cast<size_t>(std::clamp(x, 0, res_ - 1));
    return near_ + load(mixed_, texel, 0) * (far_ - near_);
}

void ShadowMap::store(Layer& layer, std::vector<float>& normalised) const {
    const Codec codec{settings_.storage, components_};
    if (settings_.storage == ShadowMapStorage::kFloat) {
        layer.floats.swap(normalised);
        return;
    }
    const size_t texels = normalised.size() / static_cast<size_t>(components_);
    layer.bytes.resize(texels * codec.bytesPerTexel());
    const double levels = codec.levels();
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, texels, 16384), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i < r.end(); ++i) {
                uint8_t* out = layer.bytes.data() + i * codec.bytesPerTexel();
                for (int c = 0; c < components_; ++c) {
                    const double x = std::clamp<double>(
                        normalised[i * static_cast<size_t>(components_) + static_cast<size_t>(c)],
                        0, 1);
                    const auto q = static_cast<uint32_t>(std::llround(x * levels));
                    if (settings_.storage == ShadowMapStorage::kEightBit) {
                        out[c] = static_cast<uint8_t>(q);
                    } else if (components_ == 1) {
                        // R, G, B, A: most significant byte first.
                        out[0] = static_cast<uint8_t>(q >> 24);
                        out[1] = static_cast<uint8_t>(q >> 16);
                        out[2] = static_cast<uint8_t>(q >> 8);
                        out[3] = static_cast<uint8_t>(q);
                    } else {
                        out[2 * c] = static_cast<uint8_t>(q >> 8);
                        out[2 * c + 1] = static_cast<uint8_t>(q);
                    }
                }
            }
        });
}

float ShadowMap::load(const Layer& layer, size_t texel, int component) const {
    const Codec codec{settings_.storage, components_};
    if (settings_.storage == ShadowMapStorage::kFloat)
        return layer
            .floats[texel * static_cast<size_t>(components_) + static_cast<size_t>(component)];
    const uint8_t* in = layer.bytes.data() + texel * codec.bytesPerTexel();
    uint32_t q;
    if (settings_.storage == ShadowMapStorage::kEightBit)
        q = in[component];
    else if (components_ == 1)
        q = (uint32_t{in[0]} << 24) | (uint32_t{in[1]} << 16) | (uint32_t{in[2]} << 8) | in[3];
    else
        q = (uint32_t{in[2 * component]} << 8) | in[2 * component + 1];
    return static_cast<float>(static_cast<double>(q) / codec.levels());
}

float ShadowMap::hardTest(const Layer& layer, int x, int y, float depth) const {
    x = std::clamp(x, 0, res_ - 1);
    y = std::clamp(y, 0, res_ - 1);
    const size_t texel =
        static_cast<size_t>(y) * static_cast<size_t>(res_) + static_cast<size_t>(x);
    return depth <= load(layer, texel, 0) ? 1.f : 0.f;
}

// Each tap is the bilinear blend of its four texels' tests, so the taps together ramp linearly
// over pcf_kernel texels across an edge.
float ShadowMap::pcf(const Layer& layer, const LightSpace& q, float depth) const {
    const int k = settings_.pcf_kernel;
    const float first = -0.5f * static_cast<float>(k - 1);
    float lit = 0;
    for (int j = 0; j < k; ++j) {
        for (int i = 0; i < k; ++i) {
            const float x = q.x + first + static_cast<float>(i);
            const float y = q.y + first + static_cast<float>(j);
            const float fx = std::floor(x), fy = std::floor(y);
            const float tx = x - fx, ty = y - fy;
            const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
            lit += (1 - ty) * ((1 - tx) * hardTest(layer, x0, y0, depth) +
                               tx * hardTest(layer, x0 + 1, y0, depth)) +
                   ty * ((1 - tx) * hardTest(layer, x0, y0 + 1, depth) +
                         tx * hardTest(layer, x0 + 1, y0 + 1, depth));
        }
    }
    return lit / static_cast<float>(k * k);
}

float ShadowMap::chebyshev(const Layer& layer, const LightSpace& q, float depth) const {
    const float fx = std::floor(q.x), fy = std::floor(q.y);
    const float tx = q.x - fx, ty = q.y - fy;
    const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
    float moments[2] = {0, 0};
    for (int dy = 0; dy < 2; ++dy) {
        for (int dx = 0; dx < 2; ++dx) {
            const int x = std::clamp(x0 + dx, 0, res_ - 1);
            const int y = std::clamp(y0 + dy, 0, res_ - 1);
            const size_t texel =
                static_cast<size_t>(y) * static_cast<size_t>(res_) + static_cast<size_t>(x);
            const float weight = (dx ? tx : 1 - tx) * (dy ? ty : 1 - ty);
            moments[0] += weight * load(layer, texel, 0);
            moments[1] += weight * load(layer, texel, 1);
        }
    }
    const float mean = moments[0];
    if (depth <= mean)
        return 1;
    // The stored moments' own precision bounds the variance from below.
    const double levels = Codec{settings_.storage, components_}.levels();
    const float step = levels > 0 ? static_cast<float>(1 / levels) : 0.f;
    const float variance = std::max(moments[1] - mean * mean, std::max(1e-7f, step * step));
    const float d = depth - mean;
    const float bound = variance / (variance + d * d);
    const float a = settings_.bleeding_reduction;
    return std::clamp((bound - a) / (1 - a), 0.f, 1.f);
}

float ShadowMap::lookup(const Layer& layer, const LightSpace& q, float depth) const {
    switch (settings_.filter) {
        case ShadowMapFilter::kHard:
            return hardTest(layer, static_cast<int>(std::lround(q.x)),
                            static_cast<int>(std::lround(q.y)), depth);
        case ShadowMapFilter::kPcf:
            return pcf(layer, q, depth);
        case ShadowMapFilter::kVsm:
            return chebyshev(layer, q, depth);
    }
    return 1;
}

std::optional<Pair> ShadowMap::visibility(const Vec3& p, const Vec3& n, Mode mode) const {
    const float texel = texelSize(p);
    const LightSpace q = toLight(p + kNormalOffsetTexels * texel * n);
    const float edge = static_cast<float>(res_) - 0.5f;
    if (!(q.x >= -0.5f && q.x <= edge && q.y >= -0.5f && q.y <= edge))
        return std::nullopt;
    const float range = far_ - near_;
    // A texel's depth and the storage's rounding, as a fraction of the range.
    const float bias = (texel + depthStep_m()) / range;
    const float depth = std::min(1.f, (q.depth - near_) / range) - bias;
    Pair out;
    if (mode != Mode::kReal)
        out.m = Vec3::Constant(lookup(mixed_, q, depth));
    if (mode != Mode::kMixed)
        out.r = Vec3::Constant(lookup(real_, q, depth));
    return out;
}

}  // namespace mixray::render::detail
