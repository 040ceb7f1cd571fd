// Background threads: work whose lateness holds up no frame on its way to a composite.
#pragma once

namespace mixray {

// The nice value of background threads: about a third of a normal thread's share of a busy
// core, so the threads a composite waits for (capture, marker tracking, light records, the
// renderer) go first and the background catches up in between.
inline constexpr int kBackgroundNice = 5;

// Lowers the calling thread to kBackgroundNice, for threads that can fall behind without
// delaying a composite: the recorder (a queue absorbs delays) and, live, the fish-eye and probe
// estimators (the newest answer wins, older ones are skipped). Linux gives each thread its own
// nice value; where it is refused nothing else changes.
void runAsBackgroundThread();

}  // namespace mixray
