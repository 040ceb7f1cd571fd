// The driver compliance suite (libcamera's lc-compliance): the same capture tests against every
// backend, each opened on a real peer — the source its own library reads (a recording, Aravis's
// fake camera and GigE Vision simulator, OpenNI2's player and DummyDevice, a umockdev-emulated
// UVC camera). The tests live in compliance_suite.cpp; each test executable instantiates them
// over the peers it can host (one per preload need).
#pragma once

#include <gtest/gtest.h>

#include <functional>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "mixray/graph/device.h"

namespace mixray::compliance {

// One mode a device can be opened in, and what its frames must then look like.
struct PeerMode {
    DeviceConfig config;
    ImageDesc expected;  // width, height and format of the subscribed stream's frames
};

// A finite run that ends by itself: every frame of a file, through a lossless edge.
struct FiniteRun {
    DeviceConfig config;
    uint64_t frames = 0;  // frames of the subscribed stream, as the peer's own API counts them
};

// A backend with its peer. Created fresh for every test; the destructor tears the peer down.
class CompliancePeer {
public:
    virtual ~CompliancePeer() = default;
    // Empty when the peer can run here; else why not (the test skips with this message).
    virtual std::string missing() const { return {}; }
    // Starts what the peer needs (a simulator process, an emulated device).
    virtual Status setUp() { return Status::ok(); }
    virtual std::unique_ptr<DeviceBackend> backend() const = 0;
    // An endless source (live, or a file on loop) with `buffers()` pool buffers per stream.
    virtual DeviceConfig config() const = 0;
    virtual size_t buffers() const { return 4; }
    // The short name of the stream the tests subscribe to ("color", "mono", ...).
    virtual std::string stream() const = 0;
    // At least two modes to reconfigure between; fewer: reconfigure skips with modesMissing().
    virtual std::vector<PeerMode> modes() const { return {}; }
    virtual std::string modesMissing() const { return {}; }
    // For files: a run that ends with the last frame.
    virtual std::optional<FiniteRun> finite() const { return std::nullopt; }
    // A device id this backend cannot open.
    virtual std::string missingId() const = 0;
};

struct PeerParam {
    std::string name;  // gtest parameter name
    std::function<std::unique_ptr<CompliancePeer>()> make;
};

class Compliance : public ::testing::TestWithParam<PeerParam> {
protected:
    void SetUp() override;
    std::unique_ptr<CompliancePeer> peer_;
};

// gtest prints parameters in failure messages and test lists: the name says it all.
inline void PrintTo(const PeerParam& param, std::ostream* os) {
    *os << param.name;
}

inline std::string peerName(const ::testing::TestParamInfo<PeerParam>& info) {
    return info.param.name;
}

}  // namespace mixray::compliance
