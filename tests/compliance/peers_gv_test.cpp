// The compliance suite over the Aravis backend and Aravis's GigE Vision camera simulator
// (arv-fake-gv-camera-0.8) on loopback, started for each test: a process of its own, as the
// simulator binds 127.0.0.1:3956 (ctest resource lock arv_fake_gv_camera).

#include "compliance_suite.h"
#include "gv_simulator.h"
#include "mixray/aravis/aravis_backend.h"

namespace mixray::compliance {
namespace {

class AravisGvPeer : public CompliancePeer {
public:
    std::string missing() const override {
        return test::GvSimulator::installed()
                   ? ""
                   : std::string(test::kGvSimulator) +
                         " is missing (Debian package aravis-tools): the GigE Vision peer";
    }
    Status setUp() override {
        if (!simulator_.start())
            return {ErrorCode::kUnavailable, std::string("cannot start ") + test::kGvSimulator};
        auto opened = test::openWhenUp(*backend(), config());
        return opened ? Status::ok() : opened.status();
    }
    std::unique_ptr<DeviceBackend> backend() const override {
        return std::make_unique<aravis::AravisBackend>();
    }
    DeviceConfig config() const override { return mode(320, 240).config; }
    std::string stream() const override { return "mono"; }
    std::vector<PeerMode> modes() const override { return {mode(320, 240), mode(256, 128)}; }
    std::string missingId() const override { return "NOSUCHSERIAL"; }

private:
    static PeerMode mode(int width, int height) {
        DeviceConfig c;
        c.name = "gv";
        c.driver = "aravis";
        c.id = test::kGvSimulatorAddress;
        c.options = {{"fps", "50"},
                     {"buffers", "4"},
                     {"width", std::to_string(width)},
                     {"height", std::to_string(height)}};
        return {c, ImageDesc::packed(PixelFormat::kMono8, width, height)};
    }

    test::GvSimulator simulator_;
};

INSTANTIATE_TEST_SUITE_P(Peers, Compliance,
                         ::testing::Values(PeerParam{
                             "aravis_gv", [] { return std::make_unique<AravisGvPeer>(); }}),
                         peerName);

}  // namespace
}  // namespace mixray::compliance
