// The IEEE CRC-32 (zlib's) computed bit by bit: the documented check value of mixray's binary
// stream records, independent of the table-driven one the library uses.
#pragma once

#include <cstddef>
#include <cstdint>

namespace mixray::test {

inline uint32_t referenceCrc32(const uint8_t* data, size_t size) {
    uint32_t crc = 0xffffffffu;
    for (size_t i = 0; i < size; ++i) {
        crc ^= data[i];
        for (int k = 0; k < 8; ++k)
            crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

}  // namespace mixray::test
