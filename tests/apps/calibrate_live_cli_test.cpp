// mixray calibrate --live on a rig whose device replays the simulated calibration session at
// its own pace: the session ends with the devices (or Ctrl-C), prints what was kept and what is
// missing, records the kept views, and `mixray calibrate` solves that recording offline.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cstdio>
#include <map>
#include <regex>
#include <set>
#include <thread>

#include "cli_runner.h"
#include "headless_chromium.h"
#include "mixray/calibration/calibration_file.h"
#include "mixray/calibration/detect.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;
using test::mixray;
using test::q;

const char* const kTarget = "charuco:7x5:0.05:0.037:DICT_6X6_250";

// A rig of one device: the replay backend playing the session as its rig recorded it.
fs::path writeRig(const fs::path& dir, bool loop = false) {
    const fs::path rig = dir / "sim_calibration_rig.yaml";
    test::writeText(rig,
                    "version: 1\nrig: sim-calibration\ndevices:\n  - name: session\n"
                    "    driver: replay\n    id: \"" +
                        (test::fixturesDir() / "sessions" / "sim_calibration.mkv").string() +
                        "\"\n    options: {pace: original, names: recorded, stamps: "
                        "arrival, loop: " +
                        (loop ? "true" : "false") + "}\n");
    return rig;
}

TEST(CalibrateLiveCli, WholeSessionIsRecordedAndSolvesOffline) {
    const fs::path dir = test::tempDir();
    const fs::path rig = writeRig(dir);
    const fs::path record = dir / "kept.mkv";
    const test::CliRun live = mixray("calibrate --live " + q(rig) + " --target " + kTarget +
                                     " --record " + q(record) + " -o " + q(dir / "live"));
    std::printf("%s", live.output.c_str());
    ASSERT_EQ(live.exit_code, 0) << live.output;
    EXPECT_NE(live.output.find("session stopped by the end of the devices' streams"),
              std::string::npos);
    EXPECT_NE(live.output.find("kinect/color: "), std::string::npos);
    EXPECT_NE(live.output.find("views seen by both"), std::string::npos);
    EXPECT_NE(live.output.find("env/color: "), std::string::npos);
    EXPECT_NE(live.output.find("rejected (no target"), std::string::npos) << live.output;

    // The recording: the kept views of every camera with the depth at their instants.
    auto found = calibration::detectInRecording(record, calibration::parseTarget(kTarget).value());
    ASSERT_TRUE(found) << found.status().toString();
    std::map<std::string, size_t> usable;
    for (const calibration::CameraViews& c : found->cameras)
        usable[c.camera] = c.usable().size();
    // How many views a session at the recording's own pace keeps depends on how many frames the
    // machine got through (14 under ASan on two cores, 17 without): a dozen calibrate a camera.
    EXPECT_GE(usable["kinect/color"], 12u);
    EXPECT_GE(usable["kinect/ir"], 12u);
    EXPECT_GE(usable["env/color"], 3u);
    EXPECT_EQ(found->depth.size(), 1u);

    // The offline solve of what the session kept, as the session's last line says.
    const test::CliRun offline =
        mixray("calibrate " + q(record) + " --target " + kTarget +
               " --model env/color=fisheye --marker DICT_6X6_250:23:0.1 -o " + q(dir / "solve"));
    std::printf("%s", offline.output.c_str());
    ASSERT_EQ(offline.exit_code, 0) << offline.output;
    auto file = calibration::readCalibrationFile(dir / "solve" / "calibration.yaml");
    ASSERT_TRUE(file) << file.status().toString();
    std::set<std::string> names;
    for (const auto& c : file->cameras)
        names.insert(c.name);
    EXPECT_TRUE(names.count("kinect/color"));
    EXPECT_TRUE(names.count("kinect/ir"));
    EXPECT_TRUE(names.count("env/color"));
}

