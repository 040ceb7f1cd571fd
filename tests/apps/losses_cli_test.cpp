// Losses the command line must report: what a target format cannot hold, damage inside a
// recording, a record stopped by a signal or ended early, every frame of an .oni at its pace.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "cli_runner.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;

using test::CliRun;
using test::mixray;
using test::q;

const fs::path kSession = test::fixturesDir() / "sessions" / "pattern_rgbd.mkv";

// A rig of one realtime pattern device that never ends by itself.
void writeEndlessRig(const fs::path& rig) {
    std::ofstream(rig) << "rig: endless\ndevices:\n  - name: cam\n    driver: pattern\n"
                       << "    id: rgbd\n    streams: [color]\n"
                       << "    options: {color.width: 64, color.height: 48, fps: 30}\n";
}

// Runs mixray with `args`, sends `signal_number` `delay` after it can catch signals, returns the
// exit code (-1 when killed by a signal) and what it printed.
CliRun runAndSignal(const std::vector<std::string>& args, int signal_number,
                    std::chrono::milliseconds delay, const fs::path& log) {
    CliRun run;
    const pid_t pid = fork();
    if (pid == 0) {
        const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fd, 1);
        dup2(fd, 2);
        std::vector<std::string> all = {test::cliPath().string()};
        all.insert(all.end(), args.begin(), args.end());
        std::vector<char*> argv;
        for (auto& a : all)
            argv.push_back(a.data());
        argv.push_back(nullptr);
        execv(argv[0], argv.data());
        _exit(127);
    }
    // The program can catch nothing while the loader maps its libraries (seconds on a loaded
    // machine): the delay counts from when it caught SIGINT.
    test::waitUntilCatching(pid, SIGINT);
    std::this_thread::sleep_for(delay);
    kill(pid, signal_number);
    int status = 0;
    waitpid(pid, &status, 0);
    run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    std::ifstream in(log);
    run.output.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    return run;
}

// The bundled session holds rgbd/color, rgbd/depth, mono/mono and rig.yaml: TUM holds the
// first two only. Without --drop-unsupported nothing is written and the losses are named.
TEST(LossesCli, ConvertRefusesWhatTheFormatCannotHoldUnlessAskedToDropIt) {
    const fs::path dir = test::tempDir();
    CliRun refused = mixray("convert " + q(kSession) + " " + q(dir / "tum"));
    EXPECT_EQ(refused.exit_code, 3) << refused.output;
    EXPECT_NE(refused.output.find("mono/mono"), std::string::npos) << refused.output;
    EXPECT_NE(refused.output.find("rig.yaml"), std::string::npos) << refused.output;
    EXPECT_NE(refused.output.find("--drop-unsupported"), std::string::npos) << refused.output;
    EXPECT_FALSE(fs::exists(dir / "tum" / "rgb.txt"));

    CliRun dropped = mixray("convert --drop-unsupported " + q(kSession) + " " + q(dir / "tum"));
    ASSERT_EQ(dropped.exit_code, 0) << dropped.output;
    EXPECT_NE(dropped.output.find("120 of 150 frames written"), std::string::npos)
        << dropped.output;
    EXPECT_NE(dropped.output.find("not written: stream 'mono/mono'"), std::string::npos)
        << dropped.output;
    EXPECT_NE(dropped.output.find("not written: attachment 'rig.yaml'"), std::string::npos)
        << dropped.output;
    EXPECT_NE(dropped.output.find("'rgbd/color' is read back as 'tum/color'"), std::string::npos)
        << dropped.output;
    // The per-stream lines say which frames went where.
    EXPECT_NE(dropped.output.find("not written (the format cannot hold them)"), std::string::npos)
        << dropped.output;
    auto info = nlohmann::json::parse(mixray("info --json " + q(dir / "tum")).output);
    EXPECT_EQ(info["frames"], 120);

    // PCL TIFF is refused the same way; mkv holds everything and says 150 of 150.
    CliRun pcl = mixray("convert --to pcl-tiff " + q(kSession) + " " + q(dir / "pcl"));
    EXPECT_EQ(pcl.exit_code, 3) << pcl.output;
    EXPECT_NE(pcl.output.find("mono/mono"), std::string::npos) << pcl.output;
    CliRun mkv = mixray("convert " + q(kSession) + " " + q(dir / "copy.mkv"));
    ASSERT_EQ(mkv.exit_code, 0) << mkv.output;
    EXPECT_NE(mkv.output.find("150 of 150 frames written"), std::string::npos) << mkv.output;
}

