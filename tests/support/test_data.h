// Test helpers: where the repository, the build and ../shared/data are.
#pragma once

#include <filesystem>
#include <string>

namespace mixray::test {

std::filesystem::path sourceDir();
std::filesystem::path fixturesDir();
// ../shared/data beside the repository (override with MIXRAY_SHARED_DATA).
std::filesystem::path sharedDataDir();
// The Kinect v1 .oni recording under shared data that the OpenNI2 tests play.
std::filesystem::path kinectV1Oni();
// A fresh empty directory under the build tree, unique to the calling test.
std::filesystem::path tempDir();

}  // namespace mixray::test

// Skips the calling test with a clear message when `path` (under shared data) is absent.
#define MIXRAY_REQUIRE_SHARED_DATA(path)                                             \
    do {                                                                             \
        if (!std::filesystem::exists(path)) {                                        \
            GTEST_SKIP() << "real data not available: " << (path)                    \
                         << " (expected under ../shared/data; see its MANIFEST.md)"; \
        }                                                                            \
    } while (0)
