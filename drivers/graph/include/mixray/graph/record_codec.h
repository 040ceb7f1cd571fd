// Field helpers for the binary stream records (pose, IMU, lights, environment maps): every
// record starts with a little-endian u32 magic and u16 version and ends with a CRC-32 of all
// bytes before it. Shared by the modules that define records; not a user-facing API.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "mixray/graph/result.h"

namespace mixray::record {

// Little-endian field access (the file format is little-endian on every host).
inline void putLe(uint8_t* out, uint64_t value, int bytes) {
    for (int i = 0; i < bytes; ++i)
        out[i] = static_cast<uint8_t>(value >> (8 * i));
}
inline uint64_t getLe(const uint8_t* in, int bytes) {
    uint64_t value = 0;
    for (int i = 0; i < bytes; ++i)
        value |= static_cast<uint64_t>(in[i]) << (8 * i);
    return value;
}

// CRC-32 (IEEE, as in zlib and Matroska's CRC-32 element) of `size` bytes.
uint32_t crc32(const uint8_t* data, size_t size);

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

// True for text of printable characters only: valid UTF-8 without control characters
// (U+0000..U+001F, U+007F..U+009F), no overlong forms, surrogates or code points past U+10FFFF.
bool isPrintableUtf8(std::string_view text);

// `text` made fit for a record's text field: each control character or byte that is not valid
// UTF-8 becomes a space, and the text is cut at a character boundary to at most `max_bytes`.
std::string printableText(std::string_view text, size_t max_bytes);

// Writes `text` (at most field - 1 bytes) into a NUL-padded field of `field` bytes.
inline void putPaddedText(uint8_t* out, size_t field, std::string_view text) {
    std::memset(out, 0, field);
    std::memcpy(out, text.data(), text.size() < field ? text.size() : field - 1);
}

// Reads a NUL-padded text field of `field` bytes into `text`: kCorruptData "<kind> record:
// <name> ..." when it is not NUL-terminated or its padding is not zero.
Status getPaddedText(const uint8_t* in, size_t field, std::string_view kind, std::string_view name,
                     std::string* text);

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
    putLe(out + size - 4, crc32(out, size - 4), 4);
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
    if (getLe(data + size - 4, 4) != crc32(data, size - 4))
        return corrupt(kind, "CRC mismatch (the record is damaged)");
    const auto found = static_cast<uint16_t>(getLe(data + kOffVersion, 2));
    if (found != version)
        return corrupt(kind, "unsupported version " + std::to_string(found));
    return Status::ok();
}

}  // namespace mixray::record
