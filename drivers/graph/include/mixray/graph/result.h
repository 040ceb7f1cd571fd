// Status and Result<T>: how every mixray module API reports failure (no exceptions across APIs).
#pragma once

#include <cassert>
#include <string>
#include <string_view>
#include <utility>
#include <variant>

namespace mixray {

// What kind of failure a Status carries. Callers branch on the code; people read the message.
enum class ErrorCode {
    kOk = 0,
    kInvalidArgument,  // the caller passed something that can never work (bad option, bad usage)
    kNotFound,         // a file, device, stream or key does not exist
    kCorruptData,      // input exists but its content is malformed (truncated file, bad YAML)
    kIoError,          // the operating system refused a read or write (disk full, permissions)
    kUnsupported,      // valid request this build or device cannot do
    kUnavailable,      // transiently impossible (device unplugged, queue closed)
    kEndOfStream,      // a reader reached the end of its data; not a failure for loops
    kCancelled,        // stopped on request
    kInternal,         // a bug in mixray or a library misbehaving
};

const char* toString(ErrorCode code);

// Outcome of an operation: ok, or an error code with a human-readable message.
// Reentrant; a Status is a plain value.
class [[nodiscard]] Status {
public:
    Status() = default;
    Status(ErrorCode code, std::string message) : code_(code), message_(std::move(message)) {}

    static Status ok() { return {}; }

    bool isOk() const { return code_ == ErrorCode::kOk; }
    explicit operator bool() const { return isOk(); }
    ErrorCode code() const { return code_; }
    const std::string& message() const { return message_; }

    // "corrupt data: file.mkv: truncated header" — code name then message.
    std::string toString() const;

    // Returns a copy whose message is prefixed with context ("reading rig.yaml: ...").
    Status withContext(std::string_view context) const;

private:
    ErrorCode code_ = ErrorCode::kOk;
    std::string message_;
};

// A value or the Status explaining why there is none (like std::expected, which C++20 lacks).
template <typename T>
class [[nodiscard]] Result {
public:
    Result(T value) : storage_(std::move(value)) {}        // NOLINT(google-explicit-constructor)
    Result(Status status) : storage_(std::move(status)) {  // NOLINT(google-explicit-constructor)
        assert(!std::get<Status>(storage_).isOk() && "Result built from an ok Status has no value");
    }
    Result(ErrorCode code, std::string message) : storage_(Status(code, std::move(message))) {}

    bool isOk() const { return std::holds_alternative<T>(storage_); }
    explicit operator bool() const { return isOk(); }

    T& value() & {
        assert(isOk());
        return std::get<T>(storage_);
    }
    const T& value() const& {
        assert(isOk());
        return std::get<T>(storage_);
    }
    T&& value() && {
        assert(isOk());
        return std::get<T>(std::move(storage_));
    }
    T* operator->() { return &value(); }
    const T* operator->() const { return &value(); }
    T& operator*() & { return value(); }
    const T& operator*() const& { return value(); }

    // The error; Status::ok() when a value is present.
    Status status() const { return isOk() ? Status::ok() : std::get<Status>(storage_); }

private:
    std::variant<T, Status> storage_;
};

}  // namespace mixray

// Returns early from a function returning Status or Result<T> when `expr` (a Status) failed.
#define MIXRAY_RETURN_IF_ERROR(expr)              \
    do {                                          \
        ::mixray::Status mixray_status_ = (expr); \
        if (!mixray_status_.isOk())               \
            return mixray_status_;                \
    } while (0)
