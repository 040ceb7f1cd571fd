// mixray render under SIGTERM and SIGINT: it stops within an image tile, drops the frame in
// progress, closes the video (ffprobe decodes the frames done) and exits 143 / 130 saying so.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <string>
#include <thread>
#include <tuple>

#include "cli_runner.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// The decodable video frames ffprobe counts in `video`; -1 when it cannot read the file.
int ffprobeFrameCount(const fs::path& video) {
    const std::string command =
        "ffprobe -v error -count_frames -select_streams v:0 -show_entries "
        "stream=nb_read_frames -of csv=p=0 " +
        test::q(video) + " 2>/dev/null";
    FILE* pipe = popen(command.c_str(), "r");
    if (!pipe)
        return -1;
    int frames = -1;
    if (std::fscanf(pipe, "%d", &frames) != 1)
        frames = -1;
    return pclose(pipe) == 0 ? frames : -1;
}

int pngCount(const fs::path& dir) {
    int n = 0;
    for (const auto& entry : fs::directory_iterator(dir))
        n += entry.path().extension() == ".png";
    return n;
}

struct Stopped {
    test::CliRun run;
    double said_s = -1;  // from the signal to the "stopped by" line (files closed)
};

// Starts a slow render of the bundled session (glass, a mirror, 4 samples per pixel with 7
// shadow rays each: most of a second a frame on two threads, 300 tiles), waits until the first
// frame is written (its PNG appears, right after the video frame) and sends `signal`, so it lands
// in the middle of the second frame.
Stopped renderAndSignal(const fs::path& dir, int signal, int second_signal = 0) {
    const test::CliProcess process =
        test::startMixray({"render",
                           (test::fixturesDir() / "sessions" / "pattern_rgbd.mkv").string(),
                           "--scene",
                           (test::fixturesDir() / "scenes" / "pattern_session.yaml").string(),
                           "-o",
                           (dir / "out.mp4").string(),
                           "--png-dir",
                           (dir / "png").string(),
                           "--png-every",
                           "1",
                           "--max-frames",
                           "6",
                           "--shadows",
                           "uniform",
                           "--shadow-samples",
                           "7",
                           "--samples",
                           "4",
                           "--threads",
                           "2"},
                          dir / "log.txt");
    Stopped stopped;
    EXPECT_GT(process.pid, 0);
    if (process.pid <= 0)
        return stopped;
    const auto deadline = Clock::now() + std::chrono::seconds(120);
    while (!fs::exists(dir / "png" / "frame_000000.png") && Clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_TRUE(fs::exists(dir / "png" / "frame_000000.png")) << test::readText(dir / "log.txt");
    const auto signalled = Clock::now();
    kill(process.pid, signal);
    if (second_signal != 0)
        kill(process.pid, second_signal);
    // stderr is unbuffered: the line appears as soon as the video is closed.
    // Whether it has exited, without reaping it (waitMixray does).
    const auto exited = [&] {
        siginfo_t info{};
        return waitid(P_PID, static_cast<id_t>(process.pid), &info, WEXITED | WNOHANG | WNOWAIT) ==
                   0 &&
               info.si_pid == process.pid;
    };
    const auto said_deadline = Clock::now() + std::chrono::seconds(120);
    while (test::readText(dir / "log.txt").find("stopped by") == std::string::npos && !exited() &&
           Clock::now() < said_deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    stopped.said_s = std::chrono::duration<double>(Clock::now() - signalled).count();
    stopped.run = test::waitMixray(process);
    return stopped;
}

TEST(RenderCancelCli, ASignalStopsMidFrameAndLeavesAPlayableVideoOfTheFramesDone) {
    if (std::system("command -v ffprobe > /dev/null 2>&1") != 0)
        GTEST_SKIP() << "ffprobe (Debian package ffmpeg) is not installed";
    for (const auto& [signal, name, code] :
         {std::tuple{SIGTERM, "SIGTERM", 143}, std::tuple{SIGINT, "SIGINT", 130}}) {
        SCOPED_TRACE(name);
        const fs::path dir = test::tempDir() / name;
        fs::create_directories(dir);
        const Stopped stopped = renderAndSignal(dir, signal);
        const std::string& output = stopped.run.output;
        EXPECT_EQ(stopped.run.exit_code, code) << output;

        const std::regex said(std::string("stopped by ") + name +
                              " after ([0-9]+) of 6 frames; (.*) holds ([0-9]+) frames?\n");
        std::smatch m;
        ASSERT_TRUE(std::regex_search(output, m, said)) << output;
        const int done = std::stoi(m[1]);
        EXPECT_EQ(m[2].str(), (dir / "out.mp4").string());
        EXPECT_EQ(std::stoi(m[3]), done);
        EXPECT_GE(done, 1);
        EXPECT_LT(done, 6);
        // The video is finished (an MP4 without its trailer does not open) and holds exactly
        // the frames done: the frame in progress was dropped, not written half rendered.
        EXPECT_EQ(ffprobeFrameCount(dir / "out.mp4"), done) << output;
        EXPECT_EQ(pngCount(dir / "png"), done);

        // It stopped within the frame, not at its end: well under one frame's time.
        std::smatch timing;
        ASSERT_TRUE(std::regex_search(output, timing, std::regex("mean ([0-9.]+) ms"))) << output;
        const double frame_s = std::stod(timing[1]) / 1e3;
        EXPECT_GT(frame_s, 0.3) << "the scene renders too fast to show a stop within a frame";
        EXPECT_LT(stopped.said_s, 0.5 * frame_s) << "a frame takes " << frame_s << " s";
    }
}

// A second signal (another number: the same one could merge with the first while pending)
// does not wait for the video to be closed: mixray exits at once with 128 + that signal, without
// the orderly stop's message.
TEST(RenderCancelCli, ASecondSignalExitsAtOnce) {
    const fs::path dir = test::tempDir();
    const Stopped stopped = renderAndSignal(dir, SIGINT, SIGTERM);
    // Two threads may take the two signals at once; whichever came second sets the code.
    EXPECT_TRUE(stopped.run.exit_code == 143 || stopped.run.exit_code == 130)
        << stopped.run.exit_code << "\n"
        << stopped.run.output;
    EXPECT_NE(stopped.run.output.find("second signal, exiting at once"), std::string::npos)
        << stopped.run.output;
    EXPECT_EQ(stopped.run.output.find("stopped by"), std::string::npos) << stopped.run.output;
}

TEST(RenderCancelCli, HelpSaysWhatASignalDoes) {
    const test::CliRun help = test::mixray("render --help");
    EXPECT_EQ(help.exit_code, 0);
    EXPECT_NE(help.output.find("SIGTERM stops within one image tile"), std::string::npos)
        << help.output;
    EXPECT_NE(help.output.find("143"), std::string::npos) << help.output;
}

}  // namespace
}  // namespace mixray
