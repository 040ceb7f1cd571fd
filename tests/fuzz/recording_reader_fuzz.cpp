// libFuzzer target for the Matroska recording reader: any bytes must give a clean error or
// frames that match their stream, then a clean end; never a crash, a hang or a wrong status.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "mixray/graph/mkv.h"

namespace {

// Stops the run with a message: libFuzzer records the input that got here.
[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "recording_reader_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

// An in-memory file with a path (no disk I/O per input): /proc/self/fd/<memfd>.
struct MemoryFile {
    int fd = -1;
    std::string path;
    MemoryFile() {
        fd = memfd_create("recording_reader_fuzz", 0);
        if (fd < 0)
            broken("memfd_create failed", "");
        path = "/proc/self/fd/" + std::to_string(fd);
    }
    void assign(const uint8_t* data, size_t size) {
        if (ftruncate(fd, 0) != 0)
            broken("ftruncate failed", path);
        size_t done = 0;
        while (done < size) {
            const ssize_t n = pwrite(fd, data + done, size - done, static_cast<off_t>(done));
            if (n <= 0)
                broken("pwrite failed", path);
            done += static_cast<size_t>(n);
        }
    }
};

void checkEnd(const mixray::Status& status, const std::string& path) {
    using mixray::ErrorCode;
    if (status.code() != ErrorCode::kEndOfStream && status.code() != ErrorCode::kCorruptData)
        broken("next() ended with an unexpected code", status.toString());
    if (status.message().find(path) == std::string::npos)
        broken("end message without the file name", status.toString());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static MemoryFile* file = [] {
        mixray::setFfmpegLogging(false);
        return new MemoryFile();
    }();
    file->assign(data, size);

    mixray::MkvReaderOptions options;
    options.buffers_per_stream = 2;
    options.decoder_threads = 1;
    auto reader = mixray::openMkv(file->path, options);
    if (!reader) {
        const mixray::Status status = reader.status();
        using mixray::ErrorCode;
        if (status.code() != ErrorCode::kCorruptData && status.code() != ErrorCode::kUnsupported)
            broken("open failed with an unexpected code", status.toString());
        if (status.message().find(file->path) == std::string::npos)
            broken("open error without the file name", status.toString());
        return 0;
    }
    const auto& streams = (*reader)->streams();
    if (streams.empty())
        broken("a reader without streams", (*reader)->format());

    int64_t first_stamp = INT64_MAX;
    for (int i = 0; i < 100000; ++i) {
        auto frame = (*reader)->next();
        if (!frame) {
            checkEnd(frame.status(), file->path);
            break;
        }
        const mixray::FrameMetadata& meta = frame->meta();
        if (meta.stream >= streams.size())
            broken("frame of an unknown stream", "");
        if (meta.host_stamp_ns < first_stamp)
            first_stamp = meta.host_stamp_ns;
        const mixray::ImageView view = frame->image();
        const mixray::ImageDesc& want = streams[meta.stream].format;
        if (view.desc.format != want.format)
            broken("frame format differs from its stream", "");
        if (!mixray::pixelFormatInfo(want.format).compressed && view.desc != want)
            broken("image frame with a layout other than its stream's", "");
        // Touch every payload byte: a wrong size shows up under ASan.
        volatile uint8_t sum = 0;
        for (size_t b = 0; b < view.size_bytes; ++b)
            sum = static_cast<uint8_t>(sum + view.data[b]);
        (void)sum;
    }
    // Seeking back must work as well after whatever reading did.
    if (first_stamp != INT64_MAX) {
        if (!(*reader)->seek(first_stamp).isOk())
            return 0;
        for (int i = 0; i < 4; ++i) {
            auto frame = (*reader)->next();
            if (!frame) {
                checkEnd(frame.status(), file->path);
                break;
            }
        }
    }
    return 0;
}
