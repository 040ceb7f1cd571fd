// The "v4l2" backend: UVC webcams and the fish-eye environment camera through Video4Linux2.
#pragma once

#include <atomic>
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

namespace mixray::v4l2 {

// How frames travel from the driver: buffers the kernel allocates and we map (MMAP, what real
// UVC cameras are used with), or buffers we allocate and lend to the driver (USERPTR).
enum class IoMethod : uint8_t { kMmap, kUserPtr };

// What a V4L2 control is, as VIDIOC_QUERYCTRL describes it.
struct ControlInfo {
    uint32_t id = 0;
    std::string name;   // as the driver names it: "Exposure, Auto"
    std::string key;    // the rig option key: lowercase, runs of other characters as '_'
    uint32_t type = 0;  // V4L2_CTRL_TYPE_*
    int32_t minimum = 0;
    int32_t maximum = 0;
    int32_t step = 1;
    int32_t default_value = 0;
    bool read_only = false;
};

// "Exposure, Auto" -> "exposure_auto" (the names v4l2-ctl uses).
std::string controlKey(std::string_view name);

// How a V4L2 device is opened. Parsed from DeviceConfig::options (all values are strings; a
// rig's `color: 1280x720@30 mjpeg` mode arrives as color.width/height/fps/format):
//   color.format   yuyv (kYUYV) | mjpeg (kept compressed, kMJPEG, for recording) | rgb8 (the
//                  camera's MJPEG decoded with libjpeg-turbo) (default yuyv)
//   color.width, color.height   a frame size the device lists (default 640x480)
//   color.fps      frame rate set with VIDIOC_S_PARM, 0 = the driver's (default 0)
//   io             mmap | userptr (default mmap)
//   buffers        driver buffers, 2..32 (default 4)
//   pool           graph buffers of the stream, 1..1024 (default 8)
//   role           camera | environment: the environment camera's exposure and white balance
//                  are locked to manual, so that light estimation sees fixed exposure and
//                  colour gains (default camera)
//   exposure_us    manual exposure time (auto exposure off; UVC counts 100 µs units)
//   auto_white_balance   true | false
//   white_balance_k      manual white balance temperature in kelvin
//   clock          auto | device: kernel stamps flagged CLOCK_MONOTONIC are host time already
//                  (kHostClockDomain); `device`, or a driver whose stamps are not monotonic,
//                  gives the device a clock domain of its own for the graph's ClockModel
//                  (default auto)
//   reconnect      true | false: a camera lost while streaming is reopened when its node
//                  answers again (renegotiated, controls set again), or its stream ends
//                  (default true)
//   ctrl.<key>     any control by its key (integer; booleans and menus as their numbers),
//                  e.g. ctrl.brightness=10; set after the settings above, in key order
struct V4l2Options {
    enum class Role : uint8_t { kCamera, kEnvironment };
    enum class ClockMode : uint8_t { kAuto, kDevice };

    uint32_t fourcc = 0x56595559;  // V4L2_PIX_FMT_YUYV, or V4L2_PIX_FMT_MJPEG
    int width = 640;
    int height = 480;
    double fps = 0;
    bool decode_rgb = false;
    IoMethod io = IoMethod::kMmap;
    uint32_t buffers = 4;
    size_t pool = 8;
    Role role = Role::kCamera;
    ClockMode clock = ClockMode::kAuto;
    int32_t exposure_us = 0;                  // 0: not set
    int32_t auto_white_balance = -1;          // -1: not set, else 0 or 1
    int32_t white_balance_k = 0;              // 0: not set
    bool reconnect = true;
    std::map<std::string, int32_t> controls;  // by key

    // kInvalidArgument naming the device and the option for unknown keys and bad values.
    static Result<V4l2Options> fromConfig(const DeviceConfig& config);
    Status validate() const;
};

// One V4L2 capture device (a /dev/video node) as a graph source. It publishes one stream,
// "<name>/color": kYUYV, kMJPEG or kRGB8 at the negotiated size. The driver's sequence numbers
// become frame sequences (a gap is a frame the driver lost); the kernel buffer timestamp is
// the device stamp, the host CLOCK_MONOTONIC at dequeue the host stamp. Buffers the driver
// flags V4L2_BUF_FLAG_ERROR are published as FrameStatus::kIncomplete; exposure_us is set
// while exposure is manual (-1 otherwise). A frame is copied (or
// decoded) from the driver's buffer into the stream's pool and the buffer is queued again at
// once; when the pool is empty the frame is dropped (counted), as a camera does not wait.
// open() (through V4l2Backend) opens the node, checks it captures and streams, negotiates the
// format and sets the controls; start() allocates and queues the buffers and starts
// streaming; stop() stops streaming and frees them, so start/stop cycle. A device lost while
// streaming (ENODEV) is reported by error() (kUnavailable) while the capture thread reopens
// its node every 200 ms; once it answers, the format is negotiated and the controls set again
// and frames resume (sequences restart from the driver's 0), error() is ok again and
// reconnects() counts it. With reconnect=false, or when the node comes back with another
// layout, the stream ends instead (Graph::endStream).
// Thread-safety: connect/start/stop and the control calls are called by the graph's owner;
// counters may be read from any thread.
class V4l2Device : public Device {
public:
    ~V4l2Device() override;

