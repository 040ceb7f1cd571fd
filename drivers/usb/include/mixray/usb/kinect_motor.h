// The Kinect v1 motor device (045e:02b0): tilt motor, LED and accelerometer through libfreenect,
// the accelerometer published as an IMU stream.
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>

#include "mixray/graph/device.h"
#include "mixray/graph/frame.h"

namespace mixray::usb {

// The LED modes the motor accepts (libfreenect's freenect_led_options values).
enum class KinectLed : uint8_t {
    kOff = 0,
    kGreen = 1,
    kRed = 2,
    kYellow = 3,
    kBlinkGreen = 4,
    kBlinkRedYellow = 6,
};
std::string_view toString(KinectLed led);

// What the motor reports about its movement (freenect_tilt_status_code).
enum class TiltStatus : uint8_t { kStopped = 0, kLimit = 1, kMoving = 4 };
std::string_view toString(TiltStatus status);

// The tilt range the motor accepts, in degrees from the horizon.
inline constexpr double kMaxTiltDegrees = 31;

// Rig options of a Kinect motor device (DeviceConfig::options):
//   tilt_deg   tilt to set when opened and after a reconnect, degrees in [-31, 31] (default:
//              leave the motor where it is)
//   led        off | green | red | yellow | blink_green | blink_red_yellow (default: leave it)
//   rate_hz    accelerometer polls per second, in (0, 200] (default 20)
//   buffers    graph buffers of the gravity stream, 1..1024 (default 8)
//   reconnect  true | false: a motor lost while streaming is reopened when it returns, or its
//              stream ends (default true)
struct KinectMotorOptions {
    std::optional<double> tilt_deg;
    std::optional<KinectLed> led;
    double rate_hz = 20;
    size_t buffers = 8;
    bool reconnect = true;

    // kInvalidArgument naming the device and the option for unknown keys and bad values.
    static Result<KinectMotorOptions> fromConfig(const DeviceConfig& config);
};

// One reading of the motor's state.
struct KinectMotorState {
    // libfreenect's freenect_get_mks_accel: the raw counts / 819 * 9.80665, in the
    // accelerometer's axes and signs as libfreenect reports them.
    Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();
    int16_t raw[3] = {0, 0, 0};  // the counts
    double tilt_deg = 0;         // freenect_get_tilt_degs: the encoder's half degrees / 2
    TiltStatus status = TiltStatus::kStopped;
};

// The motor as a graph source. It publishes "<name>/gravity" (StreamKind::kImu, one
// mixray/graph/imu.h record per frame, accelerometer only): every 1 / rate_hz the state is read
// (freenect_update_tilt_state), stamped with host CLOCK_MONOTONIC (device and host stamp; the
// motor has no clock of its own) and published; a reading that finds the pool empty is dropped
// and counted. A motor lost while streaming is reported by error() (kUnavailable) while the
// polling thread reopens it every 200 ms (found again on its port path); once it answers, the
// tilt and LED last asked for are set again, samples resume, error() is ok and reconnects()
// counts it. The graph keeps running throughout. With reconnect=false the stream ends instead
// (Graph::endStream) and error() stays kUnavailable.
// Thread-safety: connect/start/stop by the graph's owner; setTilt/setLed and the readers from
// any thread.
class KinectMotorDevice : public Device {
public:
    // Opens the motor found at `found` (a descriptor from the usb backend), claims it through
    // libfreenect, reads its state once and sets the options' tilt and LED.
    static Result<std::unique_ptr<KinectMotorDevice>> open(const DeviceConfig& config,
                                                           const DeviceDescriptor& found);
    ~KinectMotorDevice() override;

    std::string name() const override { return name_; }
    DeviceDescriptor descriptor() const override { return descriptor_; }
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    const KinectMotorOptions& options() const { return options_; }
    StreamId streamId() const { return stream_; }

    // kInvalidArgument outside [-31, 31] degrees (or not finite); kUnavailable while the motor
    // is lost (the angle is set when it returns); kIoError when the transfer fails.
    Status setTilt(double degrees);
    // kUnavailable while lost (set when it returns); kIoError when the transfer fails.
    Status setLed(KinectLed led);
    // Reads the state now (also while not streaming); kUnavailable while lost.
    Result<KinectMotorState> readState();
    // The latest state the polling thread read; nullopt before the first.
    std::optional<KinectMotorState> lastState() const;

    uint64_t publishedSamples() const { return published_.load(); }
    uint64_t poolExhausted() const { return exhausted_.load(); }
    uint64_t reconnects() const { return reconnects_.load(); }
    // Ok while the motor answers; kUnavailable naming the motor while it is lost.
    Status error() const;

    struct Handle;
    struct UsbSession;

private:
    KinectMotorDevice(std::string name, DeviceDescriptor descriptor, KinectMotorOptions options);
    Status reopenLocked();
    Status applySettingsLocked();
    Result<KinectMotorState> readStateLocked();
    void lostLocked(const std::string& why);
    void run();
    void setError(Status status);

    std::string name_;
    DeviceDescriptor descriptor_;
    KinectMotorOptions options_;
    Graph* graph_ = nullptr;
    StreamId stream_ = kInvalidStream;
    std::shared_ptr<BufferPool> pool_;

    std::unique_ptr<UsbSession> usb_;  // outlives handle_ (declared first)
    mutable std::mutex device_mutex_;  // guards handle_ and the wanted settings
    std::unique_ptr<Handle> handle_;
    std::optional<double> wanted_tilt_;
    std::optional<KinectLed> wanted_led_;

    mutable std::mutex state_mutex_;
    std::optional<KinectMotorState> last_state_;
    Status error_;

    std::mutex run_mutex_;
    std::condition_variable wake_;
    bool stop_requested_ = false;
    std::thread thread_;

    uint64_t sequence_ = 0;
    std::atomic<uint64_t> published_{0};
    std::atomic<uint64_t> exhausted_{0};
    std::atomic<uint64_t> reconnects_{0};
};

}  // namespace mixray::usb
