// The "aravis" backend: GigE Vision and USB3 Vision cameras through Aravis 0.8.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "mixray/graph/device.h"
#include "mixray/graph/frame.h"

typedef struct _ArvBuffer ArvBuffer;

namespace mixray::aravis {

// How frames are started.
enum class TriggerMode : uint8_t {
    kFreeRun,   // the camera runs at its frame rate
    kSoftware,  // one frame per AravisDevice::softwareTrigger()
    kHardware,  // one frame per edge (or level) on AravisOptions::trigger_source
};

// How an Aravis camera is set up. Parsed from DeviceConfig::options (all values are strings):
//   pixel_format   GenICam name: Mono8, Mono16, RGB8, BayerRG8, BayerGR8, BayerGB8, BayerBG8
//                  (default: the camera's current format)
//   debayer        true | false: publish Bayer frames as rgb8, demosaiced with OpenCV
//                  (default false: the mosaic is published as the graph's Bayer format)
//   exposure_us    exposure time, > 0 (default: the camera's)
//   gain           gain in the camera's unit, >= 0 (default: the camera's)
//   fps            frame rate in free run, > 0 (default: the camera's)
//   width, height, offset_x, offset_y   region of interest in pixels (default: the camera's)
//   trigger        free | software | a hardware line as the camera's TriggerSource names it
//                  (line0, line1, ...; matched without regard to case and checked against
//                  the camera's list at open) (default free)
//   trigger_activation  rising_edge | falling_edge | any_edge | level_high | level_low, with a
//                  hardware trigger only; checked against the camera's TriggerActivation
//                  (default: rising_edge where the camera has TriggerActivation)
//   ptp            true | false: enable IEEE 1588 on the camera (PtpEnable or GevIEEE1588);
//                  a camera without either is refused at open (default false)
//   buffers        frames Aravis may hold and the graph pool holds, >= 2 (default: enough for
//                  half a second at the frame rate, at least 8)
//   packet_size    GigE Vision packet size in bytes, 0 = negotiated by Aravis (default 0)
//   packet_resend  true | false: ask the camera to resend lost packets (default true)
//   lost_timeout_ms  free run without frames this long probes the camera; an unanswered
//                  probe declares the connection lost (default 2000)
//   reconnect_ms   pause between attempts to reopen a lost camera (default 500)
//   heartbeat_timeout_ms  GigE Vision: how long the camera keeps this host in control
//                  without a heartbeat (GevHeartbeatTimeout, bootstrap register 0x0938),
//                  500..600000; longer rides out a stalled or loaded host, shorter notices a
//                  pulled cable sooner (default: the camera's, typically 3000)
//   clock_domain   ClockDomainId of the camera clock, >= 1 (default: a hash of the name;
//                  with ptp, kPtpClockDomain, shared by every PTP camera)
// A rig file's stream list and stream modes arrive as DeviceConfig::streams (one of "mono",
// "color") and "<stream>.width", ".height", ".fps", ".format" (graph format names: mono8,
// mono16, rgb8, bayer_rggb8, ...); they set the same fields and must not repeat them.
struct AravisOptions {
    std::string stream;  // "mono" or "color" when the rig names it; checked at open
    std::string pixel_format;
    bool debayer = false;
    double exposure_us = 0;  // 0: keep
    double gain = -1;        // < 0: keep
    double fps = 0;          // 0: keep
    int width = 0;           // 0: keep
    int height = 0;          // 0: keep
    int offset_x = -1;       // < 0: keep
    int offset_y = -1;       // < 0: keep
    TriggerMode trigger = TriggerMode::kFreeRun;
    std::string trigger_source;      // kHardware: as given ("line1"); the camera's name at open
    std::string trigger_activation;  // GenICam name ("FallingEdge"); empty: rising edge
    bool ptp = false;
    size_t buffers = 0;  // 0: from the frame rate
    int packet_size = 0;
    bool packet_resend = true;
    int64_t lost_timeout_ms = 2000;
    int64_t reconnect_ms = 500;
    int64_t heartbeat_timeout_ms = 0;  // 0: keep
    ClockDomainId clock_domain = 0;

