// Error text, status mapping and CRC for the FFmpeg-based recording code.
#include "ffmpeg_util.h"

extern "C" {
#include <libavutil/crc.h>
#include <libavutil/error.h>
}

#include <cerrno>

namespace mixray::ffmpeg {

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
    static const AVCRC* table = av_crc_get_table(AV_CRC_32_IEEE_LE);
    return av_crc(table, UINT32_MAX, data, size) ^ UINT32_MAX;
}

uint32_t crc32(std::string_view text) {
    return crc32(reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

const char* dictValue(const AVDictionary* dict, const char* key) {
    const AVDictionaryEntry* entry = av_dict_get(dict, key, nullptr, AV_DICT_MATCH_CASE);
    return entry ? entry->value : nullptr;
}

}  // namespace mixray::ffmpeg
