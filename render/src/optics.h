// Closed-form optics the integrator shades with: reflection, Snell refraction, Schlick Fresnel,
// sRGB transfer and stratified light-disc samples. Header-only so the tests check them directly.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <vector>

namespace mixray::render::optics {

inline constexpr float kPi = 3.14159265358979323846f;

// Mirror direction of `d` (travelling towards the surface) about the unit normal `n`.
[[gnu::always_inline]] inline Eigen::Vector3f reflect(const Eigen::Vector3f& d,
                                                      const Eigen::Vector3f& n) {
    return d - 2.f * d.dot(n) * n;
}

// Snell refraction of the unit direction `d` through a surface with unit normal `n` facing the
// incoming ray (d·n < 0), `eta` = n_from / n_to. nullopt on total internal reflection.
inline std::optional<Eigen::Vector3f> refract(const Eigen::Vector3f& d, const Eigen::Vector3f& n,
                                              float eta) {
    const float cos_i = -d.dot(n);
    const float sin2_t = eta * eta * std::max(0.f, 1.f - cos_i * cos_i);
    if (sin2_t >= 1.f)
        return std::nullopt;
    const float cos_t = std::sqrt(1.f - sin2_t);
    return (eta * d + (eta * cos_i - cos_t) * n).normalized();
}

// Reflectance at normal incidence between media of indices n1 and n2: ((n1-n2)/(n1+n2))^2.
inline float fresnelR0(float n1, float n2) {
    const float r = (n1 - n2) / (n1 + n2);
    return r * r;
}

// Schlick's approximation F = F0 + (1 - F0)(1 - cos θ)^5, θ the angle to the normal.
inline float schlick(float f0, float cos_theta) {
    const float m = std::clamp(1.f - cos_theta, 0.f, 1.f);
    const float m2 = m * m;
    return f0 + (1.f - f0) * m2 * m2 * m;
}

// Fresnel reflectance of a dielectric interface for a ray arriving with cosine `cos_i` from the
// medium of index n_from into n_to. Schlick's formula holds for the angle on the denser side, so
// leaving a dense medium uses the transmitted angle; 1 beyond the critical angle.
inline float dielectricReflectance(float cos_i, float n_from, float n_to) {
    const float f0 = fresnelR0(n_from, n_to);
    if (n_from <= n_to)
        return schlick(f0, cos_i);
    const float eta = n_from / n_to;
    const float sin2_t = eta * eta * std::max(0.f, 1.f - cos_i * cos_i);
    if (sin2_t >= 1.f)
        return 1.f;
    return schlick(f0, std::sqrt(1.f - sin2_t));
}

inline float srgbToLinear(float c) {
    return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

inline float linearToSrgb(float c) {
    c = std::clamp(c, 0.f, 1.f);
    return c <= 0.0031308f ? c * 12.92f : 1.055f * std::pow(c, 1.f / 2.4f) - 0.055f;
}

// The 8-bit sRGB code of a linear value, by the formula: pow per channel.
inline uint8_t encodeSrgb8ByFormula(float linear) {
    return static_cast<uint8_t>(std::lround(linearToSrgb(linear) * 255.f));
}

// encodeSrgb8ByFormula() without pow, giving the same byte for every float: the code is the
// number of the 255 thresholds (the least float of each code 1..255, found once by bisection
// on the formula itself) at or below the value. A table indexed by the float's top bits gives
// the code at the bottom of its bucket, and at most a few thresholds are stepped over from
// there. The composite encodes every pixel it traces, and pow was a sixth of a full frame.
class SrgbEncoder {
public:
    static const SrgbEncoder& instance() {
        static const SrgbEncoder encoder;
        return encoder;
    }
    uint8_t encode(float linear) const {
        if (!(linear > 0))  // negative, zero and NaN: as the formula, whose clamp gives 0
            return linear == linear ? 0 : encodeSrgb8ByFormula(linear);
        if (linear >= 1)
            return 255;
        uint32_t code = bucket_code_[bucketOf(linear)];
        while (code < 255 && linear >= threshold_[code + 1])
            ++code;
        return static_cast<uint8_t>(code);
    }

private:
    static constexpr int kShift = 17;  // 2^6 buckets per power of two below 1
    static uint32_t bitsOf(float v) {
        uint32_t b;
        std::memcpy(&b, &v, sizeof b);
        return b;
    }
    static float floatOf(uint32_t b) {
        float v;
        std::memcpy(&v, &b, sizeof v);
        return v;
    }
    static size_t bucketOf(float v) { return bitsOf(v) >> kShift; }

    SrgbEncoder() {
        // Positive floats order as their bits: bisect each code's least float in (0, 1].
        threshold_[0] = 0;
        for (int code = 1; code < 256; ++code) {
            uint32_t lo = 0, hi = bitsOf(1.f);  // encode(lo) < code <= encode(hi)
            while (hi - lo > 1) {
                const uint32_t mid = lo + (hi - lo) / 2;
                (encodeSrgb8ByFormula(floatOf(mid)) >= code ? hi : lo) = mid;
            }
            threshold_[code] = floatOf(hi);
        }
        bucket_code_.resize(bucketOf(1.f) + 1);
        for (size_t b = 0; b < bucket_code_.size(); ++b)
            bucket_code_[b] = encodeSrgb8ByFormula(floatOf(static_cast<uint32_t>(b << kShift)));
    }

    std::array<float, 256> threshold_{};
    std::vector<uint8_t> bucket_code_;
};

inline uint8_t encodeSrgb8(float linear) {
    return SrgbEncoder::instance().encode(linear);
}

// Point k of n on the unit disc: a golden-angle spiral, stratified in area (ring k holds area
// 1/n), jittered by `jitter` in [0,1) and rotated by `rotation` radians so neighbouring pixels
// do not share one pattern.
inline Eigen::Vector2f discSample(int k, int n, float jitter, float rotation) {
    constexpr float kGoldenAngle = 2.39996322972865332f;
    const float r = std::sqrt((static_cast<float>(k) + jitter) / static_cast<float>(n));
    const float phi = static_cast<float>(k) * kGoldenAngle + rotation;
    return {r * std::cos(phi), r * std::sin(phi)};
}

// A small, fast, deterministic generator (splitmix64) for per-pixel sampling.
class Rng {
public:
    Rng() = default;  // seed 0: for arrays, each given a seeded one before use
    explicit Rng(uint64_t seed) : state_(seed) {}
    uint64_t next() {
        uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
        return z ^ (z >> 31);
    }
    // Uniform in [0, 1).
    float uniform() { return static_cast<float>(next() >> 40) * (1.f / 16777216.f); }

private:
    uint64_t state_ = 0;
};

}  // namespace mixray::render::optics
