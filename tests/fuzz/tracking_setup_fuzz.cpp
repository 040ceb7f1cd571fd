// libFuzzer target for the tracking-setup parser: any input must give a setup or a clean error,
// and an accepted setup must write out and read back to the same text.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "mixray/tracking/setup.h"

namespace {

// Stops the run with a message: libFuzzer records the input that got here.
[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "tracking_setup_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    auto setup = mixray::tracking::parseTrackingSetup(text, "fuzz/setup.yaml");
    if (!setup.isOk()) {
        const mixray::Status status = setup.status();
        if (status.code() != mixray::ErrorCode::kCorruptData)
            broken("unexpected code", status.toString());
        if (status.message().rfind("fuzz/setup.yaml", 0) != 0)
            broken("message without file", status.message());
        return 0;
    }
    if (auto status = setup->validate(); !status.isOk())
        broken("accepted setup fails validate()", status.toString());
    const std::string written = mixray::tracking::trackingSetupYaml(*setup);
    auto again = mixray::tracking::parseTrackingSetup(written, "fuzz/written.yaml");
    if (!again.isOk())
        broken("written setup does not parse", again.status().toString() + "\n" + written);
    // The same setup, poses to rounding (they go through a rotation matrix).
    if (again->targets.size() != setup->targets.size() ||
        again->probes.size() != setup->probes.size() ||
        again->environment.has_value() != setup->environment.has_value())
        broken("written setup reads back different", written);
    for (size_t i = 0; i < setup->targets.size(); ++i) {
        const auto& a = setup->targets[i];
        const auto& b = again->targets[i];
        if (a.name != b.name || a.id != b.id || a.kind != b.kind ||
            a.bound_objects != b.bound_objects ||
            !((a.T_world_target.matrix() - b.T_world_target.matrix()).cwiseAbs().maxCoeff() <
              1e-9 * (1 + a.T_world_target.translation().norm())))
            broken("a target reads back different", written);
    }
    return 0;
}
