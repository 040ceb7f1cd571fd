// Streams: what a device publishes (name, kind, layout, rate, clock), independent of any backend.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "mixray/graph/image.h"

namespace mixray {

// Index of a stream within one Graph (or one recording); dense, starting at 0.
using StreamId = uint32_t;
inline constexpr StreamId kInvalidStream = UINT32_MAX;

// Identifies one device clock. Frames with the same domain have comparable device_stamp_ns;
// kHostClockDomain means device stamps already are host monotonic time.
using ClockDomainId = uint32_t;
inline constexpr ClockDomainId kHostClockDomain = 0;

// What a stream's samples mean (the format says how they are laid out).
enum class StreamKind : uint8_t {
    kColor,     // visible-light colour image
    kDepth,     // depth map, PixelFormat::kDepth16 in millimetres
    kInfrared,  // infrared intensity image
    kMono,      // monochrome visible-light image (machine-vision cameras)
    kImu,       // accelerometer/gyroscope samples, kBinary: imu.h records or Azure Kinect samples
    kPose,      // camera or marker poses, kBinary records
    kData,      // anything else, kBinary
};

std::string_view toString(StreamKind kind);
std::optional<StreamKind> streamKindFromString(std::string_view name);

// Description of one stream. Plain value, copied freely.
struct StreamInfo {
    std::string name;    // unique in a graph, "device/stream": "kinect/depth"
    std::string device;  // the device that publishes it: "kinect"
    StreamKind kind = StreamKind::kData;
    ImageDesc format;        // layout of every frame; width/height fixed for the stream
    double nominal_fps = 0;  // 0 when unknown or irregular
    ClockDomainId clock_domain = kHostClockDomain;
    std::map<std::string, std::string> tags;  // free-form metadata, recorded as Matroska tags
};

// The least time between two frames of `stream` that a consumer may count on when it decides
// that no frame older than some stamp can still come: 80 % of the nominal period, so that
// jitter never makes that look certain too early; 0 (nothing can be ruled out) when the rate is
// unknown. The synchronizer's and the recorder's rule for a stream with nothing queued.
int64_t minFramePeriodNs(const StreamInfo& stream);

}  // namespace mixray
