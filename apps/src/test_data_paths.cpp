// Default location of ../shared/data for benchmarks and the demo.
#include "test_data_paths.h"

#include <cstdlib>

namespace mixray::cli {

std::filesystem::path defaultSharedDataDir() {
    if (const char* env = std::getenv("MIXRAY_SHARED_DATA"))
        return env;
    return std::filesystem::path(MIXRAY_SOURCE_DIR).parent_path() / "shared" / "data";
}

}  // namespace mixray::cli
