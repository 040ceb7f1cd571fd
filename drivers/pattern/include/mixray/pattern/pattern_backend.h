// The "pattern" backend: virtual cameras with simulated clocks, for tests, benchmarks and
// fixtures without hardware (libcamera's vimc).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "mixray/graph/device.h"
#include "mixray/graph/frame.h"
#include "mixray/pattern/pattern_image.h"

namespace mixray::pattern {

// The virtual devices enumerate() lists (DeviceConfig::id; empty means kRgbdId).
inline constexpr std::string_view kRgbdId = "rgbd";  // color, depth, ir; default color+depth
inline constexpr std::string_view kMonoId = "mono";  // mono

// One enabled stream of a pattern device.
struct PatternStreamOptions {
    PatternStream stream = PatternStream::kColor;
    int width = 640;
    int height = 480;
};

// How a pattern device behaves. Parsed from DeviceConfig::options (all values are strings):
//   streams         comma list of color, depth, ir, mono (default: the device's defaults);
//                   DeviceConfig::streams may list them instead, not both
//   <s>.width, <s>.height   per stream, 16..16384 x 8..16384 (default 640x480, mono 1280x960)
//   fps             frame rate, > 0 (default 30)
//   frames          capture instants before the streams end, 0 = unlimited (default 0)
//   realtime        true | false: pace at fps on the host clock, or run as fast as buffers
//                   and back-pressure allow on simulated time (default true)
//   epoch_ns        simulated time of frame 0 when not realtime (default 1000000000)
//   phase_us        shifts this device's capture instants (default 0)
//   offset_ns       device clock reading at frame 0 (default 0)
//   drift_ppm       device clock rate error, |x| < 10000 (default 0)
//   latency_us      fixed part of the arrival latency, >= 0 (default 0)
//   jitter_us       mean of the exponential random part of the arrival latency (default 0)
//   reset_at_frame  the device clock restarts from 0 at this frame, 0 = never (default 0)
//   drop_ratio      probability that a frame of a stream is lost, [0, 1) (default 0)
//   seed            random seed, mixed with the device name (default 1)
//   buffers         pool buffers per stream, >= 1 (default 8)
//   fill            full | stamp: render every pixel, or only the sequence stamp
//                   (benchmarks of the graph itself) (default full)
//   clock_domain    the device clock's ClockDomainId, >= 1 (default: a hash of the name)
struct PatternOptions {
    enum class Fill : uint8_t { kFull, kStamp };

    std::string id = std::string(kRgbdId);
    std::vector<PatternStreamOptions> streams;
    double fps = 30;
    uint64_t frames = 0;
    bool realtime = true;
    int64_t epoch_ns = 1'000'000'000;
    int64_t phase_ns = 0;
    int64_t offset_ns = 0;
    double drift_ppm = 0;
    int64_t latency_ns = 0;
    double jitter_ns = 0;
    uint64_t reset_at_frame = 0;
    double drop_ratio = 0;
    uint64_t seed = 1;
    size_t buffers = 8;
    Fill fill = Fill::kFull;
    ClockDomainId clock_domain = 0;

    // kInvalidArgument naming the device and the option for unknown keys and bad values;
    // kNotFound for an unknown device id.
    static Result<PatternOptions> fromConfig(const DeviceConfig& config);
    Status validate() const;
};

// The clock domain a pattern device named `device_name` gets by default: a hash of the name,
// never kHostClockDomain.
ClockDomainId defaultClockDomain(std::string_view device_name);

// A virtual camera: one capture thread renders frames into per-stream pools and publishes
// them as "<config.name>/<stream>" (color, depth, ir, mono). Streams of a device share their
// capture instants t_k = t_0 + k / fps; the frame's sequence is k (a dropped frame leaves a
// gap), its device stamp the device clock at t_k (offset, drift and reset applied), its host
// stamp the arrival: t_k + latency + jitter (simulated when not realtime, the real host clock
// after waiting until then when realtime). Devices that are not realtime with the same epoch
// and phase have the same instants: their frames form exact sets.
// Realtime devices drop a frame when its pool is empty (counted in poolExhausted()); others
// wait for a buffer. After `frames` instants every stream is ended with Graph::endStream().
// Thread-safety: connect/start/stop are called by the graph's owner; the counters may be read
// from any thread.
class PatternDevice : public Device {
public:
    PatternDevice(std::string name, PatternOptions options);
    ~PatternDevice() override;

    std::string name() const override { return name_; }
    DeviceDescriptor descriptor() const override;
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    const PatternOptions& options() const { return options_; }
    // Graph ids of the streams, in options().streams order (valid after connect()).
    const std::vector<StreamId>& streamIds() const { return ids_; }
    // Device stamp and ideal host instant (t_k, before latency) of frame k.
    int64_t deviceStampNs(uint64_t k) const;
    int64_t captureInstantNs(uint64_t k) const;

    uint64_t publishedFrames() const { return published_.load(); }
    uint64_t droppedFrames() const { return dropped_.load(); }  // drop_ratio losses
    uint64_t poolExhausted() const { return exhausted_.load(); }
    bool finished() const { return finished_.load(); }
    // kEnded once finished(); until then kUnknown: its streams' activity tells the rest.
    DeviceState state() const override {
        return finished() ? DeviceState::kEnded : DeviceState::kUnknown;
    }

private:
    void run();
    bool sleepUntil(int64_t host_ns);
    bool stopRequested();

    std::string name_;
    PatternOptions options_;
    Graph* graph_ = nullptr;
    std::vector<StreamId> ids_;
    std::vector<std::shared_ptr<BufferPool>> pools_;
    int64_t t0_ns_ = 0;

    std::thread thread_;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_requested_ = false;
    std::atomic<uint64_t> published_{0};
    std::atomic<uint64_t> dropped_{0};
    std::atomic<uint64_t> exhausted_{0};
    std::atomic<bool> finished_{false};
};

// The "pattern" backend. enumerate() lists the virtual devices "rgbd" and "mono"; open()
// builds a PatternDevice from DeviceConfig (name, id, options, streams).
// Thread-bound, like every DeviceBackend.
class PatternBackend : public DeviceBackend {
public:
    std::string_view name() const override { return "pattern"; }
    Result<std::vector<DeviceDescriptor>> enumerate() override;
    Result<std::unique_ptr<Device>> open(const DeviceConfig& config) override;
};

}  // namespace mixray::pattern
