// Background threads (mixray/graph/thread_priority.h).
#include "mixray/graph/thread_priority.h"

#include <sys/resource.h>
#include <unistd.h>

namespace mixray {

void runAsBackgroundThread() {
    (void)setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), kBackgroundNice);
}

}  // namespace mixray
