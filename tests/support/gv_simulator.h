// Aravis's GigE Vision camera simulator (arv-fake-gv-camera-0.8, Debian package aravis-tools) on
// loopback, for the tests that run the Aravis backend against a real GigE Vision peer.
#pragma once

#include <sys/types.h>

#include <memory>
#include <string>

#include "mixray/graph/device.h"

namespace mixray::test {

inline constexpr const char* kGvSimulator = "/usr/bin/arv-fake-gv-camera-0.8";
inline constexpr const char* kGvSimulatorSerial = "MIXRAYGV";
// It binds port 3956 there, so two simulators never run at once (ctest resource lock
// arv_fake_gv_camera).
inline constexpr const char* kGvSimulatorAddress = "127.0.0.1";

// The simulator as a child process, killed on destruction.
class GvSimulator {
public:
    GvSimulator() = default;
    ~GvSimulator() { kill(); }
    GvSimulator(const GvSimulator&) = delete;
    GvSimulator& operator=(const GvSimulator&) = delete;

    static bool installed();
    // Starts it, with `lost_per_thousand` GVSP packets dropped on purpose, describing itself
    // with the GenICam file `genicam` when one is given, in network namespace `netns` when one
    // is named (its own loopback there); false if it could not be spawned.
    bool start(int lost_per_thousand = 0, const std::string& genicam = {},
               const std::string& netns = {});
    void kill();

private:
    pid_t pid_ = -1;
};

// Aravis's fake camera description with `nodes` added to it (GenICam XML); "" when it has no
// RegisterDescription to add them to.
std::string genicamWith(const std::string& nodes);
// That description with GigE Vision's IEEE 1588 features (GevIEEE1588, GevIEEE1588Status).
std::string genicamWithPtp();
// Writes `xml` to a file `name` in the tests' temporary folder: its path, "" on failure.
std::string writeGenicam(const std::string& xml, const std::string& name);

// Opens `config`, retrying while the simulator starts up: it answers GVCP within a second or
// two, and until then the device is kNotFound. Any other error is returned at once.
Result<std::unique_ptr<Device>> openWhenUp(DeviceBackend& backend, const DeviceConfig& config);

}  // namespace mixray::test
