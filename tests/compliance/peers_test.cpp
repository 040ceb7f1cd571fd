// The compliance suite over the peers that need nothing but this process: the pattern backend
// (its own reference), the replay backend on the committed Matroska fixture, Aravis's
// in-process fake camera, and OpenNI2 playing the Kinect v1 .oni and its DummyDevice.
#include <filesystem>
#include <fstream>

#include "compliance_suite.h"
#include "mixray/aravis/aravis_backend.h"
#include "mixray/openni2/openni2_backend.h"
#include "mixray/pattern/pattern_backend.h"
#include "mixray/replay/open_recording.h"
#include "mixray/replay/replay_backend.h"
#include "test_data.h"

namespace mixray::compliance {
namespace {

DeviceConfig configOf(std::string name, std::string driver, std::string id,
                      std::map<std::string, std::string> options) {
    DeviceConfig c;
    c.name = std::move(name);
    c.driver = std::move(driver);
    c.id = std::move(id);
    c.options = std::move(options);
    return c;
}

class PatternPeer : public CompliancePeer {
public:
    std::unique_ptr<DeviceBackend> backend() const override {
        return std::make_unique<pattern::PatternBackend>();
    }
    DeviceConfig config() const override { return mode(320, 240).config; }
    std::string stream() const override { return "color"; }
    std::vector<PeerMode> modes() const override { return {mode(320, 240), mode(640, 480)}; }
    // On simulated time the device waits for buffers and back-pressure, like a file.
    std::optional<FiniteRun> finite() const override {
        PeerMode m = mode(320, 240);
        m.config.options["realtime"] = "false";
        m.config.options["frames"] = "20";
        return FiniteRun{m.config, 20};
    }
    std::string missingId() const override { return "no_such_pattern"; }

private:
    static PeerMode mode(int width, int height) {
        return {configOf("pat", "pattern", "rgbd",
                         {{"streams", "color"},
                          {"fps", "120"},
                          {"buffers", "4"},
                          {"color.width", std::to_string(width)},
                          {"color.height", std::to_string(height)}}),
                ImageDesc::packed(PixelFormat::kRGB8, width, height)};
    }
};

// The committed recording of two pattern devices (fixtures/sessions/README.md); the Matroska
// reader itself counts its frames.
class ReplayPeer : public CompliancePeer {
public:
    std::string missing() const override {
        return std::filesystem::exists(path()) ? "" : "fixture missing: " + path().string();
    }
    std::unique_ptr<DeviceBackend> backend() const override {
        return std::make_unique<replay::ReplayBackend>();
    }
    DeviceConfig config() const override {
        return configOf("rec", "replay", path().string(),
                        {{"loop", "true"}, {"speed", "4"}, {"buffers", "4"}});
    }
    std::string stream() const override { return "color"; }
    std::string modesMissing() const override {
        return "a recording plays the mode it was recorded in";
    }
    std::optional<FiniteRun> finite() const override {
        auto reader = replay::openRecording(path());
        EXPECT_TRUE(reader) << reader.status().toString();
        if (!reader)
            return std::nullopt;
        uint64_t frames = 0;
        StreamId color = kInvalidStream;
        for (size_t i = 0; i < (*reader)->streams().size(); ++i) {
            if ((*reader)->streams()[i].name == "rgbd/color")
                color = static_cast<StreamId>(i);
        }
        for (;;) {
            auto frame = (*reader)->next();
            if (!frame)
                break;
            frames += frame->meta().stream == color ? 1 : 0;
        }
        return FiniteRun{
            configOf("rec", "replay", path().string(), {{"pace", "fast"}, {"buffers", "4"}}),
            frames};
    }
    std::string missingId() const override {
        return (test::fixturesDir() / "sessions" / "no_such_recording.mkv").string();
    }

private:
    static std::filesystem::path path() {
        return test::fixturesDir() / "sessions" / "pattern_rgbd.mkv";
    }
};

// A TUM RGB-D folder made of the real TUM frame pair of ../shared/data, listed kFrames times
// 1/30 s apart. Its depth is in TUM units (5000 per metre), so the device converts every depth
// frame into a pool of its own: the stream watched here.
class ReplayTumPeer : public CompliancePeer {
public:
    static constexpr int kFrames = 8;

