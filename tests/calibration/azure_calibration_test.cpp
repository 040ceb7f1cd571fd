// The Azure Kinect factory calibration (pyk4a's calibration.json and the recording it came
// with): values against the file, the registration of the recorded depth onto the recorded
// colour image, and the own-vs-factory comparison report.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mixray/calibration/depth_registration.h"
#include "mixray/graph/mkv.h"
#include "test_data.h"

namespace mixray::calibration {
namespace {

std::filesystem::path dataDir() {
    return test::sharedDataDir() / "07_azure_kinect_mkv";
}

using mixray::test::readText;

TEST(AzureKinectCalibration, ValuesFollowTheFileAndTheSdkModeTable) {
    const auto path = dataDir() / "pyk4a_calibration.json";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto cal = parseAzureKinectCalibration(readText(path), "NFOV_UNBINNED", "720P");
    ASSERT_TRUE(cal) << cal.status().toString();
    const CameraModel& d = cal->registration.depth;
    const CameraModel& c = cal->registration.color;
    // Normalised by the 1024x1024 sensor, cropped by (192, 180) to 640x576, and shifted by
    // half a pixel to pixel centres (Azure Kinect SDK, NFOV_UNBINNED).
    EXPECT_EQ(d.width, 640);
    EXPECT_EQ(d.height, 576);
    EXPECT_NEAR(d.cx, 0.51296979188919067 * 1024 - 192 - 0.5, 1e-9);
    EXPECT_NEAR(d.cy, 0.51692354679107666 * 1024 - 180 - 0.5, 1e-9);
    EXPECT_NEAR(d.fx, 0.4927808940410614 * 1024, 1e-9);
    EXPECT_NEAR(d.fy, 0.49290284514427185 * 1024, 1e-9);
    ASSERT_EQ(d.distortion.size(), 8u);
    // OpenCV's k1 k2 p1 p2 k3 k4 k5 k6 from the file's k1..k6 codx cody p2 p1.
    EXPECT_DOUBLE_EQ(d.distortion[0], 0.54793977737426758);
    EXPECT_DOUBLE_EQ(d.distortion[1], -0.020971370860934258);
    EXPECT_DOUBLE_EQ(d.distortion[2], 2.0557534298859537E-5);
    EXPECT_DOUBLE_EQ(d.distortion[3], -7.2104157879948616E-5);
    EXPECT_DOUBLE_EQ(d.distortion[4], -0.0026522316038608551);
    EXPECT_DOUBLE_EQ(d.distortion[7], -0.013910384848713875);
    // 720P: the 4096x3072 sensor binned to 1280x960, 120 rows cropped off the top.
    EXPECT_EQ(c.width, 1280);
    EXPECT_EQ(c.height, 720);
    EXPECT_NEAR(c.cx, 0.49984714388847351 * 1280 - 0.5, 1e-9);
    EXPECT_NEAR(c.cy, 0.50661760568618774 * 960 - 120 - 0.5, 1e-9);
    EXPECT_NEAR(c.fx, 0.47796511650085449 * 1280, 1e-9);
    EXPECT_NEAR(c.fy, 0.63742393255233765 * 960, 1e-9);
    EXPECT_NEAR(c.fx / c.fy, 1.0, 1e-3);  // square pixels once both are scaled right
    EXPECT_DOUBLE_EQ(c.distortion[2], -0.00016178244550246745);
    EXPECT_DOUBLE_EQ(c.distortion[3], -0.00012944525224156678);
    // The colour camera's Rt maps depth-camera points into it; translation in metres.
    const Eigen::Isometry3d& T = cal->registration.T_color_depth;
    EXPECT_NEAR(T.translation().x(), -0.032083429396152496, 1e-12);
    EXPECT_NEAR(T.translation().y(), -0.0022053730208426714, 1e-12);
    EXPECT_NEAR(T.translation().z(), 0.0038836926687508821, 1e-12);
    EXPECT_NEAR(T.linear()(0, 1), 0.0011817576596513391, 1e-6);  // row-major
    EXPECT_NEAR(T.linear()(1, 0), -0.0011387512786313891, 1e-6);
    EXPECT_NEAR(T.linear()(1, 2), 0.0861603245139122, 1e-6);
    EXPECT_NEAR(cal->depth_metric_radius, 1.7399997711181641, 1e-12);
    EXPECT_EQ(cal->color_metric_radius, 0);
    EXPECT_EQ(cal->serial, "001514394512");
    EXPECT_TRUE(cal->registration.validate());

    // Other modes scale the same numbers.
    auto binned = parseAzureKinectCalibration(readText(path), "NFOV_2X2BINNED", "MJPG_1080P");
    ASSERT_TRUE(binned) << binned.status().toString();
    EXPECT_EQ(binned->registration.depth.width, 320);
    EXPECT_NEAR(binned->registration.depth.fx, d.fx / 2, 1e-9);
    EXPECT_NEAR(binned->registration.depth.cx, 0.51296979188919067 * 512 - 96 - 0.5, 1e-9);
    EXPECT_EQ(binned->registration.color.width, 1920);
    EXPECT_NEAR(binned->registration.color.fx, c.fx * 1.5, 1e-9);
}

TEST(AzureKinectCalibration, ClearErrors) {
    const auto path = dataDir() / "pyk4a_calibration.json";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    const std::string text = readText(path);
    EXPECT_EQ(parseAzureKinectCalibration(text, "NFOV", "720P").status().code(),
              ErrorCode::kInvalidArgument);
    EXPECT_EQ(parseAzureKinectCalibration(text, "NFOV_UNBINNED", "480P").status().code(),
              ErrorCode::kInvalidArgument);
    auto r = parseAzureKinectCalibration("{not json", "NFOV_UNBINNED", "720P");
    EXPECT_EQ(r.status().code(), ErrorCode::kCorruptData);
    std::string no_color = text;
    no_color.replace(no_color.find("CALIBRATION_CameraLocationPV0"), 29,
                     "CALIBRATION_CameraLocationXX");
    r = parseAzureKinectCalibration(no_color, "NFOV_UNBINNED", "720P");
    ASSERT_FALSE(r);
    EXPECT_NE(r.status().message().find("PV0"), std::string::npos) << r.status().message();
}

// calibration_file_fuzz: json's value() threw json::type_error out of the parser for a field of
// another type, and a colour sensor billions of pixels wide overflowed the aspect check.
TEST(AzureKinectCalibration, FieldsOfAnotherTypeAreCorruptData) {
    for (const char* text :
         {R"({"CalibrationInformation": 5})",
          R"({"CalibrationInformation": {"Cameras": [{"Location": 7}]}})",
          R"({"CalibrationInformation": {"Cameras": [{"Location": "CALIBRATION_CameraLocationD0",
              "Intrinsics": 5}]}})"}) {
        auto r = parseAzureKinectCalibration(text, "NFOV_UNBINNED", "720P");
        ASSERT_FALSE(r) << text;
        EXPECT_EQ(r.status().code(), ErrorCode::kCorruptData) << text;
        EXPECT_NE(r.status().message().find("type"), std::string::npos) << r.status().message();
    }
    const auto path = dataDir() / "pyk4a_calibration.json";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    std::string huge = readText(path);
    const std::string width = "\"SensorWidth\": 4096";
    ASSERT_NE(huge.find(width), std::string::npos);
    huge.replace(huge.find(width), width.size(), "\"SensorWidth\": 1073741824");
    auto r = parseAzureKinectCalibration(huge, "NFOV_UNBINNED", "720P");
    ASSERT_FALSE(r);
    EXPECT_EQ(r.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(r.status().message().find("SensorWidth/SensorHeight outside 1..65535"),
              std::string::npos)
        << r.status().message();
}

