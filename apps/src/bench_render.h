// mixray bench render: the Embree renderer on RT²AR's scenes against bare Embree tracing the
// same rays in the same run.
#pragma once

#include "cli.h"

namespace mixray::cli {

void registerBenchRender(CLI::App& bench, Commands& commands);

}  // namespace mixray::cli
