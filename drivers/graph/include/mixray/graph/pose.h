// Pose records: the binary payload of StreamKind::kPose streams, shared by the simulator's
// ground truth and the trackers (issue 4), so either one's poses replay through the other.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"

namespace mixray {

// How far a pose can be trusted.
enum class PoseStatus : uint8_t {
    kValid = 0,  // measured for this frame
    kStale = 1,  // carried over from an earlier frame (the tracker lost sight briefly)
    kLost = 2,   // no pose for this frame; the transform is meaningless
};

std::string_view toString(PoseStatus status);

// One pose: T_anchor_target for the frame it belongs to. The target is the camera whose
// frames the stream's tag `pose_of` names ("kinect/color"); the anchor is the frame the pose is
// expressed in: "world", or "marker:<id>" for a tracked marker (then marker_id is that id).
// Plain value.
struct PoseRecord {
    uint64_t frame_sequence = 0;        // FrameMetadata::sequence of the frame it belongs to
    int64_t frame_device_stamp_ns = 0;  // that frame's device stamp
    PoseStatus status = PoseStatus::kValid;
    int32_t marker_id = -1;        // -1 when the anchor is not a marker
    std::string anchor = "world";  // 1 to kPoseAnchorMaxChars printable ASCII characters
    Eigen::Vector3d translation = Eigen::Vector3d::Zero();         // metres
    Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // unit
    float error = -1;  // the estimator's residual (RMS reprojection, px); -1 unknown, 0 truth
    // Why the pose is stale or lost, in words a user can act on ("marker 23 not seen"): at most
    // kPoseReasonMaxBytes of printable UTF-8; empty for a valid pose (and in version-1 records,
    // which have no room for it).
    std::string reason;

    Eigen::Isometry3d transform() const;
    void setTransform(const Eigen::Isometry3d& T_anchor_target);
};

// Wire format (docs/recording-format.md, "Pose streams"): little-endian, ending with a CRC-32
// of the bytes before it. Version 2 (what the encoder writes) is 256 bytes and holds the
// reason; version 1 (128 bytes, no reason) is still read: recordings made before hold it.
inline constexpr size_t kPoseRecordBytes = 256;
inline constexpr uint16_t kPoseRecordVersion = 2;
inline constexpr size_t kPoseRecordV1Bytes = 128;
inline constexpr size_t kPoseAnchorMaxChars = 31;
inline constexpr size_t kPoseReasonMaxBytes = 127;

// kInvalidArgument for a record that cannot be encoded: anchor empty, too long or not
// printable ASCII, non-finite numbers, a rotation whose norm is not 1 within 1e-6, a status
// out of range, an error below -1, a reason that is too long or not printable UTF-8, or a
// reason on a valid pose.
Status validate(const PoseRecord& record);

// Encodes a valid record as version 2; kInvalidArgument as validate() says.
Result<std::array<uint8_t, kPoseRecordBytes>> encodePoseRecord(const PoseRecord& record);

// Decodes one record of version 2 (kPoseRecordBytes) or version 1 (kPoseRecordV1Bytes, reason
// empty). kCorruptData for a payload of another size, a wrong magic or CRC, a version that does
// not match the size, non-zero reserved bytes, or values validate() refuses.
Result<PoseRecord> decodePoseRecord(const uint8_t* data, size_t size);
inline Result<PoseRecord> decodePoseRecord(const ImageView& payload) {
    return decodePoseRecord(payload.data, payload.size_bytes);
}

// The StreamInfo of a pose stream whose poses belong to the frames of `pose_of`: kind kPose,
// binary records of kPoseRecordBytes, tags `pose_of`, `pose_record` ("mixray-pose-2") and,
// when `ground_truth`, `ground_truth` = "true".
StreamInfo makePoseStreamInfo(const std::string& name, const std::string& pose_of, double fps,
                              bool ground_truth);

}  // namespace mixray
