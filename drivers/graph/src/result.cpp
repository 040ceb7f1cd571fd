// Names and formatting of Status values.
#include "mixray/graph/result.h"

namespace mixray {

const char* toString(ErrorCode code) {
    switch (code) {
        case ErrorCode::kOk:
            return "ok";
        case ErrorCode::kInvalidArgument:
            return "invalid argument";
        case ErrorCode::kNotFound:
            return "not found";
        case ErrorCode::kCorruptData:
            return "corrupt data";
        case ErrorCode::kIoError:
            return "I/O error";
        case ErrorCode::kUnsupported:
            return "unsupported";
        case ErrorCode::kUnavailable:
            return "unavailable";
        case ErrorCode::kEndOfStream:
            return "end of stream";
        case ErrorCode::kCancelled:
            return "cancelled";
        case ErrorCode::kInternal:
            return "internal error";
    }
    return "unknown error";
}

std::string Status::toString() const {
    if (isOk())
        return "ok";
    return std::string(mixray::toString(code_)) + ": " + message_;
}

Status Status::withContext(std::string_view context) const {
    if (isOk())
        return *this;
    return Status(code_, std::string(context) + ": " + message_);
}

}  // namespace mixray
