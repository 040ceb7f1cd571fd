// The sun's position from place and time: the PSA algorithm (Blanco-Muriel et al. 2001, the one
// "Realistic Shadows for Mobile AR" uses, with the coefficients of Blanco, Milidonis & Bonanos
// 2020 or the original ones) and NREL's SPA (Reda & Andreas 2004, the reference), and the sun's
// direction in the world (marker) frame from the rig's site. docs/tracking.md ("Sun") lists the
// accuracy measured against ERFA.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string_view>

#include "mixray/graph/result.h"
#include "mixray/graph/rig.h"

namespace mixray::tracking {

enum class SunAlgorithm : uint8_t {
    // Plataforma Solar de Almería, 2020 coefficients (fitted 2020–2050): fast; within 0.0086°
    // of SPA over 2000–2050.
    kPsa,
    // NREL Solar Position Algorithm: ±0.0003° over -2000..6000 (the report); within 0.00014° of
    // ERFA over 2000–2050.
    kSpa,
    // PSA with the 2001 coefficients the paper used (fitted 1999–2015): within 0.0096° of SPA
    // over 2000–2050.
    kPsa2001,
};

std::string_view toString(SunAlgorithm algorithm);

// Where and when. Plain value.
struct SunQuery {
    double latitude_deg = 0;   // north positive
    double longitude_deg = 0;  // east positive
    double altitude_m = 0;
    int64_t utc_ns = 0;       // since the Unix epoch, UTC (taken as UT1: |UT1 − UTC| < 0.9 s)
    double delta_t_s = 69.2;  // TT − UT1 (SPA's ΔT), -8000..8000; PSA ignores it
    // Atmospheric refraction (SPA's model, both algorithms); pressure 0 for the geometric
    // position. Pressure 0..5000 mbar, temperature -273..6000 °C (SPA's limits).
    double pressure_mbar = 1013.25;
    double temperature_c = 15;

    Status validate() const;
};

// The sun as seen from the site. Plain value.
struct SunPosition {
    double zenith_deg = 0;   // topocentric, refraction-corrected when asked
    double azimuth_deg = 0;  // clockwise from true north, 0..360
    double elevation_deg() const { return 90 - zenith_deg; }
    // Unit vector towards the sun in east-north-up coordinates.
    Eigen::Vector3d toSunEnu() const;
};

// kInvalidArgument naming the field for a bad query (latitude -90..90, longitude -180..180,
// altitude above -6 500 km, SPA's limits). Reentrant.
Result<SunPosition> sunPosition(const SunQuery& query, SunAlgorithm algorithm = SunAlgorithm::kSpa);

// The rotation from the world (marker) frame to east-north-up at the site: from the site's
// heading (the compass bearing of the world frame's +y axis, the world's +z being up) or, when
// the site gives one, the device orientation. Reentrant.
Eigen::Matrix3d enuFromWorld(const RigSite& site);

// The sun's direction (towards the sun, unit) in the world frame at `utc_ns`, refracted for the
// standard atmosphere at the site's altitude (15 °C, 1013.25 mbar at sea level) and ΔT = 69.2 s.
// kInvalidArgument for a site out of range or an orientation that is no unit quaternion.
// Reentrant.
Result<Eigen::Vector3d> sunDirectionWorld(const RigSite& site, int64_t utc_ns,
                                          SunAlgorithm algorithm = SunAlgorithm::kSpa);

}  // namespace mixray::tracking
