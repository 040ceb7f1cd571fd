// .cameramodel files through mrcal's reader and writer: mrcal's own test models, round trips and
// the errors.
#include "mrcal_format.h"

#include <gtest/gtest.h>

#include <fstream>

#include "test_data.h"

namespace mixray::calibration {
namespace {

std::filesystem::path mrcalData(const char* name) {
    return test::sharedDataDir() / "04_mrcal" / name;
}

TEST(MrcalFormatTest, ReadsMrcalsTestModels) {
    MIXRAY_REQUIRE_SHARED_DATA(mrcalData("cam0.splined.cameramodel"));
    auto splined = detail::readMrcalCameramodel(mrcalData("cam0.splined.cameramodel"));
    ASSERT_TRUE(splined.isOk()) << splined.status().toString();
    EXPECT_EQ(splined->name, "cam0.splined");
    EXPECT_EQ(splined->model.lens, LensModel::kSplinedStereographic);
    EXPECT_EQ(splined->model.spline, (SplineConfig{3, 16, 11, 120}));
    EXPECT_EQ(splined->model.distortion.size(), 2u * 16u * 11u);
    EXPECT_EQ(splined->model.width, 4000);
    EXPECT_EQ(splined->model.height, 2200);
    EXPECT_DOUBLE_EQ(splined->model.fx, 1761.181055);
    const auto q = splined->model.project({0.1, 0.2, 1.0});
    ASSERT_TRUE(q.has_value());
    EXPECT_NEAR(q->x(), 2148.73465, 6e-6);  // MANIFEST.md, mrcal 2.2
    EXPECT_NEAR(q->y(), 1413.23704, 6e-6);

    auto opencv8 = detail::readMrcalCameramodel(mrcalData("cam0.opencv8.cameramodel"));
    ASSERT_TRUE(opencv8.isOk()) << opencv8.status().toString();
    EXPECT_EQ(opencv8->model.lens, LensModel::kPinhole);
    ASSERT_EQ(opencv8->model.distortion.size(), 8u);
    EXPECT_DOUBLE_EQ(opencv8->model.distortion[7], 0.0500223357);
    // The file's extrinsics are rt_cam_ref = [2e-2, -3e-1, -1e-2, 1, 2, -3]: the reference's
    // origin lands at t in the camera.
    EXPECT_EQ(opencv8->parent, "reference");
    const Eigen::Vector3d origin_in_camera = opencv8->T_parent_camera.inverse().translation();
    EXPECT_NEAR((origin_in_camera - Eigen::Vector3d(1, 2, -3)).norm(), 0, 1e-12);
    const Eigen::AngleAxisd rotation(opencv8->T_parent_camera.inverse().rotation());
    EXPECT_NEAR((rotation.axis() * rotation.angle() - Eigen::Vector3d(2e-2, -3e-1, -1e-2)).norm(),
                0, 1e-12);
}

TEST(MrcalFormatTest, WriteReadRoundTrip) {
    MIXRAY_REQUIRE_SHARED_DATA(mrcalData("cam0.splined.cameramodel"));
    const std::filesystem::path dir = test::tempDir();
    for (const char* name : {"cam0.splined.cameramodel", "cam0.opencv8.cameramodel"}) {
        SCOPED_TRACE(name);
        auto original = detail::readMrcalCameramodel(mrcalData(name));
        ASSERT_TRUE(original.isOk());
        const std::filesystem::path path = dir / name;
        ASSERT_TRUE(detail::writeMrcalCameramodel(path, *original).isOk());
        auto back = detail::readMrcalCameramodel(path);
        ASSERT_TRUE(back.isOk()) << back.status().toString();
        EXPECT_EQ(back->model.lens, original->model.lens);
        EXPECT_EQ(back->model.spline, original->model.spline);
        EXPECT_EQ(back->model.width, original->model.width);
        EXPECT_EQ(back->model.height, original->model.height);
        ASSERT_EQ(back->model.distortion.size(), original->model.distortion.size());
        // Written at full precision: every number comes back bit for bit.
        EXPECT_EQ(back->model.fx, original->model.fx);
        EXPECT_EQ(back->model.fy, original->model.fy);
        EXPECT_EQ(back->model.cx, original->model.cx);
        EXPECT_EQ(back->model.cy, original->model.cy);
        EXPECT_EQ(back->model.distortion, original->model.distortion);
        EXPECT_TRUE(back->T_parent_camera.isApprox(original->T_parent_camera, 1e-9));
    }
}

TEST(MrcalFormatTest, ErrorsNameTheFileAndTheCause) {
    const std::filesystem::path dir = test::tempDir();
    auto missing = detail::readMrcalCameramodel(dir / "absent.cameramodel");
    ASSERT_FALSE(missing.isOk());
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(missing.status().message().find("absent.cameramodel"), std::string::npos);

    std::ofstream(dir / "garbage.cameramodel") << "{ 'lensmodel': 'LENSMODEL_OPENCV8', ";
    auto garbage = detail::readMrcalCameramodel(dir / "garbage.cameramodel");
    ASSERT_FALSE(garbage.isOk());
    EXPECT_EQ(garbage.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(garbage.status().message().find("garbage.cameramodel"), std::string::npos);

    std::ofstream(dir / "cahvor.cameramodel")
        << "{ 'lensmodel': 'LENSMODEL_CAHVOR', 'intrinsics': [1000, 1000, 500, 400, 0, 0, 0, 0, "
           "0], 'imagersize': [1000, 800], 'extrinsics': [0, 0, 0, 0, 0, 0] }\n";
    auto cahvor = detail::readMrcalCameramodel(dir / "cahvor.cameramodel");
    ASSERT_FALSE(cahvor.isOk());
    EXPECT_NE(cahvor.status().message().find("LENSMODEL_CAHVOR"), std::string::npos)
        << cahvor.status().message();

    CalibratedCamera fisheye;
    fisheye.name = "env";
    fisheye.model = CameraModel::pinhole(640, 480, 300, 300, 319.5, 239.5);
    fisheye.model.lens = LensModel::kFisheye;
    fisheye.model.distortion = {0.01, 0, 0, 0};
    const Status refused = detail::writeMrcalCameramodel(dir / "env.cameramodel", fisheye);
    EXPECT_EQ(refused.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(refused.message().find("env"), std::string::npos);
    EXPECT_NE(refused.message().find("fisheye"), std::string::npos);
}

}  // namespace
}  // namespace mixray::calibration
