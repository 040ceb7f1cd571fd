// The sun's position: SPA against the report's worked example step by step and against ERFA
// (the IAU SOFA routines) over 2000–2050; PSA against SPA; the world-frame direction from a
// rig's heading or device orientation.
#include "mixray/tracking/sun.h"

#include <erfa.h>
#include <erfam.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include "spa.h"

namespace mixray::tracking {
namespace {

constexpr double kRad = std::numbers::pi / 180;
constexpr double kDeg = 180 / std::numbers::pi;

// Nanoseconds since the Unix epoch of a UTC civil time (proleptic Gregorian).
int64_t unixNs(int year, int month, int day, int hour, int minute, double second) {
    // Days from 1970-01-01 (Howard Hinnant's days_from_civil).
    year -= month <= 2;
    const int era = (year >= 0 ? year : year - 399) / 400;
    const int yoe = year - era * 400;
    const int doy = (153 * (month + (month > 2 ? -3 : 9)) + 2) / 5 + day - 1;
    const int doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    const int64_t days = int64_t{era} * 146097 + doe - 719468;
    return (days * 86400 + hour * 3600 + minute * 60) * 1'000'000'000 +
           static_cast<int64_t>(std::llround(second * 1e9));
}

// The report's example (NREL/TP-560-34302, Table A5.1): 2003-10-17 12:30:30 at UTC−7.
SunQuery workedExample() {
    SunQuery query;
    query.latitude_deg = 39.742476;
    query.longitude_deg = -105.1786;
    query.altitude_m = 1830.14;
    query.utc_ns = unixNs(2003, 10, 17, 12 + 7, 30, 30);
    query.delta_t_s = 67;
    query.pressure_mbar = 820;
    query.temperature_c = 11;
    return query;
}

detail::SpaInput spaInput(const SunQuery& q) {
    return {.jd = 2440587.5 + static_cast<double>(q.utc_ns) * 1e-9 / 86400,
            .delta_t_s = q.delta_t_s,
            .latitude_deg = q.latitude_deg,
            .longitude_deg = q.longitude_deg,
            .elevation_m = q.altitude_m,
            .pressure_mbar = q.pressure_mbar,
            .temperature_c = q.temperature_c};
}

double angleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::atan2(a.cross(b).norm(), a.dot(b)) * kDeg;
}

// Every intermediate value the report's Table A5.2 lists, to the digits it prints.
TEST(Spa, WorkedExampleStepByStep) {
    const detail::SpaOutput o = detail::spa(spaInput(workedExample()));
    EXPECT_NEAR(spaInput(workedExample()).jd, 2452930.312847, 5e-7);
    EXPECT_NEAR(o.l, 24.0182616917, 5e-11);
    EXPECT_NEAR(o.b, -0.0001011219, 5e-11);
    EXPECT_NEAR(o.r_au, 0.9965422974, 5e-11);
    EXPECT_NEAR(o.h, 11.105900, 5e-6);
    EXPECT_NEAR(o.delta_psi, -0.00399840, 5e-9);
    EXPECT_NEAR(o.delta_eps, 0.00166657, 5e-9);
    EXPECT_NEAR(o.eps, 23.440465, 5e-7);
    EXPECT_NEAR(o.zenith, 50.11162, 5e-6);
    EXPECT_NEAR(o.azimuth, 194.34024, 5e-6);
    // The other steps of the same example, to the digits usually published with it.
    EXPECT_NEAR(o.jde, 2452930.313623, 5e-7);
    // The printed JD is rounded to 1e-6 day; the instant itself is exact here.
    EXPECT_NEAR(o.jme, 0.003792781991685, 2e-12);
    EXPECT_NEAR(o.theta, 204.0182616917, 5e-11);
    EXPECT_NEAR(o.x[0], 17185.861179, 5e-7);
    EXPECT_NEAR(o.x[1], 1722.893218, 5e-7);
    EXPECT_NEAR(o.x[2], 18234.075703, 5e-7);
    EXPECT_NEAR(o.x[3], 18420.071012, 5e-7);
    EXPECT_NEAR(o.x[4], 51.686951, 5e-7);
    EXPECT_NEAR(o.eps0_arcsec, 84379.672625, 5e-7);
    EXPECT_NEAR(o.delta_tau, -0.005711, 5e-7);
    EXPECT_NEAR(o.lambda, 204.0085519281, 5e-11);
    EXPECT_NEAR(o.nu, 318.511910, 5e-6);
    EXPECT_NEAR(o.alpha, 202.22741, 5e-6);
    EXPECT_NEAR(o.delta, -9.31434, 5e-6);
    EXPECT_NEAR(o.xi, 0.002451, 5e-7);
    EXPECT_NEAR(o.delta_alpha, -0.000369, 5e-7);
    EXPECT_NEAR(o.alpha_prime, 202.22704, 5e-6);
    EXPECT_NEAR(o.delta_prime, -9.316179, 5e-7);
    EXPECT_NEAR(o.h_prime, 11.10627, 5e-6);
    EXPECT_NEAR(o.e0, 39.872046, 5e-7);
    EXPECT_NEAR(o.delta_e, 0.016332, 5e-7);
    EXPECT_NEAR(o.e, 39.888378, 5e-7);
}

TEST(Spa, WorkedExampleThroughTheApi) {
    auto sun = sunPosition(workedExample(), SunAlgorithm::kSpa);
    ASSERT_TRUE(sun.isOk()) << sun.status().toString();
    EXPECT_NEAR(sun->zenith_deg, 50.11162, 5e-6);
    EXPECT_NEAR(sun->azimuth_deg, 194.34024, 5e-6);
    EXPECT_NEAR(sun->elevation_deg(), 39.888378, 5e-6);

    // Zero pressure: the geometric elevation e0.
    SunQuery geometric = workedExample();
    geometric.pressure_mbar = 0;
    auto bare = sunPosition(geometric, SunAlgorithm::kSpa);
    ASSERT_TRUE(bare.isOk());
    EXPECT_NEAR(bare->elevation_deg(), 39.872046, 5e-6);
    EXPECT_DOUBLE_EQ(bare->azimuth_deg, sun->azimuth_deg);
}

// The topocentric geometric direction of the sun in east-north-up from ERFA: Earth ephemeris
// (eraEpv00), light time, annual aberration (eraAb), IAU 2006/2000A precession-nutation and Earth
// rotation (eraC2t06a, UT1 = the given time, no polar motion) and the WGS84 observer (eraGd2gc).
// Diurnal aberration (≤ 0.0001°) is left out.
Eigen::Vector3d erfaSunEnu(const SunQuery& q) {
    const double ut1 = static_cast<double>(q.utc_ns) * 1e-9 / ERFA_DAYSEC;
    const double tt = ut1 + q.delta_t_s / ERFA_DAYSEC;
    const double epoch = 2440587.5;

    double pvh[2][3], pvb[2][3];
    eraEpv00(epoch, tt, pvh, pvb);
    // The sun's barycentric position when the light left it, by iterating the light time.
    double p[3] = {-pvh[0][0], -pvh[0][1], -pvh[0][2]};
    for (int i = 0; i < 3; ++i) {
        const double light_days = eraPm(p) * ERFA_AULT / ERFA_DAYSEC;
        double pvh_then[2][3], pvb_then[2][3];
        eraEpv00(epoch, tt - light_days, pvh_then, pvb_then);
        for (int k = 0; k < 3; ++k)
            p[k] = (pvb_then[0][k] - pvh_then[0][k]) - pvb[0][k];
    }
    double distance_au = 0, direction[3];
    eraPn(p, &distance_au, direction);
    double v[3];
    eraSxp(ERFA_AULT / ERFA_DAYSEC, pvb[1], v);  // au/day → units of c
    const double bm1 = std::sqrt(1 - eraPdp(v, v));
    double apparent[3];
    eraAb(direction, v, distance_au, bm1, apparent);

    double rc2t[3][3];
    eraC2t06a(epoch, tt, epoch, ut1, 0, 0, rc2t);
    double terrestrial[3];
    eraRxp(rc2t, apparent, terrestrial);

    double observer[3];
    const double lat = q.latitude_deg * kRad, lon = q.longitude_deg * kRad;
    EXPECT_EQ(eraGd2gc(ERFA_WGS84, lon, lat, q.altitude_m, observer), 0);
    const Eigen::Vector3d topocentric =
        Eigen::Vector3d(terrestrial[0], terrestrial[1], terrestrial[2]) * distance_au * ERFA_DAU -
        Eigen::Vector3d(observer[0], observer[1], observer[2]);
    Eigen::Matrix3d enu_from_itrs;
    enu_from_itrs << -std::sin(lon), std::cos(lon), 0,                                  //
        -std::sin(lat) * std::cos(lon), -std::sin(lat) * std::sin(lon), std::cos(lat),  //
        std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat);
    return (enu_from_itrs * topocentric).normalized();
}

