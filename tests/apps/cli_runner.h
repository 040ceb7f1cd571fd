// Runs the mixray binary of the build tree (test::cliPath()) for end-to-end tests of the
// command line.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <string>

#include "test_data.h"

namespace mixray::test {

struct CliRun {
    int exit_code = -1;
    std::string output;  // stdout and stderr together
};

// Runs `mixray args` (args already shell-quoted where needed, see q()).
inline CliRun mixray(const std::string& args) {
    const std::string command = cliPath().string() + " " + args + " 2>&1";
    CliRun run;
    FILE* pipe = popen(command.c_str(), "r");
    if (!pipe)
        return run;
    std::array<char, 4096> buffer;
    size_t n;
    while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
        run.output.append(buffer.data(), n);
    const int status = pclose(pipe);
    run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return run;
}

// A path quoted for the shell (test paths hold no single quote).
inline std::string q(const std::filesystem::path& path) {
    return "'" + path.string() + "'";
}

}  // namespace mixray::test
