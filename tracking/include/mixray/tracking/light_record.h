// Light records and environment-map records: the binary payloads of the streams light
// estimation publishes, so estimates are recorded, replayed and inspected like poses, each with
// its Estimate<T> stale flag and reason.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"
#include "mixray/tracking/estimate.h"
#include "mixray/tracking/lights.h"

namespace mixray::tracking {

inline constexpr size_t kLightGroupNameMaxChars = 31;
inline constexpr size_t kLightReasonMaxBytes = 127;
inline constexpr size_t kLightGroupMaxLights = 32;
inline constexpr size_t kLightRecordMaxGroups = 16;

// One estimator's answer for one frame: the Estimate<T> header and its lights. Plain value.
struct LightGroup {
    // "render" (what the compositor renders with), "probe:<name>", "environment", "sun",
    // "intensity_fit": 1 to kLightGroupNameMaxChars printable ASCII characters, no space.
    std::string name;
    bool stale = true;
    std::string reason;         // empty when fresh; at most kLightReasonMaxBytes of printable UTF-8
    int64_t stamp_ns = 0;       // of the input this estimate answers
    int64_t good_stamp_ns = 0;  // of the input the lights came from
    std::vector<EstimatedLight> lights;  // at most kLightGroupMaxLights
};

// The lights known for one frame (the colour frame they were estimated for). Plain value.
struct LightRecord {
    uint64_t frame_sequence = 0;        // FrameMetadata::sequence of that frame
    int64_t frame_device_stamp_ns = 0;  // its device stamp
    std::vector<LightGroup> groups;     // at most kLightRecordMaxGroups, names unique
};

// Wire format (docs/recording-format.md, "Light streams"): little-endian, version 1, variable
// length, ending with a CRC-32 of the bytes before it.
inline constexpr uint16_t kLightRecordVersion = 1;
inline constexpr size_t kLightRecordHeaderBytes = 32;
inline constexpr size_t kLightGroupHeaderBytes = 24;
inline constexpr size_t kLightBytes = 96;
// A group's name and reason, NUL-free, padded with zeros to a multiple of 8 bytes.
inline constexpr size_t kLightGroupMaxTextBytes =
    (kLightGroupNameMaxChars + kLightReasonMaxBytes + 7) / 8 * 8;
// The largest record: the buffer size of a light stream.
inline constexpr size_t kLightRecordMaxBytes =
    kLightRecordHeaderBytes +
    kLightRecordMaxGroups *
        (kLightGroupHeaderBytes + kLightGroupMaxTextBytes + kLightGroupMaxLights * kLightBytes) +
    4;

// kInvalidArgument naming the group and field for a record that cannot be encoded: too many
// groups or lights, a name empty, too long, not printable ASCII or repeated, a reason too long,
// not printable UTF-8 or given on a fresh group, a source out of range, non-finite numbers, a
// direction whose norm is not 1 within 1e-6, a negative intensity, radius or weight.
Status validate(const LightRecord& record);

// Encodes a valid record (at most kLightRecordMaxBytes); kInvalidArgument as validate() says.
Result<std::vector<uint8_t>> encodeLightRecord(const LightRecord& record);

// Decodes one record. kCorruptData naming the field for a payload shorter than its header, a
// wrong magic, size field or CRC, an unknown version, counts or lengths past the payload or
// over the bounds, non-zero reserved or padding bytes, or values validate() refuses.
Result<LightRecord> decodeLightRecord(const uint8_t* data, size_t size);
inline Result<LightRecord> decodeLightRecord(const ImageView& payload) {
    return decodeLightRecord(payload.data, payload.size_bytes);
}

// The StreamInfo of a light stream whose records belong to the frames of `light_of` (a colour
// stream): kind kData, kBinary of width kLightRecordMaxBytes (each frame's payload is one record,
// its size varying), tags `light_of` and `light_record` ("mixray-lights-1").
StreamInfo makeLightStreamInfo(const std::string& name, const std::string& light_of, double fps);

// A group from an estimate: its stale flag, reason and stamps, and its lights (none before a
// first good value). Lights past kLightGroupMaxLights are left out (estimators order them most
// representative first); a reason longer than kLightReasonMaxBytes is cut at a character
// boundary and its control characters become spaces, so every estimate gives a valid group.
LightGroup toLightGroup(std::string name, const Estimate<std::vector<EstimatedLight>>& estimate);
LightGroup toLightGroup(std::string name, const Estimate<ProbeResult>& estimate);
LightGroup toLightGroup(std::string name, const Estimate<EnvironmentEstimate>& estimate);
LightGroup toLightGroup(std::string name, const Estimate<EstimatedLight>& estimate);

// Environment maps: linear RGB float, equirectangular (lights.h), one per record.
inline constexpr uint16_t kEnvironmentMapRecordVersion = 1;
inline constexpr size_t kEnvironmentMapHeaderBytes = 176;
inline constexpr int kEnvironmentMapMaxSide = 8192;
inline constexpr size_t kEnvironmentMapMaxPixels = size_t{2048} * 1024;

// What an environment-map record says besides its pixels. Plain value.
struct EnvironmentMapHeader {
    uint64_t frame_sequence = 0;        // the frame the map answers (the fish-eye image)
    int64_t frame_device_stamp_ns = 0;  // its device stamp
    bool stale = true;                  // the map is the last good one, not from this frame
    std::string reason;                 // empty when fresh; as LightGroup::reason
    int64_t stamp_ns = 0;               // of the input this estimate answers
    int64_t good_stamp_ns = 0;          // of the input the map came from
};

struct EnvironmentMapRecord {
    EnvironmentMapHeader header;
    FloatImage map;  // 3 channels
};

// The header for an estimate (stale flag, reason as toLightGroup() makes it, stamps).
EnvironmentMapHeader toEnvironmentMapHeader(uint64_t frame_sequence, int64_t frame_device_stamp_ns,
                                            const Estimate<EnvironmentEstimate>& estimate);

// Bytes of the record of a width x height map (0 when the size is out of bounds).
size_t environmentMapRecordBytes(int width, int height);

// Encodes `map` (3 channels, 1 to kEnvironmentMapMaxSide per side, at most
// kEnvironmentMapMaxPixels, finite values) into `out`, which holds `capacity` bytes; returns the
// bytes written. Allocates nothing (a node writes into a pooled frame). kInvalidArgument for a
// bad map or header, or when `capacity` is too small.
Result<size_t> encodeEnvironmentMapRecord(const FloatImage& map, const EnvironmentMapHeader& header,
                                          uint8_t* out, size_t capacity);

// Decodes one record, the map bit for bit. kCorruptData naming the field for a payload whose
// size does not match its width and height, a wrong magic or CRC, an unknown version, a size
// out of bounds, non-zero reserved bytes, non-finite values or a bad header.
Result<EnvironmentMapRecord> decodeEnvironmentMapRecord(const uint8_t* data, size_t size);
inline Result<EnvironmentMapRecord> decodeEnvironmentMapRecord(const ImageView& payload) {
    return decodeEnvironmentMapRecord(payload.data, payload.size_bytes);
}

// The StreamInfo of an environment-map stream of width x height maps from the frames of
// `map_of`: kind kData, kBinary of width environmentMapRecordBytes(width, height), nominal fps 0
// (maps come when the estimator has one), tags `map_of`, `environment_map_record`
// ("mixray-envmap-1"), `map_width`, `map_height`.
StreamInfo makeEnvironmentMapStreamInfo(const std::string& name, const std::string& map_of,
                                        int width, int height);

// The record streams a recording may hold, told apart by their tags (`pose_record`,
// `light_record`, `environment_map_record`; a kPose stream is a pose stream), for tools that
// inspect recordings.
enum class RecordStreamKind : uint8_t { kNone, kPose, kLight, kEnvironmentMap };
RecordStreamKind recordStreamKind(const StreamInfo& info);

// One record as an inspector sees it: whether it (or one of its light groups) is stale or lost,
// and the first reason it gives ("probe:mirror: marker 23 not seen" for a light group).
struct RecordDigest {
    bool stale = false;
    bool lost = false;  // poses only
    std::string reason;
};

// Decodes one record of a `kind` stream; the decoder's kCorruptData when it is damaged,
// kInvalidArgument for kNone. Reentrant.
Result<RecordDigest> digestRecord(RecordStreamKind kind, const ImageView& payload);

}  // namespace mixray::tracking
