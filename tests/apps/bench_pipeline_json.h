// mixray bench pipeline's JSON, for the CLI tests that run it.
#pragma once

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "cli_runner.h"

namespace mixray::test {

// Runs `mixray bench pipeline --json ARGS`, expects exit 0 and returns the JSON (progress goes
// to stderr before it); empty on failure.
inline nlohmann::json benchPipelineJson(const std::string& args) {
    const CliRun run = mixray("bench pipeline --json " + args);
    EXPECT_EQ(run.exit_code, 0) << run.output;
    const size_t start = run.output.find("\n{");
    EXPECT_NE(start, std::string::npos) << run.output;
    if (start == std::string::npos)
        return {};
    return nlohmann::json::parse(run.output.substr(start + 1), nullptr, false);
}

// Every set the real-pace run's compositor got is accounted for, once.
inline void expectEverySetAccountedFor(const nlohmann::json& real) {
    const nlohmann::json& sets = real["sets"];
    EXPECT_EQ(real["composites"].get<uint64_t>() + sets["superseded"].get<uint64_t>() +
                  sets["skipped_for_recording"].get<uint64_t>() +
                  sets["without_pose"].get<uint64_t>() + sets["corrupt"].get<uint64_t>() +
                  sets["publish_failures"].get<uint64_t>() + sets["at_stop"].get<uint64_t>(),
              sets["total"].get<uint64_t>())
        << sets.dump();
}

}  // namespace mixray::test
