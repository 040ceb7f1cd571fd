// mixray bench drivers: each backend's frames/s and CPU time per frame against its peer's own
// API on the same source, in the same run.
#pragma once

#include "cli.h"

namespace mixray::cli {

void registerBenchDrivers(CLI::App& bench, Commands& commands);

}  // namespace mixray::cli
