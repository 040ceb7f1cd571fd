// The compliance suite over the V4L2 backend and a UVC camera emulated behind umockdev
// (tests/v4l2/uvc_emulator.h): a process of its own, re-executed with umockdev's preload
// library.
#include "compliance_suite.h"
#include "mixray/v4l2/v4l2_backend.h"
#include "umockdev_preload.h"
#include "uvc_emulator.h"

namespace mixray::compliance {
namespace {

class V4l2Peer : public CompliancePeer {
public:
    std::string missing() const override {
        if (!test::umockdevPreloaded()) {
            return std::string("umockdev's preload library (") + test::kUmockdevPreload +
                   ") is not installed (Debian package umockdev): no emulated camera";
        }
        return {};
    }
    Status setUp() override {
        std::string why;
        emulator_ = v4l2::test::UvcEmulator::create(&why);
        if (!emulator_)
            return {ErrorCode::kUnavailable, "the UVC emulator: " + why};
        return Status::ok();
    }
    std::unique_ptr<DeviceBackend> backend() const override {
        return std::make_unique<v4l2::V4l2Backend>();
    }
    DeviceConfig config() const override { return mode("yuyv", 320, 240).config; }
    std::string stream() const override { return "color"; }
    std::vector<PeerMode> modes() const override {
        return {mode("yuyv", 320, 240), mode("yuyv", 640, 480), mode("mjpeg", 320, 240)};
    }
    std::string missingId() const override { return "/dev/video7"; }

private:
    static PeerMode mode(const std::string& format, int width, int height) {
        DeviceConfig c;
        c.name = "uvc";
        c.driver = "v4l2";
        c.id = "/dev/video0";
        // umockdev cannot map a device: the emulator streams USERPTR buffers only.
        c.options = {{"io", "userptr"},
                     {"pool", "4"},
                     {"color.format", format},
                     {"color.width", std::to_string(width)},
                     {"color.height", std::to_string(height)}};
        ImageDesc expected = format == "yuyv" ? ImageDesc::packed(PixelFormat::kYUYV, width, height)
                                              : ImageDesc{PixelFormat::kMJPEG, width, height, 0};
        return {c, expected};
    }

    std::unique_ptr<v4l2::test::UvcEmulator> emulator_;
};

INSTANTIATE_TEST_SUITE_P(Peers, Compliance,
                         ::testing::Values(PeerParam{"v4l2_uvc",
                                                     [] { return std::make_unique<V4l2Peer>(); }}),
                         peerName);

}  // namespace
}  // namespace mixray::compliance

int main(int argc, char** argv) {
    mixray::test::reexecWithUmockdevPreload(argc, argv);
    testing::InitGoogleTest(&argc, argv);
    return RUN_ALL_TESTS();
}
