// Matroska recordings through FFmpeg's libavformat: mixray's own lossless session files, and
// other tools' Matroska recordings (Azure Kinect) read through the same interface.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "mixray/graph/recording.h"

namespace mixray {

// How createMkvWriter stores uncompressed images (every pixel format except MJPEG and binary,
// which are always stored as delivered). Both are lossless; the reader tells them apart by the
// track's codec, so one reader reads both.
enum class MkvCompression : uint8_t {
    // FFV1 (lossless): smaller files, but encoding is CPU-bound, so fast streams on a fast
    // disk may outrun it.
    kFfv1,
    // No compression: each frame's packed rows as Matroska uncompressed video (V_UNCOMPRESSED,
    // FFmpeg rawvideo), so recording is bound by the disk rather than the CPU. Frames with
    // packed rows are handed to libavformat without a copy; padded rows are packed first.
    kNone,
    // Huffyuv, FFmpeg's lossless ffvhuff: every frame coded with its own Huffman tables, about a
    // tenth of FFV1's CPU (2 ms against 10-15 ms for a VGA colour or depth frame here) for files
    // about 4x smaller than raw where FFV1 makes them 8-40x smaller. For live recording on a
    // machine whose CPU goes to capture first.
    kHuffyuv,
};

// The name the command line and summaries use: "ffv1", "none", "ffvhuff".
const char* toString(MkvCompression compression);

struct MkvWriterOptions {
    // Storage of uncompressed images.
    MkvCompression compression = MkvCompression::kFfv1;
    // FFV1 slices per frame (more slices: more threads can encode/decode one frame).
    int ffv1_slices = 4;
    // Encoder threads per stream; 0 lets FFmpeg choose.
    int threads = 0;
    // Flush the file to the OS after every frame, so a crash loses at most the frame being
    // written. Costs a little throughput (one Matroska cluster per frame). When false, clusters
    // close at least every second, which bounds what a crash loses.
    bool flush_every_frame = true;

    bool validate(std::string* why) const;
};

// Creates `path` (overwriting it) and writes the header: streams, attachments, tags.
// Depth, IR, mono, Bayer and raw colour are stored losslessly, with FFV1 (16 bits kept
// exactly) or uncompressed as options.compression says; MJPEG is stored as delivered; binary
// streams as opaque blocks. Every frame's metadata (sequence, device and host stamps in ns,
// clock domain, exposure, status) is stored with it exactly, as Matroska BlockAdditional data
// with CRCs of the record and the payload.
// Block timestamps are host time in ms since the first frame, so players pace correctly.
// Attachments must be non-empty (Matroska drops empty ones). The writer's write() and
// writeAs() accept frames of the header's streams; see RecordingWriter for thread-safety.
Result<std::unique_ptr<RecordingWriter>> createMkvWriter(const std::filesystem::path& path,
                                                         const RecordingHeader& header,
                                                         const MkvWriterOptions& options = {});

struct MkvReaderOptions {
    size_t buffers_per_stream = 8;  // frames of one stream a consumer may hold at once
    // FFV1 decoder threads per stream; 0 lets FFmpeg choose, 1 decodes on the caller's thread.
    int decoder_threads = 0;

    bool validate(std::string* why) const;
};

// Opens a Matroska file written by mixray or by the Azure Kinect recorder (its COLOR, DEPTH,
// IR and IMU tracks, timestamps and calibration.json attachment). Errors name the file and
// what is wrong with it (missing, empty, not Matroska, no usable track).
//
// mixray files (format() "mixray-mkv") give back exactly what was written, whichever
// MkvCompression wrote them (the track's codec says which). A file cut off by a crash or a
// full disk gives every complete frame, then kCorruptData (or kEndOfStream when the cut cannot
// be told from the end); a frame whose bytes or record fail their CRC ends the reading with
// kCorruptData. Frames come in host-stamp order, merged across streams over a window of 4
// frames per stream (at least 8): files written by the Recorder or in stamp order come back
// ordered; where a file is interleaved worse, the reader keeps its order there.
// Format details: docs/recording-format.md.
//
// Azure Kinect files (format() "azure-kinect-mkv") give streams "azure_kinect/color" (mjpeg,
// nv12 or yuyv), "azure_kinect/depth" (depth16, mm), "azure_kinect/ir" (ir16) and
// "azure_kinect/imu" (binary AzureKinectImuSample records, one per frame). Device and host
// stamps are both the recording's device timestamps: block time + K4A_START_OFFSET_NS, and for
// IMU frames the accelerometer stamp, so they match the Azure Kinect SDK's playback. All
// streams share clock domain kAzureKinectClockDomain. These files carry no frame numbers:
// sequence counts a track's frames from where reading started (open or the last seek()).
// The recording's K4A_* tags are tags(), each track's K4A_* tags its StreamInfo tags; the
// factory calibration is the attachment "calibration.json".
Result<std::unique_ptr<RecordingReader>> openMkv(const std::filesystem::path& path,
                                                 const MkvReaderOptions& options = {});

// Clock domain of streams read from an Azure Kinect recording.
inline constexpr ClockDomainId kAzureKinectClockDomain = 1;

// One IMU sample as the Azure Kinect recorder stores it (the payload of "azure_kinect/imu"
// frames: 40 bytes, little-endian: u64 acc stamp ns, 3 x f32 acc m/s^2, u64 gyro stamp ns,
// 3 x f32 gyro rad/s). Stamps are in the device clock.
struct AzureKinectImuSample {
    int64_t acc_stamp_ns = 0;
    float acc_m_s2[3] = {0, 0, 0};
    int64_t gyro_stamp_ns = 0;
    float gyro_rad_s[3] = {0, 0, 0};
};
inline constexpr size_t kAzureKinectImuSampleBytes = 40;
// Parses one record; nullopt unless the view holds exactly kAzureKinectImuSampleBytes.
std::optional<AzureKinectImuSample> parseAzureKinectImuSample(const ImageView& payload);

// FFmpeg prints its own warnings to stderr (a damaged file can produce many). mixray reports
// errors through Status, so tools and tests may silence FFmpeg; this sets FFmpeg's
// process-wide log level (quiet, or warnings and errors).
void setFfmpegLogging(bool enabled);

}  // namespace mixray
