// Nothing silent (issue 31): a cut-off recording is said, with exit code 5, by every command
// that reads it; an object never drawn is named; SIGTERM exits 143 everywhere; simulate stopped
// before its first frame leaves no recording.
#include <gtest/gtest.h>
#include <signal.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <vector>

#include "cli_runner.h"
#include "recording_edit.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;

using test::CliRun;
using test::mixray;
using test::q;

constexpr int kExitIncomplete = 5;

const fs::path kSession = test::fixturesDir() / "sessions" / "sim_tabletop.mkv";

// The bundled session cut off after `fraction` of its bytes, as a crash or a full disk leaves
// it: every command that reads it sees the same damage.
fs::path cutSession(const fs::path& dir, double fraction) {
    const fs::path cut = dir / "cut.mkv";
    fs::copy_file(kSession, cut, fs::copy_options::overwrite_existing);
    fs::resize_file(cut,
                    static_cast<uintmax_t>(static_cast<double>(fs::file_size(cut)) * fraction));
    return cut;
}

// The damage said as the reader found it: the file, what is missing, the frames read.
void expectSaysTheCut(const std::string& command, const CliRun& run) {
    EXPECT_EQ(run.exit_code, kExitIncomplete) << command << "\n" << run.output;
    EXPECT_TRUE(std::regex_search(
        run.output,
        std::regex("mixray " + command +
                   ": input incomplete: .*cut\\.mkv: .*after [0-9]+ (complete )?frames")))
        << command << "\n"
        << run.output;
}

nlohmann::json readJson(const fs::path& path) {
    std::ifstream in(path);
    return nlohmann::json::parse(in, nullptr, false);
}

TEST(SilentCli, ACutOffRecordingIsSaidByRunRenderTrackAndDemoWithExitCode5) {
    const fs::path dir = test::tempDir();
    const fs::path cut = cutSession(dir, 0.3);

    const CliRun run = mixray("run " + q(cut) + " --scene " +
                              q(test::fixturesDir() / "scenes" / "sim_tabletop_demo.yaml") +
                              " --pace fast --max-depth 0 -o " + q(dir / "run"));
    expectSaysTheCut("run", run);
    EXPECT_NE(run.output.find(" composites ("), std::string::npos) << run.output;
    const auto summary = readJson(dir / "run" / "summary.json");
    ASSERT_FALSE(summary.is_discarded()) << run.output;
    EXPECT_FALSE(summary["input"]["complete"].get<bool>());
    EXPECT_NE(summary["input"]["damage"].get<std::string>().find("cut.mkv"), std::string::npos);
    EXPECT_GT(summary["composites"]["published"].get<int>(), 0);
    EXPECT_LT(summary["composites"]["published"].get<int>(), 36);

    const CliRun render = mixray(
        "render " + q(cut) + " --scene " + q(test::fixturesDir() / "scenes" / "sim_tabletop.yaml") +
        " --shadows hard --max-depth 0 --depth-rays none -o " + q(dir / "render.mkv"));
    expectSaysTheCut("render", render);
    EXPECT_NE(render.output.find("frames composited"), std::string::npos) << render.output;
    EXPECT_TRUE(fs::exists(dir / "render.mkv"));

    const CliRun track = mixray("track " + q(cut) + " -o " + q(dir / "track"));
    expectSaysTheCut("track", track);
    const auto tracked = readJson(dir / "track" / "track.json");
    ASSERT_FALSE(tracked.is_discarded()) << track.output;
    EXPECT_FALSE(tracked["input"]["complete"].get<bool>());
    EXPECT_GT(tracked["frames"].size(), 0u);

    const fs::path real_scene = test::fixturesDir() / "sessions" / "sim_tabletop.scene.yaml";
    const CliRun demo = mixray("demo --session " + q(cut) + " --real-scene " + q(real_scene) +
                               " --no-truth --samples 1 --png-every 100 -o " + q(dir / "demo"));
    expectSaysTheCut("demo", demo);
    const auto demo_summary = readJson(dir / "demo" / "summary.json");
    ASSERT_FALSE(demo_summary.is_discarded()) << demo.output;
    EXPECT_FALSE(demo_summary["pipeline"]["input"]["complete"].get<bool>());

    // The whole file is no damage: the same commands exit 0 on it (play, quickest, stands in).
    const CliRun whole = mixray("play --fast " + q(kSession));
    EXPECT_EQ(whole.exit_code, 0) << whole.output;
    EXPECT_EQ(whole.output.find("input incomplete"), std::string::npos) << whole.output;
}

// A colour frame its driver marked corrupt is never composited (virtual objects over a broken
// image would be a wrong picture), and that is said: the message, summary.json and exit 5.
TEST(SilentCli, ACorruptColourFrameIsNotCompositedAndIsSaidWithExitCode5) {
    const fs::path dir = test::tempDir();
    const fs::path input = dir / "corrupt_frame.mkv";
    test::copyRecordingEditing(kSession, input,
                               [](const std::string& stream, int n, WritableFrame& frame) {
                                   if (stream == "kinect/color" && n == 12)
                                       frame.meta().status = FrameStatus::kCorrupt;
                               });
    ASSERT_FALSE(HasFailure());
    const CliRun run = mixray("run " + q(input) + " --scene " +
                              q(test::fixturesDir() / "scenes" / "sim_tabletop_demo.yaml") +
                              " --pace fast --max-depth 0 -o " + q(dir / "run"));
    EXPECT_EQ(run.exit_code, kExitIncomplete) << run.output;
    EXPECT_NE(run.output.find(
                  "mixray run: 1 colour frame marked corrupt by its driver was not composited"),
              std::string::npos)
        << run.output;
    const auto summary = readJson(dir / "run" / "summary.json");
    ASSERT_FALSE(summary.is_discarded()) << run.output;
    EXPECT_EQ(summary["composites"]["published"].get<int>(), 35);
}

