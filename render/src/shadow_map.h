// Shadow maps (Castro et al., "Realistic shadows for mobile AR", §IV): a light's visibility looked
// up in depth maps rendered from the light instead of traced per shading point. One map of the
// mixed scene and one of the real scene's ghosts, so that the differential I_m − I_r holds; the
// hard test, percentage-closer filtering and variance shadow maps (moments, separable Gaussian
// blur, Chebyshev's bound, light-bleeding reduction), each from float texels or from their 8-bit
// paths. Internal to mixray::render.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "frame_context.h"

namespace mixray::render::detail {

class ShadowMap {
public:
    // Renders `light`'s maps over the region where `casters` (the virtual objects' bounds) can
    // shadow: orthographic along a directional light, perspective from a point or sphere light's
    // centre. Null where one map cannot cover them (no casters, a light inside their bounds).
    // `objects` are the scene's, as EmbreeScene indexes them; `recycled`, a map of an earlier
    // frame whose memory is reused. Rows run in parallel: call it inside the renderer's arena.
    static std::unique_ptr<ShadowMap> render(const ShadowMapSettings& settings,
                                             const LightData& light,
                                             const std::vector<BoundSphere>& casters,
                                             const EmbreeScene& scene,
                                             const std::vector<ObjectData>& objects,
                                             std::unique_ptr<ShadowMap> recycled = nullptr);

    // The fractions of the light surface point `p` sees in the mixed and the real scene;
    // `n` is its geometric normal on the side facing the light (the lookup moves along it by a
    // texel and a half against self-shadowing). Only the scenes `mode` asks for are looked up,
    // as ShadowRays::visibility does. Empty outside the map: trace rays there.
    std::optional<Pair> visibility(const Vec3& p, const Vec3& n, Mode mode = Mode::kBoth) const;

    // How far apart texels are, in metres across the light's rays, at `p`.
    float texelSize(const Vec3& p) const;
    const ShadowMapSettings& settings() const { return settings_; }
    // The quantisation step of one stored depth, in metres (0 for float texels).
    float depthStep_m() const;
    // The depth texel (x, y) of the mixed scene's map holds, in metres along the light's ray, as
    // stored (VSM: the blurred mean); what the 8-bit paths lose is measured against it.
    float storedDepth_m(int x, int y) const;

private:
    // A light-space position: texel coordinates (x, y) and depth along the light's ray.
    struct LightSpace {
        float x, y, depth;
    };
    // Stored values of one scene (mixed or real): `components` per texel (depth; VSM: depth and
    // depth²), normalised over [near_, far_] and kept as settings_.storage says.
    struct Layer {
        std::vector<float> floats;
        std::vector<uint8_t> bytes;
    };

    explicit ShadowMap(const ShadowMapSettings& settings) : settings_(settings) {}
    LightSpace toLight(const Vec3& p) const;
    // The ray from the light through texel centre (x, y).
    void texelRay(float x, float y, Vec3& origin, Vec3& direction) const;
    // Keeps `normalised` in the storage's precision; float texels are swapped in, leaving
    // `normalised` holding the layer's previous values.
    void store(Layer& layer, std::vector<float>& normalised) const;
    float load(const Layer& layer, size_t texel, int component) const;
    float hardTest(const Layer& layer, int x, int y, float depth) const;
    float pcf(const Layer& layer, const LightSpace& q, float depth) const;
    float chebyshev(const Layer& layer, const LightSpace& q, float depth) const;
    float lookup(const Layer& layer, const LightSpace& q, float depth) const;

    ShadowMapSettings settings_;
    bool orthographic_ = true;
    Vec3 origin_;     // orthographic: the centre of the plane rays start from; else the light
    Vec3 u_, v_, w_;  // w_ along the light's rays
    float half_extent_ = 1;     // orthographic: metres; perspective: tan(half angle)
    float near_ = 0, far_ = 1;  // depth range the stored values span
    int res_ = 0;
    int components_ = 1;
    Layer mixed_, real_;
    std::vector<float> depth_mixed_, depth_real_, values_, pass_;  // render()'s scratch
};

}  // namespace mixray::render::detail
