// Binary stream records: the CRC and text fields shared by every record kind.
#include "mixray/graph/record_codec.h"

#include "ffmpeg_util.h"

namespace mixray::record {

uint32_t crc32(const uint8_t* data, size_t size) {
    return ffmpeg::crc32(data, size);
}

namespace {

// Bytes of the printable character that starts at `p`: 0 for a control character or bytes
// that are not valid UTF-8 (overlong forms, surrogates, past U+10FFFF, cut short by `end`).
size_t printableCharBytes(const uint8_t* p, const uint8_t* end) {
    const uint8_t lead = *p;
    if (lead < 0x80)
        return lead < 0x20 || lead == 0x7f ? 0 : 1;
    size_t extra = 0;
    uint32_t code = 0;
    if ((lead & 0xe0) == 0xc0) {
        extra = 1;
        code = lead & 0x1f;
    } else if ((lead & 0xf0) == 0xe0) {
        extra = 2;
        code = lead & 0x0f;
    } else if ((lead & 0xf8) == 0xf0) {
        extra = 3;
        code = lead & 0x07;
    } else {
        return 0;  // a continuation byte or 0xf8..0xff where a character starts
    }
    if (static_cast<size_t>(end - p) <= extra)
        return 0;
    for (size_t i = 1; i <= extra; ++i) {
        if ((p[i] & 0xc0) != 0x80)
            return 0;
        code = (code << 6) | (p[i] & 0x3f);
    }
    constexpr uint32_t kSmallest[4] = {0, 0x80, 0x800, 0x10000};
    if (code < kSmallest[extra] || code > 0x10ffff || (code >= 0xd800 && code <= 0xdfff) ||
        (code >= 0x80 && code <= 0x9f))
        return 0;
    return 1 + extra;
}

}  // namespace

bool isPrintableUtf8(std::string_view text) {
    const auto* p = reinterpret_cast<const uint8_t*>(text.data());
    const auto* end = p + text.size();
    while (p < end) {
        const size_t bytes = printableCharBytes(p, end);
        if (bytes == 0)
            return false;
        p += bytes;
    }
    return true;
}

std::string printableText(std::string_view text, size_t max_bytes) {
    std::string out;
    const auto* p = reinterpret_cast<const uint8_t*>(text.data());
    const auto* end = p + text.size();
    while (p < end) {
        size_t bytes = printableCharBytes(p, end);
        const char* from = reinterpret_cast<const char*>(p);
        p += bytes == 0 ? 1 : bytes;
        if (bytes == 0) {
            from = " ";
            bytes = 1;
        }
        if (out.size() + bytes > max_bytes)
            break;
        out.append(from, bytes);
    }
    return out;
}

Status getPaddedText(const uint8_t* in, size_t field, std::string_view kind, std::string_view name,
                     std::string* text) {
    const auto* chars = reinterpret_cast<const char*>(in);
    const size_t length = strnlen(chars, field);
    if (length == field)
        return corrupt(kind, std::string(name) + " is not NUL-terminated");
    if (!allZero(in + length, field - length))
        return corrupt(kind, std::string(name) + " padding is not zero");
    text->assign(chars, length);
    return Status::ok();
}

}  // namespace mixray::record
