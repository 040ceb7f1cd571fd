// Exit-code mapping and error printing shared by all subcommands.
#include "cli.h"

#include <cstdio>

namespace mixray::cli {

int exitCodeFor(const Status& status) {
    switch (status.code()) {
        case ErrorCode::kOk:
            return kExitOk;
        case ErrorCode::kInvalidArgument:
            return kExitUsage;
        case ErrorCode::kNotFound:
        case ErrorCode::kCorruptData:
        case ErrorCode::kIoError:
        case ErrorCode::kUnsupported:
            return kExitBadInput;
        case ErrorCode::kUnavailable:
            return kExitUnavailable;
        case ErrorCode::kCancelled:
            return kExitInterrupted;
        case ErrorCode::kEndOfStream:
        case ErrorCode::kInternal:
            return kExitInternal;
    }
    return kExitInternal;
}

int fail(const std::string& command, const Status& status) {
    std::fprintf(stderr, "mixray %s: %s\n", command.c_str(), status.toString().c_str());
    return exitCodeFor(status);
}

}  // namespace mixray::cli
