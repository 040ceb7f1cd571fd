// Locations of test inputs and scratch space.
#include "test_data.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

namespace mixray::test {

std::filesystem::path sourceDir() {
    return MIXRAY_SOURCE_DIR;
}

std::filesystem::path binaryDir() {
    return MIXRAY_BINARY_DIR;
}

std::filesystem::path cliPath() {
    return binaryDir() / "apps" / "mixray";
}

std::filesystem::path fixturesDir() {
    return sourceDir() / "fixtures";
}

std::filesystem::path sharedDataDir() {
    if (const char* env = std::getenv("MIXRAY_SHARED_DATA"))
        return env;
    return sourceDir().parent_path() / "shared" / "data";
}

std::filesystem::path kinectV1Oni() {
    return sharedDataDir() / "01_oni" / "3dj_kinect1_test.oni";
}

std::filesystem::path tempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "global";
    for (char& c : name) {
        if (c == '/')
            c = '_';
    }
    auto dir = binaryDir() / "test-tmp" / name;
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

std::string readText(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

void writeText(const std::filesystem::path& path, std::string_view text) {
    std::ofstream(path, std::ios::binary) << text;
}

}  // namespace mixray::test
