// Pose records: encoding, decoding and validation of the kPose stream payload.
#include "mixray/graph/pose.h"

#include <cmath>
#include <cstring>

#include "mixray/graph/record_codec.h"

namespace mixray {
namespace {

// "MXPO" read as a little-endian u32: a record that starts elsewhere is caught at once.
constexpr uint32_t kMagic = 0x4f50584d;

using record::getF32;
using record::getF64;
using record::getLe;
using record::putF32;
using record::putF64;
using record::putLe;

// Offsets in the record; versions 1 and 2 agree up to the anchor. Version 1 ends with a
// reserved u32 at 120, version 2 with the reason at 120 and a reserved u32 at 248.
constexpr size_t kOffStatus = 6, kOffReserved0 = 7, kOffSequence = 8, kOffStamp = 16,
                 kOffMarker = 24, kOffError = 28, kOffTranslation = 32, kOffRotation = 56,
                 kOffAnchor = 88, kOffReason = 120, kOffV1Reserved = 120, kOffV2Reserved = 248;
constexpr size_t kAnchorField = kOffReason - kOffAnchor;      // 32 bytes, NUL-padded
constexpr size_t kReasonField = kOffV2Reserved - kOffReason;  // 128 bytes, NUL-padded
static_assert(kReasonField == kPoseReasonMaxBytes + 1);
static_assert(kOffV2Reserved + 8 == kPoseRecordBytes);

}  // namespace

std::string_view toString(PoseStatus status) {
    switch (status) {
        case PoseStatus::kValid:
            return "valid";
        case PoseStatus::kStale:
            return "stale";
        case PoseStatus::kLost:
            return "lost";
    }
    return "unknown";
}

Eigen::Isometry3d PoseRecord::transform() const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = rotation.normalized().toRotationMatrix();
    T.translation() = translation;
    return T;
}

void PoseRecord::setTransform(const Eigen::Isometry3d& T_anchor_target) {
    translation = T_anchor_target.translation();
    rotation = Eigen::Quaterniond(T_anchor_target.linear()).normalized();
    // One hemisphere for q and -q, so equal poses encode to equal bytes.
    if (rotation.w() < 0)
        rotation.coeffs() = -rotation.coeffs();
}

Status validate(const PoseRecord& r) {
    const auto bad = [](const std::string& what) {
        return Status(ErrorCode::kInvalidArgument, "pose record: " + what);
    };
    if (r.anchor.empty() || r.anchor.size() > kPoseAnchorMaxChars)
        return bad("anchor must have 1 to " + std::to_string(kPoseAnchorMaxChars) +
                   " characters, got " + std::to_string(r.anchor.size()));
    for (char c : r.anchor)
        if (c < 0x21 || c > 0x7e)
            return bad("anchor '" + r.anchor + "' holds a character that is not printable ASCII");
    if (static_cast<uint8_t>(r.status) > static_cast<uint8_t>(PoseStatus::kLost))
        return bad("status " + std::to_string(static_cast<int>(r.status)) + " is out of range");
    if (!r.translation.allFinite() || !r.rotation.coeffs().allFinite())
        return bad("the transform is not finite");
    if (std::abs(r.rotation.norm() - 1.0) > 1e-6)
        return bad("the rotation quaternion is not unit (norm " +
                   std::to_string(r.rotation.norm()) + ")");
    if (!std::isfinite(r.error) || r.error < -1)
        return bad("error must be finite and >= -1");
    if (r.reason.size() > kPoseReasonMaxBytes)
        return bad("reason must have at most " + std::to_string(kPoseReasonMaxBytes) +
                   " bytes, got " + std::to_string(r.reason.size()));
    if (!record::isPrintableUtf8(r.reason))
        return bad("reason holds bytes that are not printable UTF-8");
    if (r.status == PoseStatus::kValid && !r.reason.empty())
        return bad("a valid pose has no reason, got '" + r.reason + "'");
    return Status::ok();
}