    std::string missing() const override {
        return std::filesystem::exists(source() / "TUM_depth.png")
                   ? ""
                   : "real data not available: " + source().string() +
                         " (expected under ../shared/data; see its MANIFEST.md)";
    }
    Status setUp() override {
        folder_ = test::tempDir() / "tum";
        std::filesystem::create_directories(folder_ / "rgb");
        std::filesystem::create_directories(folder_ / "depth");
        std::filesystem::copy_file(source() / "TUM_color.png", folder_ / "rgb" / "frame.png");
        std::filesystem::copy_file(source() / "TUM_depth.png", folder_ / "depth" / "frame.png");
        std::ofstream rgb(folder_ / "rgb.txt");
        std::ofstream depth(folder_ / "depth.txt");
        for (int i = 0; i < kFrames; ++i) {
            const std::string stamp = std::to_string(1 + i / 30.0);
            rgb << stamp << " rgb/frame.png\n";
            depth << stamp << " depth/frame.png\n";
        }
        return rgb && depth ? Status::ok()
                            : Status(ErrorCode::kIoError, "cannot write " + folder_.string());
    }
    std::unique_ptr<DeviceBackend> backend() const override {
        return std::make_unique<replay::ReplayBackend>();
    }
    DeviceConfig config() const override {
        return configOf("tum", "replay", folder_.string(),
                        {{"loop", "true"}, {"speed", "4"}, {"buffers", "4"}});
    }
    std::string stream() const override { return "depth"; }
    std::string modesMissing() const override {
        return "a recording plays the mode it was recorded in";
    }
    std::optional<FiniteRun> finite() const override {
        return FiniteRun{
            configOf("tum", "replay", folder_.string(), {{"pace", "fast"}, {"buffers", "4"}}),
            kFrames};
    }
    std::string missingId() const override { return (folder_ / "no_such_folder").string(); }

private:
    static std::filesystem::path source() {
        return test::sharedDataDir() / "02_rgbd_single_frames_open3d";
    }
    std::filesystem::path folder_;
};

class AravisFakePeer : public CompliancePeer {
public:
    std::unique_ptr<DeviceBackend> backend() const override {
        return std::make_unique<aravis::AravisBackend>(
            aravis::AravisBackendOptions{.fake_interface = true});
    }
    DeviceConfig config() const override { return mode("Mono8", 320, 240).config; }
    std::string stream() const override { return "mono"; }
    std::vector<PeerMode> modes() const override {
        return {mode("Mono8", 320, 240), mode("Mono16", 256, 128)};
    }
    std::string missingId() const override { return "NoSuchCamera"; }

private:
    static PeerMode mode(const std::string& format, int width, int height) {
        return {configOf("fake", "aravis", "Fake_1",
                         {{"fps", "100"},
                          {"buffers", "4"},
                          {"pixel_format", format},
                          {"width", std::to_string(width)},
                          {"height", std::to_string(height)}}),
                ImageDesc::packed(format == "Mono8" ? PixelFormat::kMono8 : PixelFormat::kMono16,
                                  width, height)};
    }
};

// OpenNI2 2.2 playing the Kinect v1 recording of ../shared/data (12 depth frames, as
// OpenNI2's getNumberOfFrames reports it: shared/data/MANIFEST.md).
class OniPeer : public CompliancePeer {
public:
    std::string missing() const override {
        return std::filesystem::exists(path())
                   ? ""
                   : "real data not available: " + path().string() +
                         " (expected under ../shared/data; see its MANIFEST.md)";
    }
    std::unique_ptr<DeviceBackend> backend() const override {
        return std::make_unique<openni2::OpenNI2Backend>();
    }
    DeviceConfig config() const override {
        return configOf("oni", "openni2", path().string(),
                        {{"streams", "depth"}, {"loop", "true"}, {"speed", "4"}, {"buffers", "4"}});
    }
    std::string stream() const override { return "depth"; }
    std::string modesMissing() const override {
        return "a recording plays the mode it was recorded in";
    }
    std::optional<FiniteRun> finite() const override {
        return FiniteRun{configOf("oni", "openni2", path().string(),
                                  {{"streams", "depth"}, {"pace", "fast"}, {"buffers", "4"}}),
                         12};
    }
    std::string missingId() const override {
        return (test::sharedDataDir() / "01_oni" / "no_such_file.oni").string();
    }

private:
    static std::filesystem::path path() { return test::kinectV1Oni(); }
};

// OpenNI2's DummyDevice driver (Debian's libopenni2-0): a live device, depth 320x240@30 only.
class OpenNI2DummyPeer : public CompliancePeer {
public:
    std::string missing() const override {
        const auto driver = std::filesystem::path("/usr/lib/x86_64-linux-gnu/OpenNI2/Drivers") /
                            "libDummyDevice.so.0";
        return std::filesystem::exists(driver)
                   ? ""
                   : "OpenNI2's DummyDevice driver is not installed: " + driver.string();
    }
    std::unique_ptr<DeviceBackend> backend() const override {
        return std::make_unique<openni2::OpenNI2Backend>();
    }
    DeviceConfig config() const override {
        return configOf("dummy", "openni2", "Dummy", {{"streams", "depth"}, {"buffers", "4"}});
    }
    std::string stream() const override { return "depth"; }
    std::string modesMissing() const override {
        return "OpenNI2's DummyDevice offers depth 320x240@30 only";
    }
    std::string missingId() const override { return "no_such_uri"; }
};

template <typename P>
PeerParam peer(std::string name) {
    return {std::move(name), [] { return std::make_unique<P>(); }};
}

INSTANTIATE_TEST_SUITE_P(
    Peers, Compliance,
    ::testing::Values(peer<PatternPeer>("pattern"), peer<ReplayPeer>("replay_mkv"),
                      peer<ReplayTumPeer>("replay_tum"), peer<AravisFakePeer>("aravis_fake"),
                      peer<OniPeer>("openni2_oni"), peer<OpenNI2DummyPeer>("openni2_dummy")),
    peerName);

}  // namespace
}  // namespace mixray::compliance
