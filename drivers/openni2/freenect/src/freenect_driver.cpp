// An OpenNI2 driver plug-in for Kinect v1 on libfreenect: Debian's OpenNI2 drivers take
// PrimeSense ids only, so this is how a Kinect v1 appears inside OpenNI2 (see ../README.md).
#include <libfreenect.h>
#include <libusb.h>
#include <sys/time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <list>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <string>
#include <thread>
#include <vector>

// OniDriverAPI.h's export macro allocates the driver through these (OpenNI2's XnOS names).
#define XN_NEW(type, ...) new (std::nothrow) type(__VA_ARGS__)
#define XN_DELETE(p) delete (p)
#include <Driver/OniDriverAPI.h>

namespace mixray::openni2::freenect {
namespace {

constexpr const char* kUriScheme = "freenect://";
constexpr uint16_t kMicrosoftVid = 0x045e;
constexpr uint16_t kNuiCameraPid = 0x02ae;
constexpr uint16_t kK4wCameraPid = 0x02bf;
constexpr int kWidth = 640;
constexpr int kHeight = 480;
constexpr int kIrHeight = 488;  // the IR camera's 10-bit mode has 8 more rows than colour
constexpr int kFps = 30;
// libfreenect's frame timestamps count the camera's 60 MHz clock in 32 bits.
constexpr uint64_t kTicksPerUs = 60;
// Nominal fields of view of the Kinect v1 depth/IR and colour cameras (OpenKinect's figures).
constexpr float kPi = 3.14159265358979f;
constexpr float kDepthHfov = 58.5f * kPi / 180.f;
constexpr float kDepthVfov = 45.6f * kPi / 180.f;
constexpr float kColorHfov = 62.0f * kPi / 180.f;
constexpr float kColorVfov = 48.6f * kPi / 180.f;

OniVideoMode depthMode() {
    return {ONI_PIXEL_FORMAT_DEPTH_1_MM, kWidth, kHeight, kFps};
}
OniVideoMode colorMode() {
    return {ONI_PIXEL_FORMAT_RGB888, kWidth, kHeight, kFps};
}
OniVideoMode irMode() {
    return {ONI_PIXEL_FORMAT_GRAY16, kWidth, kIrHeight, kFps};
}

int bytesPerPixel(OniPixelFormat format) {
    return format == ONI_PIXEL_FORMAT_RGB888 ? 3 : 2;
}

bool sameMode(const OniVideoMode& a, const OniVideoMode& b) {
    return a.pixelFormat == b.pixelFormat && a.resolutionX == b.resolutionX &&
           a.resolutionY == b.resolutionY && a.fps == b.fps;
}

template <typename T>
OniStatus putValue(const T& value, void* data, int* size) {
    if (!data || !size || *size < static_cast<int>(sizeof(T)))
        return ONI_STATUS_BAD_PARAMETER;
    std::memcpy(data, &value, sizeof(T));
    *size = sizeof(T);
    return ONI_STATUS_OK;
}

template <typename T>
bool getValue(const void* data, int size, T& out) {
    if (!data || size != static_cast<int>(sizeof(T)))
        return false;
    std::memcpy(&out, data, sizeof(T));
    return true;
}

// One Kinect camera as libfreenect lists it.
struct CameraInfo {
    std::string serial;
    OniDeviceInfo info{};
};

class Device;

// One depth, colour or IR stream. Frames arrive on the driver's event thread (deliver());
// everything else on OpenNI2's caller thread.
class Stream : public oni::driver::StreamBase {
public:
    Stream(Device& device, OniSensorType type);

    OniStatus start() override;
    void stop() override;
    OniStatus getProperty(int id, void* data, int* size) override;
    OniStatus setProperty(int id, const void* data, int size) override;
    OniBool isPropertySupported(int id) override;
    int getRequiredFrameSize() override { return stride() * mode_.resolutionY; }

    OniSensorType type() const { return type_; }
    const OniVideoMode& mode() const { return mode_; }
    // Copies one libfreenect frame into an OpenNI2 frame and hands it to OpenNI2; `ticks` is
    // the device's unwrapped 60 MHz clock.
    void deliver(const void* pixels, uint64_t ticks);

private:
    int stride() const { return mode_.resolutionX * bytesPerPixel(mode_.pixelFormat); }

