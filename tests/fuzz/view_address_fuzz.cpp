// libFuzzer target for the live view's --view text ("[ADDR:]PORT", liveview::parseViewAddress):
// any text gives options that validate or a clean kInvalidArgument quoting --view, and what is
// accepted formats back as ADDR:PORT and parses to the same address and port.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "mixray/liveview/live_view.h"

namespace {

[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "view_address_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    using namespace mixray;
    const std::string text(reinterpret_cast<const char*>(data), size);
    liveview::LiveViewOptions options;
    const Status status = liveview::parseViewAddress(text, &options);
    if (!status.isOk()) {
        if (status.code() != ErrorCode::kInvalidArgument ||
            status.message().find("--view") == std::string::npos) {
            broken("rejection is not a kInvalidArgument naming --view", status.toString());
        }
        return 0;
    }
    if (!options.validate().isOk())
        broken("accepted text does not validate", text);
    liveview::LiveViewOptions again;
    const std::string formatted = options.address + ":" + std::to_string(options.port);
    if (!liveview::parseViewAddress(formatted, &again).isOk() || again.address != options.address ||
        again.port != options.port) {
        broken("formatted text does not parse back", formatted);
    }
    return 0;
}
