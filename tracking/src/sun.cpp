// The sun's position (SPA or PSA, spa.cpp) and its direction in the world (marker) frame.
#include "mixray/tracking/sun.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>

#include "spa.h"

namespace mixray::tracking {
namespace {

constexpr double kRad = std::numbers::pi / 180;

Status invalid(std::string what) {
    return Status(ErrorCode::kInvalidArgument, "sun query: " + std::move(what));
}

bool within(double value, double min, double max) {
    return value >= min && value <= max;
}

// Julian day (UT) of a Unix time; JD 2440587.5 is the Unix epoch. A double resolves a Julian
// day to about 40 µs, which moves the sun by 1e-9°.
double julianDay(int64_t utc_ns) {
    return 2440587.5 + static_cast<double>(utc_ns) * 1e-9 / 86400;
}

// The standard atmosphere's pressure at an altitude (ISA troposphere), for sites whose file
// gives no weather.
double standardPressureMbar(double altitude_m) {
    const double base = 1 - 2.25577e-5 * std::max(altitude_m, -11000.0);
    return base > 0 ? 1013.25 * std::pow(base, 5.25588) : 0;
}

}  // namespace

std::string_view toString(SunAlgorithm algorithm) {
    switch (algorithm) {
        case SunAlgorithm::kPsa:
            return "psa";
        case SunAlgorithm::kSpa:
            return "spa";
        case SunAlgorithm::kPsa2001:
            return "psa-2001";
    }
    return "unknown";
}

Status SunQuery::validate() const {
    if (!within(latitude_deg, -90, 90))
        return invalid("latitude_deg must be in -90..90, got " + std::to_string(latitude_deg));
    if (!within(longitude_deg, -180, 180))
        return invalid("longitude_deg must be in -180..180, got " + std::to_string(longitude_deg));
    if (!within(altitude_m, -6'500'000, 1e9))
        return invalid("altitude_m must be above -6500000, got " + std::to_string(altitude_m));
    if (!within(delta_t_s, -8000, 8000))
        return invalid("delta_t_s must be in -8000..8000, got " + std::to_string(delta_t_s));
    if (!within(pressure_mbar, 0, 5000))
        return invalid("pressure_mbar must be in 0..5000, got " + std::to_string(pressure_mbar));
    if (!(temperature_c > -273 && temperature_c < 6000)) {
        return invalid("temperature_c must be in -273..6000, got " + std::to_string(temperature_c));
    }
    return Status::ok();
}

Eigen::Vector3d SunPosition::toSunEnu() const {
    const double zenith = zenith_deg * kRad;
    const double azimuth = azimuth_deg * kRad;
    return {std::sin(zenith) * std::sin(azimuth), std::sin(zenith) * std::cos(azimuth),
            std::cos(zenith)};
}

Result<SunPosition> sunPosition(const SunQuery& query, SunAlgorithm algorithm) {
    MIXRAY_RETURN_IF_ERROR(query.validate());
    const double jd = julianDay(query.utc_ns);
    if (algorithm == SunAlgorithm::kSpa) {
        const detail::SpaOutput out = detail::spa({.jd = jd,
                                                   .delta_t_s = query.delta_t_s,
                                                   .latitude_deg = query.latitude_deg,
                                                   .longitude_deg = query.longitude_deg,
                                                   .elevation_m = query.altitude_m,
                                                   .pressure_mbar = query.pressure_mbar,
                                                   .temperature_c = query.temperature_c});
        return SunPosition{.zenith_deg = out.zenith, .azimuth_deg = out.azimuth};
    }
    const detail::PsaOutput out =
        detail::psa(jd, query.latitude_deg, query.longitude_deg,
                    algorithm == SunAlgorithm::kPsa2001 ? detail::PsaCoefficients::k2001
                                                        : detail::PsaCoefficients::k2020);
    const double e0 = 90 - out.zenith_deg;
    const double refraction = detail::spaRefraction(e0, query.pressure_mbar, query.temperature_c);
    return SunPosition{.zenith_deg = out.zenith_deg - refraction, .azimuth_deg = out.azimuth_deg};
}

Eigen::Matrix3d enuFromWorld(const RigSite& site) {
    if (site.orientation_wxyz) {
        const auto& q = *site.orientation_wxyz;
        return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
    }
    // The world's +y has bearing h: it points to (sin h, cos h, 0) in ENU, and +z is up, so the
    // world turns clockwise (seen from above) by h: a rotation of -h about up.
    return Eigen::AngleAxisd(-site.heading_deg * kRad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

Result<Eigen::Vector3d> sunDirectionWorld(const RigSite& site, int64_t utc_ns,
                                          SunAlgorithm algorithm) {
    if (site.orientation_wxyz) {
        const auto& q = *site.orientation_wxyz;
        const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (!(std::abs(norm - 1) <= 1e-3)) {
            return Status(
                ErrorCode::kInvalidArgument,
                "site: orientation is not a unit quaternion (norm " + std::to_string(norm) + ")");
        }
    }
    if (!std::isfinite(site.heading_deg)) {
        return Status(ErrorCode::kInvalidArgument,
                      "site: heading_deg must be finite, got " + std::to_string(site.heading_deg));
    }
    SunQuery query;
    query.latitude_deg = site.latitude_deg;
    query.longitude_deg = site.longitude_deg;
    query.altitude_m = site.altitude_m;
    query.utc_ns = utc_ns;
    query.pressure_mbar = standardPressureMbar(site.altitude_m);
    auto position = sunPosition(query, algorithm);
    if (!position)
        return position.status();
    return Eigen::Vector3d(enuFromWorld(site).transpose() * position->toSunEnu());
}

}  // namespace mixray::tracking
