// Synthetic streams and frames for the recording tests, and exact comparison of frames.
#include "recording_test_util.h"

#include <cstring>

#include "mixray/graph/mkv.h"

namespace mixray::test {
namespace {

uint32_t mix(uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

const uint8_t kTinyJpeg[] = {
    0xff, 0xd8, 0xff, 0xe0, 0x00, 0x10, 0x4a, 0x46, 0x49, 0x46, 0x00, 0x01, 0x02, 0x00, 0x00, 0x01,
    0x00, 0x01, 0x00, 0x00, 0xff, 0xfe, 0x00, 0x10, 0x4c, 0x61, 0x76, 0x63, 0x35, 0x39, 0x2e, 0x33,
    0x37, 0x2e, 0x31, 0x30, 0x30, 0x00, 0xff, 0xdb, 0x00, 0x43, 0x00, 0x08, 0x10, 0x10, 0x13, 0x10,
    0x13, 0x16, 0x16, 0x16, 0x16, 0x16, 0x16, 0x1a, 0x18, 0x1a, 0x1b, 0x1b, 0x1b, 0x1a, 0x1a, 0x1a,
    0x1a, 0x1b, 0x1b, 0x1b, 0x1d, 0x1d, 0x1d, 0x22, 0x22, 0x22, 0x1d, 0x1d, 0x1d, 0x1b, 0x1b, 0x1d,
    0x1d, 0x20, 0x20, 0x22, 0x22, 0x25, 0x26, 0x25, 0x23, 0x23, 0x22, 0x23, 0x26, 0x26, 0x28, 0x28,
    0x28, 0x30, 0x30, 0x2e, 0x2e, 0x38, 0x38, 0x3a, 0x45, 0x45, 0x53, 0xff, 0xc4, 0x00, 0x6a, 0x00,
    0x01, 0x01, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x07, 0x02, 0x06, 0x01, 0x01, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x02, 0x03, 0x10, 0x00, 0x01, 0x02, 0x06, 0x02, 0x03, 0x01, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x02, 0x03, 0x00, 0x21, 0x11, 0x12, 0x04, 0x05,
    0x22, 0x34, 0x41, 0x42, 0x71, 0x13, 0x11, 0x00, 0x01, 0x04, 0x01, 0x03, 0x05, 0x01, 0x01, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x21, 0x11, 0x03, 0x01, 0x12, 0x31, 0x00, 0x04,
    0x13, 0x22, 0x32, 0x05, 0x42, 0x14, 0x15, 0xff, 0xc0, 0x00, 0x11, 0x08, 0x00, 0x08, 0x00, 0x10,
    0x03, 0x01, 0x22, 0x00, 0x02, 0x11, 0x00, 0x03, 0x11, 0x00, 0xff, 0xda, 0x00, 0x0c, 0x03, 0x01,
    0x00, 0x02, 0x11, 0x03, 0x11, 0x00, 0x3f, 0x00, 0xcb, 0xb3, 0xaf, 0xc8, 0x3a, 0xc4, 0x00, 0xdf,
    0x25, 0x29, 0x5e, 0xc8, 0x98, 0xb9, 0x24, 0x4e, 0xef, 0xb0, 0x8c, 0x73, 0x98, 0x46, 0xd5, 0xb5,
    0x97, 0x28, 0x96, 0xef, 0xfd, 0x0d, 0x17, 0x20, 0x5b, 0xa0, 0x90, 0x15, 0x3c, 0x87, 0x8a, 0xc5,
    0xe3, 0xf4, 0x98, 0x83, 0xcc, 0x8e, 0xeb, 0xf0, 0x78, 0x35, 0xfd, 0x30, 0x79, 0x7b, 0x7f, 0x1d,
    0xcd, 0xd3, 0xc1, 0x1f, 0x3b, 0x17, 0xcd, 0xf2, 0x7f, 0x1a, 0xd1, 0xb7, 0x61, 0x3b, 0x93, 0xdb,
    0x87, 0x10, 0x96, 0x38, 0x84, 0xc4, 0x6f, 0xe9, 0xac, 0x64, 0x15, 0xbd, 0x12, 0xa4, 0xb6, 0x44,
    0x6a, 0xdf, 0xff, 0xd9,
};

}  // namespace

const std::vector<uint8_t>& tinyJpeg() {
    static const std::vector<uint8_t> jpeg(std::begin(kTinyJpeg), std::end(kTinyJpeg));
    return jpeg;
}

StreamInfo makeStream(const std::string& name, PixelFormat format, int width, int height) {
    StreamInfo info;
    info.name = name;
    info.device = name.substr(0, name.find('/'));
    info.format = ImageDesc::packed(format, width, height);
    switch (format) {
        case PixelFormat::kDepth16:
            info.kind = StreamKind::kDepth;
            break;
        case PixelFormat::kIR16:
            info.kind = StreamKind::kInfrared;
            break;
        case PixelFormat::kMono8:
        case PixelFormat::kMono16:
            info.kind = StreamKind::kMono;
            break;
        case PixelFormat::kBinary:
            info.kind = StreamKind::kImu;
            break;
        default:
            info.kind = StreamKind::kColor;
            break;
    }
    info.nominal_fps = 30;
    return info;
}

std::vector<StreamInfo> everyFormatStreams() {
    std::vector<StreamInfo> streams;
    for (int f = 1; f <= static_cast<int>(PixelFormat::kBinary); ++f) {
        const auto format = static_cast<PixelFormat>(f);
        const bool chroma = format == PixelFormat::kYUYV || format == PixelFormat::kNV12;
        StreamInfo info =
            makeStream("cam" + std::to_string(f % 3) + "/" + std::string(toString(format)), format,
                       chroma ? 18 : 17, chroma ? 10 : 9);
        info.nominal_fps = 29.97 + f;
        info.clock_domain = static_cast<ClockDomainId>(f % 3);
        info.tags["Format Name"] = std::string(toString(format));
        streams.push_back(info);
    }
    // Rows padded beyond the pixels, as drivers deliver them.
    StreamInfo padded = makeStream("cam9/depth_padded", PixelFormat::kDepth16, 21, 7);
    padded.format.stride_bytes = 64;
    padded.tags["odd=key\nwith%"] = "value\r\n=100%";
    streams.push_back(padded);
    return streams;
}

RecordingHeader makeHeader(std::vector<StreamInfo> streams) {
    RecordingHeader header;
    header.streams = std::move(streams);
    Attachment rig{"rig.yaml", "application/x-yaml", {}};
    const std::string text = "name: test rig\ndevices:\n  - name: cam0\n";
    rig.data.assign(text.begin(), text.end());
    Attachment calibration{"calibration.bin", "application/octet-stream", {}};
    for (int i = 0; i < 3000; ++i)
        calibration.data.push_back(static_cast<uint8_t>(mix(i)));
    calibration.data[10] = 0;  // NUL bytes inside an attachment must survive
    header.attachments = {rig, calibration};
    header.tags = {{"title", "unit test"}, {"Mixed Case", "Value with\nnewline"}, {"empty", ""}};
    return header;
}

FrameRef makeFrame(const StreamInfo& info, const FrameMetadata& meta, uint32_t seed) {
    ImageDesc desc = info.format;
    std::vector<uint8_t> payload;
    if (desc.format == PixelFormat::kMJPEG) {
        payload = tinyJpeg();
        // Varying size; a JPEG decoder ignores bytes after the end-of-image marker.
        for (uint32_t i = 0; i < seed % 7; ++i)
            payload.push_back(static_cast<uint8_t>(mix(seed + i)));
    } else if (desc.format == PixelFormat::kBinary) {
        const size_t bytes = seed % 5 == 0 ? 0 : 8 + seed % 61;
        for (size_t i = 0; i < bytes; ++i)
            payload.push_back(static_cast<uint8_t>(mix(seed * 131 + i)));
        desc = ImageDesc{PixelFormat::kBinary, static_cast<int>(bytes), 1, static_cast<int>(bytes)};
    }
    BufferPoolOptions options;
    options.desc = desc;
    options.buffer_bytes = std::max<size_t>(desc.bufferBytes(), payload.size() + 64);
    options.buffer_count = 1;
    options.name = info.name;
    auto pool = BufferPool::create(options);
    WritableFrame frame = pool->acquire();
    frame.setDesc(desc);
    MutableImageView view = frame.image();
    if (!payload.empty() || pixelFormatInfo(desc.format).compressed) {
        if (!payload.empty())
            std::memcpy(view.data, payload.data(), payload.size());
        frame.setPayloadBytes(payload.size());
    } else {
        // Smooth gradient plus noise: compressible like an image, yet every value matters.
        const size_t bytes = desc.bufferBytes();
        for (size_t i = 0; i < bytes; ++i) {
            const uint32_t noise = mix(seed * 7919 + static_cast<uint32_t>(i));
            view.data[i] = static_cast<uint8_t>((i + seed) / 3 + (noise & 0x0F));
        }
        if (bytes >= 4) {
            view.data[0] = 0xFF;  // extremes of the 16-bit range
            view.data[1] = 0xFF;
            view.data[2] = 0;
            view.data[3] = 0;
        }
    }
    frame.meta() = meta;
    return std::move(frame).publish();
}

::testing::AssertionResult sameFrame(const FrameRef& got, const ExpectedFrame& want) {
    if (!got)
        return ::testing::AssertionFailure() << "no frame";
    const FrameMetadata& a = got.meta();
    const FrameMetadata& b = want.meta;
    if (a.stream != b.stream || a.sequence != b.sequence ||
        a.device_stamp_ns != b.device_stamp_ns || a.host_stamp_ns != b.host_stamp_ns ||
        a.clock_domain != b.clock_domain || a.exposure_us != b.exposure_us ||
        a.status != b.status) {
        return ::testing::AssertionFailure()
               << "metadata differs: stream " << a.stream << "/" << b.stream << " seq "
               << a.sequence << "/" << b.sequence << " device " << a.device_stamp_ns << "/"
               << b.device_stamp_ns << " host " << a.host_stamp_ns << "/" << b.host_stamp_ns
               << " clock " << a.clock_domain << "/" << b.clock_domain << " exposure "
               << a.exposure_us << "/" << b.exposure_us;
    }
    if (!sameImage(got.image(), want.frame.image())) {
        return ::testing::AssertionFailure()
               << "payload differs (" << toString(got.image().desc.format) << " "
               << got.image().desc.width << "x" << got.image().desc.height << ", "
               << got.image().size_bytes << " vs " << want.frame.image().size_bytes << " bytes)";
    }
    return ::testing::AssertionSuccess();
}

void expectSameFrame(const FrameRef& got, const ExpectedFrame& want, const std::string& where) {
    EXPECT_TRUE(sameFrame(got, want)) << where;
}

void expectSameStreams(const std::vector<StreamInfo>& got, const std::vector<StreamInfo>& want) {
    ASSERT_EQ(got.size(), want.size());
    for (size_t i = 0; i < got.size(); ++i) {
        SCOPED_TRACE(want[i].name);
        EXPECT_EQ(got[i].name, want[i].name);
        EXPECT_EQ(got[i].device, want[i].device);
        EXPECT_EQ(got[i].kind, want[i].kind);
        EXPECT_EQ(got[i].format, want[i].format);
        EXPECT_EQ(got[i].nominal_fps, want[i].nominal_fps);
        EXPECT_EQ(got[i].clock_domain, want[i].clock_domain);
        EXPECT_EQ(got[i].tags, want[i].tags);
    }
}

std::vector<ExpectedFrame> writeRecording(const std::filesystem::path& path,
                                          const RecordingHeader& header, int frames_per_stream,
                                          std::vector<uint64_t>* offsets, uint64_t* header_bytes) {
    std::vector<ExpectedFrame> written;
    auto writer = createMkvWriter(path, header);
    EXPECT_TRUE(writer) << writer.status().toString();
    if (!writer)
        return written;
    if (header_bytes)
        *header_bytes = (*writer)->bytesWritten();
    const int64_t t0 = 1'700'000'000'123'456'789;  // odd nanoseconds on purpose
    for (int i = 0; i < frames_per_stream; ++i) {
        for (size_t s = 0; s < header.streams.size(); ++s) {
            FrameMetadata meta;
            meta.stream = static_cast<StreamId>(s);
            meta.sequence = 1000 + static_cast<uint64_t>(i) * 3 + s;
            const int64_t n = i;
            meta.host_stamp_ns = t0 + n * 33'333'333 + static_cast<int64_t>(s) * 1'000'001;
            meta.device_stamp_ns = -5'000'000'007 + n * 33'000'001 + static_cast<int64_t>(s);
            meta.clock_domain = header.streams[s].clock_domain;
            meta.exposure_us = (i + static_cast<int>(s)) % 4 == 0 ? -1 : 8000 + i;
            meta.status = static_cast<FrameStatus>((i + s) % 3);
            FrameRef frame = makeFrame(header.streams[s], meta, static_cast<uint32_t>(i * 37 + s));
            Status status = (*writer)->write(frame);
            EXPECT_TRUE(status) << status.toString();
            if (offsets)
                offsets->push_back((*writer)->bytesWritten());
            written.push_back({frame, meta});
        }
    }
    Status closed = (*writer)->close();
    EXPECT_TRUE(closed) << closed.toString();
    return written;
}

FrameRef copyFrame(const FrameRef& frame) {
    const ImageView view = frame.image();
    BufferPoolOptions options;
    options.desc = view.desc;
    options.buffer_bytes = std::max<size_t>({view.desc.bufferBytes(), view.size_bytes, 1});
    options.buffer_count = 1;
    auto pool = BufferPool::create(options);
    return copyIntoPool(*pool, view, frame.meta());
}

std::vector<FrameRef> readAll(RecordingReader& reader, Status* end) {
    std::vector<FrameRef> frames;
    while (true) {
        auto frame = reader.next();
        if (!frame) {
            if (end)
                *end = frame.status();
            return frames;
        }
        // A copy: the reader's own buffers go back at once, however many frames are kept.
        frames.push_back(copyFrame(*frame));
    }
}

}  // namespace mixray::test
