// Internal helpers for the fixed-size binary stream records (pose, IMU): every record starts
// with a little-endian u32 magic and u16 version and ends with a CRC-32 of all bytes before it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "ffmpeg_util.h"
#include "mixray/graph/result.h"

namespace mixray::record {

using ffmpeg::getLe;
using ffmpeg::putLe;

// Floating-point fields are stored as their IEEE-754 bits, little-endian.
inline void putF64(uint8_t* out, double v) {
    uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    putLe(out, bits, 8);
}
inline double getF64(const uint8_t* in) {
    const uint64_t bits = getLe(in, 8);
    double v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
}
inline void putF32(uint8_t* out, float v) {
    uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    putLe(out, bits, 4);
}
inline float getF32(const uint8_t* in) {
    const auto bits = static_cast<uint32_t>(getLe(in, 4));
    float v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
}

inline bool allZero(const uint8_t* data, size_t n) {
    for (size_t i = 0; i < n; ++i)
        if (data[i] != 0)
            return false;
    return true;
}

inline constexpr size_t kOffVersion = 4;

// Writes the magic and version at the start of a record.
inline void putHeader(uint8_t* out, uint32_t magic, uint16_t version) {
    putLe(out, magic, 4);
    putLe(out + kOffVersion, version, 2);
}

// Writes the trailing CRC once every other field is in place.
inline void putCrc(uint8_t* out, size_t size) {
    putLe(out + size - 4, ffmpeg::crc32(out, size - 4), 4);
}

// kCorruptData "<kind> record: <what>", kind being "pose", "IMU"...
inline Status corrupt(std::string_view kind, const std::string& what) {
    return Status(ErrorCode::kCorruptData, std::string(kind) + " record: " + what);
}

// Checks, in this order, the size, the magic, the CRC and the version of a record, so that a
// payload from another stream says "bad magic" rather than "CRC mismatch".
inline Status checkFrame(const uint8_t* data, size_t size, size_t expected_size, uint32_t magic,
                         uint16_t version, std::string_view kind) {
    if (data == nullptr || size != expected_size)
        return corrupt(kind, "expected " + std::to_string(expected_size) + " bytes, got " +
                                 std::to_string(data == nullptr ? 0 : size));
    if (getLe(data, 4) != magic)
        return corrupt(kind, "bad magic (not a mixray " + std::string(kind) + " record)");
    if (getLe(data + size - 4, 4) != ffmpeg::crc32(data, size - 4))
        return corrupt(kind, "CRC mismatch (the record is damaged)");
    const auto found = static_cast<uint16_t>(getLe(data + kOffVersion, 2));
    if (found != version)
        return corrupt(kind, "unsupported version " + std::to_string(found));
    return Status::ok();
}

}  // namespace mixray::record
