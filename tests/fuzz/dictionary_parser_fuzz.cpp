// libFuzzer target for OpenCV dictionary files (parseMarkerDictionary): any input must give a
// dictionary or a clean kCorruptData naming the file, and an accepted dictionary must validate
// and write out and read back to the same markers.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "mixray/calibration/marker_dictionary.h"

namespace {

// Stops the run with a message: libFuzzer records the input that got here.
[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "dictionary_parser_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    using mixray::calibration::MarkerDictionary;
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    auto dict = mixray::calibration::parseMarkerDictionary(text, "fuzz/dict.yml");
    if (!dict.isOk()) {
        const mixray::Status status = dict.status();
        if (status.code() != mixray::ErrorCode::kCorruptData)
            broken("unexpected code", status.toString());
        if (status.message().rfind("fuzz/dict.yml: ", 0) != 0)
            broken("message without file", status.message());
        return 0;
    }
    if (auto status = dict->validate(); !status.isOk())
        broken("accepted dictionary fails validate()", status.toString());
    if (dict->name != "custom:dict")
        broken("name not from the file", dict->name);
    const std::string written = mixray::calibration::markerDictionaryYaml(*dict);
    auto again = mixray::calibration::parseMarkerDictionary(written, "fuzz/dict.yml");
    if (!again.isOk())
        broken("written dictionary does not parse", again.status().toString() + "\n" + written);
    if (again->marker_size != dict->marker_size ||
        again->max_correction_bits != dict->max_correction_bits || again->markers != dict->markers)
        broken("written dictionary reads back different", written);
    return 0;
}
