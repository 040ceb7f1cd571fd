// An MCAP file as Foxglove's own readers see it (tests/mcap/read_mcap.mjs under Node.js:
// @mcap/core's indexed and stream readers, the ROS 2 CDR decoded with the file's schemas).
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>

namespace mixray::test {

// The reader's JSON (see read_mcap.mjs). Adds a test failure, naming the fix, and returns null
// when Node.js or the readers are not installed (scripts/setup-deps installs them) or the file
// cannot be read.
nlohmann::json readMcapWithFoxglove(const std::filesystem::path& file);

}  // namespace mixray::test
