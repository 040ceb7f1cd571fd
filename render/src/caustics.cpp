// Caustics by photon mapping (caustics.h).
#include "caustics.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <unordered_map>

#include "integrator.h"

namespace mixray::render::detail {
namespace {

// Photons from a directional light start this far before a generator towards the light, so that
// real surfaces between them and the light (a ceiling in the depth mesh) still block them.
constexpr float kDirectionalLead_m = 100;
// Specular bounces a photon may take before it is dropped (a photon caught between two mirrors).
constexpr int kMaxBounces = 12;
constexpr uint64_t kPhotonSeed = 0x63617573746963ULL;  // "caustic"

bool isGenerator(const Material& m) {
    return m.type == MaterialType::kMirror || m.type == MaterialType::kMetal ||
           m.type == MaterialType::kGlass;
}

// Shirley's concentric map of the unit square onto the unit disk: strata stay compact.
Vec2 concentricDisk(float u, float v) {
    const float a = 2 * u - 1, b = 2 * v - 1;
    if (a == 0 && b == 0)
        return Vec2::Zero();
    float r, phi;
    if (a * a > b * b) {
        r = a;
        phi = (optics::kPi / 4) * (b / a);
    } else {
        r = b;
        phi = (optics::kPi / 2) - (optics::kPi / 4) * (a / b);
    }
    return {r * std::cos(phi), r * std::sin(phi)};
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// PhotonGrid

size_t PhotonGrid::cellOf(const Vec3& p, int dx, int dy, int dz) const {
    const auto cell = [&](float x, int d) {
        return static_cast<int64_t>(std::floor(x / radius_)) + d;
    };
    const uint64_t h = static_cast<uint64_t>(cell(p.x(), dx)) * 73856093ULL ^
                       static_cast<uint64_t>(cell(p.y(), dy)) * 19349663ULL ^
                       static_cast<uint64_t>(cell(p.z(), dz)) * 83492791ULL;
    return static_cast<size_t>(h & (cell_start_.size() - 2));
}

size_t PhotonGrid::tableFor(size_t photons) {
    size_t table = 1024;
    while (table < 2 * photons)
        table *= 2;
    return table;
}

void PhotonGrid::build(std::vector<Photon> photons, float radius, size_t table) {
    radius_ = radius;
    if (table == 0)
        table = tableFor(photons.size());
    cell_start_.assign(table + 1, 0);
    std::vector<uint32_t> cell(photons.size());
    for (size_t i = 0; i < photons.size(); ++i) {
        cell[i] = static_cast<uint32_t>(cellOf(photons[i].p, 0, 0, 0));
        ++cell_start_[cell[i] + 1];
    }
    for (size_t c = 0; c < table; ++c)
        cell_start_[c + 1] += cell_start_[c];
    photons_.resize(photons.size());
    std::vector<uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
    for (size_t i = 0; i < photons.size(); ++i)
        photons_[fill[cell[i]]++] = photons[i];
}

Vec3 PhotonGrid::irradiance(const Vec3& p, const Vec3& n) const {
    Vec3 sum = Vec3::Zero();
    if (photons_.empty())
        return sum;
    // The 27 cells around p; hashing may send two of them to one bucket: read it once.
    std::array<size_t, 27> seen;
    int n_seen = 0;
    const float r2 = radius_ * radius_;
    const float norm = 2 / (optics::kPi * r2);  // the 2D Epanechnikov kernel integrates to 1
    for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                const size_t c = cellOf(p, dx, dy, dz);
                if (std::find(seen.begin(), seen.begin() + n_seen, c) != seen.begin() + n_seen)
                    continue;
                seen[static_cast<size_t>(n_seen++)] = c;
                for (uint32_t i = cell_start_[c]; i < cell_start_[c + 1]; ++i) {
                    const Photon& ph = photons_[i];
                    const float d2 = (ph.p - p).squaredNorm();
                    if (d2 < r2 && ph.n.dot(n) > 0)
                        sum += ph.power * (norm * (1 - d2 / r2));
                }
            }
    return sum;
}

bool PhotonGrid::near(const Vec3& p) const {
    if (photons_.empty())
        return false;
    const float r2 = radius_ * radius_;
    for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                const size_t c = cellOf(p, dx, dy, dz);
                for (uint32_t i = cell_start_[c]; i < cell_start_[c + 1]; ++i)
                    if ((photons_[i].p - p).squaredNorm() < r2)
                        return true;
            }
    return false;
}

Vec3 PhotonGrid::totalPower() const {
    Vec3 sum = Vec3::Zero();
    for (const Photon& ph : photons_)
        sum += ph.power;
    return sum;
}

// ---------------------------------------------------------------------------------------------
// CausticMaps

CausticMaps::CausticMaps(const CausticSettings& settings, const std::vector<ObjectData>& objects,
                         const std::vector<MaterialData>& materials)
    : settings_(settings), objects_(objects) {
    for (size_t i = 0; i < objects.size(); ++i) {
        const ObjectData& o = objects[i];
        if (o.depth_surface || !isGenerator(materials[static_cast<size_t>(o.material)].material))
            continue;
        generators_.push_back({i, o.role == ObjectRole::kVirtual});
    }
}

void CausticMaps::tracePhoton(const Vec3& origin, const Vec3& d_in, Vec3 power, RTCScene target,
                              const DifferentialIntegrator& integrator, optics::Rng& rng,
                              std::vector<Photon>& out) {
    Vec3 o = origin, d = d_in;
    int specular = 0;
    int channel = -1;  // set once dispersion picks one
    for (int bounce = 0; bounce <= kMaxBounces; ++bounce) {
        const Hit hit = EmbreeScene::intersect(target, o, d, kInf);
        if (!hit.valid)
            return;
        const Surface s = integrator.surfaceAt(hit, o, d);
        const Material& mat = s.material->material;
        const bool entering = s.n_geometric.dot(d) < 0;
        const Vec3 n_geo = entering ? s.n_geometric : Vec3(-s.n_geometric);
        const Vec3 n = entering ? s.n_shading : Vec3(-s.n_shading);
        const float eps = offsetFor(s.p);
        const auto reflectOff = [&] {
            d = optics::reflect(d, n).normalized();
            o = s.p + eps * n_geo;
        };
        switch (mat.type) {
            case MaterialType::kDiffuse:
            case MaterialType::kPhong:
                // RT²AR's reflectance: that share of the photons goes on as a mirror's.
                if (mat.reflectance > 0 && rng.uniform() < mat.reflectance) {
                    reflectOff();
                    break;
                }
                if (specular > 0)
                    out.push_back({s.p, power, n_geo, specular});
                return;
            case MaterialType::kMirror:
                power *= mat.reflectance > 0 ? mat.reflectance : 1.f;
                reflectOff();
                break;
            case MaterialType::kMetal: {
                const float cos_i = std::clamp(-d.dot(n), 0.f, 1.f);
                for (int c = 0; c < 3; ++c)
                    power[c] *= optics::schlick(mat.f0[c], cos_i);
                reflectOff();
                break;
            }
            case MaterialType::kGlass: {
                if (!entering)
                    for (int c = 0; c < 3; ++c)
                        power[c] *= std::pow(std::max(mat.transmission[c], 0.f), hit.t);
                const bool dispersive = mat.ior.x() != mat.ior.y() || mat.ior.x() != mat.ior.z();
                if (dispersive && channel < 0) {
                    // One wavelength band per photon, its power three times its share.
                    channel = std::min(2, static_cast<int>(rng.uniform() * 3));
                    const float keep = 3 * power[channel];
                    power = Vec3::Zero();
                    power[channel] = keep;
                }
                const float ior = mat.ior[channel < 0 ? 0 : channel];
                const float n_from = entering ? 1.f : ior, n_to = entering ? ior : 1.f;
                const float cos_i = std::clamp(-d.dot(n), 0.f, 1.f);
                const auto refracted = optics::refract(d, n, n_from / n_to);
                const float reflectance =
                    refracted ? optics::dielectricReflectance(cos_i, n_from, n_to) : 1.f;
                // Russian roulette on Fresnel: the photon keeps its power either way.
                if (rng.uniform() < reflectance) {
                    reflectOff();
                } else {
                    d = *refracted;
                    o = s.p - eps * n_geo;
                }
                break;
            }
        }
        ++specular;
        if (!(power.maxCoeff() > 1e-20f))
            return;
    }
}

std::vector<Photon> CausticMaps::shoot(const Frame& f, RTCScene target, bool real_only,
                                       const DifferentialIntegrator& integrator) const {
    struct Aim {
        Vec3 centre;
        float radius;
        size_t generator;  // index in generators_: the photons' seeds
        bool shot;         // shot in this scene
    };
    // Every active generator is aimed at in both scenes with the same photons, so that a real
    // generator's caustic is the same in I_m and I_r where nothing virtual changes it.
    std::vector<Aim> aims;
    for (size_t g = 0; g < generators_.size(); ++g) {
        const ObjectData& o = objects_[generators_[g].object];
        if (!o.active)
            continue;
        aims.push_back({o.R_world_object * o.bound_centre + o.t_world_object,
                        o.bound_radius * 1.001f + 1e-4f, g,
                        !real_only || !generators_[g].is_virtual});
    }
    // Blocks of photons stored in block order: the same photons in the same order on every run,
    // and a ghost generator's in the same order in both scenes (changedPhotons() relies on it).
    constexpr int kBlock = 256;
    std::vector<std::vector<Photon>> stored;
    if (aims.empty() || f.lights.empty())
        return {};
    const int per_light = std::max(1, settings_.photons / static_cast<int>(f.lights.size()));
    for (size_t l = 0; l < f.lights.size(); ++l) {
        const LightData& light = *f.lights[l];
        const bool directional = light.light.type == LightType::kDirectional;
        const Vec3 from = light.position_world;
        const Vec3 travel = light.direction_world;
        // What each aim catches of the light: a solid angle, or an area across the beam.
        std::vector<float> catches(aims.size());
        std::vector<float> cos_half(aims.size(), 1.f);
        for (size_t a = 0; a < aims.size(); ++a) {
            if (directional) {
                catches[a] = optics::kPi * aims[a].radius * aims[a].radius;
            } else {
                const float dist = (aims[a].centre - from).norm();
                const float s = std::min(1.f, aims[a].radius / std::max(dist, 1e-6f));
                cos_half[a] = dist > aims[a].radius ? std::sqrt(1 - s * s) : -1.f;
                catches[a] = 2 * optics::kPi * (1 - cos_half[a]);
            }
        }
        float total = 0;
        for (float c : catches)
            total += c;
        for (size_t a = 0; a < aims.size(); ++a) {
            if (!aims[a].shot)
                continue;
            const int count = std::max(
                1,
                static_cast<int>(std::lround(per_light * static_cast<double>(catches[a] / total))));
            const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(count))));
            const Aim aim = aims[a];
            const Vec3 axis = directional ? travel : Vec3((aim.centre - from).normalized());
            const Vec3 u = axis.unitOrthogonal(), v = axis.cross(u);
            const Vec3 power_per = light.light.intensity * (catches[a] / static_cast<float>(count));
            const size_t first_block = stored.size();
            const int blocks = (count + kBlock - 1) / kBlock;
            stored.resize(first_block + static_cast<size_t>(blocks));
            tbb::parallel_for(0, blocks, [&](int block) {
                std::vector<Photon>& out = stored[first_block + static_cast<size_t>(block)];
                for (int i = block * kBlock; i < std::min(count, (block + 1) * kBlock); ++i) {
                    optics::Rng rng(hashIndex(kPhotonSeed ^ (static_cast<uint64_t>(l) << 32),
                                              aim.generator, static_cast<uint64_t>(i)));
                    // Stratified and jittered over the disk or the cone.
                    const float su =
                        (static_cast<float>(i % side) + rng.uniform()) / static_cast<float>(side);
                    const float sv = (static_cast<float>(i / side % side) + rng.uniform()) /
                                     static_cast<float>(side);
                    Vec3 origin, dir;
                    if (directional) {
                        const Vec2 q = concentricDisk(su, sv) * aim.radius;
                        const Vec3 point = aim.centre + q.x() * u + q.y() * v;
                        dir = axis;
                        origin = point - (aim.radius + kDirectionalLead_m) * axis;
                    } else {
                        const float cos_t = 1 - su * (1 - cos_half[a]);
                        const float sin_t = std::sqrt(std::max(0.f, 1 - cos_t * cos_t));
                        const float phi = 2 * optics::kPi * sv;
                        dir = (sin_t * std::cos(phi) * u + sin_t * std::sin(phi) * v + cos_t * axis)
                                  .normalized();
                        origin = from;
                    }
                    // Aims overlapping along this direction share it: each sampled it.
                    int overlap = 0;
                    for (size_t b = 0; b < aims.size(); ++b) {
                        if (!aims[b].shot)
                            continue;
                        if (directional) {
                            const Vec3 c = aims[b].centre - origin;
                            overlap += (c - c.dot(dir) * dir).norm() <= aims[b].radius ? 1 : 0;
                        } else {
                            overlap += dir.dot((aims[b].centre - from).normalized()) >= cos_half[b]
                                           ? 1
                                           : 0;
                        }
                    }
                    tracePhoton(origin, dir, power_per / static_cast<float>(std::max(1, overlap)),
                                target, integrator, rng, out);
                }
            });
        }
    }
    std::vector<Photon> all;
    for (const std::vector<Photon>& part : stored)
        all.insert(all.end(), part.begin(), part.end());
    return all;
}