// Random instants over [from, to) and sites anywhere on Earth, geometric (no refraction).
std::vector<SunQuery> randomQueries(int count, int from_year, int to_year, uint32_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<int64_t> time(unixNs(from_year, 1, 1, 0, 0, 0),
                                                unixNs(to_year, 1, 1, 0, 0, 0) - 1);
    std::uniform_real_distribution<double> unit(-1, 1);
    std::vector<SunQuery> queries(count);
    for (SunQuery& q : queries) {
        q.utc_ns = time(rng);
        q.latitude_deg = std::asin(unit(rng)) * kDeg;  // uniform over the sphere
        q.longitude_deg = 180 * unit(rng);
        q.altitude_m = 2500 + 2500 * unit(rng);
        q.pressure_mbar = 0;
    }
    return queries;
}

struct ErrorStats {
    double max = 0, median = 0;
};

ErrorStats stats(std::vector<double> errors) {
    std::sort(errors.begin(), errors.end());
    return {errors.back(), errors[errors.size() / 2]};
}

TEST(Spa, MatchesErfaOver2000To2050) {
    std::vector<double> angle, zenith, azimuth_arc;
    for (const SunQuery& q : randomQueries(2000, 2000, 2051, 4)) {
        auto sun = sunPosition(q, SunAlgorithm::kSpa);
        ASSERT_TRUE(sun.isOk());
        const Eigen::Vector3d reference = erfaSunEnu(q);
        angle.push_back(angleDeg(sun->toSunEnu(), reference));
        const double reference_zenith = std::acos(std::clamp(reference.z(), -1.0, 1.0)) * kDeg;
        zenith.push_back(std::abs(sun->zenith_deg - reference_zenith));
        double reference_azimuth = std::atan2(reference.x(), reference.y()) * kDeg;
        double d = std::remainder(sun->azimuth_deg - reference_azimuth, 360.0);
        // An azimuth error moves the sun by that angle times sin(zenith).
        azimuth_arc.push_back(std::abs(d) * std::sin(reference_zenith * kRad));
    }
    const ErrorStats a = stats(angle), z = stats(zenith), az = stats(azimuth_arc);
    std::printf(
        "SPA vs ERFA, 2000 instants 2000-2050: angle max %.6f median %.6f deg; zenith "
        "max %.6f; azimuth*sin(zenith) max %.6f\n",
        a.max, a.median, z.max, az.max);
    EXPECT_LE(a.max, 0.01);
    EXPECT_LE(z.max, 0.01);
    EXPECT_LE(az.max, 0.01);
    // What the comparison actually shows, so that a regression in the tables shows too.
    EXPECT_LE(a.max, 0.001);
}

