// A rig across three hosts, made of network namespaces joined by veth pairs: hosts A and B run
// `mixray publish` with their clocks offset on purpose (time namespaces), host C runs
// `mixray record` of a rig whose devices are theirs. Every frame arrives, bit-exact, in one
// recording; frames of the two hosts are matched into sets on C's time base. And what
// `mixray publish --ros2` tells ROS 2 of a calibrated rig.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "cli_runner.h"
#include "gv_simulator.h"
#include "mixray/graph/mkv.h"
#include "network_namespaces.h"

namespace mixray::test {
namespace {

using hosts::linkNamespaces;
using hosts::shell;

// `publish --ros2` finds each image stream's calibration in the files the rig names and says
// what goes to camera_info and tf_static (tests/dds/ros2_interop_test.cpp checks what a second
// DDS receives); a calibration of another size, or --calibration without --ros2, is refused.
TEST(PublishToRos2, SaysWhichCameraInfoAndTransformsItPublishes) {
    const auto dir = tempDir();
    const auto calibration = [](int width, int height) {
        const std::string size =
            "width: " + std::to_string(width) + ", height: " + std::to_string(height);
        return "version: 1\ncameras:\n"
               "  - name: rgbd/color\n"
               "    model: {lens: pinhole, " +
               size +
               ", fx: 262.4, fy: 262.7, cx: 159.3, cy: 120.9,\n"
               "            distortion: [0.045, -0.11, 6.0e-04, -4.0e-04]}\n"
               "    parent: world\n"
               "    T_parent_camera: {translation: [0.1, 0, 0.5], quaternion: [1, 0, 0, 0]}\n"
               "  - name: env/color\n"
               "    model: {lens: fisheye, width: 480, height: 480, fx: 140, fy: 140, cx: 239.2,"
               " cy: 240.3, distortion: [0.02, -0.005, 0.001, -2.0e-04]}\n"
               "    parent: rgbd/color\n"
               "    T_parent_camera: {translation: [-0.3, 0.28, 0.12], quaternion: [1, 0, 0, 0]}\n";
    };
    writeText(dir / "calibration.yaml", calibration(320, 240));
    writeText(dir / "wrong_size.yaml", calibration(640, 480));
    writeText(dir / "rig.yaml",
              "rig: studio\ndevices:\n"
              "  - name: rgbd\n    driver: pattern\n    id: rgbd\n    streams: [color, depth]\n"
              "    calibration: calibration.yaml\n"
              "    options: {color.width: 320, color.height: 240, depth.width: 320,"
              " depth.height: 240, fps: 30, frames: 10}\n");
    const std::string publish = "publish " + q(dir / "rig.yaml") + " --domain " +
                                std::to_string(1 + getpid() % 200) + " --duration 3";

    const CliRun ros2 = mixray(publish + " --ros2 studio");
    ASSERT_EQ(ros2.exit_code, 0) << ros2.output;
    EXPECT_NE(ros2.output.find("ROS 2 camera_info of rgbd/color: 320x240, plumb_bob"),
              std::string::npos)
        << ros2.output;
    EXPECT_EQ(ros2.output.find("camera_info of rgbd/depth"), std::string::npos)
        << "the depth stream has no camera of its name in the file\n"
        << ros2.output;
    EXPECT_NE(ros2.output.find("ROS 2 tf_static: 2 transforms (rgbd/color in world, env/color in "
                               "rgbd/color)"),
              std::string::npos)
        << ros2.output;

    const CliRun wrong =
        mixray(publish + " --ros2 studio --calibration " + q(dir / "wrong_size.yaml"));
    EXPECT_NE(wrong.exit_code, 0);
    EXPECT_NE(wrong.output.find("640x480 images and the stream's are 320x240"), std::string::npos)
        << wrong.output;

    const CliRun no_ros2 = mixray(publish + " --calibration " + q(dir / "calibration.yaml"));
    EXPECT_NE(no_ros2.exit_code, 0);
    EXPECT_NE(no_ros2.output.find("add --ros2"), std::string::npos) << no_ros2.output;
}

// The composite is a stream like any other: `mixray run --publish` puts it (and the poses, as
// mixray frames: no ROS 2 here) on DDS, and another mixray reads it as a device and records it.
TEST(RunPublish, AnotherHostRecordsTheComposite) {
    const auto dir = tempDir();
    const std::string domain = std::to_string(1 + getpid() % 200);
    writeText(dir / "viewer.yaml",
              "rig: viewer\ndevices:\n  - name: remote\n    driver: dds\n"
              "    id: renderer/composite\n    options: {domain: " +
                  domain + ", discovery_timeout_ms: 20000}\n");
    CliProcess run =
        startMixray({"run", (fixturesDir() / "sessions/sim_tabletop.mkv").string(), "--scene",
                     (fixturesDir() / "scenes/sim_tabletop_demo.yaml").string(), "--max-depth", "0",
                     "--loop", "--duration", "8", "--publish", "--host", "renderer", "--domain",
                     domain, "-o", (dir / "run").string()},
                    dir / "run.log");
    const CliRun recorded = mixray("record " + q(dir / "viewer.yaml") + " -o " +
                                   q(dir / "composite.mkv") + " --duration 4");
    const CliRun ran = waitMixray(run);
    ASSERT_EQ(ran.exit_code, 0) << ran.output;
    EXPECT_NE(ran.output.find("publishing composite/color, tracking/pose over DDS as host "
                              "'renderer'"),
              std::string::npos)
        << ran.output;
    ASSERT_EQ(recorded.exit_code, 0) << recorded.output << "\n" << ran.output;
    const CliRun info = mixray("info " + q(dir / "composite.mkv"));
    ASSERT_EQ(info.exit_code, 0) << info.output;
    const size_t at = info.output.find("remote/color");
    ASSERT_NE(at, std::string::npos) << info.output;
    const std::string line = info.output.substr(at, info.output.find('\n', at) - at);
    EXPECT_NE(line.find("rgb8 640x480"), std::string::npos) << line;
    const size_t frames = line.find(" frames");
    ASSERT_NE(frames, std::string::npos) << line;
    const size_t start = line.rfind(' ', frames - 1);
    // About 25 composites a second reach the recorder in the release build, 3 under the
    // sanitizers.
    EXPECT_GE(std::stoi(line.substr(start + 1, frames - start - 1)), 3) << line;
}

// Three namespaces: a and b each joined to c by a veth pair. Deleted with the fixture.
class Hosts : public ::testing::Test {
protected:
    void SetUp() override {
        if (geteuid() != 0)
            GTEST_SKIP() << "needs root to make network namespaces (CI runs as root)";
        const std::string id = std::to_string(getpid() % 100000);
        a_ = "mxa" + id;
        b_ = "mxb" + id;
        c_ = "mxc" + id;
        // A /24 per test process, so parallel runs never share addresses.
        net_ = "10." + std::to_string(100 + getpid() % 100) + ".";
        for (const std::string& ns : {a_, b_, c_}) {
            if (shell("ip netns add " + ns) != 0)
                GTEST_SKIP() << "ip netns add failed: no network namespaces here";
            made_.push_back(ns);
            ASSERT_EQ(shell("ip -n " + ns + " link set lo up"), 0);
        }
        id_ = id;
        linkA();
        link(b_, net_ + "2.2", net_ + "2.1", "vb" + id, "vcb" + id);
        if (shell("unshare --time --monotonic 1 true") != 0)
            GTEST_SKIP() << "unshare --time failed: no time namespaces here";
    }

