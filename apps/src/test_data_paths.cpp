// Default location of ../shared/data for benchmarks and the demo.
#include "test_data_paths.h"

#include <cstdlib>

namespace mixray::cli {

std::filesystem::path sourceDir() {
    return MIXRAY_SOURCE_DIR;
}

std::filesystem::path defaultSharedDataDir() {
    if (const char* env = std::getenv("MIXRAY_SHARED_DATA"))
        return env;
    return sourceDir().parent_path() / "shared" / "data";
}

}  // namespace mixray::cli