// The recording's first depth and colour frames, the factory calibration attached to it.
struct Recorded {
    AzureKinectCalibration calibration;
    Image depth;
    cv::Mat gray;  // the colour frame, decoded
};

std::optional<Recorded> readRecording() {
    auto reader = openMkv(dataDir() / "pyk4a_recording.mkv");
    if (!reader)
        return std::nullopt;
    Recorded out;
    std::string depth_mode, color_mode;
    for (const auto& s : (*reader)->streams()) {
        if (s.name == "azure_kinect/depth")
            depth_mode = s.tags.at("K4A_DEPTH_MODE");
        if (s.name == "azure_kinect/color")
            color_mode = s.tags.at("K4A_COLOR_MODE");
    }
    for (const auto& a : (*reader)->attachments()) {
        if (a.name != "calibration.json")
            continue;
        auto cal = parseAzureKinectCalibration(
            std::string_view(reinterpret_cast<const char*>(a.data.data()), a.data.size()),
            depth_mode, color_mode);
        EXPECT_TRUE(cal) << cal.status().toString();
        if (!cal)
            return std::nullopt;
        out.calibration = *cal;
    }
    const auto& streams = (*reader)->streams();
    while (out.depth.desc().width == 0 || out.gray.empty()) {
        auto frame = (*reader)->next();
        if (!frame)
            break;
        const std::string& name = streams[frame->meta().stream].name;
        const ImageView v = frame->image();
        if (name == "azure_kinect/depth" && out.depth.desc().width == 0)
            out.depth = Image::copyOf(v);
        if (name == "azure_kinect/color" && out.gray.empty()) {
            const cv::Mat bytes(1, static_cast<int>(v.size_bytes), CV_8U,
                                const_cast<uint8_t*>(v.data));
            out.gray = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
        }
    }
    if (out.depth.desc().width == 0 || out.gray.empty())
        return std::nullopt;
    return out;
}

