// Image sizes given on the command line ("640x480"), for the subcommands that take one.
#pragma once

#include <string>
#include <utility>

#include "mixray/graph/result.h"

namespace mixray::cli {

// "WIDTHxHEIGHT" (320x240) as given to `option`; kInvalidArgument naming the option otherwise.
Result<std::pair<int, int>> parseSize(const std::string& option, const std::string& text);

}  // namespace mixray::cli
