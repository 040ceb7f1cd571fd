// Thread roles and their nice values (mixray/graph/thread_priority.h).
#include "mixray/graph/thread_priority.h"

#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>

namespace mixray {

const char* toString(ThreadRole role) {
    switch (role) {
        case ThreadRole::kCapture:
            return "capture";
        case ThreadRole::kRecorder:
            return "recorder";
        case ThreadRole::kPublisher:
            return "publisher";
        case ThreadRole::kEstimator:
            return "estimator";
        case ThreadRole::kRenderer:
            return "renderer";
    }
    return "unknown";
}

int requestedNice(ThreadRole role) {
    // Nice weights fall by about 1.25x a step: a renderer thread at 10 gets a tenth of a
    // core against one at 0, so a busy renderer costs capture and the recorder almost
    // nothing, yet renders at full speed on an otherwise idle machine.
    switch (role) {
        case ThreadRole::kCapture:
            return -10;
        case ThreadRole::kRecorder:
            return -5;
        case ThreadRole::kPublisher:
            return 0;
        case ThreadRole::kEstimator:
            return 5;
        case ThreadRole::kRenderer:
            return 10;
    }
    return 0;
}

int currentNice() {
    errno = 0;
    const int nice = getpriority(PRIO_PROCESS, static_cast<id_t>(gettid()));
    return errno == 0 ? nice : 0;
}

bool setCurrentNice(int nice) {
    return setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), nice) == 0;
}

int runAs(ThreadRole role) {
    const int wanted = requestedNice(role);
    if (!setCurrentNice(wanted) && wanted < 0) {
        // Unprivileged: the best it may have is normal priority (unless it already has less,
        // which it cannot undo).
        (void)setCurrentNice(0);
    }
    return currentNice();
}

}  // namespace mixray