// How well depth edges of the registered image sit on intensity edges of the colour image:
// the mean colour gradient magnitude over pixels where the registered depth jumps by > 5 %.
double edgeAgreement(const Image& registered, const cv::Mat& gray) {
    cv::Mat blurred, gx, gy, magnitude;
    cv::GaussianBlur(gray, blurred, cv::Size(5, 5), 1.0);
    cv::Sobel(blurred, gx, CV_32F, 1, 0);
    cv::Sobel(blurred, gy, CV_32F, 0, 1);
    cv::magnitude(gx, gy, magnitude);
    double sum = 0;
    int n = 0;
    const ImageView v = registered.view();
    for (int y = 1; y + 1 < v.desc.height; ++y)
        for (int x = 1; x + 1 < v.desc.width; ++x) {
            const int a = v.row<uint16_t>(y)[x];
            const int right = v.row<uint16_t>(y)[x + 1];
            const int down = v.row<uint16_t>(y + 1)[x];
            if (!a || !right || !down)
                continue;
            if (std::abs(a - right) > 0.05 * a || std::abs(a - down) > 0.05 * a) {
                sum += magnitude.at<float>(y, x);
                ++n;
            }
        }
    return n ? sum / n : 0;
}

TEST(AzureKinectCalibration, RegistersTheRecordedDepthOntoTheColourImage) {
    MIXRAY_REQUIRE_SHARED_DATA(dataDir() / "pyk4a_recording.mkv");
    setFfmpegLogging(false);
    const auto recorded = readRecording();
    ASSERT_TRUE(recorded);
    const DepthRegistration& factory = recorded->calibration.registration;
    ASSERT_EQ(recorded->gray.cols, factory.color.width);
    ASSERT_EQ(recorded->gray.rows, factory.color.height);
    auto registered = registerDepth(factory, recorded->depth.view());
    ASSERT_TRUE(registered) << registered.status().toString();

    // Coverage: the colour pixels whose rays the depth camera's image spans at 1.5 m, and
    // of those, the share holding a registered depth.
    int inside = 0, filled = 0;
    const ImageView r = registered->view();
    for (int y = 0; y < factory.color.height; y += 2)
        for (int x = 0; x < factory.color.width; x += 2) {
            const auto dir = factory.color.unproject({double(x), double(y)});
            const auto px =
                factory.depth.project(factory.T_color_depth.inverse() * (*dir * (1.5 / dir->z())));
            if (!px || px->x() < 0 || px->y() < 0 || px->x() > factory.depth.width - 1 ||
                px->y() > factory.depth.height - 1)
                continue;
            ++inside;
            filled += r.row<uint16_t>(y)[x] != 0;
        }
    const double coverage = static_cast<double>(filled) / inside;
    // ... against the share of depth pixels holding a reading (NFOV's corners and the window
    // glass read nothing): registration must not lose readings (no cracks).
    int valid = 0;
    const ImageView d = recorded->depth.view();
    for (int y = 0; y < d.desc.height; ++y)
        for (int x = 0; x < d.desc.width; ++x)
            valid += d.row<uint16_t>(y)[x] != 0;
    const double depth_valid = static_cast<double>(valid) / (d.desc.width * d.desc.height);

    // Depth edges (the mug, the window frame) on colour edges, better than with the depth
    // camera moved by 2 cm either way.
    const double factory_score = edgeAgreement(*registered, recorded->gray);
    double best_shifted = 0;
    for (const Eigen::Vector3d& shift :
         {Eigen::Vector3d(0.02, 0, 0), Eigen::Vector3d(-0.02, 0, 0), Eigen::Vector3d(0, 0.02, 0),
          Eigen::Vector3d(0, -0.02, 0)}) {
        DepthRegistration moved = factory;
        moved.T_color_depth.translation() += shift;
        auto shifted = registerDepth(moved, recorded->depth.view());
        ASSERT_TRUE(shifted);
        best_shifted = std::max(best_shifted, edgeAgreement(*shifted, recorded->gray));
    }
    std::printf(
        "coverage %.3f of %d px (depth readings %.3f); edge agreement factory %.1f, "
        "best shifted %.1f\n",
        coverage, inside, depth_valid, factory_score, best_shifted);
    EXPECT_GT(coverage, 0.95 * depth_valid);
    EXPECT_GT(factory_score, 1.2 * best_shifted);
}

