// The Kinect v1 motor through libfreenect's motor API, on a libusb context of our own so that the
// motor libfreenect opens is the one the usb backend found (by port path).
#include "mixray/usb/kinect_motor.h"

#include <libfreenect.h>
#include <libusb.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "mixray/graph/device_options.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/imu.h"
#include "usb_internal.h"

namespace mixray::usb {

namespace {

constexpr uint16_t kMicrosoft = 0x045e;
constexpr uint16_t kMotor = 0x02b0;
constexpr auto kReopenPeriod = std::chrono::milliseconds(200);

std::string libusbText(int rc) {
    return std::string(libusb_error_name(rc)) + " (" + std::to_string(rc) + ")";
}

}  // namespace

std::string_view toString(KinectLed led) {
    switch (led) {
        case KinectLed::kOff:
            return "off";
        case KinectLed::kGreen:
            return "green";
        case KinectLed::kRed:
            return "red";
        case KinectLed::kYellow:
            return "yellow";
        case KinectLed::kBlinkGreen:
            return "blink_green";
        case KinectLed::kBlinkRedYellow:
            return "blink_red_yellow";
    }
    return "unknown";
}

std::string_view toString(TiltStatus status) {
    switch (status) {
        case TiltStatus::kStopped:
            return "stopped";
        case TiltStatus::kLimit:
            return "limit";
        case TiltStatus::kMoving:
            return "moving";
    }
    return "unknown";
}

Result<KinectMotorOptions> KinectMotorOptions::fromConfig(const DeviceConfig& config) {
    KinectMotorOptions o;
    DeviceOptionReader reader(config, "usb");
    for (const std::string& stream : config.streams) {
        if (stream != "gravity")
            return Status(ErrorCode::kInvalidArgument, "usb device '" + config.name +
                                                           "': the Kinect motor has no stream '" +
                                                           stream + "' (it offers gravity)");
    }
    if (reader.find("tilt_deg")) {
        double tilt = 0;
        MIXRAY_RETURN_IF_ERROR(reader.real("tilt_deg", tilt, -kMaxTiltDegrees, kMaxTiltDegrees,
                                           "degrees in [-31, 31]"));
        o.tilt_deg = tilt;
    }
    if (reader.find("led")) {
        KinectLed led = KinectLed::kOff;
        MIXRAY_RETURN_IF_ERROR(
            reader.choice<KinectLed>("led", led,
                                     {{"off", KinectLed::kOff},
                                      {"green", KinectLed::kGreen},
                                      {"red", KinectLed::kRed},
                                      {"yellow", KinectLed::kYellow},
                                      {"blink_green", KinectLed::kBlinkGreen},
                                      {"blink_red_yellow", KinectLed::kBlinkRedYellow}},
                                     "off, green, red, yellow, blink_green or blink_red_yellow"));
        o.led = led;
    }
    MIXRAY_RETURN_IF_ERROR(reader.real("rate_hz", o.rate_hz, 0, 200, "a rate in (0, 200] Hz",
                                       DeviceOptionReader::Bound::kOpen));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer<size_t>("buffers", o.buffers, 1, 1024, "an integer in [1, 1024]"));
    MIXRAY_RETURN_IF_ERROR(reader.boolean("reconnect", o.reconnect));
    MIXRAY_RETURN_IF_ERROR(reader.leftovers("tilt_deg, led, rate_hz, buffers, reconnect"));
    return o;
}

// One libusb context for the device's life: its device list follows hot-plug events, so a
// returning motor shows up in it, and no context is created and torn down at every reopen
// (libusb's event monitor would come and go with them).
struct KinectMotorDevice::UsbSession {
    libusb_context* usb = nullptr;

    ~UsbSession() {
        if (usb)
            libusb_exit(usb);
    }
};

// libfreenect's context and the opened motor, on the UsbSession's libusb context.
struct KinectMotorDevice::Handle {
    freenect_context* freenect = nullptr;
    freenect_device* device = nullptr;

    ~Handle() {
        if (device)
            freenect_close_device(device);
        if (freenect)
            freenect_shutdown(freenect);
    }
};

namespace {

// libfreenect opens the motor by its rank among the motors of the context's device list; the
// one we want is the one on `location` (its port path stays when it is replugged, its address
// does not). kUnavailable when no motor is there.
Result<int> motorIndex(libusb_context* usb, const std::string& location) {
    libusb_device** list = nullptr;
    const ssize_t n = libusb_get_device_list(usb, &list);
    if (n < 0)
        return Status(ErrorCode::kIoError,
                      "usb: libusb_get_device_list failed: " + libusbText(static_cast<int>(n)));
    int rank = 0;
    int found = -1;
    for (ssize_t i = 0; i < n && found < 0; ++i) {
        libusb_device_descriptor desc{};
        if (libusb_get_device_descriptor(list[i], &desc) != LIBUSB_SUCCESS ||
            desc.idVendor != kMicrosoft || desc.idProduct != kMotor)
            continue;
        if (detail::portPath(list[i]) == location)
            found = rank;
        ++rank;
    }
    libusb_free_device_list(list, 1);
    if (found < 0)
        return Status(ErrorCode::kUnavailable, "no Kinect motor on port " + location);
    return found;
}

}  // namespace