TEST(SilentCli, PlayAndConvertOfACutOffRecordingKeepWhatWasReadAndSaySo) {
    const fs::path dir = test::tempDir();
    const fs::path cut = cutSession(dir, 0.5);

    const CliRun play = mixray("play --fast " + q(cut));
    expectSaysTheCut("play", play);
    EXPECT_NE(play.output.find("played "), std::string::npos) << play.output;

    const CliRun convert = mixray("convert " + q(cut) + " " + q(dir / "copy.mkv"));
    expectSaysTheCut("convert", convert);
    EXPECT_NE(convert.output.find("copy.mkv is partial"), std::string::npos) << convert.output;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(convert.output, m, std::regex("([0-9]+) of ([0-9]+) frames")))
        << convert.output;
    const int written = std::stoi(m[1]);
    EXPECT_GT(written, 0);
    // What was read is a finished recording of its own.
    const CliRun info = mixray("info --json " + q(dir / "copy.mkv"));
    ASSERT_EQ(info.exit_code, 0) << info.output;
    EXPECT_EQ(nlohmann::json::parse(info.output)["frames"].get<int>(), written);
}

// demo.yaml's objects sit on marker 0; the session's tracking knows marker 23 only.
TEST(SilentCli, AnObjectNeverDrawnIsNamedInTheMessageAndTheSummary) {
    const fs::path dir = test::tempDir();
    const CliRun run = mixray("run " + q(kSession) + " --scene " +
                              q(test::fixturesDir() / "scenes" / "demo.yaml") +
                              " --pace fast --max-depth 0 -o " + q(dir));
    // Not an error: the output is what was asked for; the warning says what it lacks.
    EXPECT_EQ(run.exit_code, 0) << run.output;
    const std::string teapot =
        "object 'teapot' (anchor marker:0) was never drawn: marker 0 had no pose in any of 36 "
        "composites";
    EXPECT_NE(run.output.find("mixray run: " + teapot), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("object 'ball' (anchor marker:0) was never drawn"), std::string::npos)
        << run.output;
    const auto summary = readJson(dir / "summary.json");
    ASSERT_FALSE(summary.is_discarded()) << run.output;
    bool said = false;
    for (const auto& message : summary["messages"])
        said = said || message.get<std::string>() == teapot;
    EXPECT_TRUE(said) << summary.dump(1);
    for (const auto& object : summary["objects"])
        EXPECT_EQ(object["drawn"], 0) << object.dump();
    EXPECT_TRUE(summary["input"]["complete"].get<bool>());
}

// Starts `args`, sends SIGTERM once mixray catches it, and returns how it ended.
CliRun terminated(const std::vector<std::string>& args, const fs::path& log) {
    const test::CliProcess process = test::startMixray(args, log);
    EXPECT_GT(process.pid, 0);
    EXPECT_TRUE(test::waitUntilCatching(process.pid, SIGTERM)) << test::readText(log);
    kill(process.pid, SIGTERM);
    return test::waitMixray(process);
}

TEST(SilentCli, SigtermExits143FromPlayTrackAndConvert) {
    const fs::path dir = test::tempDir();
    const CliRun play = terminated({"play", "--loop", kSession.string()}, dir / "play.log");
    EXPECT_EQ(play.exit_code, 143) << play.output;
    EXPECT_NE(play.output.find("mixray play: stopped by SIGTERM"), std::string::npos)
        << play.output;

    const CliRun track =
        terminated({"track", kSession.string(), "-o", (dir / "track").string()}, dir / "track.log");
    EXPECT_EQ(track.exit_code, 143) << track.output;
    EXPECT_NE(track.output.find("mixray track: stopped by SIGTERM"), std::string::npos)
        << track.output;

    // ASCII point clouds, one per depth frame: seconds of work to stop.
    const CliRun convert =
        terminated({"convert", kSession.string(), (dir / "clouds").string(), "--to", "pcd",
                    "--pcd-data", "ascii", "--intrinsics", "524.8,525.4,318.6,241.9"},
                   dir / "convert.log");
    EXPECT_EQ(convert.exit_code, 143) << convert.output;
    EXPECT_NE(convert.output.find("mixray convert: stopped by SIGTERM"), std::string::npos)
        << convert.output;
}

TEST(SilentCli, SimulateStoppedBeforeItsFirstFrameLeavesNoRecordingAndSaysSo) {
    const fs::path dir = test::tempDir();
    const fs::path out = dir / "s.mkv";
    // 16 samples per pixel at 640x480: seconds for the first frame, which the signal drops.
    const CliRun run = terminated(
        {"simulate", "--frames", "5", "--samples", "16", "--threads", "2", "-o", out.string()},
        dir / "simulate.log");
    EXPECT_EQ(run.exit_code, 143) << run.output;
    EXPECT_NE(run.output.find("mixray simulate: stopped by SIGTERM before the first of 5 frames; "
                              "no recording written"),
              std::string::npos)
        << run.output;
    EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace mixray
