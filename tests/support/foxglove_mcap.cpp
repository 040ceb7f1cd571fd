#include "foxglove_mcap.h"

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <string>

#include "test_data.h"

namespace mixray::test {

nlohmann::json readMcapWithFoxglove(const std::filesystem::path& file) {
    const std::filesystem::path folder = sourceDir() / "tests/mcap";
    if (!std::filesystem::exists(folder / "node_modules/@mcap/core")) {
        ADD_FAILURE() << "Foxglove's MCAP readers are not installed in " << folder
                      << ": run scripts/setup-deps (it runs npm ci there)";
        return nullptr;
    }
    const std::string command =
        "node '" + (folder / "read_mcap.mjs").string() + "' '" + file.string() + "' 2>&1";
    std::FILE* pipe = popen(command.c_str(), "r");
    if (!pipe) {
        ADD_FAILURE() << "cannot run " << command;
        return nullptr;
    }
    std::string output;
    std::array<char, 65536> buffer{};
    for (size_t n; (n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0;)
        output.append(buffer.data(), n);
    if (pclose(pipe) != 0) {
        ADD_FAILURE() << command << " failed:\n" << output;
        return nullptr;
    }
    auto parsed = nlohmann::json::parse(output, nullptr, false);
    if (parsed.is_discarded()) {
        ADD_FAILURE() << "not JSON from " << command << ":\n" << output;
        return nullptr;
    }
    return parsed;
}

}  // namespace mixray::test
