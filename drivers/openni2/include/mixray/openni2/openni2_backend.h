// The "openni2" backend: PrimeSense-family depth sensors and OpenNI `.oni` recordings through
// OpenNI2 2.2, as graph devices.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/device.h"
#include "mixray/graph/frame.h"

namespace mixray::openni2 {

// Stream tag: the stream's field of view as OpenNI2 reports it, "horizontal,vertical" in
// radians (absent when the device or recording reports none).
inline constexpr const char* kFieldOfViewTag = "openni2_fov_rad";

// The sensors of an OpenNI2 device, published as "<device>/depth", "/color", "/ir".
enum class Sensor : uint8_t { kDepth, kColor, kInfrared };
std::string_view toString(Sensor sensor);

// One requested stream; 0 means "the device's current mode".
struct SensorRequest {
    Sensor sensor = Sensor::kDepth;
    int width = 0;
    int height = 0;
    int fps = 0;
    PixelFormat format = PixelFormat::kUnknown;  // kUnknown: any this backend delivers
};

// How an OpenNI2 device is opened. Parsed from DeviceConfig::options (all values strings):
//   streams        comma list of depth, color, ir (or the rig's stream list; default: depth and
//                  color where the device has them)
//   <s>.width, <s>.height, <s>.fps, <s>.format   video mode per stream (as a rig file's
//                  `mode:` passes them; default: the device's current);
//                  a recording accepts only what was recorded
//   registration   on | off: hardware depth->color registration (default off); on fails on
//                  devices that cannot register (recordings, drivers without it)
//   sync           on | off: hardware depth/color frame sync on live devices (default on when
//                  depth and color are both enabled)
//   pace           original | fast: recordings only; both play every frame (OpenNI2's manual
//                  playback); original publishes each when its own timestamp (/ speed) is due,
//                  fast as soon as consumers allow (default original)
//   speed          > 0, recordings with pace=original (default 1)
//   loop           true | false: recordings only, OpenNI2's repeat (default false)
//   seek           frame number (OpenNI2 numbering, 1 = first) of the first enabled stream
//                  where playback begins, reached by dropping the frames before it at the
//                  playback's pace; recordings only (default 1)
//   buffers        pool buffers per stream, 1..1024 (default 8)
//   clock_domain   ClockDomainId of the device clock, >= 1 (default: a hash of the name)
//   reconnect      true | false: a live device lost while streaming is reopened when it returns
//                  (default), or its streams end (Graph::endStream)
// Mirroring is always off: a device or recording that cannot turn it off is un-mirrored in
// software (see README.md).
struct OpenNI2Options {
    enum class Pace : uint8_t { kOriginal, kFast };

    std::vector<SensorRequest> streams;  // empty: the device's defaults
    std::vector<SensorRequest> modes;    // "<s>.width" etc., applied to the enabled streams
    bool registration = false;
    int sync = -1;  // -1: default, 0 off, 1 on
    Pace pace = Pace::kOriginal;
    double speed = 1;
    bool speed_given = false;
    bool loop = false;
    int seek = 1;
    size_t buffers = 8;
    bool reconnect = true;
    ClockDomainId clock_domain = kHostClockDomain;  // kHostClockDomain: derived from the name

    // kInvalidArgument naming the device and option for unknown keys and bad values.
    static Result<OpenNI2Options> fromConfig(const DeviceConfig& config);
};

// The clock domain an OpenNI2 device named `device_name` gets by default (never the host's).
ClockDomainId defaultClockDomain(std::string_view device_name);

// One open OpenNI2 device or recording. The device is opened by OpenNI2Backend::open(); its
// streams are declared by connect() and started by start(), which launches one capture thread
// that copies every OpenNI2 frame into the stream's pool and publishes it:
//   sequence        OpenNI2's frame index (recordings number from 1; on loops later passes
//                   continue the count)
//   device_stamp_ns OpenNI2's timestamp (µs) in ns, in the device's clock domain (recordings:
//                   rebased to 0 by OpenNI2; on loops later passes are shifted by one pass)
//   host_stamp_ns   live devices: CLOCK_MONOTONIC when the capture thread read the frame;
//                   recordings: the first frame's read time plus the frame's own device time
//                   since the first frame (divided by speed), so a recording keeps its timing
//                   whatever the pace
// so that ClockSync maps device time onto host time. A recording without loop ends every
// stream (Graph::endStream) after its last frame. Recordings deliver every frame (they wait
// for a pool buffer); on live devices a full pool drops the frame. Every frame that does not
// reach the graph (a full pool, a frame number OpenNI2 skipped, frames a recording never
// delivered) is counted in droppedFrames() and Graph::lostCount().
// One recording can back one device at a time in a process (OpenNI2 would share its player);
// a second open is kUnavailable.
// A live device lost while streaming (OpenNI2's device-disconnected event for its URI, or a
// failed wait or read) is released and error() is kUnavailable naming it; the graph keeps
// running. With reconnect (the default) the capture thread looks for it again (its URI, else a
// newly listed device with its serial), reopens it with the same modes, registration and sync,
// clears error() and counts reconnects(); sequences continue from the last one published and
// device stamps are shifted so that the first frame after the gap lies the host time of the
// gap after the last one (the camera's clock restarts when it powers up). With reconnect=false
// its streams end (Graph::endStream) and error() stays kUnavailable.
// Thread-safety: connect/start/stop from the graph's owner; counters from any thread.
class OpenNI2Device : public Device {
public:
    // One run of the capture loop on a thread kept for OpenNI2 (see openni2_backend.cpp).
    class CaptureJob {
    public:
        void finish() {
            {
                std::lock_guard lock(mutex_);
                done_ = true;
            }
            done_cv_.notify_all();
        }
        void wait() {
            std::unique_lock lock(mutex_);
            done_cv_.wait(lock, [this] { return done_; });
        }

