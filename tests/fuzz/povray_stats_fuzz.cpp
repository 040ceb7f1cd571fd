// libFuzzer target for POV-Ray's statistics as mixray reads them (parsePovrayStats,
// mixray/render/povray.h): any text gives statistics or a clean kCorruptData, and accepted
// statistics have a finite, non-negative trace time.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "mixray/render/povray.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    using namespace mixray;
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    const Result<render::PovrayStats> stats = render::parsePovrayStats(text);
    if (!stats) {
        if (stats.status().code() != ErrorCode::kCorruptData) {
            std::fprintf(stderr, "povray_stats_fuzz: rejection is not kCorruptData: %s\n",
                         stats.status().toString().c_str());
            std::abort();
        }
        return 0;
    }
    if (!std::isfinite(stats->trace_s) || stats->trace_s < 0 || !std::isfinite(stats->parse_s) ||
        stats->parse_s < 0) {
        std::fprintf(stderr, "povray_stats_fuzz: accepted a time that is not a time\n");
        std::abort();
    }
    return 0;
}