// PSA against SPA (geometric, SPA at ΔT = 69.2 s): the bound over 2000–2050 and over each
// coefficient set's fitted range.
ErrorStats psaError(SunAlgorithm algorithm, int from_year, int to_year) {
    std::vector<double> errors;
    for (const SunQuery& q : randomQueries(10000, from_year, to_year, 7)) {
        auto psa = sunPosition(q, algorithm);
        auto spa = sunPosition(q, SunAlgorithm::kSpa);
        EXPECT_TRUE(psa.isOk() && spa.isOk());
        errors.push_back(angleDeg(psa->toSunEnu(), spa->toSunEnu()));
    }
    const ErrorStats s = stats(errors);
    std::printf("%s vs SPA %d-%d: max %.6f median %.6f deg\n", toString(algorithm).data(),
                from_year, to_year - 1, s.max, s.median);
    return s;
}

// The bounds are those a scan of a million instants found (docs/tracking.md): 0.0080° over
// 2020–2050 and 0.0086° over 2000–2050 for the 2020 coefficients; 0.0074° over 2000–2015 and
// 0.0096° over 2000–2050 for the 2001 ones.
TEST(Psa, CoefficientsOf2020AgainstSpa) {
    EXPECT_LE(psaError(SunAlgorithm::kPsa, 2020, 2051).max, 0.0085);
    EXPECT_LE(psaError(SunAlgorithm::kPsa, 2000, 2051).max, 0.009);
}