Result<std::array<uint8_t, kPoseRecordBytes>> encodePoseRecord(const PoseRecord& r) {
    MIXRAY_RETURN_IF_ERROR(validate(r));
    std::array<uint8_t, kPoseRecordBytes> out{};
    record::putHeader(out.data(), kMagic, kPoseRecordVersion);
    out[kOffStatus] = static_cast<uint8_t>(r.status);
    out[kOffReserved0] = 0;
    putLe(out.data() + kOffSequence, r.frame_sequence, 8);
    putLe(out.data() + kOffStamp, static_cast<uint64_t>(r.frame_device_stamp_ns), 8);
    putLe(out.data() + kOffMarker, static_cast<uint32_t>(r.marker_id), 4);
    putF32(out.data() + kOffError, r.error);
    for (int i = 0; i < 3; ++i)
        putF64(out.data() + kOffTranslation + 8 * i, r.translation[i]);
    const double q[4] = {r.rotation.x(), r.rotation.y(), r.rotation.z(), r.rotation.w()};
    for (int i = 0; i < 4; ++i)
        putF64(out.data() + kOffRotation + 8 * i, q[i]);
    std::memcpy(out.data() + kOffAnchor, r.anchor.data(), r.anchor.size());
    std::memcpy(out.data() + kOffReason, r.reason.data(), r.reason.size());
    record::putCrc(out.data(), out.size());
    return out;
}

Result<PoseRecord> decodePoseRecord(const uint8_t* data, size_t size) {
    const auto corrupt = [](const std::string& what) { return record::corrupt("pose", what); };
    // The size says the version; the version field must then agree (checkFrame).
    const bool v1 = size == kPoseRecordV1Bytes;
    if (data == nullptr || (!v1 && size != kPoseRecordBytes))
        return corrupt("expected " + std::to_string(kPoseRecordBytes) + " bytes (version 2) or " +
                       std::to_string(kPoseRecordV1Bytes) + " (version 1), got " +
                       std::to_string(data == nullptr ? 0 : size));
    MIXRAY_RETURN_IF_ERROR(
        record::checkFrame(data, size, size, kMagic, v1 ? 1 : kPoseRecordVersion, "pose"));
    if (data[kOffReserved0] != 0 || getLe(data + (v1 ? kOffV1Reserved : kOffV2Reserved), 4) != 0)
        return corrupt("reserved bytes are not zero");
    PoseRecord r;
    if (data[kOffStatus] > static_cast<uint8_t>(PoseStatus::kLost))
        return corrupt("status " + std::to_string(data[kOffStatus]) + " is out of range");
    r.status = static_cast<PoseStatus>(data[kOffStatus]);
    r.frame_sequence = getLe(data + kOffSequence, 8);
    r.frame_device_stamp_ns = static_cast<int64_t>(getLe(data + kOffStamp, 8));
    r.marker_id = static_cast<int32_t>(static_cast<uint32_t>(getLe(data + kOffMarker, 4)));
    r.error = getF32(data + kOffError);
    for (int i = 0; i < 3; ++i)
        r.translation[i] = getF64(data + kOffTranslation + 8 * i);
    r.rotation =
        Eigen::Quaterniond(getF64(data + kOffRotation + 24), getF64(data + kOffRotation),
                           getF64(data + kOffRotation + 8), getF64(data + kOffRotation + 16));
    MIXRAY_RETURN_IF_ERROR(
        record::getPaddedText(data + kOffAnchor, kAnchorField, "pose", "anchor", &r.anchor));
    if (!v1) {
        MIXRAY_RETURN_IF_ERROR(
            record::getPaddedText(data + kOffReason, kReasonField, "pose", "reason", &r.reason));
    }
    if (Status s = validate(r); !s)
        return Status(ErrorCode::kCorruptData, s.message());
    return r;
}

StreamInfo makePoseStreamInfo(const std::string& name, const std::string& pose_of, double fps,
                              bool ground_truth) {
    StreamInfo info;
    info.name = name;
    info.device = name.substr(0, name.find('/'));
    info.kind = StreamKind::kPose;
    info.format = ImageDesc::packed(PixelFormat::kBinary, static_cast<int>(kPoseRecordBytes), 1);
    info.nominal_fps = fps;
    info.tags["pose_of"] = pose_of;
    info.tags["pose_record"] = "mixray-pose-2";
    if (ground_truth)
        info.tags["ground_truth"] = "true";
    return info;
}

}  // namespace mixray
