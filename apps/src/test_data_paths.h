// Where the command line looks for real third-party data by default.
#pragma once

#include <filesystem>

namespace mixray::cli {

// The source tree this binary was built from (its fixtures/ hold the bundled sessions).
std::filesystem::path sourceDir();

// $MIXRAY_SHARED_DATA, else ../shared/data beside the source tree this binary was built from.
std::filesystem::path defaultSharedDataDir();

}  // namespace mixray::cli
