// Caustics by photon mapping (Kán & Kaufmann §3.2): photons shot from the lights at the caustic
// generators' bounding spheres, reflected and refracted through specular surfaces with the
// renderer's Fresnel and per-channel indices, stored where they land on a diffuse surface after
// at least one specular bounce, and gathered with a fixed narrow Epanechnikov kernel from a hash
// grid. One map of the mixed scene and one of the real scene, so that a virtual glass's caustic
// on a real table enters the composite through I_m − I_r while a real mirror's, already in the
// camera image, cancels. Internal to mixray::render.
#pragma once

#include <cstdint>
#include <vector>

#include "frame_context.h"

namespace mixray::render::detail {

class DifferentialIntegrator;

// One photon where it landed: its power (W per channel), the normal of the surface there, and
// how many specular reflections and refractions brought it (2: into a glass and out).
struct Photon {
    Vec3 p;
    Vec3 power;
    Vec3 n;
    int specular_events = 0;
};

// Photons sorted into a hash grid of cells as wide as the kernel: a gather reads the 27 cells
// around the point. Hand-written: no Debian library has a fixed-radius grid, and nanoflann's
// k-d tree answers k-nearest queries this kernel does not need.
class PhotonGrid {
public:
    // `table`: the hash table's buckets, a power of two, 0 to size it to the photons. Two grids
    // with the same table and the same photons in the same order gather bit-identical sums.
    void build(std::vector<Photon> photons, float radius, size_t table = 0);
    static size_t tableFor(size_t photons);
    // Σ Φ_i K(|p − p_i|) over photons on the side `n` faces: irradiance, W/m².
    Vec3 irradiance(const Vec3& p, const Vec3& n) const;
    // Whether any photon lies within the kernel of p.
    bool near(const Vec3& p) const;
    const std::vector<Photon>& photons() const { return photons_; }
    Vec3 totalPower() const;

private:
    size_t cellOf(const Vec3& p, int dx, int dy, int dz) const;

    float radius_ = 0;
    std::vector<Photon> photons_;       // sorted by cell
    std::vector<uint32_t> cell_start_;  // table_size + 1 offsets into photons_
};

// A caustic generator: a specular object (mirror, metal, glass) and its role.
struct CausticGenerator {
    size_t object = 0;
    bool is_virtual = true;
};

// Figures of the last update(), for `mixray bench render`.
struct CausticTimes {
    double shoot_s = 0;  // t_p: tracing photons
    double build_s = 0;  // t_b: sorting them into the grids
    bool reshot = false;
    size_t stored_mixed = 0, stored_real = 0;
    size_t changed = 0;  // photons only one scene has
};

class CausticMaps {
public:
    // Finds the generators among `objects` (kept by reference, as the renderer's).
    CausticMaps(const CausticSettings& settings, const std::vector<ObjectData>& objects,
                const std::vector<MaterialData>& materials);

    // Shoots the frame's photons when a light or an object moved since the last frame (or the
    // depth surface exists: it changes every frame), else keeps them. Call inside the render
    // arena, after the frame's poses are set.
    void update(const Frame& f, const EmbreeScene& scene, const DifferentialIntegrator& integrator);

    // Caustic irradiance at surface point p (normal n, on the side light arrives from) in the
    // mixed and the real scene; only those `mode` asks for.
    Pair irradiance(const Vec3& p, const Vec3& n, Mode mode = Mode::kBoth) const {
        Pair out;
        if (mode != Mode::kReal)
            out.m = mixed_.irradiance(p, n);
        if (mode != Mode::kMixed)
            out.r = real_.irradiance(p, n);
        return out;
    }
    // Whether a caustic one scene has and the other has not reaches p: the footprint must shade
    // it. Photons the two scenes share (a real generator's, where nothing virtual is in their
    // way) gather bit-identical sums in both, so they change no pixel: the grids share a table
    // and the photons their order.
    bool near(const Vec3& p) const { return changed().near(p); }
    // Whether any photon landed this frame.
    bool landed() const { return !mixed_.photons().empty() || !real_.photons().empty(); }

    const PhotonGrid& mixed() const { return mixed_; }
    const PhotonGrid& real() const { return real_; }
    // The photons only one of the scenes has: what the footprint must cover.
    const PhotonGrid& changed() const {
        return changed_in_ == ChangedIn::kMixed  ? mixed_
               : changed_in_ == ChangedIn::kReal ? real_
                                                 : changed_;
    }
    const CausticTimes& times() const { return times_; }
    bool any() const { return !generators_.empty(); }

    // One photon's path from `origin` along `d` carrying `power` through `target` (all() or
    // ghosts()): where it lands after a specular bounce, if it does. Exposed for the tests.
    static void tracePhoton(const Vec3& origin, const Vec3& d, Vec3 power, RTCScene target,
                            const DifferentialIntegrator& integrator, optics::Rng& rng,
                            std::vector<Photon>& out);

private:
    // Photons of `lights` at the generators `use` picks, traced in `target`.
    std::vector<Photon> shoot(const Frame& f, RTCScene target, bool real_only,
                              const DifferentialIntegrator& integrator) const;
    // Light positions and object poses, to tell whether the photons still hold.
    std::vector<float> stateOf(const Frame& f) const;

    CausticSettings settings_;
    const std::vector<ObjectData>& objects_;
    std::vector<CausticGenerator> generators_;
    PhotonGrid mixed_, real_, changed_;
    // Where the changed photons are: all of one scene's when the other has none (no ghost
    // generator, say), else changed_.
    enum class ChangedIn : uint8_t { kMixed, kReal, kOwn };
    ChangedIn changed_in_ = ChangedIn::kOwn;
    std::vector<float> last_state_;
    CausticTimes times_;
};

}  // namespace mixray::render::detail
