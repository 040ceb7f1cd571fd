// mixray bench track: marker tracking against OpenCV's bare detectMarkers on the same frames,
// and light estimation milliseconds per frame.
#pragma once

#include "cli.h"

namespace mixray::cli {

void registerBenchTrack(CLI::App& bench, Commands& commands);

}  // namespace mixray::cli
