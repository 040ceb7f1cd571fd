// IMU records and levelling (mixray/graph/imu.h): round trips, damaged records refused, and
// roll/pitch recovered from gravity vectors of known camera orientations.
#include "mixray/graph/imu.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

namespace mixray {
namespace {

ImuSample fullSample() {
    ImuSample s;
    s.accel = Eigen::Vector3d(0.125, -9.80665, 1.0 / 3.0);
    s.gyro = Eigen::Vector3d(-0.5, 1e-7, 3.25);
    s.temperature_c = 31.5f;
    return s;
}

TEST(ImuRecord, RoundTripIsExact) {
    const ImuSample in = fullSample();
    auto bytes = encodeImuRecord(in);
    ASSERT_TRUE(bytes) << bytes.status().toString();
    auto out = decodeImuRecord(bytes->data(), bytes->size());
    ASSERT_TRUE(out) << out.status().toString();
    EXPECT_EQ(out->accel, in.accel);  // doubles stored bit for bit
    ASSERT_TRUE(out->gyro);
    EXPECT_EQ(*out->gyro, *in.gyro);
    ASSERT_TRUE(out->temperature_c);
    EXPECT_EQ(*out->temperature_c, 31.5f);
}

TEST(ImuRecord, AbsentGyroAndTemperatureStayAbsent) {
    ImuSample in;
    in.accel = Eigen::Vector3d(1, 2, 3);
    auto bytes = encodeImuRecord(in);
    ASSERT_TRUE(bytes);
    EXPECT_EQ((*bytes)[6], 0);  // flags
    auto out = decodeImuRecord(bytes->data(), bytes->size());
    ASSERT_TRUE(out) << out.status().toString();
    EXPECT_FALSE(out->gyro);
    EXPECT_FALSE(out->temperature_c);
    EXPECT_EQ(out->accel, in.accel);
}

TEST(ImuRecord, LayoutIsLittleEndianAtDocumentedOffsets) {
    ImuSample s;
    s.accel = Eigen::Vector3d(1.0, 0, -2.0);
    s.temperature_c = 1.0f;
    auto bytes = encodeImuRecord(s);
    ASSERT_TRUE(bytes);
    const auto& b = *bytes;
    EXPECT_EQ(b.size(), 64u);
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(b.data()), 4), "MXIM");
    EXPECT_EQ(b[4], 1);  // version
    EXPECT_EQ(b[5], 0);
    EXPECT_EQ(b[6], 0x02);  // temperature present, gyro absent
    // ax = 1.0 as an IEEE double at offset 8: 00 .. 00 f0 3f.
    EXPECT_EQ(b[8 + 6], 0xf0);
    EXPECT_EQ(b[8 + 7], 0x3f);
    // az = -2.0 at offset 24: 00 .. 00 00 c0.
    EXPECT_EQ(b[24 + 7], 0xc0);
    for (size_t i = 32; i < 56; ++i)
        EXPECT_EQ(b[i], 0) << "gyro byte " << i;
    // 1.0f at offset 56: 00 00 80 3f.
    EXPECT_EQ(b[56 + 2], 0x80);
    EXPECT_EQ(b[56 + 3], 0x3f);
}

TEST(ImuRecord, DamagedOrTruncatedRecordsAreRefused) {
    auto bytes = encodeImuRecord(fullSample());
    ASSERT_TRUE(bytes);
    for (size_t size : {size_t{0}, size_t{1}, size_t{63}}) {
        auto out = decodeImuRecord(bytes->data(), size);
        ASSERT_FALSE(out) << size;
        EXPECT_EQ(out.status().code(), ErrorCode::kCorruptData);
    }
    std::vector<uint8_t> longer(bytes->begin(), bytes->end());
    longer.push_back(0);
    EXPECT_FALSE(decodeImuRecord(longer.data(), longer.size()));
    EXPECT_FALSE(decodeImuRecord(nullptr, kImuRecordBytes));
    for (size_t i = 0; i < kImuRecordBytes; ++i) {
        auto damaged = *bytes;
        damaged[i] ^= 0x10;
        auto out = decodeImuRecord(damaged.data(), damaged.size());
        ASSERT_FALSE(out) << "byte " << i;
        EXPECT_EQ(out.status().code(), ErrorCode::kCorruptData);
    }
}