    // Host A's link to C, made again after A was torn down.
    void linkA() { link(a_, net_ + "1.2", net_ + "1.1", "va" + id_, "vca" + id_); }

    // Tears host A down: its namespace, and with it both ends of its link to C.
    void tearDownA() {
        shell("ip netns del " + a_);
        // The namespace goes when its last process has; C's end of the link goes with it.
        for (int i = 0; i < 100 && shell("ip -n " + c_ + " link show vca" + id_) == 0; ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }

    void bringBackA() {
        ASSERT_EQ(shell("ip netns add " + a_), 0);
        ASSERT_EQ(shell("ip -n " + a_ + " link set lo up"), 0);
        linkA();
    }

    void TearDown() override {
        for (const std::string& ns : made_)
            shell("ip netns del " + ns);
    }

    void link(const std::string& ns, const std::string& address, const std::string& c_address,
              const std::string& name, const std::string& c_name) {
        ASSERT_TRUE(linkNamespaces({.ns = ns, .name = name, .address = address},
                                   {.ns = c_, .name = c_name, .address = c_address}))
            << ns << " to " << c_;
    }

    // `mixray args` in namespace `ns`, its CLOCK_MONOTONIC `offset_s` ahead of the others'.
    CliProcess startIn(const std::string& ns, int offset_s, const std::vector<std::string>& args,
                       const std::filesystem::path& output) {
        std::vector<std::string> argv{"ip",
                                      "netns",
                                      "exec",
                                      ns,
                                      "unshare",
                                      "--time",
                                      "--monotonic",
                                      std::to_string(offset_s),
                                      cliPath().string()};
        argv.insert(argv.end(), args.begin(), args.end());
        std::vector<char*> c_argv;
        for (std::string& a : argv)
            c_argv.push_back(a.data());
        c_argv.push_back(nullptr);
        const std::string out = output.string();
        CliProcess process{-1, output};
        process.pid = fork();
        if (process.pid == 0) {
            const int fd = open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
            if (fd < 0 || dup2(fd, STDOUT_FILENO) < 0 || dup2(fd, STDERR_FILENO) < 0)
                _exit(127);
            execvp("ip", c_argv.data());
            _exit(127);
        }
        return process;
    }

    std::string a_, b_, c_, net_, id_;
    std::vector<std::string> made_;
};

// Every frame of a recording by stream name and sequence: its payload.
std::map<std::pair<std::string, uint64_t>, std::vector<uint8_t>> framesOf(
    const std::filesystem::path& path) {
    std::map<std::pair<std::string, uint64_t>, std::vector<uint8_t>> out;
    auto reader = openMkv(path);
    EXPECT_TRUE(reader.isOk()) << reader.status().toString();
    if (!reader.isOk())
        return out;
    for (;;) {
        auto frame = (*reader)->next();
        if (!frame.isOk())
            break;
        const ImageView image = frame->image();
        const std::string& stream = (*reader)->streams()[frame->meta().stream].name;
        out[{stream, frame->meta().sequence}].assign(image.data, image.data + image.size_bytes);
    }
    return out;
}

TEST_F(Hosts, ARecordingOnOneHostHoldsEveryFrameOfDevicesOnTwoOthers) {
    const auto dir = tempDir();
    // Host A: an RGB-D pattern device stamped by A's clock; host B: a mono device with its
    // own drifting clock. Both real time, finite.
    const std::string pattern_a =
        "  - name: rgbd\n    driver: pattern\n    id: rgbd\n    streams: [color, depth]\n"
        "    options: {color.width: 320, color.height: 240, depth.width: 320, depth.height: 240,"
        " fps: 30, frames: 60, realtime: REALTIME}\n";
    const std::string pattern_b =
        "  - name: mono\n    driver: pattern\n    id: mono\n"
        "    options: {mono.width: 640, mono.height: 480, fps: 15, frames: 30, realtime: REALTIME,"
        " drift_ppm: 100, phase_us: 4000}\n";
    auto realtime = [](std::string text, const char* value) {
        return text.replace(text.find("REALTIME"), 8, value);
    };
    writeText(dir / "a.yaml", "rig: host-a\ndevices:\n" + realtime(pattern_a, "true"));
    writeText(dir / "b.yaml", "rig: host-b\ndevices:\n" + realtime(pattern_b, "true"));
    // The same devices in this process, as fast as they go: the frames to compare with.
    writeText(dir / "reference.yaml", "rig: reference\ndevices:\n" + realtime(pattern_a, "false") +
                                          realtime(pattern_b, "false"));
    const CliRun reference =
        mixray("record " + q(dir / "reference.yaml") + " -o " + q(dir / "reference.mkv"));
    ASSERT_EQ(reference.exit_code, 0) << reference.output;

    const std::string domain = std::to_string(1 + getpid() % 200);
    auto device = [&](const char* name, const char* id, const std::string& c_address,
                      const std::string& peer, const char* clock) {
        return std::string("  - name: ") + name + "\n    driver: dds\n    id: " + id +
               "\n    options: {domain: " + domain + ", address: " + c_address +
               ", peers: " + peer +
               ", transport: udp, discovery_timeout_ms: 20000, clock: " + clock + "}\n";
    };
    // A's clock by the exchanges alone; B's through the wall clocks, which time namespaces
    // leave shared, so in step as PTP would hold them.
    writeText(dir / "c.yaml",
              "rig: host-c\ndevices:\n" +
                  device("left", "hostA/rgbd", net_ + "1.1", net_ + "1.2", "exchange") +
                  device("right", "hostB/mono", net_ + "2.1", net_ + "2.2", "wall") +
                  "sync:\n  streams: [left/color, left/depth, right/mono]\n"
                  "  max_skew_ms: 40\n");
    auto publish = [&](const std::string& host, const std::string& address,
                       const std::string& peer) {
        return std::vector<std::string>{
            "publish",        (dir / (host + ".yaml")).string(),
            "--host",         "host" + std::string(1, std::toupper(host[0])),
            "--domain",       domain,
            "--address",      address,
            "--peers",        peer,
            "--transport",    "udp",
            "--wait-readers", "1"};
    };
    // Clocks 1000 s and 2000 s ahead of C's: only a mapping makes their frames meet. C's
    // clock is this process's.
    const auto monotonic_ns = [] {
        return std::chrono::duration_cast<std::chrono::nanoseconds>(
                   std::chrono::steady_clock::now().time_since_epoch())
            .count();
    };
    const int64_t t_begin = monotonic_ns();
    CliProcess a = startIn(a_, 1000, publish("a", net_ + "1.2", net_ + "1.1"), dir / "a.log");
    CliProcess b = startIn(b_, 2000, publish("b", net_ + "2.2", net_ + "2.1"), dir / "b.log");
    CliProcess c =
        startIn(c_, 0, {"record", (dir / "c.yaml").string(), "-o", (dir / "c.mkv").string()},
                dir / "c.log");
    const CliRun recorded = waitMixray(c);
    const CliRun published_a = waitMixray(a);
    const CliRun published_b = waitMixray(b);
    const int64_t t_end = monotonic_ns();
    ASSERT_EQ(recorded.exit_code, 0) << recorded.output;
    ASSERT_EQ(published_a.exit_code, 0) << published_a.output;
    ASSERT_EQ(published_b.exit_code, 0) << published_b.output;
    EXPECT_NE(recorded.output.find("the rig's streams ended"), std::string::npos)
        << recorded.output;

    // C measured each host's clock over DDS, and said so: A's from the exchanges, within the
    // network's reach; B's from the wall clocks, to the microsecond or so that reading two
    // clocks back to back costs.
    for (const auto& [name, host, ahead_s, within_s] :
         {std::tuple{"left", "hostA", 1000.0, 0.002},
          std::tuple{"right", "hostB", 2000.0, 50e-6}}) {
        const std::string said = std::string("  ") + name + ": " + host + " clock ";
        const size_t at = recorded.output.find(said);
        ASSERT_NE(at, std::string::npos) << recorded.output;
        const std::string line = recorded.output.substr(at, recorded.output.find('\n', at) - at);
        RecordProperty(std::string(name) + "_clock", line);
        EXPECT_NEAR(std::stod(recorded.output.substr(at + said.size())), ahead_s, within_s) << line;
        EXPECT_EQ(line.find("from the wall clocks (clock: wall)") != std::string::npos,
                  std::string(host) == "hostB")
            << line;
    }
    // A's frames, stamped on arrival by A's clock, reach the recording on C's: inside the run,
    // not 1000 s on. (The pattern device's own clock stays its own.)
    {
        auto reader = openMkv(dir / "c.mkv");
        ASSERT_TRUE(reader.isOk()) << reader.status().toString();
        size_t checked = 0;
        for (auto frame = (*reader)->next(); frame.isOk(); frame = (*reader)->next()) {
            const FrameMetadata& meta = frame->meta();
            if ((*reader)->streams()[meta.stream].name != "left/color")
                continue;
            EXPECT_NE(meta.clock_domain, kHostClockDomain);
            EXPECT_GT(meta.host_stamp_ns, t_begin);
            EXPECT_LT(meta.host_stamp_ns, t_end);
            ++checked;
        }
        EXPECT_EQ(checked, 60u);
    }

    const auto expected = framesOf(dir / "reference.mkv");
    const auto got = framesOf(dir / "c.mkv");
    ASSERT_EQ(expected.size(), 150u);
    EXPECT_EQ(got.size(), expected.size()) << "every frame arrives\n" << recorded.output;
    const std::map<std::string, std::string> renamed{
        {"left/color", "rgbd/color"}, {"left/depth", "rgbd/depth"}, {"right/mono", "mono/mono"}};
    size_t identical = 0;
    for (const auto& [key, payload] : got) {
        const auto found = expected.find({renamed.at(key.first), key.second});
        ASSERT_NE(found, expected.end()) << key.first << " " << key.second;
        identical += found->second == payload;
    }
    EXPECT_EQ(identical, got.size()) << "bit-exact across hosts";

    // Sets across hosts on C's time base: the synchroniser reports them in the status line.
    const size_t sets = recorded.output.rfind("sync ");
    ASSERT_NE(sets, std::string::npos) << recorded.output;
    EXPECT_GT(std::stoul(recorded.output.substr(sets + 5)), 10u) << recorded.output;
}

// `mixray run` with the renderer on host C and the Kinect on host A, whose clock is 1000 s
// ahead: A publishes the bundled session's Kinect as its live device would (replayed at its
// pace, stamped as it goes), C tracks the marker in it, renders the virtual objects into it and
// records the composite. The latency from capture to composite is measured on C's clock from
// A's stamps mapped onto it.
TEST_F(Hosts, RunRendersOnOneHostTheKinectStreamOfAnother) {
    const auto dir = tempDir();
    const std::string domain = std::to_string(1 + getpid() % 200);
    writeText(dir / "kinect-host.yaml",
              "rig: kinect-host\ndevices:\n  - name: session\n    driver: replay\n    id: " +
                  (fixturesDir() / "sessions/sim_tabletop.mkv").string() +
                  "\n    options: {names: recorded, pace: original, stamps: arrival}\n");
    writeText(dir / "renderer.yaml",
              "rig: renderer\ndevices:\n  - name: kinect\n    driver: dds\n    id: hostA/kinect\n"
              "    options: {domain: " +
                  domain + ", address: " + net_ + "1.1, peers: " + net_ +
                  "1.2, transport: udp, discovery_timeout_ms: 20000}\n");
    CliProcess a =
        startIn(a_, 1000,
                {"publish", (dir / "kinect-host.yaml").string(), "--host", "hostA", "--domain",
                 domain, "--address", net_ + "1.2", "--peers", net_ + "1.1", "--transport", "udp",
                 "--streams", "kinect/color,kinect/depth", "--wait-readers", "1"},
                dir / "a.log");
    CliProcess c =
        startIn(c_, 0,
                {"run", (dir / "renderer.yaml").string(), "--scene",
                 (fixturesDir() / "scenes/sim_tabletop_demo.yaml").string(), "--setup",
                 (fixturesDir() / "sessions/sim_tabletop.tracking.yaml").string(), "--max-depth",
                 "0", "-o", (dir / "out").string(), "--record", (dir / "out/run.mkv").string()},
                dir / "c.log");
    const CliRun ran = waitMixray(c);
    const CliRun published = waitMixray(a);
    ASSERT_EQ(ran.exit_code, 0) << ran.output << "\n" << published.output;
    ASSERT_EQ(published.exit_code, 0) << published.output;

    std::ifstream in(dir / "out/summary.json");
    const auto summary = nlohmann::json::parse(in, nullptr, false);
    ASSERT_FALSE(summary.is_discarded()) << ran.output;
    EXPECT_EQ(summary["stopped_by"], "the end of the source") << summary.dump();
    // The compositor keeps pace by skipping frames it cannot render in time (many under the
    // sanitizers), never by falling behind.
    EXPECT_GT(summary["composites"]["published"].get<int>(), 0) << summary.dump();
    EXPECT_LE(summary["composites"]["published"].get<int>(), 36);
    // Capture to composite on C's clock: milliseconds, not the 1000 s between the clocks.
    EXPECT_LT(summary["latency_ms"]["p99"].get<double>(), 5000.0) << summary.dump();
    const std::string clock = summary["devices"][0]["clock"];
    RecordProperty("kinect_clock", clock);
    EXPECT_EQ(clock.rfind("hostA clock +1000.0", 0), 0u) << clock;

    const CliRun info = mixray("info " + q(dir / "out/run.mkv"));
    ASSERT_EQ(info.exit_code, 0) << info.output;
    for (const char* stream : {"kinect/color", "kinect/depth", "tracking/pose", "composite/color"})
        EXPECT_NE(info.output.find(stream), std::string::npos) << stream << "\n" << info.output;
}

// PTP cameras on two hosts share one time on the third. Hosts A and B each run Aravis's GigE
// Vision simulator described with IEEE 1588 (GevIEEE1588), opened with ptp: true and published;
// their monotonic clocks are 1000 s and 2000 s ahead of C's. The simulator stamps frames with
// the wall clock, which time namespaces leave shared: two cameras following one grandmaster.
// C records both: their streams arrive in the one PTP clock domain, and the two cameras' stamps
// stand in the same relation to C's clock, within a few milliseconds.
TEST_F(Hosts, PtpCamerasOnTwoHostsShareOneTimeOnTheThird) {
    if (!GvSimulator::installed())
        GTEST_SKIP() << "Aravis's simulator is not installed (aravis-tools)";
    const auto dir = tempDir();
    const std::string genicam = writeGenicam(genicamWithPtp(), "mixray_hosts_ptp.xml");
    ASSERT_FALSE(genicam.empty());
    GvSimulator camera_a, camera_b;
    ASSERT_TRUE(camera_a.start(0, genicam, a_));
    ASSERT_TRUE(camera_b.start(0, genicam, b_));
    // Each answers GVCP within a second or two on its host's loopback.
    for (const std::string& ns : {a_, b_}) {
        bool up = false;
        for (int i = 0; i < 50 && !up; ++i) {
            up = shell("ip netns exec " + ns + " ss -uln | grep -q ':3956 '") == 0;
            if (!up)
                std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
        ASSERT_TRUE(up) << "the simulator never listened in " << ns;
    }
    const std::string camera =
        "rig: HOST\ndevices:\n  - name: gv\n    driver: aravis\n    id: 127.0.0.1\n"
        "    mode:\n      mono: 256x128@20 mono8\n"
        "    options: {ptp: true, packet_size: 8000, buffers: 64}\n";
    auto named = [&](const std::string& host) {
        std::string text = camera;
        return text.replace(text.find("HOST"), 4, host);
    };
    writeText(dir / "a.yaml", named("host-a"));
    writeText(dir / "b.yaml", named("host-b"));
    const std::string domain = std::to_string(1 + getpid() % 200);
    auto device = [&](const char* name, const char* id, const std::string& c_address,
                      const std::string& peer) {
        return std::string("  - name: ") + name + "\n    driver: dds\n    id: " + id +
               "\n    options: {domain: " + domain + ", address: " + c_address +
               ", peers: " + peer + ", transport: udp, discovery_timeout_ms: 20000}\n";
    };
    writeText(dir / "c.yaml", "rig: host-c\ndevices:\n" +
                                  device("left", "hostA/gv", net_ + "1.1", net_ + "1.2") +
                                  device("right", "hostB/gv", net_ + "2.1", net_ + "2.2") +
                                  "sync:\n  streams: [left/mono, right/mono]\n  max_skew_ms: 30\n");
    auto publish = [&](const std::string& host, const std::string& address,
                       const std::string& peer) {
        return std::vector<std::string>{
            "publish",     (dir / (host + ".yaml")).string(),
            "--host",      "host" + std::string(1, std::toupper(host[0])),
            "--domain",    domain,
            "--address",   address,
            "--peers",     peer,
            "--transport", "udp",
            "--duration",  "8"};
    };
    CliProcess a = startIn(a_, 1000, publish("a", net_ + "1.2", net_ + "1.1"), dir / "a.log");
    CliProcess b = startIn(b_, 2000, publish("b", net_ + "2.2", net_ + "2.1"), dir / "b.log");
    CliProcess c = startIn(
        c_, 0,
        {"record", (dir / "c.yaml").string(), "-o", (dir / "c.mkv").string(), "--duration", "3"},
        dir / "c.log");
    const CliRun recorded = waitMixray(c);
    const CliRun published_a = waitMixray(a);
    const CliRun published_b = waitMixray(b);
    ASSERT_EQ(recorded.exit_code, 0) << recorded.output << published_a.output << published_b.output;
    ASSERT_EQ(published_a.exit_code, 0) << published_a.output;
    ASSERT_EQ(published_b.exit_code, 0) << published_b.output;

    auto reader = openMkv(dir / "c.mkv");
    ASSERT_TRUE(reader.isOk()) << reader.status().toString();
    constexpr ClockDomainId kPtpClockDomain = 0x50545031;  // aravis::kPtpClockDomain, "PTP1"
    for (const StreamInfo& s : (*reader)->streams())
        EXPECT_EQ(s.clock_domain, kPtpClockDomain) << s.name;
    // Camera stamp minus C's host stamp, per host: one time base gives one value (up to each
    // host's capture and network delay), where the hosts' own clocks are 1000 s apart.
    std::map<std::string, std::vector<int64_t>> offsets;
    for (auto frame = (*reader)->next(); frame.isOk(); frame = (*reader)->next()) {
        const FrameMetadata& meta = frame->meta();
        offsets[(*reader)->streams()[meta.stream].name].push_back(meta.device_stamp_ns -
                                                                  meta.host_stamp_ns);
    }
    ASSERT_GE(offsets["left/mono"].size(), 20u) << recorded.output;
    ASSERT_GE(offsets["right/mono"].size(), 20u) << recorded.output;
    const auto median = [](std::vector<int64_t> v) {
        std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
        return v[v.size() / 2];
    };
    const double apart_ms =
        static_cast<double>(median(offsets["left/mono"]) - median(offsets["right/mono"])) / 1e6;
    RecordProperty("ptp_cameras_apart_ms", std::to_string(apart_ms));
    EXPECT_LT(std::abs(apart_ms), 10.0) << "the two PTP cameras are not on one time base";
    const size_t sets = recorded.output.rfind("sync ");
    ASSERT_NE(sets, std::string::npos) << recorded.output;
    EXPECT_GT(std::stoul(recorded.output.substr(sets + 5)), 10u) << recorded.output;
}

enum class Fault { kHostTornDown, kPartition };

class HostFaults : public Hosts, public ::testing::WithParamInterface<Fault> {};

// Host C runs the rig live (mixray run, no scene: a monitor of its streams) with a local device
// and host A's. Mid-stream host A is torn down (its publisher killed without a word, its
// namespace and link deleted) and made again, or the link between them is cut for three seconds.
// C reports A's device reconnecting, keeps its local stream at its rate, and receives A's
// streams again when A is back.
TEST_P(HostFaults, TheLostHostIsReportedAndRejoinsWhileLocalStreamsKeepTheirRate) {
    const auto dir = tempDir();
    const std::string domain = std::to_string(1 + getpid() % 200);
    writeText(dir / "a.yaml",
              "rig: host-a\ndevices:\n  - name: rgbd\n    driver: pattern\n    id: rgbd\n"
              "    streams: [color]\n    options: {color.width: 320, color.height: 240, fps: 30,"
              " frames: 1000000, realtime: true}\n");
    writeText(dir / "c.yaml",
              "rig: host-c\ndevices:\n  - name: remote\n    driver: dds\n    id: hostA/rgbd\n"
              "    options: {domain: " +
                  domain + ", address: " + net_ + "1.1, peers: " + net_ +
                  "1.2, transport: udp, lease_s: 1, discovery_timeout_ms: 20000}\n"
                  "  - name: local\n    driver: pattern\n    id: mono\n"
                  "    options: {mono.width: 320, mono.height: 240, fps: 15, frames: 1000000,"
                  " realtime: true}\n");
    const std::vector<std::string> publish{"publish",     (dir / "a.yaml").string(),
                                           "--host",      "hostA",
                                           "--domain",    domain,
                                           "--address",   net_ + "1.2",
                                           "--peers",     net_ + "1.1",
                                           "--transport", "udp"};
    CliProcess a = startIn(a_, 1000, publish, dir / "a.log");
    CliProcess c = startIn(
        c_, 0, {"run", (dir / "c.yaml").string(), "--duration", "12", "-o", (dir / "out").string()},
        dir / "c.log");
    std::this_thread::sleep_for(std::chrono::seconds(4));
    if (GetParam() == Fault::kHostTornDown) {
        kill(a.pid, SIGKILL);  // no goodbye: C learns it from the silence
        waitMixray(a);
        tearDownA();
        std::this_thread::sleep_for(std::chrono::seconds(3));
        bringBackA();
        // Back as if rebooted: its clock another 2000 s on.
        a = startIn(a_, 3000, publish, dir / "a2.log");
    } else {
        ASSERT_EQ(shell("ip -n " + c_ + " link set vca" + id_ + " down"), 0);
        std::this_thread::sleep_for(std::chrono::seconds(3));
        ASSERT_EQ(shell("ip -n " + c_ + " link set vca" + id_ + " up"), 0);
    }
    const CliRun ran = waitMixray(c);
    kill(a.pid, SIGTERM);
    waitMixray(a);
    ASSERT_EQ(ran.exit_code, 0) << ran.output;
    EXPECT_NE(ran.output.find("remote reconnecting"), std::string::npos) << ran.output;

    const auto summary = nlohmann::json::parse(readText(dir / "out" / "summary.json"));
    std::map<std::string, nlohmann::json> streams;
    for (const auto& s : summary.at("streams"))
        streams[s.at("name").get<std::string>()] = s;
    for (const auto& d : summary.at("devices")) {
        if (d.at("name") == "remote") {
            EXPECT_EQ(d.at("state"), "streaming") << "rejoined: " << summary.dump();
            // The host's clock as it is now: the fit started again when it jumped.
            const std::string clock = d.at("clock");
            const std::string ahead = GetParam() == Fault::kHostTornDown ? "+3000.00" : "+1000.00";
            RecordProperty("remote_clock", clock);
            EXPECT_EQ(clock.rfind("hostA clock " + ahead, 0), 0u) << clock;
            EXPECT_EQ(clock.find("clock jump") != std::string::npos,
                      GetParam() == Fault::kHostTornDown)
                << clock;
        }
    }
    // 12 s of a 15 fps local camera, whatever the network does.
    EXPECT_GE(streams.at("local/mono").at("published").get<int>(), 15 * 12 * 9 / 10)
        << summary.dump();
    // About 4 s before the fault and about 4 s after it, at 30 fps.
    EXPECT_GE(streams.at("remote/color").at("published").get<int>(), 30 * 6) << summary.dump();
}

INSTANTIATE_TEST_SUITE_P(Faults, HostFaults,
                         ::testing::Values(Fault::kHostTornDown, Fault::kPartition),
                         [](const ::testing::TestParamInfo<Fault>& param) {
                             return std::string(param.param == Fault::kHostTornDown
                                                    ? "HostTornDownAndBack"
                                                    : "LinkCutForThreeSeconds");
                         });

}  // namespace
}  // namespace mixray::test
