// Starting and stopping Aravis's GigE Vision camera simulator.
#include "gv_simulator.h"

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace mixray::test {

bool GvSimulator::installed() {
    return access(kGvSimulator, X_OK) == 0;
}

bool GvSimulator::start(int lost_per_thousand, const std::string& genicam) {
    const std::string lost = std::to_string(lost_per_thousand);
    std::vector<const char*> argv = {kGvSimulator,       "-i", kGvSimulatorAddress, "-s",
                                     kGvSimulatorSerial, "-r", lost.c_str()};
    if (!genicam.empty()) {
        argv.push_back("-g");
        argv.push_back(genicam.c_str());
    }
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, kGvSimulator, nullptr, nullptr, const_cast<char**>(argv.data()),
                    environ) != 0) {
        pid_ = -1;
        return false;
    }
    return true;
}

void GvSimulator::kill() {
    if (pid_ <= 0)
        return;
    ::kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
}

Result<std::unique_ptr<Device>> openWhenUp(DeviceBackend& backend, const DeviceConfig& config) {
    Result<std::unique_ptr<Device>> opened{ErrorCode::kNotFound, "not tried"};
    for (int attempt = 0; attempt < 40; ++attempt) {
        opened = backend.open(config);
        if (opened || opened.status().code() != ErrorCode::kNotFound)
            return opened;
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
    return opened;
}

}  // namespace mixray::test
