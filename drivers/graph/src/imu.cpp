// IMU records: encoding, decoding and validation of the kImu stream payload; levelling.
#include "mixray/graph/imu.h"

#include <cmath>

#include "mixray/graph/record_codec.h"

namespace mixray {
namespace {

// "MXIM" read as a little-endian u32.
constexpr uint32_t kMagic = 0x4d49584d;

using record::allZero;
using record::getF32;
using record::getF64;
using record::putF32;
using record::putF64;

constexpr uint8_t kHasGyro = 0x01;
constexpr uint8_t kHasTemperature = 0x02;

constexpr size_t kOffFlags = 6, kOffReserved0 = 7, kOffAccel = 8, kOffGyro = 32,
                 kOffTemperature = 56, kOffCrc = 60;

}  // namespace

Status validate(const ImuSample& s) {
    const auto bad = [](const std::string& what) {
        return Status(ErrorCode::kInvalidArgument, "IMU record: " + what);
    };
    if (!s.accel.allFinite())
        return bad("the accelerometer vector is not finite");
    if (s.gyro && !s.gyro->allFinite())
        return bad("the gyroscope vector is not finite");
    if (s.temperature_c && (!std::isfinite(*s.temperature_c) || *s.temperature_c < -273.15f))
        return bad("the temperature must be finite and at least -273.15 °C");
    return Status::ok();
}

Result<std::array<uint8_t, kImuRecordBytes>> encodeImuRecord(const ImuSample& s) {
    MIXRAY_RETURN_IF_ERROR(validate(s));
    std::array<uint8_t, kImuRecordBytes> out{};
    record::putHeader(out.data(), kMagic, kImuRecordVersion);
    out[kOffFlags] =
        static_cast<uint8_t>((s.gyro ? kHasGyro : 0) | (s.temperature_c ? kHasTemperature : 0));
    for (int i = 0; i < 3; ++i)
        putF64(out.data() + kOffAccel + 8 * i, s.accel[i]);
    if (s.gyro) {
        for (int i = 0; i < 3; ++i)
            putF64(out.data() + kOffGyro + 8 * i, (*s.gyro)[i]);
    }
    if (s.temperature_c)
        putF32(out.data() + kOffTemperature, *s.temperature_c);
    record::putCrc(out.data(), out.size());
    return out;
}

Result<ImuSample> decodeImuRecord(const uint8_t* data, size_t size) {
    const auto corrupt = [](const std::string& what) { return record::corrupt("IMU", what); };
    MIXRAY_RETURN_IF_ERROR(
        record::checkFrame(data, size, kImuRecordBytes, kMagic, kImuRecordVersion, "IMU"));
    const uint8_t flags = data[kOffFlags];
    if ((flags & ~(kHasGyro | kHasTemperature)) != 0)
        return corrupt("unknown flags " + std::to_string(flags));
    if (data[kOffReserved0] != 0)
        return corrupt("reserved bytes are not zero");
    ImuSample s;
    for (int i = 0; i < 3; ++i)
        s.accel[i] = getF64(data + kOffAccel + 8 * i);
    if (flags & kHasGyro) {
        Eigen::Vector3d gyro;
        for (int i = 0; i < 3; ++i)
            gyro[i] = getF64(data + kOffGyro + 8 * i);
        s.gyro = gyro;
    } else if (!allZero(data + kOffGyro, kOffTemperature - kOffGyro)) {
        return corrupt("gyroscope bytes are set but flagged absent");
    }
    if (flags & kHasTemperature)
        s.temperature_c = getF32(data + kOffTemperature);
    else if (!allZero(data + kOffTemperature, kOffCrc - kOffTemperature))
        return corrupt("temperature bytes are set but flagged absent");
    if (Status st = validate(s); !st)
        return Status(ErrorCode::kCorruptData, st.message());
    return s;
}

StreamInfo makeImuStreamInfo(const std::string& name, double rate_hz, const std::string& axes) {
    StreamInfo info;
    info.name = name;
    info.device = name.substr(0, name.find('/'));
    info.kind = StreamKind::kImu;
    info.format = ImageDesc::packed(PixelFormat::kBinary, static_cast<int>(kImuRecordBytes), 1);
    info.nominal_fps = rate_hz;
    info.tags["imu_record"] = "mixray-imu-1";
    info.tags["imu_axes"] = axes;
    return info;
}

Result<Leveling> levelFromGravity(const Eigen::Vector3d& gravity_in_camera) {
    if (!gravity_in_camera.allFinite() || gravity_in_camera.norm() < 1e-9)
        return Status(ErrorCode::kInvalidArgument,
                      "levelling: the gravity vector must be finite and non-zero");
    const Eigen::Vector3d u = gravity_in_camera.normalized();
    Leveling out;
    // Rz(roll) swings gravity into the y-z plane, then Rx(pitch) onto +y.
    out.roll_rad = std::atan2(u.x(), u.y());
    out.pitch_rad = std::atan2(-u.z(), std::hypot(u.x(), u.y()));
    out.level_from_camera = Eigen::AngleAxisd(out.pitch_rad, Eigen::Vector3d::UnitX()) *
                            Eigen::AngleAxisd(out.roll_rad, Eigen::Vector3d::UnitZ());
    return out;
}

}  // namespace mixray