    // kInvalidArgument naming the device and the option for unknown keys and bad values.
    static Result<AravisOptions> fromConfig(const DeviceConfig& config);
    Status validate() const;
};

// The clock domain of cameras whose timestamps are PTP time. Cameras synchronised to one PTP
// grandmaster stamp in one time base, so they share one domain and one clock model.
inline constexpr ClockDomainId kPtpClockDomain = 0x50545031;  // "PTP1"

// GenICam TriggerActivation name of an option value ("falling_edge" -> "FallingEdge"); empty
// for unknown values.
std::string triggerActivationName(std::string_view option_value);

// The clock domain an Aravis device named `device_name` gets by default: a hash of the name,
// never kHostClockDomain.
ClockDomainId defaultClockDomain(std::string_view device_name);

// Demosaics an 8-bit Bayer image (kBayer*8) into `rgb` (kRGB8, same size) with OpenCV's
// bilinear interpolation. kInvalidArgument for other formats or mismatched sizes.
Status debayer(const ImageView& bayer, const MutableImageView& rgb);

// How far the camera's frame id `id` lies past `previous`: 1 for the next frame, more across
// lost frames. GigE Vision 1.x ids count 1..65535 and wrap to 1; 64-bit ids (GigE Vision 2,
// USB3 Vision) do not wrap. 0 when `id` does not follow `previous` (repeated, or the camera
// restarted its count): no gap can be told.
uint64_t frameIdAdvance(uint64_t previous, uint64_t id);

// What a device has seen since it was opened. Plain value.
struct AravisStats {
    uint64_t published = 0;         // frames handed to the graph
    uint64_t incomplete = 0;        // of those, published with FrameStatus::kIncomplete
    uint64_t failed = 0;            // buffers Aravis gave up on (timeout, size mismatch, ...)
    uint64_t missing_frames = 0;    // gaps in the camera's frame ids
    uint64_t pool_exhausted = 0;    // frames dropped because every graph buffer was in use
    uint64_t received_packets = 0;  // GigE Vision only, summed over connections
    uint64_t missing_packets = 0;   // packets never received, even after resend requests
    uint64_t resend_requests = 0;
    uint64_t resent_packets = 0;
    uint64_t underruns = 0;          // frames the camera sent while Aravis had no free buffer
    uint64_t connection_losses = 0;  // times the camera stopped answering
    uint64_t reconnects = 0;         // times it was opened again and streams again
    bool connected = false;
};

// One Aravis camera as a graph source. connect() declares one stream, "<name>/mono" for
// Mono8/Mono16 or "<name>/color" for RGB8 and Bayer; start() launches the capture thread,
// which copies each buffer Aravis fills into a frame of the stream's pool (Aravis owns its
// receive buffers) and publishes it. The frame's sequence is the camera's frame id unwrapped
// to 64 bits (a lost frame leaves a gap), its device stamp the camera's timestamp in the
// device's clock domain, its host stamp the host monotonic time at which the first packet of
// the frame arrived. Frames with lost packets are published with FrameStatus::kIncomplete.
//
// When the camera stops answering (GigE Vision heartbeat lost, or free run without frames
// for lost_timeout_ms and a failed register read), the device counts a connection loss,
// releases the camera and tries to reopen it every reconnect_ms with the same settings;
// frames resume on the same stream. The graph is never stopped by a loss. Aravis calls that
// wait for a gone camera (probe, reopen, release) run on helper threads, so stop() returns at
// once; the destructor joins them and may wait for Aravis's retries (seconds).
//
// Thread-safety: connect/start/stop are called by the graph's owner; softwareTrigger() and
// stats() may be called from any thread.
class AravisDevice : public Device {
public:
    // Opens the camera `id` (Aravis device id, serial number or IP address; empty: the first
    // found) and applies `options`. kNotFound when no such camera answers.
    static Result<std::unique_ptr<AravisDevice>> open(std::string name, std::string id,
                                                      AravisOptions options);
    ~AravisDevice() override;
    AravisDevice(const AravisDevice&) = delete;
    AravisDevice& operator=(const AravisDevice&) = delete;