    Device& device_;
    OniSensorType type_;
    OniVideoMode mode_;
    std::atomic<bool> mirror_{false};
    int frame_index_ = 0;
};

class Driver;

// One open Kinect. libfreenect has one depth and one video endpoint: colour and IR share the
// video endpoint, so only one of them streams at a time.
class Device : public oni::driver::DeviceBase {
public:
    Device(Driver& driver, freenect_device* device, CameraInfo camera);
    ~Device() override;

    OniStatus getSensorInfoList(OniSensorInfo** infos, int* count) override;
    oni::driver::StreamBase* createStream(OniSensorType type) override;
    void destroyStream(oni::driver::StreamBase* stream) override;
    OniStatus getProperty(int id, void* data, int* size) override;
    OniStatus setProperty(int id, const void* data, int size) override;
    OniBool isPropertySupported(int id) override;
    OniBool isImageRegistrationModeSupported(OniImageRegistrationMode mode) override {
        return mode == ONI_IMAGE_REGISTRATION_OFF || mode == ONI_IMAGE_REGISTRATION_DEPTH_TO_COLOR;
    }

    OniStatus startStream(Stream& stream);
    void stopStream(Stream& stream);
    void errorText(const std::string& text);

private:
    static void onDepth(freenect_device* device, void* pixels, uint32_t ticks);
    static void onVideo(freenect_device* device, void* pixels, uint32_t ticks);
    int startDepth();
    uint64_t unwrap(uint32_t ticks);

    Driver& driver_;
    freenect_device* device_;
    CameraInfo camera_;
    OniVideoMode depth_modes_[1] = {depthMode()};
    OniVideoMode color_modes_[1] = {colorMode()};
    OniVideoMode ir_modes_[1] = {irMode()};
    OniSensorInfo sensors_[3] = {};
    bool registration_ = false;
    std::vector<Stream*> streams_;
    // The streams receiving frames; the event thread reads them under mutex_.
    std::mutex mutex_;
    Stream* depth_ = nullptr;
    Stream* video_ = nullptr;
    // One 64-bit clock for all streams of the camera (they share its 60 MHz counter), so that
    // depth and colour stamps compare: libfreenect's 32-bit stamps unwrapped, from 2^32 + the
    // first stamp seen (no stream's stamp, slightly older than that, goes below zero).
    bool have_ticks_ = false;
    uint32_t last_ticks_ = 0;
    uint64_t ticks_ = 0;
};

// The driver: one libfreenect context, the Kinects it lists, and one thread that runs
// libfreenect's (libusb's) event loop from initialize() to shutdown(): frames, and libusb's
// hot-plug events, after which it lists the cameras again and tells OpenNI2 who came and went.
class Driver : public oni::driver::DriverBase {
public:
    explicit Driver(OniDriverServices* services) : DriverBase(services) {}
    ~Driver() override { shutdown(); }

    OniStatus initialize(oni::driver::DeviceConnectedCallback connected,
                         oni::driver::DeviceDisconnectedCallback disconnected,
                         oni::driver::DeviceStateChangedCallback changed, void* cookie) override;
    oni::driver::DeviceBase* deviceOpen(const char* uri, const char* mode) override;
    void deviceClose(oni::driver::DeviceBase* device) override;
    OniStatus tryDevice(const char* uri) override;
    void shutdown() override;

    void errorText(const std::string& text) { getServices().errorLoggerAppend("%s", text.c_str()); }
    // Held around every libfreenect call that does USB I/O or walks the context's device list
    // (listing, opening, closing, starting and stopping streams), from whichever thread:
    // libfreenect's context is not thread-safe, and OpenNI2 opens a camera on its caller's
    // thread while the event thread lists the bus after a hot-plug. Not held while the event
    // thread runs libusb's events, which a control transfer in another thread may wait on.
    std::mutex& usbMutex() { return usb_mutex_; }

private:
    static int LIBUSB_CALL onHotplug(libusb_context* context, libusb_device* device,
                                     libusb_hotplug_event event, void* user);
    // Lists the cameras; reports new ones to OpenNI2 and, with `departures`, the ones gone.
    // False when libusb sees more Kinect cameras than libfreenect could read a serial from.
    bool enumerate(bool departures);
    void runEvents();

