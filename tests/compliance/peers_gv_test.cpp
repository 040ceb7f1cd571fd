// The compliance suite over the Aravis backend and Aravis's GigE Vision camera simulator
// (arv-fake-gv-camera-0.8) on loopback, started for each test: a process of its own, as the
// simulator binds 127.0.0.1:3956 (ctest resource lock arv_fake_gv_camera).
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "compliance_suite.h"
#include "mixray/aravis/aravis_backend.h"

extern char** environ;

namespace mixray::compliance {
namespace {

constexpr const char* kSimulator = "/usr/bin/arv-fake-gv-camera-0.8";
constexpr const char* kSerial = "MIXRAYGV";
constexpr const char* kAddress = "127.0.0.1";

class AravisGvPeer : public CompliancePeer {
public:
    ~AravisGvPeer() override {
        if (pid_ > 0) {
            kill(pid_, SIGKILL);
            waitpid(pid_, nullptr, 0);
        }
    }
    std::string missing() const override {
        return access(kSimulator, X_OK) == 0
                   ? ""
                   : std::string(kSimulator) +
                         " is missing (Debian package aravis-tools): the GigE Vision peer";
    }
    Status setUp() override {
        const char* argv[] = {kSimulator, "-i", kAddress, "-s", kSerial, nullptr};
        if (posix_spawn(&pid_, kSimulator, nullptr, nullptr, const_cast<char**>(argv), environ) !=
            0) {
            pid_ = -1;
            return {ErrorCode::kUnavailable, std::string("cannot start ") + kSimulator};
        }
        // It answers GVCP within a second or two of starting.
        auto b = backend();
        Status last{ErrorCode::kNotFound, "not tried"};
        for (int attempt = 0; attempt < 40; ++attempt) {
            auto opened = b->open(config());
            if (opened)
                return Status::ok();
            last = opened.status();
            if (last.code() != ErrorCode::kNotFound)
                return last;
            std::this_thread::sleep_for(std::chrono::milliseconds(250));
        }
        return last;
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
        c.id = kAddress;
        c.options = {{"fps", "50"},
                     {"buffers", "4"},
                     {"width", std::to_string(width)},
                     {"height", std::to_string(height)}};
        return {c, ImageDesc::packed(PixelFormat::kMono8, width, height)};
    }

    pid_t pid_ = -1;
};

INSTANTIATE_TEST_SUITE_P(Peers, Compliance,
                         ::testing::Values(PeerParam{
                             "aravis_gv", [] { return std::make_unique<AravisGvPeer>(); }}),
                         peerName);

}  // namespace
}  // namespace mixray::compliance