    std::string name() const override { return name_; }
    DeviceDescriptor descriptor() const override;
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    // The stream this device publishes (valid after connect()) and its description.
    StreamId streamId() const { return stream_id_; }
    const StreamInfo& streamInfo() const { return info_; }
    const AravisOptions& options() const { return options_; }

    // Starts one frame in software-trigger mode. kUnsupported in free run, kUnavailable while
    // the camera is lost.
    Status softwareTrigger();
    AravisStats stats() const;
    // kStreaming while connected; kReconnecting once the camera stopped answering while the
    // capture thread tries to reopen it; kLost when it was stopped while the camera was gone.
    DeviceState state() const override;

    // The camera's current value of the GenICam feature `name`, read through Aravis (for an
    // enumeration its entry name: "On", "Line0"). kNotFound when the camera has no such
    // feature, kUnavailable while the camera is lost or does not answer.
    Result<std::string> feature(const std::string& name) const;
    // The camera's IEEE 1588 state (PtpStatus or GevIEEE1588Status: "Master", "Slave",
    // "Listening", ...). kUnsupported when the device was opened without ptp.
    Result<std::string> ptpStatus() const;

private:
    struct Camera;
    AravisDevice(std::string name, AravisOptions options);
    void run();
    bool waitFor(int64_t ms);
    Status startStream();  // with mutex_ held
    Status reconnect();
    // Runs `work` on a helper thread (Aravis calls that may wait seconds for a camera that
    // is gone); `done` is set when it has finished. Helpers are joined by the destructor.
    void spawnAside(std::function<void()> work, std::shared_ptr<std::atomic<bool>> done = {});
    // Runs `work` aside and waits for it or for stop(); false when stop() came first.
    bool runAside(std::function<void()> work);
    void handleBuffer(ArvBuffer* buffer);

    std::string name_;
    AravisOptions options_;
    std::unique_ptr<Camera> camera_;
    std::string reopen_id_;
    DeviceDescriptor descriptor_;
    StreamInfo info_;
    Graph* graph_ = nullptr;
    StreamId stream_id_ = kInvalidStream;
    std::shared_ptr<BufferPool> pool_;
    ImageDesc camera_desc_;     // what the camera sends (before debayering)
    size_t payload_bytes_ = 0;  // size of each Aravis buffer

    std::thread thread_;
    struct Helper {
        std::thread thread;
        std::shared_ptr<std::atomic<bool>> done;
    };
    std::vector<Helper> helpers_;  // used by the capture thread, then by the destructor
    mutable std::mutex mutex_;     // guards camera_ against softwareTrigger(), stats and stop
    std::condition_variable wake_;
    bool stop_requested_ = false;
    AravisStats stats_;
    uint64_t next_sequence_ = 0;
    uint64_t last_frame_id_ = 0;
    bool have_frame_id_ = false;
};

// Backend options: which Aravis interfaces enumerate() and open() use.
struct AravisBackendOptions {
    // Also offer Aravis's in-process "Fake" interface (device ids "Fake_1", ...): a camera
    // without any network, for fast tests.
    bool fake_interface = false;
};

// The "aravis" backend. enumerate() runs Aravis discovery (GigE Vision broadcast on every
// interface, USB3 Vision on the bus); open() builds an AravisDevice from DeviceConfig.
// Thread-bound, like every DeviceBackend.
class AravisBackend : public DeviceBackend {
public:
    explicit AravisBackend(const AravisBackendOptions& options = {});
    std::string_view name() const override { return "aravis"; }
    Result<std::vector<DeviceDescriptor>> enumerate() override;
    Result<std::unique_ptr<Device>> open(const DeviceConfig& config) override;

private:
    AravisBackendOptions options_;
};

}  // namespace mixray::aravis
