// Error text, status mapping and CRC for the FFmpeg-based recording code.
#include "ffmpeg_util.h"

extern "C" {
#include <libavutil/error.h>
#include <libavutil/log.h>
}

#include <array>
#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <map>

namespace mixray::ffmpeg {
namespace {

// CRC-32 (IEEE, reflected polynomial 0xEDB88320) by slicing 16 bytes at a time: about 2.5x
// FFmpeg's av_crc, which matters because every payload byte of an uncompressed recording is
// checksummed once when written and once when read. Table s holds the CRC of a byte followed
// by s zero bytes.
using CrcTables = std::array<std::array<uint32_t, 256>, 16>;

constexpr CrcTables makeCrcTables() {
    CrcTables t{};
    for (uint32_t i = 0; i < 256; ++i) {
        uint32_t c = i;
        for (int k = 0; k < 8; ++k)
            c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
        t[0][i] = c;
    }
    for (size_t s = 1; s < t.size(); ++s) {
        for (uint32_t i = 0; i < 256; ++i)
            t[s][i] = (t[s - 1][i] >> 8) ^ t[0][t[s - 1][i] & 0xFF];
    }
    return t;
}

constexpr CrcTables kCrcTables = makeCrcTables();

// The contexts whose errors are collected, and the lock the log callback takes to find them.
std::mutex& registryMutex() {
    static std::mutex mutex;
    return mutex;
}
std::map<const void*, DemuxerErrors*>& registry() {
    static std::map<const void*, DemuxerErrors*> contexts;
    return contexts;
}

// FFmpeg passes its own printf format: the attribute lets clang check the call below.
extern "C" __attribute__((format(printf, 3, 0))) void logCallback(void* avcl, int level,
                                                                  const char* format,
                                                                  va_list args) {
    DemuxerErrors* errors = nullptr;
    if (avcl && level <= AV_LOG_ERROR) {
        std::lock_guard lock(registryMutex());
        auto it = registry().find(avcl);
        if (it != registry().end())
            errors = it->second;
    }
    if (!errors) {
        av_log_default_callback(avcl, level, format, args);
        return;
    }
    std::array<char, 512> text{};
    va_list copy;
    va_copy(copy, args);
    std::vsnprintf(text.data(), text.size(), format, copy);
    va_end(copy);
    std::string message = text.data();
    while (!message.empty() && (message.back() == '\n' || message.back() == ' '))
        message.pop_back();
    // The callback runs on the thread that drives the demuxer, so its position is stable.
    const auto* context = static_cast<const AVFormatContext*>(avcl);
    errors->add({context->pb ? avio_tell(context->pb) : -1, std::move(message)});
}

}  // namespace

DemuxerErrors::DemuxerErrors(AVFormatContext* context) : context_(context) {
    static std::once_flag installed;
    std::call_once(installed, [] { av_log_set_callback(logCallback); });
    std::lock_guard lock(registryMutex());
    registry()[context_] = this;
}

DemuxerErrors::~DemuxerErrors() {
    std::lock_guard lock(registryMutex());
    auto it = registry().find(context_);
    if (it != registry().end() && it->second == this)
        registry().erase(it);
}

std::vector<DemuxerErrors::Entry> DemuxerErrors::take() {
    std::lock_guard lock(mutex_);
    std::vector<Entry> out;
    out.swap(entries_);
    return out;
}

void DemuxerErrors::add(Entry entry) {
    std::lock_guard lock(mutex_);
    // A resynchronising demuxer can log an error per byte it skips; the first ones tell where.
    if (entries_.size() < 64)
        entries_.push_back(std::move(entry));
}

std::string errorString(int av_error) {
    char text[AV_ERROR_MAX_STRING_SIZE] = {};
    if (av_strerror(av_error, text, sizeof(text)) < 0) {
        return "FFmpeg error " + std::to_string(av_error);
    }
    return text;
}

Status toStatus(int av_error, std::string_view context) {
    ErrorCode code = ErrorCode::kInternal;
    switch (av_error) {
        case AVERROR(ENOSPC):
        case AVERROR(EFBIG):
        case AVERROR(EDQUOT):
        case AVERROR(EIO):
        case AVERROR(EACCES):
        case AVERROR(EPERM):
        case AVERROR(EROFS):
        case AVERROR(ENOENT):
        case AVERROR(EISDIR):
            code = ErrorCode::kIoError;
            break;
        case AVERROR_INVALIDDATA:
        case AVERROR_EOF:
        case AVERROR(EINVAL):
            code = ErrorCode::kCorruptData;
            break;
        case AVERROR(ENOMEM):
            code = ErrorCode::kUnavailable;
            break;
        default:
            break;
    }
    std::string message(context);
    message += ": ";
    message += errorString(av_error);
    if (av_error == AVERROR(ENOSPC) || av_error == AVERROR(EFBIG) || av_error == AVERROR(EDQUOT)) {
        message += " (disk full or file size limit reached)";
    }
    return {code, std::move(message)};
}

uint32_t crc32(const uint8_t* data, size_t size) {
    const CrcTables& t = kCrcTables;
    uint32_t crc = UINT32_MAX;
    for (; size >= 16; data += 16, size -= 16) {
        const auto a = static_cast<uint32_t>(getLe(data, 4)) ^ crc;
        const auto b = static_cast<uint32_t>(getLe(data + 4, 4));
        const auto c = static_cast<uint32_t>(getLe(data + 8, 4));
        const auto d = static_cast<uint32_t>(getLe(data + 12, 4));
        crc = t[15][a & 0xFF] ^ t[14][(a >> 8) & 0xFF] ^ t[13][(a >> 16) & 0xFF] ^ t[12][a >> 24] ^
              t[11][b & 0xFF] ^ t[10][(b >> 8) & 0xFF] ^ t[9][(b >> 16) & 0xFF] ^ t[8][b >> 24] ^
              t[7][c & 0xFF] ^ t[6][(c >> 8) & 0xFF] ^ t[5][(c >> 16) & 0xFF] ^ t[4][c >> 24] ^
              t[3][d & 0xFF] ^ t[2][(d >> 8) & 0xFF] ^ t[1][(d >> 16) & 0xFF] ^ t[0][d >> 24];
    }
    for (; size > 0; ++data, --size)
        crc = (crc >> 8) ^ t[0][(crc ^ *data) & 0xFF];
    return crc ^ UINT32_MAX;
}

uint32_t crc32(std::string_view text) {
    return crc32(reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

const char* dictValue(const AVDictionary* dict, const char* key) {
    const AVDictionaryEntry* entry = av_dict_get(dict, key, nullptr, AV_DICT_MATCH_CASE);
    return entry ? entry->value : nullptr;
}

}  // namespace mixray::ffmpeg
