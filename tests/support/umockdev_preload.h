// umockdev emulates devices by preloading a library that redirects /dev, /sys and device
// ioctls; tests that use it re-execute themselves with it preloaded, so ctest and a plain run
// need no wrapper script.
#pragma once

#include <gtest/gtest.h>

namespace mixray::test {

inline constexpr const char* kUmockdevPreload = "libumockdev-preload.so.0";

// True when this process runs with umockdev's preload library.
bool umockdevPreloaded();

// Call first in main(): re-executes the binary with umockdev's preload library (and ASan told
// not to insist on being loaded first) when the library is installed and not yet preloaded.
// Returns when it did not (already preloaded, library missing, or only listing tests).
void reexecWithUmockdevPreload(int argc, char** argv);

}  // namespace mixray::test

// Skips the calling test when umockdev's preload library is missing: no device can be emulated.
#define MIXRAY_REQUIRE_UMOCKDEV()                                                                \
    do {                                                                                         \
        if (!::mixray::test::umockdevPreloaded())                                                \
            GTEST_SKIP() << "umockdev's preload library (" << ::mixray::test::kUmockdevPreload   \
                         << ") is not installed (Debian package umockdev): no emulated USB bus"; \
    } while (0)