KinectMotorDevice::KinectMotorDevice(std::string name, DeviceDescriptor descriptor,
                                     KinectMotorOptions options)
    : name_(std::move(name)), descriptor_(std::move(descriptor)), options_(std::move(options)) {
    wanted_tilt_ = options_.tilt_deg;
    wanted_led_ = options_.led;
}

KinectMotorDevice::~KinectMotorDevice() {
    stop();
}

Result<std::unique_ptr<KinectMotorDevice>> KinectMotorDevice::open(const DeviceConfig& config,
                                                                   const DeviceDescriptor& found) {
    auto options = KinectMotorOptions::fromConfig(config);
    if (!options)
        return options.status();
    DeviceDescriptor d = found;
    char mode[48];
    std::snprintf(mode, sizeof(mode), "gravity imu@%g", options->rate_hz);
    d.modes = {mode};
    std::unique_ptr<KinectMotorDevice> device(
        new KinectMotorDevice(config.name, std::move(d), std::move(*options)));
    auto session = std::make_unique<UsbSession>();
    if (const int rc = libusb_init(&session->usb); rc != LIBUSB_SUCCESS)
        return Status(ErrorCode::kIoError,
                      "usb device '" + config.name + "': libusb_init failed: " + libusbText(rc));
    device->usb_ = std::move(session);
    std::lock_guard lock(device->device_mutex_);
    if (Status s = device->reopenLocked(); !s)
        return s;
    auto state = device->readStateLocked();
    if (!state)
        return state.status();
    return device;
}

// Opens (again) the motor on descriptor_.location and sets the wanted tilt and LED.
Status KinectMotorDevice::reopenLocked() {
    const std::string what = "usb device '" + name_ + "' (Kinect motor " + descriptor_.id + ")";
    auto index = motorIndex(usb_->usb, descriptor_.location);
    if (!index)
        return index.status().withContext(what);
    auto h = std::make_unique<Handle>();
    if (freenect_init(&h->freenect, usb_->usb) < 0)
        return Status(ErrorCode::kIoError, what + ": freenect_init failed");
    // libfreenect prints its own failures; ours carry them as statuses.
    freenect_set_log_level(h->freenect, FREENECT_LOG_FATAL);
    freenect_select_subdevices(h->freenect, FREENECT_DEVICE_MOTOR);
    if (freenect_open_device(h->freenect, &h->device, *index) < 0) {
        h->device = nullptr;
        return Status(ErrorCode::kUnavailable,
                      what + ": libfreenect could not open and claim the motor on port " +
                          descriptor_.location);
    }
    handle_ = std::move(h);
    if (Status s = applySettingsLocked(); !s) {
        handle_.reset();
        return s;
    }
    return Status::ok();
}

Status KinectMotorDevice::applySettingsLocked() {
    const std::string what = "usb device '" + name_ + "'";
    if (wanted_tilt_) {
        if (const int rc = freenect_set_tilt_degs(handle_->device, *wanted_tilt_); rc < 0)
            return Status(ErrorCode::kIoError,
                          what + ": setting the tilt failed: " + libusbText(rc));
    }
    if (wanted_led_) {
        if (const int rc =
                freenect_set_led(handle_->device, static_cast<freenect_led_options>(*wanted_led_));
            rc < 0)
            return Status(ErrorCode::kIoError,
                          what + ": setting the LED failed: " + libusbText(rc));
    }
    return Status::ok();
}

void KinectMotorDevice::lostLocked(const std::string& why) {
    handle_.reset();
    setError(Status(ErrorCode::kUnavailable,
                    "usb device '" + name_ + "' (Kinect motor on port " + descriptor_.location +
                        ") was lost (" + why + "); " +
                        (options_.reconnect ? "reopening it when it returns" : "its stream ends")));
}

Status KinectMotorDevice::setTilt(double degrees) {
    if (!std::isfinite(degrees) || std::abs(degrees) > kMaxTiltDegrees)
        return Status(ErrorCode::kInvalidArgument, "usb device '" + name_ + "': tilt " +
                                                       std::to_string(degrees) +
                                                       " degrees is outside [-31, 31]");
    std::lock_guard lock(device_mutex_);
    wanted_tilt_ = degrees;
    if (!handle_)
        return error();
    const int rc = freenect_set_tilt_degs(handle_->device, degrees);
    if (rc == LIBUSB_ERROR_NO_DEVICE) {
        lostLocked(libusbText(rc));
        return error();
    }
    if (rc < 0)
        return Status(ErrorCode::kIoError,
                      "usb device '" + name_ + "': setting the tilt failed: " + libusbText(rc));
    return Status::ok();
}

