// Busy child processes as an external CPU load (cpu_load.h).
#include "cpu_load.h"

#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>
#include <utility>

namespace mixray::cli {

Result<CpuLoad> CpuLoad::start(int processes) {
    CpuLoad load;
    const pid_t parent = getpid();
    for (int i = 0; i < processes; ++i) {
        const pid_t child = fork();
        if (child < 0)
            return Status(ErrorCode::kUnavailable,
                          std::string("cannot start a CPU load process: ") + std::strerror(errno));
        if (child == 0) {
            // Only async-signal-safe calls here: the parent may have other threads.
            prctl(PR_SET_PDEATHSIG, SIGKILL);
            if (getppid() != parent)
                _exit(0);
            volatile unsigned long spin = 0;
            for (;;)
                spin = spin + 1;
        }
        load.children_.push_back(child);
    }
    return load;
}

CpuLoad::CpuLoad(CpuLoad&& other) noexcept : children_(std::exchange(other.children_, {})) {}

CpuLoad& CpuLoad::operator=(CpuLoad&& other) noexcept {
    if (this != &other) {
        stop();
        children_ = std::exchange(other.children_, {});
    }
    return *this;
}

CpuLoad::~CpuLoad() {
    stop();
}

void CpuLoad::stop() {
    for (pid_t child : children_)
        kill(child, SIGKILL);
    for (pid_t child : children_) {
        while (waitpid(child, nullptr, 0) < 0 && errno == EINTR) {
        }
    }
    children_.clear();
}

}  // namespace mixray::cli
