// mixray bench dds, end to end with few frames: every stream and path has its row of figures
// beside bare Fast DDS's, and nothing is lost at 30 fps.
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "cli_runner.h"

namespace mixray::test {
namespace {

TEST(BenchDdsCli, EveryStreamAndPathHasItsFiguresBesideBareFastDds) {
    const CliRun run = mixray("bench dds --frames 30 --paced-frames 10");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    int rows = 0;
    std::istringstream lines(run.output);
    for (std::string line; std::getline(lines, line);) {
        std::istringstream fields(line);
        std::string format, size, path;
        fields >> format >> size >> path;
        if (path != "udp" && path != "shm")
            continue;
        double fps = 0, bare_fps = 0, ratio = 0, recv = 0, bare_recv = 0, p50 = 0, p99 = 0;
        double bare_p50 = 0, bare_p99 = 0, cpu = 0, bare_cpu = 0, cpu_ratio = 0;
        unsigned long long lost = 1;
        fields >> fps >> bare_fps >> ratio >> recv >> bare_recv >> p50 >> p99 >> bare_p50 >>
            bare_p99 >> cpu >> bare_cpu >> cpu_ratio >> lost;
        ASSERT_TRUE(fields) << line;
        EXPECT_GT(fps, 0) << line;
        EXPECT_GT(bare_fps, 0) << line;
        EXPECT_GT(recv, 0) << line;
        EXPECT_GT(p50, 0) << line;
        EXPECT_GE(p99, p50) << line;
        EXPECT_GT(cpu, 0) << line;
        EXPECT_EQ(lost, 0u) << "a 30 fps stream loses nothing on loopback: " << line;
        ++rows;
    }
    EXPECT_EQ(rows, 6) << run.output;  // rgb8, depth16, mono8 over udp and shm
}

}  // namespace
}  // namespace mixray::test