std::vector<float> CausticMaps::stateOf(const Frame& f) const {
    std::vector<float> state;
    for (const LightData* light : f.lights) {
        state.insert(state.end(), light->position_world.data(), light->position_world.data() + 3);
        state.insert(state.end(), light->direction_world.data(), light->direction_world.data() + 3);
        state.insert(state.end(), light->light.intensity.data(), light->light.intensity.data() + 3);
    }
    for (const ObjectData& o : objects_) {
        state.push_back(o.active ? 1.f : 0.f);
        state.insert(state.end(), o.R_world_object.data(), o.R_world_object.data() + 9);
        state.insert(state.end(), o.t_world_object.data(), o.t_world_object.data() + 3);
    }
    return state;
}

namespace {

// The photons of `a` that `b` has not and of `b` that `a` has not, as multisets, by their
// exact position and power.
std::vector<Photon> changedPhotons(const std::vector<Photon>& a, const std::vector<Photon>& b) {
    using Key = std::array<uint32_t, 6>;
    struct KeyHash {
        size_t operator()(const Key& k) const {
            uint64_t h = 1469598103934665603ull;
            for (uint32_t v : k)
                h = (h ^ v) * 1099511628211ull;
            return static_cast<size_t>(h);
        }
    };
    const auto keyOf = [](const Photon& ph) {
        Key k;
        std::memcpy(k.data(), ph.p.data(), 3 * sizeof(float));
        std::memcpy(k.data() + 3, ph.power.data(), 3 * sizeof(float));
        return k;
    };
    std::unordered_map<Key, int, KeyHash> count;
    count.reserve(a.size());
    for (const Photon& ph : a)
        ++count[keyOf(ph)];
    std::vector<Photon> out;
    for (const Photon& ph : b) {
        auto found = count.find(keyOf(ph));
        if (found != count.end() && found->second > 0)
            --found->second;
        else
            out.push_back(ph);
    }
    for (const Photon& ph : a) {
        auto found = count.find(keyOf(ph));
        if (found->second > 0) {
            --found->second;
            out.push_back(ph);
        }
    }
    return out;
}

}  // namespace

