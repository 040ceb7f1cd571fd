// mixray bench calibrate: time to calibrate one camera from N chessboard views with mixray's
// mrcal back end, OpenCV's calibrateCamera and mrcal's own CLI on the same corners, same run.
#pragma once

#include "cli.h"

namespace mixray::cli {

void registerBenchCalibrate(CLI::App& bench, Commands& commands);

}  // namespace mixray::cli