TEST(CalibrateLiveCli, CtrlCEndsTheSessionRecordsAndSolves) {
    const fs::path dir = test::tempDir();
    const fs::path rig = writeRig(dir);
    const test::CliProcess p = test::startMixray(
        {"calibrate", "--live", rig.string(), "--target", kTarget, "--view", "127.0.0.1:0",
         "--solve", "--camera", "kinect/color", "-o", (dir / "out").string()},
        dir / "output.txt");
    ASSERT_GT(p.pid, 0);
    // Until the session kept a few views of the camera to solve (a slow machine, or a sanitizer
    // build, takes longer to get there), then Ctrl-C.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(90);
    const std::regex kept(R"(kinect/color ([0-9]+) kept)");
    while (std::chrono::steady_clock::now() < deadline) {
        const std::string text = test::readText(dir / "output.txt");
        int most = 0;
        for (auto it = std::sregex_iterator(text.begin(), text.end(), kept);
             it != std::sregex_iterator(); ++it)
            most = std::max(most, std::stoi((*it)[1]));
        if (most >= 6)
            break;
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    kill(p.pid, SIGINT);
    const test::CliRun run = test::waitMixray(p);
    std::printf("%s", run.output.c_str());
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("live view at http://127.0.0.1:"), std::string::npos);
    EXPECT_NE(run.output.find("session stopped by SIGINT"), std::string::npos);
    EXPECT_NE(run.output.find("missing: "), std::string::npos) << "a 6 s session lacks views";
    EXPECT_TRUE(fs::exists(dir / "out" / "live_session.mkv"));
    EXPECT_NE(run.output.find("solving "), std::string::npos);
    EXPECT_TRUE(fs::exists(dir / "out" / "calibration.yaml")) << run.output;
}

TEST(CalibrateLiveCli, LiveTakesOneRigFile) {
    const fs::path dir = test::tempDir();
    const test::CliRun run =
        mixray("calibrate --live " + q(test::fixturesDir() / "sessions" / "sim_calibration.mkv") +
               " --target " + kTarget + " -o " + q(dir));
    EXPECT_EQ(run.exit_code, 2) << run.output;
    EXPECT_NE(run.output.find("--live takes one rig file"), std::string::npos) << run.output;
    const test::CliRun missing =
        mixray("calibrate --live " + q(dir / "absent.yaml") + " --target " + kTarget);
    EXPECT_EQ(missing.exit_code, 3) << missing.output;
    EXPECT_NE(missing.output.find("absent.yaml"), std::string::npos) << missing.output;
}

// The session's view in a real browser: each camera's tile with the detected board drawn over
// it, a coverage tile per camera whose picture changes as views are kept, and what is missing
// among the figures.
TEST(CalibrateLiveCli, ViewShowsCoverageTilesOverlaysAndWhatIsMissing) {
    if (test::chromiumPath().empty()) {
        GTEST_SKIP() << "chromium is not installed (apt-get install chromium); the page is not "
                        "checked in a browser";
    }
    const fs::path dir = test::tempDir();
    const fs::path rig = writeRig(dir, true);
    const test::CliProcess p =
        test::startMixray({"calibrate", "--live", rig.string(), "--target", kTarget, "--view",
                           "127.0.0.1:0", "--duration", "60", "-o", (dir / "out").string()},
                          dir / "output.txt");
    ASSERT_GT(p.pid, 0);
    std::string url;
    for (int i = 0; i < 200 && url.empty(); ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        const std::string text = test::readText(p.output);
        const size_t at = text.find("live view at ");
        const size_t end = text.find('\n', at);
        if (at != std::string::npos && end != std::string::npos)
            url = text.substr(at + 13, end - at - 13);
    }
    ASSERT_FALSE(url.empty()) << test::readText(p.output);
    test::ChromiumOptions chrome;
    chrome.timeout = std::chrono::seconds(40);
    chrome.until_js =
        "(() => { const c = document.querySelector('.tile[data-stream=\"coverage/kinect/color\"]');"
        " const k = document.querySelector('.tile[data-stream=\"kinect/color\"]');"
        " const m = document.getElementById('messages');"
        " return !!c && Number(c.dataset.distinct) >= 3 && !!k && Number(k.dataset.overlays) >= 1"
        " && !!m && m.textContent.includes('missing: '); })()";
    chrome.result_js =
        "JSON.stringify({tiles: [...document.querySelectorAll('.tile')].map(t => ({stream: "
        "t.dataset.stream, distinct: Number(t.dataset.distinct), overlays: "
        "Number(t.dataset.overlays)})), messages: (document.getElementById('messages') || "
        "{}).textContent})";
    chrome.screenshot = dir / "calibrate_live_view.png";
    const test::ChromiumRun run = test::runHeadlessChromium(url, chrome);
    kill(p.pid, SIGINT);
    const test::CliRun done = test::waitMixray(p);
    ASSERT_TRUE(run.started) << run.error;
    std::printf("page: %s\nscreenshot: %s\n", run.result.c_str(), chrome.screenshot.c_str());
    EXPECT_TRUE(run.until_met) << run.result << "\n" << run.error;
    EXPECT_NE(run.result.find("coverage/env/color"), std::string::npos);
    EXPECT_NE(run.result.find("coverage/kinect/ir"), std::string::npos);
    EXPECT_EQ(done.exit_code, 0) << done.output;
}

}  // namespace
}  // namespace mixray
