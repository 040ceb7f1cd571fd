// Helpers for the replay tests: synthetic and real TUM / PCL folders, reading whole recordings.
#include "replay_test_util.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mixray/replay/tum.h"
#include "test_data.h"

namespace mixray::test {

std::vector<OwnedFrame> readAll(RecordingReader& reader) {
    std::vector<OwnedFrame> frames;
    while (true) {
        auto frame = reader.next();
        if (!frame) {
            EXPECT_EQ(frame.status().code(), ErrorCode::kEndOfStream) << frame.status().toString();
            break;
        }
        frames.push_back({frame->meta(), Image::copyOf(frame->image())});
    }
    return frames;
}

void expectSameFrames(const std::vector<OwnedFrame>& a, const std::vector<OwnedFrame>& b,
                      const std::string& what) {
    ASSERT_EQ(a.size(), b.size()) << what;
    for (size_t i = 0; i < a.size(); ++i) {
        SCOPED_TRACE(what + ", frame " + std::to_string(i));
        EXPECT_EQ(a[i].meta.stream, b[i].meta.stream);
        EXPECT_EQ(a[i].meta.sequence, b[i].meta.sequence);
        EXPECT_EQ(a[i].meta.device_stamp_ns, b[i].meta.device_stamp_ns);
        EXPECT_EQ(a[i].meta.host_stamp_ns, b[i].meta.host_stamp_ns);
        EXPECT_EQ(a[i].meta.clock_domain, b[i].meta.clock_domain);
        EXPECT_EQ(a[i].meta.exposure_us, b[i].meta.exposure_us);
        EXPECT_EQ(a[i].meta.status, b[i].meta.status);
        EXPECT_TRUE(sameImage(a[i].image.view(), b[i].image.view()));
    }
}

std::vector<int64_t> writeSyntheticTum(const std::filesystem::path& dir, int frames, int w, int h) {
    using replay::formatTumStamp;
    std::filesystem::create_directories(dir / "rgb");
    std::filesystem::create_directories(dir / "depth");
    std::string rgb_list = "# color images\n# file: 'synthetic'\n# timestamp filename\n";
    std::string depth_list = "# depth maps\n# file: 'synthetic'\n# timestamp filename\n";
    std::vector<int64_t> stamps;
    const int64_t t0 = 1305031102175304000;
    for (int i = 0; i < frames; ++i) {
        const int64_t rgb_ns = t0 + i * 33'333'000;  // microsecond stamps, like TUM's
        const int64_t depth_ns = rgb_ns - 14'897'000;
        stamps.push_back(rgb_ns);
        cv::Mat bgr(h, w, CV_8UC3);
        cv::Mat depth(h, w, CV_16UC1);
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                bgr.at<cv::Vec3b>(y, x) =
                    cv::Vec3b(static_cast<uint8_t>(x * 7 + i), static_cast<uint8_t>(y * 11),
                              static_cast<uint8_t>(x + y * 3 + i * 5));
                // 0 (no measurement), 1..4 (below 1 mm) and odd values up to 16 bits.
                const int v = (x + y) % 9 == 0 ? 0 : (x * 997 + y * 331 + i * 13) % 65536;
                depth.at<uint16_t>(y, x) = static_cast<uint16_t>(x == 1 && y == 0 ? 3 : v);
            }
        }
        const std::string rgb_name = "rgb/" + formatTumStamp(rgb_ns, 6) + ".png";
        const std::string depth_name = "depth/" + formatTumStamp(depth_ns, 6) + ".png";
        cv::imwrite((dir / rgb_name).string(), bgr);
        cv::imwrite((dir / depth_name).string(), depth);
        rgb_list += formatTumStamp(rgb_ns, 6) + " " + rgb_name + "\n";
        depth_list += formatTumStamp(depth_ns, 6) + " " + depth_name + "\n";
    }
    writeText(dir / "rgb.txt", rgb_list);
    writeText(dir / "depth.txt", depth_list);
    writeText(dir / "accelerometer.txt",
              "# accelerometer data\n# timestamp ax ay az\n1305031102.175304 0.1 -9.8 0.2\n");
    writeText(dir / "groundtruth.txt",
              "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n"
              "1305031102.1758 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\n");
    return stamps;
}

std::filesystem::path realTumColor() {
    return sharedDataDir() / "02_rgbd_single_frames_open3d" / "TUM_color.png";
}
std::filesystem::path realTumDepth() {
    return sharedDataDir() / "02_rgbd_single_frames_open3d" / "TUM_depth.png";
}
std::filesystem::path realPclDir() {
    return sharedDataDir() / "02_rgbd_pcl_openni_tiff";
}

bool writeRealTum(const std::filesystem::path& dir) {
    if (!std::filesystem::exists(realTumColor()) || !std::filesystem::exists(realTumDepth())) {
        return false;
    }
    // The source did not record the frame's timestamps; these are fr1/xyz's first pair.
    std::filesystem::create_directories(dir / "rgb");
    std::filesystem::create_directories(dir / "depth");
    std::filesystem::copy_file(realTumColor(), dir / "rgb" / "1305031102.175304.png");
    std::filesystem::copy_file(realTumDepth(), dir / "depth" / "1305031102.160407.png");
    writeText(dir / "rgb.txt",
              "# color images\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n# timestamp filename\n"
              "1305031102.175304 rgb/1305031102.175304.png\n");
    writeText(dir / "depth.txt",
              "# depth maps\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n# timestamp filename\n"
              "1305031102.160407 depth/1305031102.160407.png\n");
    return true;
}

void expectSamePixels(const std::filesystem::path& a, const std::filesystem::path& b) {
    cv::Mat ma = cv::imread(a.string(), cv::IMREAD_UNCHANGED);
    cv::Mat mb = cv::imread(b.string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(ma.empty()) << a;
    ASSERT_FALSE(mb.empty()) << b;
    ASSERT_EQ(ma.type(), mb.type()) << a << " vs " << b;
    ASSERT_EQ(ma.size(), mb.size()) << a << " vs " << b;
    EXPECT_EQ(cv::norm(ma, mb, cv::NORM_INF), 0.0) << a << " vs " << b;
}

std::string readFile(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace mixray::test