TEST(Psa, CoefficientsOf2001AgainstSpa) {
    EXPECT_LE(psaError(SunAlgorithm::kPsa2001, 2000, 2016).max, 0.008);
    EXPECT_LE(psaError(SunAlgorithm::kPsa2001, 2000, 2051).max, 0.01);
}

TEST(Sun, RefractionRaisesTheSunForBothAlgorithms) {
    for (SunAlgorithm algorithm : {SunAlgorithm::kSpa, SunAlgorithm::kPsa}) {
        SunQuery query = workedExample();
        auto refracted = sunPosition(query, algorithm);
        query.pressure_mbar = 0;
        auto geometric = sunPosition(query, algorithm);
        ASSERT_TRUE(refracted.isOk() && geometric.isOk());
        EXPECT_NEAR(refracted->elevation_deg() - geometric->elevation_deg(), 0.016332, 1e-4)
            << toString(algorithm);
    }
}

TEST(Sun, BadQueriesNameTheField) {
    const struct {
        void (*set)(SunQuery&);
        const char* field;
    } cases[] = {
        {[](SunQuery& q) { q.latitude_deg = 91; }, "latitude_deg"},
        {[](SunQuery& q) { q.longitude_deg = std::nan(""); }, "longitude_deg"},
        {[](SunQuery& q) { q.altitude_m = -7e6; }, "altitude_m"},
        {[](SunQuery& q) { q.delta_t_s = 9000; }, "delta_t_s"},
        {[](SunQuery& q) { q.pressure_mbar = -1; }, "pressure_mbar"},
        {[](SunQuery& q) { q.temperature_c = -300; }, "temperature_c"},
    };
    for (const auto& c : cases) {
        SunQuery query = workedExample();
        c.set(query);
        auto sun = sunPosition(query, SunAlgorithm::kPsa);
        ASSERT_FALSE(sun.isOk()) << c.field;
        EXPECT_EQ(sun.status().code(), ErrorCode::kInvalidArgument);
        EXPECT_NE(sun.status().message().find(c.field), std::string::npos)
            << sun.status().message();
    }
    EXPECT_EQ(toString(SunAlgorithm::kPsa2001), "psa-2001");
}

RigSite goldenSite() {
    RigSite site;
    site.latitude_deg = 39.742476;
    site.longitude_deg = -105.1786;
    site.altitude_m = 1830.14;
    return site;
}

TEST(SunDirection, HeadingZeroIsEastNorthUp) {
    const int64_t t = workedExample().utc_ns;
    auto world = sunDirectionWorld(goldenSite(), t);
    ASSERT_TRUE(world.isOk()) << world.status().toString();
    EXPECT_NEAR(world->norm(), 1, 1e-12);
    // Due south-south-west and about 40° up, as in the worked example.
    const double azimuth = std::atan2(world->x(), world->y()) * kDeg + 360;
    EXPECT_NEAR(azimuth, 194.34, 0.01);
    EXPECT_NEAR(std::asin(world->z()) * kDeg, 39.89, 0.01);
    EXPECT_TRUE(enuFromWorld(goldenSite()).isIdentity(1e-15));
}

