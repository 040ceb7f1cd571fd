// libFuzzer target for linuxptp's pmc output as mixray reads it (parsePmcOutput, mixray/graph/
// ptp.h): any text gives a state or a clean kUnavailable / kCorruptData, and a state that is
// accepted describes itself in one line and is locked only as following() or grandmaster() say.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "mixray/graph/ptp.h"

namespace {

[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "pmc_answer_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    using namespace mixray;
    const std::string text(reinterpret_cast<const char*>(data), size);
    const Result<PtpState> state = parsePmcOutput(text);
    if (!state) {
        const ErrorCode code = state.status().code();
        if (code != ErrorCode::kUnavailable && code != ErrorCode::kCorruptData)
            broken("rejection is neither kUnavailable nor kCorruptData", state.status().toString());
        if (state.status().message().size() > 400)
            broken("rejection quotes too much", state.status().message());
        return 0;
    }
    const std::string line = state->describe();
    if (line.empty() || line.find('\n') != std::string::npos)
        broken("description is not one line", line);
    if (state->locked() != (state->following() || state->grandmaster()))
        broken("locked() disagrees with following() and grandmaster()", line);
    if ((line.rfind("PTP-locked", 0) == 0) != state->locked())
        broken("description disagrees with locked()", line);
    return 0;
}