TEST(AzureKinectCalibration, ComparisonReport) {
    const auto path = dataDir() / "pyk4a_calibration.json";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto cal = parseAzureKinectCalibration(readText(path), "NFOV_UNBINNED", "720P");
    ASSERT_TRUE(cal);
    const DepthRegistration& factory = cal->registration;
    auto same = compareRegistrations(factory, factory);
    ASSERT_TRUE(same);
    EXPECT_EQ(same->depth.dfx, 0);
    EXPECT_LT(same->registration_max_px, 1e-6);
    EXPECT_LT(same->color.grid_max_px, 1e-6);

    DepthRegistration own = factory;
    own.color.fx += 2;
    own.T_color_depth.translation().x() += 0.005;
    own.T_color_depth.linear() =
        own.T_color_depth.linear() *
        Eigen::AngleAxisd(0.2 * std::numbers::pi / 180, Eigen::Vector3d::UnitY())
            .toRotationMatrix();
    auto diff = compareRegistrations(own, factory);
    ASSERT_TRUE(diff);
    EXPECT_NEAR(diff->color.dfx, 2, 1e-9);
    EXPECT_NEAR(diff->translation_m, 0.005, 1e-9);
    EXPECT_NEAR(diff->rotation_deg, 0.2, 1e-6);
    // fx + 2 moves image borders by ~2 px; 5 mm at 1.5 m is ~2 px, 0.2° another ~2 px.
    EXPECT_GT(diff->color.grid_max_px, 1.5);
    EXPECT_GT(diff->registration_rms_px, 2);
    EXPECT_LT(diff->registration_max_px, 10);
    const std::string report = diff->report();
    EXPECT_NE(report.find("dfx +2.00"), std::string::npos) << report;
    EXPECT_NE(report.find("translation by 5.0 mm"), std::string::npos) << report;

    DepthRegistration other_size = own;
    other_size.color = other_size.color.scaled(0.5);
    EXPECT_EQ(compareRegistrations(other_size, factory).status().code(),
              ErrorCode::kInvalidArgument);
}

}  // namespace
}  // namespace mixray::calibration
