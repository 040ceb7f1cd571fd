// libFuzzer target for the rig-file parser: any input must give a rig or a clean error.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "mixray/graph/rig.h"

namespace {

// Stops the run with a message: libFuzzer records the input that got here.
[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "rig_parser_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    auto rig = mixray::parseRig(text, "fuzz/rig.yaml");
    if (!rig.isOk()) {
        const mixray::Status status = rig.status();
        // Bad content is kCorruptData naming the file; anything else is a parser bug.
        if (status.code() != mixray::ErrorCode::kCorruptData)
            broken("unexpected code", status.toString());
        if (status.message().rfind("fuzz/rig.yaml", 0) != 0)
            broken("message without file", status.message());
        return 0;
    }
    // An accepted rig is self-consistent and keeps its text.
    if (auto status = rig->validate(); !status.isOk())
        broken("accepted rig fails validate()", status.toString());
    if (rig->source_text != text)
        broken("source text changed", rig->source_path);
    if (rig->devices.empty())
        broken("accepted rig without devices", rig->name);
    for (const auto& device : rig->devices) {
        if (device.name().empty() || device.config.driver.empty())
            broken("device without name or driver", device.name());
        if (device.where.line < 1)
            broken("device without location", device.name());
    }
    if (rig->deviceConfigs().size() != rig->devices.size())
        broken("deviceConfigs() size", rig->name);
    for (const auto& device : rig->devices) {
        for (const auto& stream : device.streams) {
            const auto* file = rig->findCalibration(device.name(), stream.name);
            if (file && !file->device.empty() && file->device != device.name()) {
                broken("calibration of another device", file->path);
            }
        }
    }
    for (const auto& ref : rig->sync.streams) {
        if (!rig->findDevice(ref.device))
            broken("sync names unknown device", ref.name());
    }
    return 0;
}
