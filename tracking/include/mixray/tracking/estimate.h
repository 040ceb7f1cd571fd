// What tracking hands on: estimated lights, and estimates that remember when they were last
// good, so a pipeline keeps the last good value, marks it stale and says why.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace mixray::tracking {

// Where an estimated light came from.
enum class LightSource : uint8_t {
    kProbeMirror,   // highlight on a mirror light-probe sphere
    kProbeDiffuse,  // shading of a diffuse light-probe sphere
    kEnvironment,   // bright blob in the fish-eye environment image
    kSun,           // the sun's computed position
};

std::string_view toString(LightSource source);

// One light source as estimated. Directions are unit vectors in the world (marker) frame,
// pointing from the scene towards the light. Plain value.
struct EstimatedLight {
    LightSource source = LightSource::kEnvironment;
    Eigen::Vector3d to_light_world{0, 0, 1};
    // Linear RGB. Environment: irradiance the light gives a surface facing it (the blob's
    // radiance integrated over its solid angle). Probes: relative strength, the brightest
    // light 1 (a probe alone cannot tell absolute intensity).
    Eigen::Vector3d intensity{1, 1, 1};
    double angular_radius_rad = 0;  // apparent size (0: unknown / point-like)
    // Where the light is when the room size is configured (environment); else empty.
    std::optional<Eigen::Vector3d> position_world;
    double weight = 0;  // the evidence's size: pixels of its component or blob
};

// The state of a value estimated frame by frame. `stale` is true when the latest input gave no
// good estimate and `value` is the last good one (or none yet); `reason` says why, in words a
// user can act on ("marker 23 not seen", "environment image over-exposed").
template <typename T>
struct Estimate {
    std::optional<T> value;
    bool stale = true;
    std::string reason;         // empty when fresh
    int64_t stamp_ns = 0;       // of the input this estimate answers
    int64_t good_stamp_ns = 0;  // of the input `value` came from
    int64_t updates = 0;        // fresh estimates so far
    int64_t stale_updates = 0;  // inputs that gave none so far

    // A fresh value for input at `stamp`.
    void update(T fresh, int64_t stamp) {
        value = std::move(fresh);
        stale = false;
        reason.clear();
        stamp_ns = good_stamp_ns = stamp;
        ++updates;
    }
    // No good value from input at `stamp`: keep the last one, mark it stale, say why.
    void keep(std::string why, int64_t stamp) {
        stale = true;
        reason = std::move(why);
        stamp_ns = stamp;
        ++stale_updates;
    }
};

}  // namespace mixray::tracking