    libusb_context* usb_ = nullptr;
    freenect_context* context_ = nullptr;
    std::mutex usb_mutex_;
    libusb_hotplug_callback_handle hotplug_ = 0;
    bool have_hotplug_ = false;
    std::mutex cameras_mutex_;
    std::list<CameraInfo> cameras_;  // a list: OpenNI2 is handed pointers to the infos
    size_t next_index_ = 0;
    std::thread events_;
    std::atomic<bool> stop_events_{false};
    std::atomic<bool> rescan_{false};
};

Stream::Stream(Device& device, OniSensorType type) : device_(device), type_(type) {
    mode_ = type == ONI_SENSOR_DEPTH   ? depthMode()
            : type == ONI_SENSOR_COLOR ? colorMode()
                                       : irMode();
}

OniStatus Stream::start() {
    return device_.startStream(*this);
}

void Stream::stop() {
    device_.stopStream(*this);
}

OniBool Stream::isPropertySupported(int id) {
    switch (id) {
        case ONI_STREAM_PROPERTY_VIDEO_MODE:
        case ONI_STREAM_PROPERTY_CROPPING:
        case ONI_STREAM_PROPERTY_HORIZONTAL_FOV:
        case ONI_STREAM_PROPERTY_VERTICAL_FOV:
        case ONI_STREAM_PROPERTY_STRIDE:
        case ONI_STREAM_PROPERTY_MIRRORING:
            return TRUE;
        case ONI_STREAM_PROPERTY_MAX_VALUE:
        case ONI_STREAM_PROPERTY_MIN_VALUE:
            return type_ == ONI_SENSOR_DEPTH;
        default:
            return FALSE;
    }
}

OniStatus Stream::getProperty(int id, void* data, int* size) {
    const bool color = type_ == ONI_SENSOR_COLOR;
    switch (id) {
        case ONI_STREAM_PROPERTY_VIDEO_MODE:
            return putValue(mode_, data, size);
        case ONI_STREAM_PROPERTY_CROPPING: {
            const OniCropping none{FALSE, 0, 0, mode_.resolutionX, mode_.resolutionY};
            return putValue(none, data, size);
        }
        case ONI_STREAM_PROPERTY_HORIZONTAL_FOV:
            return putValue(color ? kColorHfov : kDepthHfov, data, size);
        case ONI_STREAM_PROPERTY_VERTICAL_FOV:
            return putValue(color ? kColorVfov : kDepthVfov, data, size);
        case ONI_STREAM_PROPERTY_STRIDE:
            return putValue(stride(), data, size);
        case ONI_STREAM_PROPERTY_MIRRORING:
            return putValue(OniBool(mirror_.load() ? TRUE : FALSE), data, size);
        case ONI_STREAM_PROPERTY_MAX_VALUE:
            if (type_ != ONI_SENSOR_DEPTH)
                return ONI_STATUS_NOT_SUPPORTED;
            return putValue(int(FREENECT_DEPTH_MM_MAX_VALUE), data, size);
        case ONI_STREAM_PROPERTY_MIN_VALUE:
            if (type_ != ONI_SENSOR_DEPTH)
                return ONI_STATUS_NOT_SUPPORTED;
            return putValue(int(FREENECT_DEPTH_MM_NO_VALUE), data, size);
        default:
            return ONI_STATUS_NOT_SUPPORTED;
    }
}

OniStatus Stream::setProperty(int id, const void* data, int size) {
    switch (id) {
        case ONI_STREAM_PROPERTY_VIDEO_MODE: {
            // One mode per sensor: setting it is accepted only when it names that mode.
            OniVideoMode mode{};
            if (!getValue(data, size, mode))
                return ONI_STATUS_BAD_PARAMETER;
            return sameMode(mode, mode_) ? ONI_STATUS_OK : ONI_STATUS_NOT_SUPPORTED;
        }
        case ONI_STREAM_PROPERTY_CROPPING: {
            OniCropping cropping{};
            if (!getValue(data, size, cropping))
                return ONI_STATUS_BAD_PARAMETER;
            return cropping.enabled ? ONI_STATUS_NOT_SUPPORTED : ONI_STATUS_OK;
        }
        case ONI_STREAM_PROPERTY_MIRRORING: {
            OniBool on = FALSE;
            if (!getValue(data, size, on))
                return ONI_STATUS_BAD_PARAMETER;
            mirror_ = on != FALSE;
            return ONI_STATUS_OK;
        }
        default:
            return ONI_STATUS_NOT_SUPPORTED;
    }
}

void Stream::deliver(const void* pixels, uint64_t ticks) {
    OniFrame* frame = getServices().acquireFrame();
    if (!frame)
        return;
    const int row = stride();
    const int height = mode_.resolutionY;
    const auto* in = static_cast<const uint8_t*>(pixels);
    auto* out = static_cast<uint8_t*>(frame->data);
    if (mirror_) {
        const int bpp = bytesPerPixel(mode_.pixelFormat);
        for (int y = 0; y < height; ++y) {
            const uint8_t* src = in + static_cast<size_t>(y) * row;
            uint8_t* dst = out + static_cast<size_t>(y) * row;
            for (int x = 0; x < mode_.resolutionX; ++x)
                std::memcpy(dst + (mode_.resolutionX - 1 - x) * bpp, src + x * bpp, bpp);
        }
    } else {
        std::memcpy(out, in, static_cast<size_t>(row) * height);
    }
    frame->dataSize = row * height;
    frame->sensorType = type_;
    frame->timestamp = ticks / kTicksPerUs;
    frame->frameIndex = ++frame_index_;
    frame->width = mode_.resolutionX;
    frame->height = height;
    frame->videoMode = mode_;
    frame->croppingEnabled = FALSE;
    frame->cropOriginX = 0;
    frame->cropOriginY = 0;
    frame->stride = row;
    raiseNewFrame(frame);
    getServices().releaseFrame(frame);
}

Device::Device(Driver& driver, freenect_device* device, CameraInfo camera)
    : driver_(driver), device_(device), camera_(std::move(camera)) {
    sensors_[0] = {ONI_SENSOR_DEPTH, 1, depth_modes_};
    sensors_[1] = {ONI_SENSOR_COLOR, 1, color_modes_};
    sensors_[2] = {ONI_SENSOR_IR, 1, ir_modes_};
    freenect_set_user(device_, this);
    freenect_set_depth_callback(device_, &Device::onDepth);
    freenect_set_video_callback(device_, &Device::onVideo);
}

Device::~Device() {
    for (Stream* s : streams_) {
        stopStream(*s);
        delete s;
    }
    std::lock_guard lock(driver_.usbMutex());
    freenect_close_device(device_);
}

void Device::errorText(const std::string& text) {
    driver_.errorText(text);
}

OniStatus Device::getSensorInfoList(OniSensorInfo** infos, int* count) {
    *infos = sensors_;
    *count = 3;
    return ONI_STATUS_OK;
}

oni::driver::StreamBase* Device::createStream(OniSensorType type) {
    if (type != ONI_SENSOR_DEPTH && type != ONI_SENSOR_COLOR && type != ONI_SENSOR_IR)
        return nullptr;
    auto* stream = new (std::nothrow) Stream(*this, type);
    if (stream)
        streams_.push_back(stream);
    return stream;
}

void Device::destroyStream(oni::driver::StreamBase* base) {
    auto it = std::find(streams_.begin(), streams_.end(), base);
    if (it == streams_.end())
        return;
    Stream* stream = *it;
    streams_.erase(it);
    stopStream(*stream);
    delete stream;
}

OniBool Device::isPropertySupported(int id) {
    return id == ONI_DEVICE_PROPERTY_SERIAL_NUMBER || id == ONI_DEVICE_PROPERTY_DRIVER_VERSION ||
           id == ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION;
}

OniStatus Device::getProperty(int id, void* data, int* size) {
    switch (id) {
        case ONI_DEVICE_PROPERTY_SERIAL_NUMBER: {
            const int needed = static_cast<int>(camera_.serial.size()) + 1;
            if (!data || !size || *size < needed)
                return ONI_STATUS_BAD_PARAMETER;
            std::memcpy(data, camera_.serial.c_str(), static_cast<size_t>(needed));
            *size = needed;
            return ONI_STATUS_OK;
        }
        case ONI_DEVICE_PROPERTY_DRIVER_VERSION: {
            const OniVersion version{0, 5, 3, 0};  // the libfreenect API it is built against
            return putValue(version, data, size);
        }
        case ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION: {
            const OniImageRegistrationMode mode =
                registration_ ? ONI_IMAGE_REGISTRATION_DEPTH_TO_COLOR : ONI_IMAGE_REGISTRATION_OFF;
            return putValue(mode, data, size);
        }
        default:
            return ONI_STATUS_NOT_SUPPORTED;
    }
}

OniStatus Device::setProperty(int id, const void* data, int size) {
    if (id != ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION)
        return ONI_STATUS_NOT_SUPPORTED;
    OniImageRegistrationMode mode{};
    if (!getValue(data, size, mode) || !isImageRegistrationModeSupported(mode))
        return ONI_STATUS_BAD_PARAMETER;
    const bool on = mode == ONI_IMAGE_REGISTRATION_DEPTH_TO_COLOR;
    if (on == registration_)
        return ONI_STATUS_OK;
    registration_ = on;
    Stream* depth = nullptr;
    {
        std::lock_guard lock(mutex_);
        depth = depth_;
    }
    if (!depth)
        return ONI_STATUS_OK;
    // libfreenect changes the depth mode only while depth is stopped.
    stopStream(*depth);
    return startStream(*depth);
}

int Device::startDepth() {
    std::lock_guard lock(driver_.usbMutex());
    const freenect_frame_mode mode = freenect_find_depth_mode(
        FREENECT_RESOLUTION_MEDIUM, registration_ ? FREENECT_DEPTH_REGISTERED : FREENECT_DEPTH_MM);
    if (freenect_set_depth_mode(device_, mode) < 0)
        return -1;
    return freenect_start_depth(device_);
}

OniStatus Device::startStream(Stream& stream) {
    const bool depth = stream.type() == ONI_SENSOR_DEPTH;
    {
        std::lock_guard lock(mutex_);
        Stream*& slot = depth ? depth_ : video_;
        if (slot == &stream)
            return ONI_STATUS_OK;
        if (slot) {
            errorText("Kinect " + camera_.serial +
                      ": colour and IR share one camera endpoint; stop one to start the other");
            return ONI_STATUS_ERROR;
        }
        slot = &stream;
    }
    int result = 0;
    if (depth) {
        result = startDepth();
    } else {
        std::lock_guard lock(driver_.usbMutex());
        const freenect_frame_mode mode = freenect_find_video_mode(
            FREENECT_RESOLUTION_MEDIUM,
            stream.type() == ONI_SENSOR_COLOR ? FREENECT_VIDEO_RGB : FREENECT_VIDEO_IR_10BIT);
        result = freenect_set_video_mode(device_, mode);
        if (result >= 0)
            result = freenect_start_video(device_);
    }
    if (result < 0) {
        std::lock_guard lock(mutex_);
        (depth ? depth_ : video_) = nullptr;
        errorText("Kinect " + camera_.serial + ": libfreenect could not start the " +
                  (depth ? "depth" : "video") + " stream (" + std::to_string(result) + ")");
        return ONI_STATUS_ERROR;
    }
    return ONI_STATUS_OK;
}

void Device::stopStream(Stream& stream) {
    const bool depth = stream.type() == ONI_SENSOR_DEPTH;
    {
        std::lock_guard lock(mutex_);
        Stream*& slot = depth ? depth_ : video_;
        if (slot != &stream)
            return;
        slot = nullptr;
    }
    std::lock_guard lock(driver_.usbMutex());
    if (depth) {
        freenect_stop_depth(device_);
    } else {
        freenect_stop_video(device_);
    }
}

uint64_t Device::unwrap(uint32_t ticks) {
    if (have_ticks_) {
        // The streams' frames interleave slightly out of order: a signed step, modulo 2^32.
        ticks_ +=
            static_cast<uint64_t>(static_cast<int64_t>(static_cast<int32_t>(ticks - last_ticks_)));
    } else {
        ticks_ = (uint64_t{1} << 32) + ticks;
        have_ticks_ = true;
    }
    last_ticks_ = ticks;
    return ticks_;
}

void Device::onDepth(freenect_device* device, void* pixels, uint32_t ticks) {
    auto* self = static_cast<Device*>(freenect_get_user(device));
    std::lock_guard lock(self->mutex_);
    if (self->depth_)
        self->depth_->deliver(pixels, self->unwrap(ticks));
}

void Device::onVideo(freenect_device* device, void* pixels, uint32_t ticks) {
    auto* self = static_cast<Device*>(freenect_get_user(device));
    std::lock_guard lock(self->mutex_);
    if (self->video_)
        self->video_->deliver(pixels, self->unwrap(ticks));
}

OniStatus Driver::initialize(oni::driver::DeviceConnectedCallback connected,
                             oni::driver::DeviceDisconnectedCallback disconnected,
                             oni::driver::DeviceStateChangedCallback changed, void* cookie) {
    DriverBase::initialize(connected, disconnected, changed, cookie);
    // Without USB (no usbfs) there is no Kinect to find: the driver stays loaded and lists
    // nothing, like OpenNI2's PS1080 driver.
    if (libusb_init(&usb_) < 0) {
        usb_ = nullptr;
        return ONI_STATUS_OK;
    }
    if (freenect_init(&context_, usb_) < 0) {
        context_ = nullptr;
        return ONI_STATUS_OK;
    }
    freenect_set_log_level(context_, FREENECT_LOG_FATAL);
    freenect_select_subdevices(context_, FREENECT_DEVICE_CAMERA);
    (void)enumerate(false);
    if (libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG)) {
        have_hotplug_ =
            libusb_hotplug_register_callback(
                usb_,
                static_cast<libusb_hotplug_event>(LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED |
                                                  LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT),
                static_cast<libusb_hotplug_flag>(0), kMicrosoftVid, LIBUSB_HOTPLUG_MATCH_ANY,
                LIBUSB_HOTPLUG_MATCH_ANY, &Driver::onHotplug, this, &hotplug_) == LIBUSB_SUCCESS;
    }
    stop_events_ = false;
    events_ = std::thread([this] { runEvents(); });
    return ONI_STATUS_OK;
}

int LIBUSB_CALL Driver::onHotplug(libusb_context* /*context*/, libusb_device* /*device*/,
                                  libusb_hotplug_event /*event*/, void* user) {
    // No I/O from inside libusb's event handling: the event thread lists the cameras after it.
    static_cast<Driver*>(user)->rescan_ = true;
    return 0;
}

bool Driver::enumerate(bool departures) {
    if (!context_)
        return true;
    std::unique_lock usb_lock(usb_mutex_);
    freenect_device_attributes* list = nullptr;
    const int count = freenect_list_device_attributes(context_, &list);
    std::vector<std::string> serials;
    for (freenect_device_attributes* a = count > 0 ? list : nullptr; a; a = a->next)
        serials.push_back(a->camera_serial ? a->camera_serial : "");
    freenect_free_device_attributes(list);
    if (count < 0)
        return false;  // the bus could not be listed: nobody came or went
    // libfreenect lists serials only; the camera's product id comes from libusb's list, in
    // which libfreenect found them in the same order (cameras with a serial descriptor).
    std::vector<uint16_t> pids;
    libusb_device** devices = nullptr;
    const ssize_t n = libusb_get_device_list(usb_, &devices);
    for (ssize_t i = 0; i < n; ++i) {
        libusb_device_descriptor desc{};
        if (libusb_get_device_descriptor(devices[i], &desc) == 0 &&
            desc.idVendor == kMicrosoftVid &&
            (desc.idProduct == kNuiCameraPid || desc.idProduct == kK4wCameraPid) &&
            desc.iSerialNumber != 0) {
            pids.push_back(desc.idProduct);
        }
    }
    if (n >= 0)
        libusb_free_device_list(devices, 1);
    usb_lock.unlock();

    std::vector<const OniDeviceInfo*> arrived;
    std::vector<OniDeviceInfo> left;
    {
        std::lock_guard lock(cameras_mutex_);
        for (size_t index = 0; index < serials.size(); ++index) {
            const std::string& serial = serials[index];
            const bool known = std::any_of(cameras_.begin(), cameras_.end(),
                                           [&](const CameraInfo& c) { return c.serial == serial; });
            if (known || serial.empty())
                continue;
            CameraInfo camera;
            camera.serial = serial;
            // The index orders the cameras for people (never reused); the serial keeps the
            // URI of a camera when others come and go.
            std::snprintf(camera.info.uri, sizeof(camera.info.uri), "%s%zu/%s", kUriScheme,
                          next_index_++, serial.c_str());
            std::snprintf(camera.info.vendor, sizeof(camera.info.vendor), "Microsoft");
            const uint16_t pid = pids.size() == serials.size() ? pids[index] : kNuiCameraPid;
            std::snprintf(camera.info.name, sizeof(camera.info.name), "%s",
                          pid == kK4wCameraPid ? "Kinect for Windows" : "Kinect");
            camera.info.usbVendorId = kMicrosoftVid;
            camera.info.usbProductId = pid;
            cameras_.push_back(camera);
            arrived.push_back(&cameras_.back().info);
        }
        if (departures) {
            for (auto it = cameras_.begin(); it != cameras_.end();) {
                if (std::find(serials.begin(), serials.end(), it->serial) == serials.end()) {
                    left.push_back(it->info);
                    it = cameras_.erase(it);
                } else {
                    ++it;
                }
            }
        }
    }
    // Outside the lock: OpenNI2's listeners may open the device from the callback.
    for (const OniDeviceInfo* info : arrived)
        deviceConnected(info);
    for (const OniDeviceInfo& info : left)
        deviceDisconnected(&info);
    return pids.size() <= serials.size();
}

OniStatus Driver::tryDevice(const char* uri) {
    if (!uri || std::strncmp(uri, kUriScheme, std::strlen(kUriScheme)) != 0)
        return ONI_STATUS_ERROR;
    (void)enumerate(false);
    std::lock_guard lock(cameras_mutex_);
    for (const CameraInfo& c : cameras_) {
        if (std::strcmp(c.info.uri, uri) == 0)
            return ONI_STATUS_OK;
    }
    return ONI_STATUS_ERROR;
}

oni::driver::DeviceBase* Driver::deviceOpen(const char* uri, const char* /*mode*/) {
    std::optional<CameraInfo> camera;
    {
        std::lock_guard lock(cameras_mutex_);
        for (const CameraInfo& c : cameras_) {
            if (uri && std::strcmp(c.info.uri, uri) == 0)
                camera = c;
        }
    }
    if (!camera || !context_) {
        errorText(std::string("no Kinect at ") + (uri ? uri : "(null)"));
        return nullptr;
    }
    // By serial, which names the camera whatever else is plugged in since it was listed.
    freenect_device* device = nullptr;
    std::unique_lock usb_lock(usb_mutex_);
    const int result =
        freenect_open_device_by_camera_serial(context_, &device, camera->serial.c_str());
    if (result < 0 || !device) {
        // freenect_open_device hands out (and keeps listed) a device whose camera set-up
        // failed; only closing it releases the camera and unlinks it from the context.
        if (device)
            freenect_close_device(device);
        usb_lock.unlock();
        errorText("libfreenect could not open the Kinect with serial " + camera->serial + " (" +
                  std::to_string(result) + ")");
        return nullptr;
    }
    auto* opened = new (std::nothrow) Device(*this, device, *camera);
    if (!opened)
        freenect_close_device(device);
    return opened;  // the Device constructor does no I/O
}

void Driver::deviceClose(oni::driver::DeviceBase* device) {
    delete static_cast<Device*>(device);
}

void Driver::runEvents() {
    // A camera announced by the kernel may not be openable yet (udev is still setting its
    // node's permissions): it is listed again, every 250 ms for 5 s, until its serial reads.
    constexpr auto kRetryEvery = std::chrono::milliseconds(250);
    constexpr int kRetries = 20;
    int retries = 0;
    auto retry_at = std::chrono::steady_clock::now();
    while (!stop_events_) {
        timeval timeout{0, 50'000};
        if (freenect_process_events_timeout(context_, &timeout) < 0)
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        const bool announced = rescan_.exchange(false);
        if (announced)
            retries = kRetries;
        if (announced || (retries > 0 && std::chrono::steady_clock::now() >= retry_at)) {
            retries = enumerate(true) ? 0 : retries - 1;
            retry_at = std::chrono::steady_clock::now() + kRetryEvery;
        }
    }
}

void Driver::shutdown() {
    if (have_hotplug_) {
        libusb_hotplug_deregister_callback(usb_, hotplug_);
        have_hotplug_ = false;
    }
    if (events_.joinable()) {
        stop_events_ = true;
        events_.join();
    }
    if (context_) {
        freenect_shutdown(context_);
        context_ = nullptr;
    }
    if (usb_) {
        libusb_exit(usb_);
        usb_ = nullptr;
    }
    std::lock_guard lock(cameras_mutex_);
    cameras_.clear();
}

}  // namespace
}  // namespace mixray::openni2::freenect

ONI_EXPORT_DRIVER(mixray::openni2::freenect::Driver)
