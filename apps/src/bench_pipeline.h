// mixray bench pipeline: the whole AR pipeline (ArPipeline) on the bundled session, at fast
// pace against the renderer alone on the same frames, and at real pace: fps, latency, ladder.
#pragma once

#include "cli.h"

namespace mixray::cli {

void registerBenchPipeline(CLI::App& bench, Commands& commands);

}  // namespace mixray::cli
