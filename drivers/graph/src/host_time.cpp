#include "mixray/graph/host_time.h"

#include <ctime>

namespace mixray {

namespace {

int64_t readNs(clockid_t clock) {
    timespec ts{};
    clock_gettime(clock, &ts);
    return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

int64_t monotonicNowNs() { return readNs(CLOCK_MONOTONIC); }

int64_t realtimeNowNs() { return readNs(CLOCK_REALTIME); }

int64_t realtimeMinusMonotonicNs() {
    // Monotonic read either side of the wall clock: the midpoint halves the error of the gap.
    const int64_t before = monotonicNowNs();
    const int64_t realtime = realtimeNowNs();
    const int64_t after = monotonicNowNs();
    return realtime - (before + (after - before) / 2);
}

}  // namespace mixray