void CausticMaps::update(const Frame& f, const EmbreeScene& scene,
                         const DifferentialIntegrator& integrator) {
    std::vector<float> state = stateOf(f);
    times_.reshot = f.depth_mesh || state != last_state_;
    if (!times_.reshot)
        return;
    last_state_ = std::move(state);
    const auto start = std::chrono::steady_clock::now();
    std::vector<Photon> mixed = shoot(f, scene.all(), false, integrator);
    std::vector<Photon> real = shoot(f, scene.ghosts(), true, integrator);
    const auto shot = std::chrono::steady_clock::now();
    times_.stored_mixed = mixed.size();
    times_.stored_real = real.size();
    // Without photons in one scene (no ghost generator, say), all of the other's changed.
    changed_in_ = real.empty()    ? ChangedIn::kMixed
                  : mixed.empty() ? ChangedIn::kReal
                                  : ChangedIn::kOwn;
    changed_.build(
        changed_in_ == ChangedIn::kOwn ? changedPhotons(mixed, real) : std::vector<Photon>{},
        settings_.radius_m);
    times_.changed = changed_in_ == ChangedIn::kMixed  ? mixed.size()
                     : changed_in_ == ChangedIn::kReal ? real.size()
                                                       : changed_.photons().size();
    const size_t table = PhotonGrid::tableFor(std::max(mixed.size(), real.size()));
    mixed_.build(std::move(mixed), settings_.radius_m, table);
    real_.build(std::move(real), settings_.radius_m, table);
    const auto built = std::chrono::steady_clock::now();
    times_.shoot_s = std::chrono::duration<double>(shot - start).count();
    times_.build_s = std::chrono::duration<double>(built - shot).count();
}

}  // namespace mixray::render::detail
