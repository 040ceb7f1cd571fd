// NREL's Solar Position Algorithm (Reda & Andreas 2004, NREL/TP-560-34302) and the PSA algorithm
// (Blanco-Muriel et al. 2001; Blanco, Milidonis & Bonanos 2020), with SPA's intermediate values
// exposed so that tests can check each step against the report's worked example.
#pragma once

#include <cstdint>
#include <span>

namespace mixray::tracking::detail {

// One term A·cos(B + C·τ) of the VSOP87 series SPA uses for the Earth's heliocentric longitude,
// latitude and radius (report Table A4.2).
struct PeriodicTerm {
    double a, b, c;
};

// One row of the nutation table (report Table A4.3): the multiples of the five fundamental
// arguments X0..X4 and the coefficients a, b (longitude) and c, d (obliquity), in 0.0001″.
struct NutationTerm {
    int8_t y[5];
    double a, b, c, d;
};

// Table A4.2, series L0..L5, B0..B1, R0..R4 (spa_tables.cpp).
extern const std::span<const PeriodicTerm> kSpaL[6];
extern const std::span<const PeriodicTerm> kSpaB[2];
extern const std::span<const PeriodicTerm> kSpaR[5];
// Table A4.3.
extern const std::span<const NutationTerm> kSpaNutation;

// SPA's inputs; angles in degrees. The caller has validated them.
struct SpaInput {
    double jd = 0;  // Julian day of the instant, UT
    double delta_t_s = 0;
    double latitude_deg = 0;
    double longitude_deg = 0;
    double elevation_m = 0;
    double pressure_mbar = 0;  // 0: no refraction
    double temperature_c = 0;
};

// SPA's steps in the report's symbols (all angles in degrees).
struct SpaOutput {
    double jde = 0, jc = 0, jce = 0, jme = 0;
    double l = 0, b = 0, r_au = 0;        // heliocentric longitude, latitude, radius
    double theta = 0, beta = 0;           // geocentric longitude, latitude
    double x[5] = {};                     // nutation arguments X0..X4
    double delta_psi = 0, delta_eps = 0;  // nutation in longitude and obliquity
    double eps0_arcsec = 0, eps = 0;      // mean and true obliquity
    double delta_tau = 0, lambda = 0;     // aberration, apparent longitude
    double nu0 = 0, nu = 0;               // mean and apparent sidereal time at Greenwich
    double alpha = 0, delta = 0;          // geocentric right ascension, declination
    double h = 0;                         // local hour angle
    double xi = 0, delta_alpha = 0;       // horizontal parallax, parallax in right ascension
    double alpha_prime = 0, delta_prime = 0, h_prime = 0;  // topocentric
    double e0 = 0, delta_e = 0, e = 0;  // elevation without and with refraction, refraction
    double zenith = 0, azimuth = 0;     // topocentric zenith, azimuth (from north, eastwards)
};

SpaOutput spa(const SpaInput& in);

// PSA's coefficient sets.
enum class PsaCoefficients : uint8_t {
    k2001,  // Blanco-Muriel et al. 2001, fitted over 1999–2015
    k2020,  // Blanco, Milidonis & Bonanos 2020 ("PSA+"), fitted over 2020–2050
};

struct PsaOutput {
    double zenith_deg = 0;  // topocentric (parallax-corrected), no refraction
    double azimuth_deg = 0;
};

// `jd` is the Julian day in UT; PSA takes no ΔT.
PsaOutput psa(double jd, double latitude_deg, double longitude_deg, PsaCoefficients set);

// SPA's refraction correction of a topocentric elevation (degrees): zero for zero pressure and
// for the sun well below the horizon, where SPA applies none.
double spaRefraction(double e0_deg, double pressure_mbar, double temperature_c);

}  // namespace mixray::tracking::detail
