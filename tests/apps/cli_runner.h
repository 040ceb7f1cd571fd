// Runs the mixray binary of the build tree (test::cliPath()) for end-to-end tests of the
// command line.
#pragma once

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

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

// A mixray process running in the background (startMixray), so a test can signal it.
struct CliProcess {
    pid_t pid = -1;
    std::filesystem::path output;  // stdout and stderr together
};

// Starts `mixray args...` directly (no shell between, so signals reach mixray itself), its
// output going to `output`. pid -1 when it cannot start.
inline CliProcess startMixray(const std::vector<std::string>& args,
                              const std::filesystem::path& output) {
    const std::string program = cliPath().string();
    std::vector<char*> argv{const_cast<char*>(program.c_str())};
    for (const std::string& a : args)
        argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const std::string out = output.string();
    CliProcess process{-1, output};
    process.pid = fork();
    if (process.pid == 0) {  // only async-signal-safe calls until exec
        const int fd = open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd < 0 || dup2(fd, STDOUT_FILENO) < 0 || dup2(fd, STDERR_FILENO) < 0)
            _exit(127);
        execv(program.c_str(), argv.data());
        _exit(127);
    }
    return process;
}

// Waits until process `pid` catches `signal_number` (its SigCgt in /proc: mixray installs its
// handler only once it has parsed its options, and the loader may take seconds on a loaded
// machine), at most `timeout`. False when it never did (it ended, or never installed one).
inline bool waitUntilCatching(pid_t pid, int signal_number,
                              std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    do {
        std::ifstream status("/proc/" + std::to_string(pid) + "/status");
        std::string line;
        while (std::getline(status, line))
            if (line.rfind("SigCgt:", 0) == 0 &&
                (std::stoull(line.substr(7), nullptr, 16) & (1ull << (signal_number - 1))) != 0)
                return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    } while (std::chrono::steady_clock::now() < deadline);
    return false;
}

// Waits for a process startMixray started: its exit code, or -1 when a signal killed it.
inline CliRun waitMixray(const CliProcess& process) {
    CliRun run;
    int status = 0;
    if (process.pid > 0 && waitpid(process.pid, &status, 0) == process.pid)
        run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    run.output = readText(process.output);
    return run;
}

}  // namespace mixray::test
