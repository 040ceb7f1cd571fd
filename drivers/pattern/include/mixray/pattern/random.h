// Deterministic random numbers for simulated devices and the tests that check them.
#pragma once

#include <cmath>
#include <cstdint>

namespace mixray::pattern {

// splitmix64: tiny, fast, and the same sequence on every platform and standard library (the
// std distributions are not), so a seed reproduces a simulated run exactly. Thread-bound.
class SplitMix64 {
public:
    explicit SplitMix64(uint64_t seed) : state_(seed) {}
    uint64_t next() {
        uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    // Uniform in [0, 1).
    double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
    // Exponentially distributed with the given mean; 0 for a mean <= 0.
    double exponential(double mean) { return mean > 0 ? -std::log1p(-uniform()) * mean : 0.0; }

private:
    uint64_t state_;
};

}  // namespace mixray::pattern
