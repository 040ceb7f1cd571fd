// SPA (Reda & Andreas 2004) step by step in the report's notation, and PSA (Blanco-Muriel et
// al. 2001, coefficients updated by Blanco, Milidonis & Bonanos 2020).
#include "spa.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

namespace mixray::tracking::detail {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kRad = kPi / 180;
constexpr double kDeg = 180 / kPi;

double sind(double deg) {
    return std::sin(deg * kRad);
}
double cosd(double deg) {
    return std::cos(deg * kRad);
}
double tand(double deg) {
    return std::tan(deg * kRad);
}

// Into [0, 360).
double wrap360(double deg) {
    double wrapped = std::fmod(deg, 360.0);
    return wrapped < 0 ? wrapped + 360 : wrapped;
}

double seriesSum(std::span<const PeriodicTerm> terms, double jme) {
    double sum = 0;
    for (const PeriodicTerm& t : terms)
        sum += t.a * std::cos(t.b + t.c * jme);
    return sum;
}

// Σ_i S_i·τ^i / 1e8 over the series of one quantity (Table A4.2 is in units of 1e-8).
double earthValue(std::span<const std::span<const PeriodicTerm>> series, double jme) {
    double value = 0;
    double power = 1;
    for (std::span<const PeriodicTerm> s : series) {
        value += seriesSum(s, jme) * power;
        power *= jme;
    }
    return value / 1e8;
}

double cubic(double a, double b, double c, double d, double t) {
    return a + t * (b + t * (c + t * d));
}

// The sun's apparent radius plus the standard refraction at the horizon (SPA's defaults): below
// this elevation the sun has set even with refraction, and SPA adds none.
constexpr double kSunRadiusDeg = 0.26667;
constexpr double kHorizonRefractionDeg = 0.5667;

}  // namespace

double spaRefraction(double e0_deg, double pressure_mbar, double temperature_c) {
    if (pressure_mbar <= 0 || e0_deg < -(kSunRadiusDeg + kHorizonRefractionDeg))
        return 0;
    return (pressure_mbar / 1010.0) * (283.0 / (273.0 + temperature_c)) * 1.02 /
           (60.0 * tand(e0_deg + 10.3 / (e0_deg + 5.11)));
}

SpaOutput spa(const SpaInput& in) {
    SpaOutput o;
    // 3.1 Julian day, ephemeris day, centuries and millennium.
    o.jde = in.jd + in.delta_t_s / 86400.0;
    o.jc = (in.jd - 2451545.0) / 36525.0;
    o.jce = (o.jde - 2451545.0) / 36525.0;
    o.jme = o.jce / 10.0;

    // 3.2 Earth heliocentric longitude, latitude and radius vector.
    o.l = wrap360(earthValue(kSpaL, o.jme) * kDeg);
    o.b = earthValue(kSpaB, o.jme) * kDeg;
    o.r_au = earthValue(kSpaR, o.jme);

    // 3.3 Geocentric longitude and latitude.
    o.theta = wrap360(o.l + 180.0);
    o.beta = -o.b;

    // 3.4 Nutation in longitude and obliquity.
    const double t = o.jce;
    o.x[0] = cubic(297.85036, 445267.111480, -0.0019142, 1.0 / 189474.0, t);
    o.x[1] = cubic(357.52772, 35999.050340, -0.0001603, -1.0 / 300000.0, t);
    o.x[2] = cubic(134.96298, 477198.867398, 0.0086972, 1.0 / 56250.0, t);
    o.x[3] = cubic(93.27191, 483202.017538, -0.0036825, 1.0 / 327270.0, t);
    o.x[4] = cubic(125.04452, -1934.136261, 0.0020708, 1.0 / 450000.0, t);
    double psi = 0, eps = 0;
    for (const NutationTerm& term : kSpaNutation) {
        double arg = 0;
        for (int j = 0; j < 5; ++j)
            arg += o.x[j] * term.y[j];
        psi += (term.a + term.b * t) * sind(arg);
        eps += (term.c + term.d * t) * cosd(arg);
    }
    o.delta_psi = psi / 36000000.0;
    o.delta_eps = eps / 36000000.0;

    // 3.5 True obliquity of the ecliptic.
    static constexpr std::array<double, 11> kEps0 = {
        84381.448, -4680.93, -1.55, 1999.25, -51.38, -249.67, -39.05, 7.12, 27.87, 5.79, 2.45};
    const double u = o.jme / 10.0;
    double eps0 = 0;
    for (size_t i = kEps0.size(); i-- > 0;)
        eps0 = eps0 * u + kEps0[i];
    o.eps0_arcsec = eps0;
    o.eps = eps0 / 3600.0 + o.delta_eps;

    // 3.6–3.7 Aberration and apparent sun longitude.
    o.delta_tau = -20.4898 / (3600.0 * o.r_au);
    o.lambda = o.theta + o.delta_psi + o.delta_tau;

    // 3.8 Apparent sidereal time at Greenwich.
    o.nu0 = wrap360(280.46061837 + 360.98564736629 * (in.jd - 2451545.0) +
                    o.jc * o.jc * (0.000387933 - o.jc / 38710000.0));
    o.nu = o.nu0 + o.delta_psi * cosd(o.eps);

    // 3.9–3.10 Geocentric right ascension and declination.
    o.alpha = wrap360(
        std::atan2(sind(o.lambda) * cosd(o.eps) - tand(o.beta) * sind(o.eps), cosd(o.lambda)) *
        kDeg);
    o.delta =
        std::asin(sind(o.beta) * cosd(o.eps) + cosd(o.beta) * sind(o.eps) * sind(o.lambda)) * kDeg;

    // 3.11 Observer local hour angle.
    o.h = wrap360(o.nu + in.longitude_deg - o.alpha);

    // 3.12 Topocentric right ascension and declination (parallax on the SPA ellipsoid).
    o.xi = 8.794 / (3600.0 * o.r_au);
    const double u_rad = std::atan(0.99664719 * tand(in.latitude_deg));
    const double x = std::cos(u_rad) + in.elevation_m / 6378140.0 * cosd(in.latitude_deg);
    const double y =
        0.99664719 * std::sin(u_rad) + in.elevation_m / 6378140.0 * sind(in.latitude_deg);
    const double denominator = cosd(o.delta) - x * sind(o.xi) * cosd(o.h);
    o.delta_alpha = std::atan2(-x * sind(o.xi) * sind(o.h), denominator) * kDeg;
    o.alpha_prime = o.alpha + o.delta_alpha;
    o.delta_prime =
        std::atan2((sind(o.delta) - y * sind(o.xi)) * cosd(o.delta_alpha), denominator) * kDeg;

    // 3.13 Topocentric local hour angle.
    o.h_prime = o.h - o.delta_alpha;

    // 3.14 Topocentric zenith angle, with refraction.
    o.e0 = std::asin(sind(in.latitude_deg) * sind(o.delta_prime) +
                     cosd(in.latitude_deg) * cosd(o.delta_prime) * cosd(o.h_prime)) *
           kDeg;
    o.delta_e = spaRefraction(o.e0, in.pressure_mbar, in.temperature_c);
    o.e = o.e0 + o.delta_e;
    o.zenith = 90.0 - o.e;

    // 3.15 Topocentric azimuth, from north eastwards.
    const double gamma =
        std::atan2(sind(o.h_prime), cosd(o.h_prime) * sind(in.latitude_deg) -
                                        tand(o.delta_prime) * cosd(in.latitude_deg)) *
        kDeg;
    o.azimuth = wrap360(gamma + 180.0);
    return o;
}