// 5000 bytes overwritten in the middle of a recording: info reports damage, where, and fails.
TEST(LossesCli, InfoReportsDamageInsideARecordingWithWhere) {
    const fs::path dir = test::tempDir();
    const fs::path file = dir / "damaged.mkv";
    CliRun record = mixray("record " + q(test::fixturesDir() / "rigs" / "pattern_rgbd.yaml") +
                           " -o " + q(file));
    ASSERT_EQ(record.exit_code, 0) << record.output;
    // Overwritten from the first Matroska cluster at or after the middle of the file, so the
    // damage breaks the file's structure (a payload alone would fail its CRC).
    std::string bytes;
    {
        std::ifstream in(file, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    const size_t at = bytes.find("\x1F\x43\xB6\x75", bytes.size() / 2);
    ASSERT_NE(at, std::string::npos);
    ASSERT_LT(at + 5000, bytes.size());
    {
        std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
        f.seekp(static_cast<std::streamoff>(at));
        const std::string junk(5000, '\x55');
        f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
    }
    CliRun info = mixray("info " + q(file));
    EXPECT_EQ(info.exit_code, 3) << info.output;
    EXPECT_NE(info.output.find("damage"), std::string::npos) << info.output;
    EXPECT_NE(info.output.find("at byte "), std::string::npos) << info.output;

    CliRun json = mixray("info --json " + q(file));
    EXPECT_EQ(json.exit_code, 3) << json.output;
    const auto start = json.output.find('{');
    ASSERT_NE(start, std::string::npos) << json.output;
    const auto end = json.output.rfind('}');
    auto j = nlohmann::json::parse(json.output.substr(start, end - start + 1));
    EXPECT_FALSE(j["complete"]);
    ASSERT_FALSE(j["damage"].empty()) << json.output;
    const int64_t offset = j["damage"][0]["byte_offset"].get<int64_t>();
    // Found within the overwritten bytes or the cluster they broke.
    EXPECT_GE(offset, static_cast<int64_t>(at) - 65536) << json.output;
    EXPECT_LE(offset, static_cast<int64_t>(at) + 5000 + 65536) << json.output;
}

TEST(LossesCli, RecordRefusesADurationThatIsNotAFinitePositiveNumber) {
    const fs::path dir = test::tempDir();
    writeEndlessRig(dir / "rig.yaml");
    for (const char* bad : {"nan", "inf", "0", "-1", "ten"}) {
        CliRun run = mixray("record " + q(dir / "rig.yaml") + " -o " + q(dir / "x.mkv") +
                            " --duration " + bad);
        EXPECT_EQ(run.exit_code, 2) << bad << ": " << run.output;
        EXPECT_NE(run.output.find("--duration"), std::string::npos) << run.output;
        EXPECT_FALSE(fs::exists(dir / "x.mkv")) << bad;
    }
}

// The bundled rig's pattern devices end after 60 and 30 frames, far before 100 s.
TEST(LossesCli, RecordSaysWhenTheRigEndsBeforeTheDuration) {
    const fs::path dir = test::tempDir();
    CliRun run = mixray("record " + q(test::fixturesDir() / "rigs" / "pattern_rgbd.yaml") + " -o " +
                        q(dir / "short.mkv") + " --duration 100");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("the rig's streams ended after"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("before --duration 100 s"), std::string::npos) << run.output;

    writeEndlessRig(dir / "rig.yaml");
    CliRun timed =
        mixray("record " + q(dir / "rig.yaml") + " -o " + q(dir / "timed.mkv") + " --duration 0.5");
    ASSERT_EQ(timed.exit_code, 0) << timed.output;
    EXPECT_NE(timed.output.find("stopped after --duration 0.5 s"), std::string::npos)
        << timed.output;
}

// SIGINT or SIGTERM 2 s after start: a finished, valid file, a summary that says which, and
// 130 or 143.
TEST(LossesCli, RecordStoppedBySignalLeavesAValidFileAndSaysSo) {
    const fs::path dir = test::tempDir();
    writeEndlessRig(dir / "rig.yaml");
    for (int sig : {SIGINT, SIGTERM}) {
        const fs::path out = dir / ("stopped_" + std::to_string(sig) + ".mkv");
        CliRun run = runAndSignal({"record", (dir / "rig.yaml").string(), "-o", out.string()}, sig,
                                  std::chrono::milliseconds(2000), dir / "run.log");
        EXPECT_EQ(run.exit_code, 128 + sig) << run.output;
        EXPECT_NE(run.output.find(sig == SIGINT ? "stopped by SIGINT" : "stopped by SIGTERM"),
                  std::string::npos)
            << run.output;
        EXPECT_NE(run.output.find("written"), std::string::npos) << run.output;
        ASSERT_TRUE(fs::exists(out)) << run.output;
        CliRun info = mixray("info --json " + q(out));
        ASSERT_EQ(info.exit_code, 0) << info.output;
        EXPECT_TRUE(nlohmann::json::parse(info.output)["complete"]);
    }
}

// The Kinect v1 .oni at the default pace: all 12 + 12 frames, stamped by their own times (the
// host stamps keep the recorded intervals), nothing lost.
TEST(LossesCli, RecordsEveryFrameOfAnOniAtTheDefaultPace) {
    const fs::path oni = test::kinectV1Oni();
    MIXRAY_REQUIRE_SHARED_DATA(oni);
    const fs::path dir = test::tempDir();
    for (const char* pace : {"original", "fast"}) {
        std::ofstream(dir / "rig.yaml")
            << "rig: oni\ndevices:\n  - name: kinect\n    driver: openni2\n"
            << "    id: " << oni.string() << "\n    options: { pace: " << pace << " }\n";
        const fs::path out = dir / (std::string(pace) + ".mkv");
        CliRun record = mixray("record " + q(dir / "rig.yaml") + " -o " + q(out));
        ASSERT_EQ(record.exit_code, 0) << record.output;
        EXPECT_NE(record.output.find("recorded 24 frames"), std::string::npos) << record.output;
        EXPECT_EQ(record.output.find("lost by the device"), std::string::npos) << record.output;
        const auto info = nlohmann::json::parse(mixray("info --json " + q(out)).output);
        ASSERT_EQ(info["streams"].size(), 2u);
        for (const auto& s : info["streams"]) {
            EXPECT_EQ(s["frames"], 12) << pace << " " << s["name"];
            // 12 frames over the recorded 0.367 s: ~30 fps, no gap of a frame period or more.
            EXPECT_NEAR(s["measured_fps"].get<double>(), 30.0, 1.5) << pace << " " << s["name"];
            EXPECT_EQ(s["gaps"], 0) << pace << " " << s["name"];
        }
    }
}

}  // namespace
}  // namespace mixray
