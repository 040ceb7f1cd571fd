// An external CPU load for benchmarks: busy processes beside mixray, as another job on the
// same machine would be.
#pragma once

#include <sys/types.h>

#include <vector>

#include "mixray/graph/result.h"

namespace mixray::cli {

// Starts `processes` child processes that spin until it is destroyed (each dies with its
// parent too, should mixray be killed). They run at normal priority, as a user's other job
// would, so they compete with mixray's capture and recorder threads as they would there.
// Thread-bound.
class CpuLoad {
public:
    static Result<CpuLoad> start(int processes);
    CpuLoad() = default;
    CpuLoad(CpuLoad&& other) noexcept;
    CpuLoad& operator=(CpuLoad&& other) noexcept;
    CpuLoad(const CpuLoad&) = delete;
    CpuLoad& operator=(const CpuLoad&) = delete;
    ~CpuLoad();

    int processes() const { return static_cast<int>(children_.size()); }
    // Kills and reaps the processes; idempotent.
    void stop();

private:
    std::vector<pid_t> children_;
};

}  // namespace mixray::cli
