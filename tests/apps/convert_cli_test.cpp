// mixray convert --to ply|pcd|mcap and mixray info/convert of .oni recordings, end to end.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "cli_runner.h"
#include "foxglove_mcap.h"
#include "mixray/replay/point_cloud.h"
#include "replay_test_util.h"
#include "test_data.h"

namespace mixray::test {
namespace {

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// Every frame of the bundled RGB-D session to MCAP, under the rig's name, as Foxglove's readers
// count them; a stream MCAP cannot hold is refused until --drop-unsupported.
TEST(ConvertCli, ToMcapWritesEveryImageUnderTheRigsName) {
    const auto dir = tempDir();
    const CliRun converted = mixray("convert " + q(fixturesDir() / "sessions/pattern_rgbd.mkv") +
                                    " " + q(dir / "session.mcap"));
    ASSERT_EQ(converted.exit_code, 0) << converted.output;
    EXPECT_TRUE(contains(converted.output, "150 of 150 frames written")) << converted.output;
    const nlohmann::json got = readMcapWithFoxglove(dir / "session.mcap");
    ASSERT_TRUE(got.is_object());
    EXPECT_EQ(got["statistics"]["messageCount"], 150);
    std::vector<std::string> topics;
    for (const auto& channel : got["channels"])
        topics.push_back(channel["topic"]);
    EXPECT_EQ(topics, (std::vector<std::string>{"/pattern_rgbd/rgbd/color/image_raw",
                                                "/pattern_rgbd/rgbd/depth/image_raw",
                                                "/pattern_rgbd/mono/mono/image_raw"}));

    const CliRun pose = mixray("convert " + q(fixturesDir() / "sessions/sim_tabletop.mkv") + " " +
                               q(dir / "tabletop.mcap"));
    EXPECT_NE(pose.exit_code, 0);
    EXPECT_TRUE(contains(pose.output, "truth/pose: sensor_msgs/Image has no encoding for binary"))
        << pose.output;
    EXPECT_FALSE(std::filesystem::exists(dir / "tabletop.mcap"));
}

TEST(ConvertCli, PclFolderToPcdMatchesPclsReferenceCloud) {
    const auto pcl = realPclDir();
    const auto reference = pcl / "frame_20121214T142255.814212.reference.pcd";
    MIXRAY_REQUIRE_SHARED_DATA(reference);
    const auto out = tempDir() / "clouds";
    CliRun run = mixray("convert --to pcd --pcd-data ascii " + q(pcl) + " " + q(out));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    auto ours = replay::readPointCloud(out / "cloud_000000.pcd");
    ASSERT_TRUE(ours) << ours.status().toString();
    auto theirs = replay::readPointCloud(reference);
    ASSERT_TRUE(theirs) << theirs.status().toString();
    ASSERT_EQ(ours->size(), theirs->size());
    size_t differing = 0;
    for (size_t i = 0; i < ours->xyz.size(); ++i) {
        const float a = ours->xyz[i], b = theirs->xyz[i];
        if (std::isnan(a) != std::isnan(b) ||
            (!std::isnan(a) && std::abs(a - b) > 4e-7f * std::max(1.f, std::abs(b)))) {
            ++differing;
        }
    }
    EXPECT_EQ(differing, 0u);
    EXPECT_EQ(ours->rgb, theirs->rgb);
}

TEST(ConvertCli, PointCloudsNeedIntrinsicsAndSayHow) {
    const auto dir = tempDir();
    writeSyntheticTum(dir / "tum", 2);
    CliRun none = mixray("convert --to ply " + q(dir / "tum") + " " + q(dir / "a"));
    EXPECT_NE(none.exit_code, 0);
    EXPECT_TRUE(contains(none.output, "--intrinsics")) << none.output;
    CliRun bad =
        mixray("convert --to ply --intrinsics 517,516 " + q(dir / "tum") + " " + q(dir / "b"));
    EXPECT_NE(bad.exit_code, 0);
    EXPECT_TRUE(contains(bad.output, "fx,fy,cx,cy")) << bad.output;
    CliRun good = mixray("convert --to ply --intrinsics 517.3,516.5,15.5,11.5 " + q(dir / "tum") +
                         " " + q(dir / "c"));
    ASSERT_EQ(good.exit_code, 0) << good.output;
    EXPECT_TRUE(std::filesystem::exists(dir / "c" / "cloud_000001.ply"));
    EXPECT_TRUE(contains(readText(dir / "c" / "clouds.txt"), "517.3,516.5,15.5,11.5"));
    CliRun help = mixray("convert --help");
    EXPECT_TRUE(contains(help.output, "--intrinsics")) << help.output;
    EXPECT_TRUE(contains(help.output, "--no-color"));
}

TEST(ConvertCli, OniRecordingsInfoAndConvert) {
    const auto oni = kinectV1Oni();
    MIXRAY_REQUIRE_SHARED_DATA(oni);
    CliRun info = mixray("info " + q(oni));
    ASSERT_EQ(info.exit_code, 0) << info.output;
    EXPECT_TRUE(contains(info.output, "oni/depth")) << info.output;
    EXPECT_TRUE(contains(info.output, "oni/color")) << info.output;
    EXPECT_TRUE(contains(info.output, "24 frames")) << info.output;
    EXPECT_TRUE(contains(info.output, "depth16 640x480")) << info.output;

    const auto dir = tempDir();
    CliRun mkv = mixray("convert " + q(oni) + " " + q(dir / "kinect.mkv"));
    ASSERT_EQ(mkv.exit_code, 0) << mkv.output;
    CliRun back = mixray("info --json " + q(dir / "kinect.mkv"));
    ASSERT_EQ(back.exit_code, 0) << back.output;
    EXPECT_TRUE(contains(back.output, "\"frames\": 24")) << back.output;

    CliRun tum = mixray("convert --to tum " + q(oni) + " " + q(dir / "tum"));
    ASSERT_EQ(tum.exit_code, 0) << tum.output;
    EXPECT_TRUE(std::filesystem::exists(dir / "tum" / "depth.txt"));

    CliRun ply = mixray("convert --to ply " + q(oni) + " " + q(dir / "clouds"));
    ASSERT_EQ(ply.exit_code, 0) << ply.output;
    EXPECT_TRUE(std::filesystem::exists(dir / "clouds" / "cloud_000011.ply"));
    EXPECT_FALSE(std::filesystem::exists(dir / "clouds" / "cloud_000012.ply"));
}

}  // namespace
}  // namespace mixray::test
