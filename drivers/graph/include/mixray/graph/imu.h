// IMU records: the binary payload of StreamKind::kImu streams (accelerometer, optional gyroscope
// and temperature), and the floor-levelling rotation a gravity vector gives.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"

namespace mixray {

// One IMU sample, in the sensor's own axes (the stream's tag `imu_axes` names them). Its time is
// the frame's: FrameMetadata stamps and sequence. Plain value.
struct ImuSample {
    Eigen::Vector3d accel = Eigen::Vector3d::Zero();  // specific force as reported, m/s^2
    std::optional<Eigen::Vector3d> gyro;              // rad/s; absent on accelerometer-only IMUs
    std::optional<float> temperature_c;               // sensor temperature, when it reports one
};

// Wire format (docs/recording-format.md, "IMU streams"): 64 bytes, little-endian, version 1,
// ending with a CRC-32 of the first 60. One record per frame.
inline constexpr size_t kImuRecordBytes = 64;
inline constexpr uint16_t kImuRecordVersion = 1;

// kInvalidArgument for a sample that cannot be encoded: a non-finite accelerometer or gyroscope
// value, or a temperature that is not finite or below absolute zero.
Status validate(const ImuSample& sample);

// Encodes a valid sample; kInvalidArgument as validate() says.
Result<std::array<uint8_t, kImuRecordBytes>> encodeImuRecord(const ImuSample& sample);

// Decodes one record. kCorruptData for a payload that is not exactly one record, a wrong magic
// or CRC, an unknown version, unknown flag bits, non-zero reserved bytes or absent fields, or
// values validate() refuses.
Result<ImuSample> decodeImuRecord(const uint8_t* data, size_t size);
inline Result<ImuSample> decodeImuRecord(const ImageView& payload) {
    return decodeImuRecord(payload.data, payload.size_bytes);
}

// The StreamInfo of an IMU stream: kind kImu, binary records of kImuRecordBytes, device the
// part of `name` before '/', tags `imu_record` ("mixray-imu-1") and `imu_axes` (what the
// sensor's x, y and z are, free text).
StreamInfo makeImuStreamInfo(const std::string& name, double rate_hz, const std::string& axes);

// The camera's roll and pitch against gravity, and the rotation that levels it. Camera axes
// as everywhere in mixray: x right, y down, z forward.
struct Leveling {
    double roll_rad = 0;   // about the camera's z: positive when the down direction leans to +x
    double pitch_rad = 0;  // about x: positive when the camera looks up (gravity towards -z)
    // R_level_camera = Rx(pitch) * Rz(roll): takes camera-frame vectors to a frame with the same
    // heading whose y axis points straight down, so that the floor plane is y = const there.
    Eigen::Quaterniond level_from_camera = Eigen::Quaterniond::Identity();
};

// From the direction of gravity (pointing down) in the camera frame; its length is ignored.
// kInvalidArgument for a vector that is not finite or shorter than 1e-9.
Result<Leveling> levelFromGravity(const Eigen::Vector3d& gravity_in_camera);

}  // namespace mixray
