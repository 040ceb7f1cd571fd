// mixray bench dds, end to end with few frames: every stream and path has its row of figures
// beside bare Fast DDS's, and nothing is lost at 30 fps; across namespaces the frames cross the
// veth pair.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include "cli_runner.h"

namespace mixray::test {
namespace {

// The rows of `paths` in the bench's output, each checked; how many there were.
int checkRows(const std::string& output, const std::vector<std::string>& paths) {
    int rows = 0;
    std::istringstream lines(output);
    for (std::string line; std::getline(lines, line);) {
        std::istringstream fields(line);
        std::string format, size, path;
        fields >> format >> size >> path;
        if (std::find(paths.begin(), paths.end(), path) == paths.end())
            continue;
        double fps = 0, bare_fps = 0, ratio = 0, recv = 0, bare_recv = 0, p50 = 0, p99 = 0;
        double bare_p50 = 0, bare_p99 = 0, cpu = 0, bare_cpu = 0, cpu_ratio = 0;
        unsigned long long lost = 1;
        fields >> fps >> bare_fps >> ratio >> recv >> bare_recv >> p50 >> p99 >> bare_p50 >>
            bare_p99 >> cpu >> bare_cpu >> cpu_ratio >> lost;
        EXPECT_TRUE(fields) << line;
        EXPECT_GT(fps, 0) << line;
        EXPECT_GT(bare_fps, 0) << line;
        EXPECT_GT(recv, 0) << line;
        EXPECT_GT(p50, 0) << line;
        EXPECT_GE(p99, p50) << line;
        EXPECT_GT(cpu, 0) << line;
        EXPECT_EQ(lost, 0u) << "a 30 fps stream loses nothing: " << line;
        ++rows;
    }
    return rows;
}

TEST(BenchDdsCli, EveryStreamAndPathHasItsFiguresBesideBareFastDds) {
    const CliRun run = mixray("bench dds --frames 30 --paced-frames 10 --transports udp,shm");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_EQ(checkRows(run.output, {"udp", "shm"}), 6) << run.output;  // 3 streams x 2 paths
}

// Each end's participant in a network namespace of its own: the frames cross the veth pair
// (its kernel counters carry at least every payload byte sent).
TEST(BenchDdsCli, AcrossNamespacesTheFramesCrossTheVethPair) {
    if (geteuid() != 0)
        GTEST_SKIP() << "needs root to make network namespaces (CI runs as root)";
    const CliRun run = mixray("bench dds --frames 30 --paced-frames 10 --transports veth");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_EQ(checkRows(run.output, {"veth"}), 3) << run.output;
    const size_t at = run.output.find(" MB crossed the veth pair");
    ASSERT_NE(at, std::string::npos) << run.output;
    const size_t start = run.output.rfind(' ', at - 1);
    const double mb = std::stod(run.output.substr(start + 1, at - start - 1));
    // 40 frames each of rgb8 and depth16 640x480 and mono8 1280x960, by mixray and by bare
    // Fast DDS.
    const double payload_mb = 2 * 40 * (640 * 480 * 3 + 640 * 480 * 2 + 1280 * 960) / 1e6;
    EXPECT_GE(mb, payload_mb) << run.output;
}

}  // namespace
}  // namespace mixray::test
