// mixray bench dds: frames/s, latency and CPU per frame of streams between two graphs over DDS,
// against bare Fast DDS with the same payload and settings, in the same run.
#pragma once

#include "cli.h"

namespace mixray::cli {

void registerBenchDds(CLI::App& bench, Commands& commands);

}  // namespace mixray::cli