    private:
        std::mutex mutex_;
        std::condition_variable done_cv_;
        bool done_ = false;
    };

    ~OpenNI2Device() override;

    std::string name() const override { return name_; }
    DeviceDescriptor descriptor() const override { return descriptor_; }
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    bool isRecording() const;
    const OpenNI2Options& options() const { return options_; }
    // Enabled sensors in stream order, and their graph ids (after connect()).
    std::vector<Sensor> sensors() const;
    const std::vector<StreamId>& streamIds() const { return ids_; }
    // Frames a recording holds per enabled stream (OpenNI2's count); empty for live devices.
    std::vector<int> recordedFrameCounts() const;
    // Whether frames are un-mirrored in software, per enabled stream.
    std::vector<bool> softwareUnmirror() const;

    uint64_t publishedFrames() const { return published_.load(); }
    uint64_t droppedFrames() const { return dropped_.load(); }
    bool finished() const { return finished_.load(); }
    // ok while running and after a clean end; what went wrong otherwise (kUnavailable while a
    // live device is lost, ok again once it is reopened).
    Status status() const;
    // The same as status(), under the name the other live backends use.
    Status error() const { return status(); }
    // Times a lost device was reopened.
    uint64_t reconnects() const { return reconnects_.load(); }
    // Live devices: kStreaming while the capture loop runs and the device is there,
    // kReconnecting while it is lost and looked for, kLost when it is lost and not looked for
    // (reconnect=false, or stopped meanwhile). Recordings: kEnded at their end, else kUnknown.
    DeviceState state() const override;

private:
    friend class OpenNI2Backend;
    struct Impl;
    OpenNI2Device(std::string name, OpenNI2Options options, std::unique_ptr<Impl> impl);
    void run();
    void setError(Status status);
    // Counts frames of stream `stream` (index into ids_) that never reached the graph, here and
    // in the graph's lost count.
    void countLost(size_t stream, uint64_t frames);
    // Sets the status whatever it was: a loss replaces ok, a reopen clears the loss.
    void resetError(Status status);
    // Stops and destroys the streams and closes the lost device.
    void release();
    // Reopens the lost device and restarts its streams as they were; false to try again later.
    bool reopen(std::vector<std::string>& known_uris);

    std::string name_;
    OpenNI2Options options_;
    std::unique_ptr<Impl> impl_;
    DeviceDescriptor descriptor_;
    Graph* graph_ = nullptr;
    std::vector<StreamId> ids_;
    std::vector<std::shared_ptr<BufferPool>> pools_;
    std::shared_ptr<CaptureJob> capture_;  // the capture loop, on a kept thread
    std::atomic<bool> stop_requested_{false};
    std::atomic<bool> finished_{false};
    std::atomic<bool> capturing_{false};  // between start() and the capture loop's end
    std::atomic<uint64_t> published_{0};
    std::atomic<uint64_t> dropped_{0};
    std::atomic<uint64_t> reconnects_{0};
    mutable std::mutex mutex_;
    Status status_;
};

// The "openni2" backend. DeviceConfig::id: an OpenNI2 URI ("1d27/0601@3/2"), a device serial,
// the path of an .oni recording, or empty for the first device. enumerate() lists connected
// devices (opening each briefly for its serial and video modes).
// OpenNI2 is initialised on first use and stays initialised until the process ends.
// Thread-bound, like every DeviceBackend.
class OpenNI2Backend : public DeviceBackend {
public:
    std::string_view name() const override { return "openni2"; }
    Result<std::vector<DeviceDescriptor>> enumerate() override;
    Result<std::unique_ptr<Device>> open(const DeviceConfig& config) override;
};

}  // namespace mixray::openni2
