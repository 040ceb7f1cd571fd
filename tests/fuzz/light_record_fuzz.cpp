// libFuzzer target for the binary stream records a pipeline publishes: light records,
// environment-map records and pose records (versions 1 and 2). Every input is given to each
// decoder; each must refuse it with a clean kCorruptData or accept it, and what it accepts must
// encode back to the very same bytes (pose version 1: to a version 2 that decodes the same).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "mixray/graph/pose.h"
#include "mixray/tracking/light_record.h"

namespace {

[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "light_record_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

void expectCorrupt(const mixray::Status& status, const char* prefix) {
    if (status.code() != mixray::ErrorCode::kCorruptData)
        broken("unexpected code", status.toString());
    if (status.message().rfind(prefix, 0) != 0)
        broken("message does not name the record", status.message());
}

bool samePose(const mixray::PoseRecord& a, const mixray::PoseRecord& b) {
    return a.frame_sequence == b.frame_sequence &&
           a.frame_device_stamp_ns == b.frame_device_stamp_ns && a.status == b.status &&
           a.marker_id == b.marker_id && a.anchor == b.anchor && a.reason == b.reason &&
           a.translation == b.translation && a.rotation.coeffs() == b.rotation.coeffs() &&
           std::memcmp(&a.error, &b.error, sizeof a.error) == 0;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    using namespace mixray;
    auto lights = tracking::decodeLightRecord(data, size);
    if (lights) {
        if (!tracking::validate(*lights).isOk())
            broken("accepted light record fails validate()", "");
        auto again = tracking::encodeLightRecord(*lights);
        if (!again)
            broken("accepted light record does not encode", again.status().toString());
        if (again->size() != size || std::memcmp(again->data(), data, size) != 0)
            broken("light record encodes to other bytes", std::to_string(size));
    } else {
        expectCorrupt(lights.status(), "light record: ");
    }

    auto map = tracking::decodeEnvironmentMapRecord(data, size);
    if (map) {
        std::vector<uint8_t> out(size);
        auto written =
            tracking::encodeEnvironmentMapRecord(map->map, map->header, out.data(), out.size());
        if (!written)
            broken("accepted map does not encode", written.status().toString());
        if (*written != size || std::memcmp(out.data(), data, size) != 0)
            broken("map record encodes to other bytes", std::to_string(size));
    } else {
        expectCorrupt(map.status(), "environment map record: ");
    }

    auto pose = decodePoseRecord(data, size);
    if (pose) {
        if (!validate(*pose).isOk())
            broken("accepted pose fails validate()", "");
        auto bytes = encodePoseRecord(*pose);
        if (!bytes)
            broken("accepted pose does not encode", bytes.status().toString());
        if (size == kPoseRecordBytes && std::memcmp(bytes->data(), data, size) != 0)
            broken("version-2 pose encodes to other bytes", "");
        auto again = decodePoseRecord(bytes->data(), bytes->size());
        if (!again || !samePose(*pose, *again))
            broken("re-encoded pose decodes different", "");
    } else {
        expectCorrupt(pose.status(), "pose record: ");
    }
    return 0;
}