    std::string name() const override { return name_; }
    DeviceDescriptor descriptor() const override { return descriptor_; }
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    const V4l2Options& options() const { return options_; }
    const std::string& path() const { return path_; }
    // The negotiated layout of the stream's frames.
    const ImageDesc& format() const { return desc_; }
    StreamId streamId() const { return stream_; }
    ClockDomainId clockDomain() const { return clock_domain_; }

    std::vector<ControlInfo> controls() const { return controls_; }
    // By key ("exposure_time_absolute"); kNotFound naming the known keys.
    Result<int32_t> control(std::string_view key) const;
    // Sets and reads back; kInvalidArgument outside the control's range, kIoError when the
    // driver refuses or reports another value.
    Status setControl(std::string_view key, int32_t value);

    uint64_t publishedFrames() const { return published_.load(); }
    uint64_t poolExhausted() const { return exhausted_.load(); }
    uint64_t decodeErrors() const { return decode_errors_.load(); }
    uint64_t sequenceGaps() const { return gaps_.load(); }  // frames the driver skipped
    uint64_t reconnects() const { return reconnects_.load(); }
    // Ok while streaming or stopped on request; the failure that ended capture otherwise.
    Status error() const;

private:
    friend class V4l2Backend;
    V4l2Device(std::string name, std::string path, V4l2Options options);
    Status openNode();
    Status negotiate();
    Status applyControls();
    const ControlInfo* findControlById(uint32_t id) const;
    Status setControlById(uint32_t id, int32_t value, std::string_view what);
    // Caches the exposure time frames report (FrameMetadata::exposure_us): known only while
    // exposure is manual.
    void updateExposure();
    Status allocateBuffers();
    void freeBuffers();
    void run();
    void fail(Status status);
    void setError(Status status);
    // On the capture thread after ENODEV: false when capture must end.
    bool recover(Status lost);
    Status reopen();
    void releaseNode();
    const ControlInfo* findControl(std::string_view key) const;

    struct Buffer {
        uint8_t* data = nullptr;
        size_t length = 0;
        bool mapped = false;  // MMAP: munmap; USERPTR: free
    };

    std::string name_;
    std::string path_;
    V4l2Options options_;
    DeviceDescriptor descriptor_;
    std::atomic<int> fd_{-1};  // replaced by the capture thread when it reconnects
    int wake_fd_ = -1;        // eventfd that interrupts the capture thread's poll
    ImageDesc desc_;          // what the graph sees
    uint32_t sizeimage_ = 0;  // bytes of one driver buffer
    double nominal_fps_ = 0;
    std::vector<ControlInfo> controls_;
    std::vector<Buffer> buffers_;
    bool streaming_ = false;

    Graph* graph_ = nullptr;
    StreamId stream_ = kInvalidStream;
    ClockDomainId clock_domain_ = kHostClockDomain;
    std::shared_ptr<BufferPool> pool_;
    std::thread thread_;
    std::atomic<bool> stop_requested_{false};
    uint64_t last_sequence_ = 0;
    bool have_sequence_ = false;

    std::atomic<uint64_t> published_{0};
    std::atomic<uint64_t> exhausted_{0};
    std::atomic<uint64_t> decode_errors_{0};
    std::atomic<uint64_t> gaps_{0};
    std::atomic<int64_t> exposure_us_{-1};
    std::atomic<uint64_t> reconnects_{0};
    mutable std::mutex error_mutex_;
    Status error_;
};

// The "v4l2" backend. enumerate() lists the /dev/videoN nodes (named by /sys/class/video4linux
// when it exists, else by /dev) that capture video and stream, with their formats, frame sizes
// and fastest rates; other nodes (UVC metadata nodes) are left out. DeviceConfig::id is a node
// path ("/dev/video0"), a node name ("video0") or a card name ("HD Webcam"); empty opens the
// first capture node.
// Thread-bound, like every DeviceBackend.
class V4l2Backend : public DeviceBackend {
public:
    std::string_view name() const override { return "v4l2"; }
    Result<std::vector<DeviceDescriptor>> enumerate() override;
    Result<std::unique_ptr<Device>> open(const DeviceConfig& config) override;
};

// The descriptor of one node, its modes as "yuyv 640x480@30", "mjpeg 1280x720@30"; kNotFound
// or kUnsupported when it is no capture device.
Result<DeviceDescriptor> describeNode(const std::string& path);

}  // namespace mixray::v4l2