PsaOutput psa(double jd, double latitude_deg, double longitude_deg, PsaCoefficients set) {
    // p[0..1] node of the moon's orbit, p[2..3] mean longitude, p[4..5] mean anomaly, p[6..9]
    // ecliptic longitude, p[10..12] obliquity, p[13..14] Greenwich mean sidereal time (hours).
    static constexpr double k2001[15] = {2.1429,     -0.0010394594, 4.8950630,   0.017202791698,
                                         6.2400600,  0.0172019699,  0.03341607,  0.00034894,
                                         -0.0001134, -0.0000203,    0.4090928,   -6.2140e-9,
                                         0.0000396,  6.6974243242,  0.0657098283};
    static constexpr double k2020[15] = {
        2.267127827,    -9.300339267e-4, 4.895036035,    1.720279602e-2,  6.239468336,
        1.720200135e-2, 3.338320972e-2,  3.497596876e-4, -1.544353226e-4, -8.689729360e-6,
        4.090904909e-1, -6.213605399e-9, 4.418094944e-5, 6.697096103,     6.570984737e-2};
    const double* p = set == PsaCoefficients::k2001 ? k2001 : k2020;

    // Days since J2000.0 and the UT hour of day.
    const double n = jd - 2451545.0;
    const double hours = (jd + 0.5 - std::floor(jd + 0.5)) * 24.0;

    const double omega = p[0] + p[1] * n;
    const double mean_longitude = p[2] + p[3] * n;
    const double mean_anomaly = p[4] + p[5] * n;
    const double ecliptic_longitude = mean_longitude + p[6] * std::sin(mean_anomaly) +
                                      p[7] * std::sin(2 * mean_anomaly) + p[8] +
                                      p[9] * std::sin(omega);
    const double obliquity = p[10] + p[11] * n + p[12] * std::cos(omega);

    const double sin_longitude = std::sin(ecliptic_longitude);
    const double right_ascension =
        std::atan2(std::cos(obliquity) * sin_longitude, std::cos(ecliptic_longitude));
    const double declination = std::asin(std::sin(obliquity) * sin_longitude);

    const double gmst_hours = p[13] + p[14] * n + hours;
    const double hour_angle = (gmst_hours * 15 + longitude_deg) * kRad - right_ascension;
    const double latitude = latitude_deg * kRad;
    const double cos_hour_angle = std::cos(hour_angle);
    double zenith =
        std::acos(std::clamp(std::cos(latitude) * cos_hour_angle * std::cos(declination) +
                                 std::sin(declination) * std::sin(latitude),
                             -1.0, 1.0));
    const double azimuth =
        std::atan2(-std::sin(hour_angle), std::tan(declination) * std::cos(latitude) -
                                              std::sin(latitude) * cos_hour_angle);
    // Parallax: the Earth's mean radius over the astronomical unit, both in km.
    zenith += 6371.01 / 149597870.7 * std::sin(zenith);
    return {zenith * kDeg, wrap360(azimuth * kDeg)};
}

}  // namespace mixray::tracking::detail
