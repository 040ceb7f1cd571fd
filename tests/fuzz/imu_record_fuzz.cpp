// libFuzzer target for IMU records (decodeImuRecord, mixray/graph/imu.h), the binary payload of
// kImu streams read back from recordings. The bytes are decoded as they are, and a 64-byte input
// once more with its CRC-32 rewritten, so that mutations reach the fields behind the checksum. A
// rejection is kCorruptData naming the record; an accepted sample validates, encodes back to the
// very same bytes, and its accelerometer levels a camera or is refused cleanly.
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "mixray/graph/imu.h"
#include "mixray/graph/record_codec.h"

namespace {

using namespace mixray;

[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "imu_record_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

void check(const uint8_t* data, size_t size) {
    auto sample = decodeImuRecord(data, size);
    if (!sample) {
        if (sample.status().code() != ErrorCode::kCorruptData)
            broken("unexpected code", sample.status().toString());
        if (sample.status().message().rfind("IMU record: ", 0) != 0)
            broken("message does not name the record", sample.status().message());
        return;
    }
    if (Status s = validate(*sample); !s)
        broken("accepted sample does not validate", s.toString());
    auto again = encodeImuRecord(*sample);
    if (!again)
        broken("accepted sample does not encode", again.status().toString());
    if (size != again->size() || std::memcmp(data, again->data(), size) != 0)
        broken("accepted sample encodes to other bytes", "");
    auto level = levelFromGravity(sample->accel);
    if (!level && level.status().code() != ErrorCode::kInvalidArgument)
        broken("unexpected levelling code", level.status().toString());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    check(data, size);
    if (size == kImuRecordBytes) {
        std::array<uint8_t, kImuRecordBytes> fixed;
        std::memcpy(fixed.data(), data, size);
        record::putCrc(fixed.data(), fixed.size());
        check(fixed.data(), fixed.size());
    }
    return 0;
}
