// Test helpers: where the repository, the build and ../shared/data are; whole files as text.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace mixray::test {

std::filesystem::path sourceDir();
std::filesystem::path fixturesDir();
// The build tree the tests were built in.
std::filesystem::path binaryDir();
// The mixray command line of that build tree.
std::filesystem::path cliPath();
// ../shared/data beside the repository (override with MIXRAY_SHARED_DATA).
std::filesystem::path sharedDataDir();
// The Kinect v1 .oni recording under shared data that the OpenNI2 tests play.
std::filesystem::path kinectV1Oni();
// A fresh empty directory under the build tree, unique to the calling test.
std::filesystem::path tempDir();
// The whole file, "" when it cannot be read.
std::string readText(const std::filesystem::path& path);
// Writes `text` as the whole file, byte for byte.
void writeText(const std::filesystem::path& path, std::string_view text);

}  // namespace mixray::test

// Skips the calling test with a clear message when `path` (under shared data) is absent.
#define MIXRAY_REQUIRE_SHARED_DATA(path)                                             \
    do {                                                                             \
        if (!std::filesystem::exists(path)) {                                        \
            GTEST_SKIP() << "real data not available: " << (path)                    \
                         << " (expected under ../shared/data; see its MANIFEST.md)"; \
        }                                                                            \
    } while (0)