Status KinectMotorDevice::setLed(KinectLed led) {
    std::lock_guard lock(device_mutex_);
    wanted_led_ = led;
    if (!handle_)
        return error();
    const int rc = freenect_set_led(handle_->device, static_cast<freenect_led_options>(led));
    if (rc == LIBUSB_ERROR_NO_DEVICE) {
        lostLocked(libusbText(rc));
        return error();
    }
    if (rc < 0)
        return Status(ErrorCode::kIoError,
                      "usb device '" + name_ + "': setting the LED failed: " + libusbText(rc));
    return Status::ok();
}

Result<KinectMotorState> KinectMotorDevice::readState() {
    std::lock_guard lock(device_mutex_);
    return readStateLocked();
}

Result<KinectMotorState> KinectMotorDevice::readStateLocked() {
    if (!handle_)
        return error();
    const int rc = freenect_update_tilt_state(handle_->device);
    if (rc < 0) {
        lostLocked(libusbText(rc));
        return error();
    }
    freenect_raw_tilt_state* raw = freenect_get_tilt_state(handle_->device);
    KinectMotorState s;
    freenect_get_mks_accel(raw, &s.accel_mps2.x(), &s.accel_mps2.y(), &s.accel_mps2.z());
    s.raw[0] = raw->accelerometer_x;
    s.raw[1] = raw->accelerometer_y;
    s.raw[2] = raw->accelerometer_z;
    s.tilt_deg = freenect_get_tilt_degs(raw);
    s.status = static_cast<TiltStatus>(freenect_get_tilt_status(raw));
    std::lock_guard state_lock(state_mutex_);
    last_state_ = s;
    return s;
}

std::optional<KinectMotorState> KinectMotorDevice::lastState() const {
    std::lock_guard lock(state_mutex_);
    return last_state_;
}

Status KinectMotorDevice::error() const {
    std::lock_guard lock(state_mutex_);
    return error_;
}

void KinectMotorDevice::setError(Status status) {
    std::lock_guard lock(state_mutex_);
    error_ = std::move(status);
}

Status KinectMotorDevice::connect(Graph& graph) {
    if (graph_)
        return Status(ErrorCode::kInvalidArgument, "usb device '" + name_ + "' connected twice");
    const StreamInfo info = makeImuStreamInfo(
        name_ + "/gravity", options_.rate_hz,
        "Kinect v1 accelerometer as libfreenect reports it (freenect_get_mks_accel x, y, z)");
    auto stream = addPooledStream(graph, info, options_.buffers);
    if (!stream)
        return stream.status().withContext("usb device '" + name_ + "'");
    stream_ = stream->id;
    pool_ = std::move(stream->pool);
    graph_ = &graph;
    return Status::ok();
}

Status KinectMotorDevice::start() {
    if (!graph_)
        return Status(ErrorCode::kInvalidArgument, "usb device '" + name_ + "': not connected");
    if (thread_.joinable())
        return Status::ok();
    {
        std::lock_guard lock(run_mutex_);
        stop_requested_ = false;
    }
    thread_ = std::thread([this] { run(); });
    return Status::ok();
}

void KinectMotorDevice::stop() {
    {
        std::lock_guard lock(run_mutex_);
        stop_requested_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable())
        thread_.join();
}

void KinectMotorDevice::run() {
    const auto period = std::chrono::nanoseconds(std::llround(1e9 / options_.rate_hz));
    auto next = std::chrono::steady_clock::now();
    for (;;) {
        bool open = false;
        bool ended = false;
        std::optional<KinectMotorState> state;
        {
            std::lock_guard lock(device_mutex_);
            if (!handle_ && !options_.reconnect) {
                ended = true;
            } else if (!handle_ && reopenLocked()) {
                reconnects_.fetch_add(1);
                setError(Status::ok());
            }
            open = handle_ != nullptr;
            if (open) {
                auto read = readStateLocked();
                if (read)
                    state = *read;
            }
        }
        if (ended) {
            graph_->endStream(stream_);
            return;
        }
        const int64_t host_ns = monotonicNowNs();
        if (state) {
            ImuSample sample;
            sample.accel = state->accel_mps2;
            auto record = encodeImuRecord(sample);
            WritableFrame frame = record ? pool_->acquire() : WritableFrame();
            if (!frame) {
                // The motor does not wait for consumers: the reading is lost.
                exhausted_.fetch_add(1);
            } else {
                std::memcpy(frame.image().data, record->data(), record->size());
                frame.setPayloadBytes(record->size());
                FrameMetadata& meta = frame.meta();
                meta.stream = stream_;
                meta.sequence = sequence_++;
                meta.device_stamp_ns = host_ns;
                meta.host_stamp_ns = host_ns;
                meta.clock_domain = kHostClockDomain;
                // Counted first, so that a consumer holding the sample sees it counted.
                published_.fetch_add(1);
                graph_->publish(std::move(frame).publish());
            }
        }
        // While lost, look for the motor again at the reopen period rather than the poll rate.
        next = open ? next + period : std::chrono::steady_clock::now() + kReopenPeriod;
        std::unique_lock lock(run_mutex_);
        if (wake_.wait_until(lock, next, [&] { return stop_requested_; }))
            return;
    }
}

}  // namespace mixray::usb