TEST(ImuRecord, InvalidSamplesAreNotEncoded) {
    ImuSample s;
    s.accel.x() = std::nan("");
    EXPECT_EQ(encodeImuRecord(s).status().code(), ErrorCode::kInvalidArgument);
    s = ImuSample{};
    s.gyro = Eigen::Vector3d(0, INFINITY, 0);
    EXPECT_EQ(encodeImuRecord(s).status().code(), ErrorCode::kInvalidArgument);
    s = ImuSample{};
    s.temperature_c = -300.0f;
    EXPECT_EQ(encodeImuRecord(s).status().code(), ErrorCode::kInvalidArgument);
}

TEST(ImuStreamInfo, DescribesTheRecords) {
    const StreamInfo info = makeImuStreamInfo("kinect_motor/gravity", 20, "libfreenect x, y, z");
    EXPECT_EQ(info.device, "kinect_motor");
    EXPECT_EQ(info.kind, StreamKind::kImu);
    EXPECT_EQ(info.format.format, PixelFormat::kBinary);
    EXPECT_EQ(info.format.width, 64);
    EXPECT_EQ(info.format.height, 1);
    EXPECT_EQ(info.nominal_fps, 20);
    EXPECT_EQ(info.tags.at("imu_record"), "mixray-imu-1");
    EXPECT_EQ(info.tags.at("imu_axes"), "libfreenect x, y, z");
}

TEST(Leveling, LevelCameraNeedsNoRotation) {
    auto level = levelFromGravity(Eigen::Vector3d(0, 9.81, 0));
    ASSERT_TRUE(level);
    EXPECT_NEAR(level->roll_rad, 0, 1e-15);
    EXPECT_NEAR(level->pitch_rad, 0, 1e-15);
    EXPECT_TRUE(level->level_from_camera.isApprox(Eigen::Quaterniond::Identity(), 1e-15));
}

TEST(Leveling, RecoversRollAndPitchOfKnownOrientations) {
    const double deg = std::numbers::pi / 180;
    for (double roll : {-60.0, -15.0, 0.0, 7.5, 45.0, 89.0}) {
        for (double pitch : {-80.0, -30.0, 0.0, 12.0, 60.0}) {
            const Eigen::Matrix3d level_from_camera =
                (Eigen::AngleAxisd(pitch * deg, Eigen::Vector3d::UnitX()) *
                 Eigen::AngleAxisd(roll * deg, Eigen::Vector3d::UnitZ()))
                    .matrix();
            // Gravity points down (+y) in the level frame; the camera sees it rotated back.
            const Eigen::Vector3d g = level_from_camera.transpose() * Eigen::Vector3d(0, 9.81, 0);
            auto level = levelFromGravity(g);
            ASSERT_TRUE(level);
            EXPECT_NEAR(level->roll_rad, roll * deg, 1e-12) << roll << " " << pitch;
            EXPECT_NEAR(level->pitch_rad, pitch * deg, 1e-12) << roll << " " << pitch;
            const Eigen::Vector3d down = level->level_from_camera * g;
            EXPECT_NEAR(down.x(), 0, 1e-12);
            EXPECT_NEAR(down.y(), 9.81, 1e-12);
            EXPECT_NEAR(down.z(), 0, 1e-12);
        }
    }
}

TEST(Leveling, SignsFollowTheCameraAxes) {
    // Looking down at the floor: gravity has a forward (+z) part, so pitch is negative.
    auto down = levelFromGravity(Eigen::Vector3d(0, 1, 1));
    ASSERT_TRUE(down);
    EXPECT_NEAR(down->pitch_rad, -std::numbers::pi / 4, 1e-12);
    // Gravity leaning to the image's right (+x): positive roll.
    auto right = levelFromGravity(Eigen::Vector3d(1, 1, 0));
    ASSERT_TRUE(right);
    EXPECT_NEAR(right->roll_rad, std::numbers::pi / 4, 1e-12);
}

TEST(Leveling, DegenerateGravityIsAnError) {
    EXPECT_EQ(levelFromGravity(Eigen::Vector3d::Zero()).status().code(),
              ErrorCode::kInvalidArgument);
    EXPECT_FALSE(levelFromGravity(Eigen::Vector3d(0, NAN, 1)));
}

}  // namespace
}  // namespace mixray