TEST(SunDirection, HeadingTurnsTheSunAboutUp) {
    const int64_t t = workedExample().utc_ns;
    RigSite site = goldenSite();
    auto north = sunDirectionWorld(site, t);
    site.heading_deg = 90;  // the world's +y points east
    auto east = sunDirectionWorld(site, t);
    ASSERT_TRUE(north.isOk() && east.isOk());
    const Eigen::Vector3d turned =
        Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()) * *north;
    EXPECT_LT((*east - turned).norm(), 1e-12);
    // The world's +y (east) is in the sun's half: the sun is in the south-south-west, so its
    // direction has a negative east component, so a negative world y.
    EXPECT_LT(east->y(), 0);
    EXPECT_NEAR(east->z(), north->z(), 1e-15);
}

TEST(SunDirection, OrientationRoundTripsAndMatchesTheHeading) {
    const int64_t t = workedExample().utc_ns;
    RigSite by_heading = goldenSite();
    by_heading.heading_deg = 135;
    const Eigen::Quaterniond q(enuFromWorld(by_heading));
    RigSite by_orientation = goldenSite();
    by_orientation.orientation_wxyz = std::array<double, 4>{q.w(), q.x(), q.y(), q.z()};
    EXPECT_TRUE(enuFromWorld(by_orientation).isApprox(enuFromWorld(by_heading), 1e-14));
    auto a = sunDirectionWorld(by_heading, t);
    auto b = sunDirectionWorld(by_orientation, t);
    ASSERT_TRUE(a.isOk() && b.isOk());
    EXPECT_LT((*a - *b).norm(), 1e-12);

    // An arbitrary orientation: the matrix is the quaternion's, and back.
    const Eigen::Quaterniond tilted =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
    by_orientation.orientation_wxyz =
        std::array<double, 4>{tilted.w(), tilted.x(), tilted.y(), tilted.z()};
    const Eigen::Matrix3d enu_from_world = enuFromWorld(by_orientation);
    EXPECT_TRUE(enu_from_world.isApprox(tilted.toRotationMatrix(), 1e-14));
    EXPECT_LT(Eigen::Quaterniond(enu_from_world).angularDistance(tilted), 1e-12);
    auto c = sunDirectionWorld(by_orientation, t);
    ASSERT_TRUE(c.isOk());
    auto enu = sunPosition(
        SunQuery{.latitude_deg = 39.742476,
                 .longitude_deg = -105.1786,
                 .altitude_m = 1830.14,
                 .utc_ns = t,
                 .pressure_mbar = 1013.25 * std::pow(1 - 2.25577e-5 * 1830.14, 5.25588)},
        SunAlgorithm::kSpa);
    ASSERT_TRUE(enu.isOk());
    EXPECT_LT((tilted * *c - enu->toSunEnu()).norm(), 1e-12);
}

TEST(SunDirection, BadSiteIsAnError) {
    RigSite site = goldenSite();
    site.latitude_deg = 120;
    auto direction = sunDirectionWorld(site, 0);
    ASSERT_FALSE(direction.isOk());
    EXPECT_EQ(direction.status().code(), ErrorCode::kInvalidArgument);
    site = goldenSite();
    site.heading_deg = std::nan("");
    EXPECT_FALSE(sunDirectionWorld(site, 0).isOk());
    site = goldenSite();
    site.orientation_wxyz = std::array<double, 4>{0, 0, 0, 0};
    direction = sunDirectionWorld(site, 0);
    ASSERT_FALSE(direction.isOk());
    EXPECT_NE(direction.status().message().find("unit quaternion"), std::string::npos);
}

}  // namespace
}  // namespace mixray::tracking
