// OpenNI2 devices and recordings: options, opening, the capture thread and enumeration.
#include "mixray/openni2/openni2_backend.h"

#include <OpenNI.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <functional>
#include <optional>
#include <set>
#include <thread>

#include "mixray/graph/clock.h"
#include "mixray/graph/device_options.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/thread_priority.h"

namespace mixray::openni2 {
namespace {

constexpr int kWaitMs = 100;
constexpr auto kDriverDrain = std::chrono::milliseconds(200);
constexpr const char* kKnownOptions =
    "streams, <stream>.width, <stream>.height, <stream>.fps, <stream>.format, registration, "
    "sync, pace, speed, "
    "loop, seek, buffers, reconnect, clock_domain";
// How often the capture thread looks for a lost device, and how it waits meanwhile.
constexpr auto kReopenPeriod = std::chrono::milliseconds(250);
constexpr auto kLostSlice = std::chrono::milliseconds(25);

// Runs capture loops on threads that never exit. Debian's OpenNI2 2.2.0.33 keeps a wait event
// for every thread that ever waited for frames and, when a new thread first waits, probes each
// recorded thread with pthread_kill(thread, 0): the descriptor of a thread that exited and was
// joined may be unmapped by then, and the probe crashed (start/stop cycles of the compliance
// suite, tests/compliance). A thread that called OpenNI2 is therefore kept and given the next
// device's capture loop.
class CaptureThreads {
public:
    static std::shared_ptr<OpenNI2Device::CaptureJob> run(std::function<void()> work) {
        // Never destroyed: its threads outlive main().
        static auto* threads = new CaptureThreads;
        return threads->submit(std::move(work));
    }

private:
    struct Task {
        std::function<void()> work;
        std::shared_ptr<OpenNI2Device::CaptureJob> job;
    };

    std::shared_ptr<OpenNI2Device::CaptureJob> submit(std::function<void()> work) {
        auto job = std::make_shared<OpenNI2Device::CaptureJob>();
        std::lock_guard lock(mutex_);
        tasks_.push_back({std::move(work), job});
        if (tasks_.size() > idle_)
            std::thread([this] { loop(); }).detach();
        else
            wake_.notify_one();
        return job;
    }

    void loop() {
        for (;;) {
            std::unique_lock lock(mutex_);
            ++idle_;
            wake_.wait(lock, [this] { return !tasks_.empty(); });
            --idle_;
            Task task = std::move(tasks_.front());
            tasks_.pop_front();
            lock.unlock();
            task.work();
            task.job->finish();
        }
    }

    std::mutex mutex_;
    std::condition_variable wake_;
    std::deque<Task> tasks_;
    size_t idle_ = 0;
};

// Pixel x of `out` is pixel width - 1 - x of `in`. The pixel size is a constant in each loop:
// a memcpy call per pixel took more than the whole rest of a frame's capture (bench drivers).
template <size_t kPixel>
void unmirrorPixels(const uint8_t* in, uint8_t* out, int width) {
    const uint8_t* from = in + static_cast<size_t>(width - 1) * kPixel;
    for (int x = 0; x < width; ++x, out += kPixel, from -= kPixel)
        std::memcpy(out, from, kPixel);
}

void unmirrorRow(const uint8_t* in, uint8_t* out, int width, size_t pixel) {
    switch (pixel) {
        case 1:
            return unmirrorPixels<1>(in, out, width);
        case 2:
            return unmirrorPixels<2>(in, out, width);
        case 3:
            return unmirrorPixels<3>(in, out, width);
        case 4:
            return unmirrorPixels<4>(in, out, width);
        default:
            for (int x = 0; x < width; ++x) {
                std::memcpy(out + static_cast<size_t>(x) * pixel,
                            in + static_cast<size_t>(width - 1 - x) * pixel, pixel);
            }
    }
}

std::string openniError() {
    std::string text = openni::OpenNI::getExtendedError();
    // OpenNI2 indents its messages with tabs and ends them with newlines.
    text.erase(std::remove(text.begin(), text.end(), '\t'), text.end());
    while (!text.empty() && (text.back() == '\n' || text.back() == ' '))
        text.pop_back();
    return text.empty() ? "no detail from OpenNI2" : text;
}

// OpenNI2 is initialised once per process and never shut down: its context keeps an event
// per thread that ever waited for frames, keyed by thread id, and after a shutdown and a new
// initialisation a capture thread that reuses such an id crashes in waitForAnyStream (seen
// with Debian's 2.2.0.33 when one device was closed and the next opened).
class Library {
public:
    static Result<std::shared_ptr<Library>> acquire() {
        static std::mutex mutex;
        static std::shared_ptr<Library> library;
        std::lock_guard lock(mutex);
        if (!library) {
            if (openni::OpenNI::initialize() != openni::STATUS_OK) {
                return {ErrorCode::kInternal, "OpenNI2 failed to initialise: " + openniError()};
            }
            library.reset(new Library());
            // The listener lives as long as OpenNI2 (never shut down, see above).
            static Hotplug hotplug;
            library->hotplug_ = &hotplug;
            if (openni::OpenNI::addDeviceDisconnectedListener(&hotplug) != openni::STATUS_OK) {
                library.reset();
                return {ErrorCode::kInternal,
                        "OpenNI2 refused a device-disconnected listener: " + openniError()};
            }
        }
        return library;
    }
    Library(const Library&) = delete;
    Library& operator=(const Library&) = delete;

    // How many times OpenNI2 announced the device `uri` disconnected since initialisation: a
    // capture thread compares it with the count when it opened the device.
    uint64_t disconnects(const std::string& uri) const { return hotplug_->count(uri); }

private:
    // OpenNI2 calls the listener on its own thread (the drivers' hot-plug events).
    class Hotplug : public openni::OpenNI::DeviceDisconnectedListener {
    public:
        void onDeviceDisconnected(const openni::DeviceInfo* info) override {
            std::lock_guard lock(mutex_);
            ++counts_[info->getUri()];
        }
        uint64_t count(const std::string& uri) const {
            std::lock_guard lock(mutex_);
            auto it = counts_.find(uri);
            return it == counts_.end() ? 0 : it->second;
        }

    private:
        mutable std::mutex mutex_;
        std::map<std::string, uint64_t> counts_;
    };

    Library() = default;
    Hotplug* hotplug_ = nullptr;
};

// Recordings open in this process. OpenNI2 hands a second open of the same file the first
// one's player (one position, one end), so a second device on it is refused instead.
class OpenRecordings {
public:
    static bool claim(const std::string& path) {
        std::lock_guard lock(mutex());
        return paths().insert(path).second;
    }
    static void release(const std::string& path) {
        std::lock_guard lock(mutex());
        paths().erase(path);
    }

private:
    static std::mutex& mutex() {
        static std::mutex m;
        return m;
    }
    static std::set<std::string>& paths() {
        static std::set<std::string> p;
        return p;
    }
};

std::optional<Sensor> sensorFromString(std::string_view name) {
    if (name == "depth")
        return Sensor::kDepth;
    if (name == "color")
        return Sensor::kColor;
    if (name == "ir")
        return Sensor::kInfrared;
    return std::nullopt;
}

openni::SensorType sensorType(Sensor sensor) {
    switch (sensor) {
        case Sensor::kDepth:
            return openni::SENSOR_DEPTH;
        case Sensor::kColor:
            return openni::SENSOR_COLOR;
        case Sensor::kInfrared:
            return openni::SENSOR_IR;
    }
    return openni::SENSOR_DEPTH;
}

StreamKind kindOf(Sensor sensor) {
    switch (sensor) {
        case Sensor::kDepth:
            return StreamKind::kDepth;
        case Sensor::kColor:
            return StreamKind::kColor;
        case Sensor::kInfrared:
            return StreamKind::kInfrared;
    }
    return StreamKind::kData;
}

// The graph format of an OpenNI2 pixel format this backend delivers; kUnknown for the others
// (100 µm depth, shifts, YUV and JPEG colour), which open() avoids by choosing another mode.
PixelFormat graphFormat(Sensor sensor, openni::PixelFormat format) {
    switch (sensor) {
        case Sensor::kDepth:
            return format == openni::PIXEL_FORMAT_DEPTH_1_MM ? PixelFormat::kDepth16
                                                             : PixelFormat::kUnknown;
        case Sensor::kColor:
            return format == openni::PIXEL_FORMAT_RGB888 ? PixelFormat::kRGB8
                                                         : PixelFormat::kUnknown;
        case Sensor::kInfrared:
            if (format == openni::PIXEL_FORMAT_GRAY16)
                return PixelFormat::kIR16;
            if (format == openni::PIXEL_FORMAT_GRAY8)
                return PixelFormat::kMono8;
            return PixelFormat::kUnknown;
    }
    return PixelFormat::kUnknown;
}

std::string modeText(Sensor sensor, const openni::VideoMode& mode) {
    const PixelFormat format = graphFormat(sensor, mode.getPixelFormat());
    std::string name = format == PixelFormat::kUnknown
                           ? "openni-format-" + std::to_string(mode.getPixelFormat())
                           : std::string(toString(format));
    return std::string(toString(sensor)) + " " + std::to_string(mode.getResolutionX()) + "x" +
           std::to_string(mode.getResolutionY()) + "@" + std::to_string(mode.getFps()) + " " + name;
}

template <typename T>
bool parseNumber(const std::string& text, T& out) {
    const char* end = text.data() + text.size();
    auto [ptr, ec] = std::from_chars(text.data(), end, out);
    return ec == std::errc() && ptr == end;
}

Status badOption(const DeviceConfig& config, const std::string& key, const std::string& value,
                 std::string_view expected) {
    return {ErrorCode::kInvalidArgument, "openni2 device '" + config.name + "': option '" + key +
                                             "': expected " + std::string(expected) + ", got '" +
                                             value + "'"};
}

Status parseSwitch(const DeviceConfig& config, const std::string& key, const std::string& value,
                   bool& out) {
    if (value == "on" || value == "true" || value == "1" || value == "yes") {
        out = true;
    } else if (value == "off" || value == "false" || value == "0" || value == "no") {
        out = false;
    } else {
        return badOption(config, key, value, "on or off");
    }
    return Status::ok();
}

std::string serialOf(openni::Device& device) {
    std::array<char, 256> serial{};
    int size = static_cast<int>(serial.size());
    if (device.getProperty(ONI_DEVICE_PROPERTY_SERIAL_NUMBER, serial.data(), &size) !=
        openni::STATUS_OK) {
        return {};
    }
    serial.back() = '\0';
    return serial.data();
}

std::vector<std::string> supportedModes(openni::Device& device) {
    std::vector<std::string> modes;
    for (Sensor sensor : {Sensor::kDepth, Sensor::kColor, Sensor::kInfrared}) {
        const openni::SensorInfo* info = device.getSensorInfo(sensorType(sensor));
        if (!info)
            continue;
        const auto& list = info->getSupportedVideoModes();
        for (int i = 0; i < list.getSize(); ++i)
            modes.push_back(modeText(sensor, list[i]));
    }
    return modes;
}

std::string modelOf(const openni::DeviceInfo& info) {
    std::string vendor = info.getVendor();
    std::string name = info.getName();
    if (vendor.empty())
        return name;
    return name.empty() ? vendor : vendor + " " + name;
}

}  // namespace

std::string_view toString(Sensor sensor) {
    switch (sensor) {
        case Sensor::kDepth:
            return "depth";
        case Sensor::kColor:
            return "color";
        case Sensor::kInfrared:
            return "ir";
    }
    return "unknown";
}

ClockDomainId defaultClockDomain(std::string_view device_name) {
    return deviceClockDomain("openni2", device_name);
}

Result<OpenNI2Options> OpenNI2Options::fromConfig(const DeviceConfig& config) {
    OpenNI2Options o;
    std::map<Sensor, SensorRequest> modes;
    std::vector<std::string> names = config.streams;
    for (const auto& [key, value] : config.options) {
        const size_t dot = key.rfind('.');
        if (dot != std::string::npos) {
            const auto sensor = sensorFromString(std::string_view(key).substr(0, dot));
            const std::string field = key.substr(dot + 1);
            if (!sensor ||
                (field != "width" && field != "height" && field != "fps" && field != "format")) {
                return {ErrorCode::kInvalidArgument,
                        "openni2 device '" + config.name + "': unknown option '" + key +
                            "' (known: " + kKnownOptions + "; streams: depth, color, ir)"};
            }
            SensorRequest& request = modes[*sensor];
            request.sensor = *sensor;
            if (field == "format") {
                const auto format = pixelFormatFromString(value);
                if (!format)
                    return badOption(config, key, value, "a pixel format such as depth16 or rgb8");
                request.format = *format;
            } else if (field == "fps") {
                // Rig files write rates as decimals; OpenNI2 modes have whole rates.
                double fps = 0;
                if (!parseNumber(value, fps) || !(fps > 0) || fps > 10000 ||
                    std::abs(fps - std::round(fps)) > 0.01) {
                    return badOption(config, key, value, "a whole frame rate such as 30");
                }
                request.fps = static_cast<int>(std::lround(fps));
            } else {
                int number = 0;
                if (!parseNumber(value, number) || number <= 0 || number > 16384)
                    return badOption(config, key, value, "a positive whole number");
                (field == "width" ? request.width : request.height) = number;
            }
        } else if (key == "streams") {
            if (!config.streams.empty()) {
                return {ErrorCode::kInvalidArgument,
                        "openni2 device '" + config.name +
                            "': streams are listed both in the rig's stream list and in option "
                            "'streams'; give them once"};
            }
            names = splitOptionList(value);
            if (names.empty())
                return badOption(config, key, value, "a comma list of depth, color, ir");
        } else if (key == "registration") {
            MIXRAY_RETURN_IF_ERROR(parseSwitch(config, key, value, o.registration));
        } else if (key == "sync") {
            bool on = false;
            MIXRAY_RETURN_IF_ERROR(parseSwitch(config, key, value, on));
            o.sync = on ? 1 : 0;
        } else if (key == "pace") {
            if (value == "original") {
                o.pace = Pace::kOriginal;
            } else if (value == "fast") {
                o.pace = Pace::kFast;
            } else {
                return badOption(config, key, value, "original or fast");
            }
        } else if (key == "speed") {
            if (!parseNumber(value, o.speed) || !std::isfinite(o.speed) || o.speed <= 0 ||
                o.speed > 1000) {
                return badOption(config, key, value, "a positive number such as 0.5 or 2");
            }
            o.speed_given = true;
        } else if (key == "loop") {
            MIXRAY_RETURN_IF_ERROR(parseSwitch(config, key, value, o.loop));
        } else if (key == "seek") {
            if (!parseNumber(value, o.seek) || o.seek < 1)
                return badOption(config, key, value, "a frame number >= 1");
        } else if (key == "buffers") {
            if (!parseNumber(value, o.buffers) || o.buffers < 1 || o.buffers > 1024)
                return badOption(config, key, value, "a whole number from 1 to 1024");
        } else if (key == "reconnect") {
            MIXRAY_RETURN_IF_ERROR(parseSwitch(config, key, value, o.reconnect));
        } else if (key == "clock_domain") {
            if (!parseNumber(value, o.clock_domain) || o.clock_domain == kHostClockDomain)
                return badOption(config, key, value, "an integer >= 1 (0 is the host clock)");
        } else {
            return {ErrorCode::kInvalidArgument, "openni2 device '" + config.name +
                                                     "': unknown option '" + key +
                                                     "' (known: " + kKnownOptions + ")"};
        }
    }
    if (o.speed_given && o.pace == Pace::kFast) {
        return {ErrorCode::kInvalidArgument,
                "openni2 device '" + config.name +
                    "': option 'speed' applies only with pace=original (pace=fast already goes "
                    "as fast as consumers allow)"};
    }
    for (const std::string& name : names) {
        const auto sensor = sensorFromString(name);
        if (!sensor) {
            return {ErrorCode::kInvalidArgument, "openni2 device '" + config.name +
                                                     "': no stream '" + name +
                                                     "' (streams: depth, color, ir)"};
        }
        for (const auto& existing : o.streams) {
            if (existing.sensor == *sensor) {
                return {ErrorCode::kInvalidArgument,
                        "openni2 device '" + config.name + "': stream '" + name + "' twice"};
            }
        }
        SensorRequest request;
        request.sensor = *sensor;
        o.streams.push_back(request);
    }
    for (const auto& [sensor, request] : modes) {
        if (!names.empty() && std::none_of(o.streams.begin(), o.streams.end(),
                                           // An init-capture: clang 14 cannot capture a
                                           // structured binding (the fuzz build uses clang).
                                           [wanted = sensor](const SensorRequest& r) {
                                               return r.sensor == wanted;
                                           })) {
            return {ErrorCode::kInvalidArgument,
                    "openni2 device '" + config.name + "': a mode is given for stream '" +
                        std::string(toString(sensor)) + "', which is not enabled"};
        }
        o.modes.push_back(request);
    }
    return o;
}

// The OpenNI2 side of a device: everything that needs OpenNI.h.
struct OpenNI2Device::Impl {
    struct Stream {
        Sensor sensor = Sensor::kDepth;
        openni::VideoStream stream;
        openni::VideoMode mode;
        ImageDesc desc;
        bool unmirror = false;
        int recorded_frames = 0;
        bool started = false;
        // Playback bookkeeping.
        int last_index = 0;
        uint64_t pass = 0;
        bool done = false;
        // Live devices: the last sequence read, and what later ones add after a reconnect.
        uint64_t last_sequence = 0;
        uint64_t sequence_offset = 0;
    };

    std::shared_ptr<Library> library;
    std::string claimed_path;  // the recording this device holds in OpenRecordings
    openni::Device device;
    bool is_file = false;
    bool streamed = false;  // a stream was started at least once
    // When a live device's streams last stopped: a driver thread may run on until it notices.
    std::chrono::steady_clock::time_point stopped_at{};
    std::vector<std::unique_ptr<Stream>> streams;
    int64_t pass_length_ns = 0;
    int64_t max_stamp_ns = 0;
    // Live devices: how to find the device again, and whether OpenNI2 announced it gone.
    std::string uri;
    std::string serial;
    uint64_t disconnects_seen = 0;
    // Live devices: the last frame's stamps and the shift of later ones after a reconnect.
    bool have_last = false;
    int64_t last_device_ns = 0;
    int64_t last_host_ns = 0;
    int64_t stamp_offset_ns = 0;
    bool rebase_pending = false;

    ~Impl() {
        for (auto& s : streams) {
            // OpenNI2 may crash destroying a stream that was not stopped.
            if (s->started)
                s->stream.stop();
        }
        if (streamed) {
            // A driver's stream thread may still deliver the frame it was making when the
            // stream stopped: OpenNI2's DummyDevice does not join its threads, and one that
            // wakes after its stream was destroyed crashes. Its threads sleep 33 ms per frame.
            // The recording player's thread walks its stream list without a lock until it sees
            // every stream stopped; destroying a stream under it crashed (1 run in 8 of a
            // recording played to its end).
            std::this_thread::sleep_for(kDriverDrain);
        }
        for (auto& s : streams)
            s->stream.destroy();
        streams.clear();
        if (device.isValid())
            device.close();
        if (!claimed_path.empty())
            OpenRecordings::release(claimed_path);
    }
};

OpenNI2Device::OpenNI2Device(std::string name, OpenNI2Options options, std::unique_ptr<Impl> impl)
    : name_(std::move(name)), options_(std::move(options)), impl_(std::move(impl)) {
    if (options_.clock_domain == kHostClockDomain)
        options_.clock_domain = defaultClockDomain(name_);
}

OpenNI2Device::~OpenNI2Device() {
    stop();
}

bool OpenNI2Device::isRecording() const {
    return impl_->is_file;
}

std::vector<Sensor> OpenNI2Device::sensors() const {
    std::vector<Sensor> out;
    for (const auto& s : impl_->streams)
        out.push_back(s->sensor);
    return out;
}

std::vector<int> OpenNI2Device::recordedFrameCounts() const {
    std::vector<int> out;
    if (!impl_->is_file)
        return out;
    for (const auto& s : impl_->streams)
        out.push_back(s->recorded_frames);
    return out;
}

std::vector<bool> OpenNI2Device::softwareUnmirror() const {
    std::vector<bool> out;
    for (const auto& s : impl_->streams)
        out.push_back(s->unmirror);
    return out;
}

Status OpenNI2Device::status() const {
    std::lock_guard lock(mutex_);
    return status_;
}

DeviceState OpenNI2Device::state() const {
    if (impl_->is_file)
        return finished_ ? DeviceState::kEnded : DeviceState::kUnknown;
    const Status s = status();
    if (s.code() == ErrorCode::kUnavailable)
        return options_.reconnect && capturing_ ? DeviceState::kReconnecting : DeviceState::kLost;
    if (!s.isOk())
        return DeviceState::kLost;
    return capturing_ ? DeviceState::kStreaming : DeviceState::kUnknown;
}

void OpenNI2Device::setError(Status status) {
    std::lock_guard lock(mutex_);
    if (status_.isOk())
        status_ = std::move(status);
}

void OpenNI2Device::resetError(Status status) {
    std::lock_guard lock(mutex_);
    status_ = std::move(status);
}

void OpenNI2Device::release() {
    Impl& impl = *impl_;
    for (auto& s : impl.streams) {
        if (s->started)
            s->stream.stop();
        s->started = false;
    }
    // The driver's stream threads may still be finishing a frame (see ~Impl).
    std::this_thread::sleep_for(kDriverDrain);
    for (auto& s : impl.streams)
        s->stream.destroy();
    if (impl.device.isValid())
        impl.device.close();
}

bool OpenNI2Device::reopen(std::vector<std::string>& known_uris) {
    Impl& impl = *impl_;
    openni::Array<openni::DeviceInfo> list;
    openni::OpenNI::enumerateDevices(&list);
    std::string uri;
    for (int i = 0; i < list.getSize() && uri.empty(); ++i) {
        if (impl.uri == list[i].getUri())
            uri = impl.uri;
    }
    // A device that comes back on another port has another URI: a newly listed one with the
    // lost device's serial is it. Devices listed while it was gone are not probed again.
    for (int i = 0; i < list.getSize() && uri.empty() && !impl.serial.empty(); ++i) {
        const std::string candidate_uri = list[i].getUri();
        if (std::find(known_uris.begin(), known_uris.end(), candidate_uri) != known_uris.end())
            continue;
        known_uris.push_back(candidate_uri);
        openni::Device candidate;
        if (candidate.open(candidate_uri.c_str()) != openni::STATUS_OK)
            continue;
        if (serialOf(candidate) == impl.serial)
            uri = candidate_uri;
        candidate.close();
    }
    if (uri.empty())
        return false;
    const auto fail = [&](const std::string& why) {
        resetError({ErrorCode::kUnavailable, "openni2 device '" + name_ + "' (" + uri +
                                                 ") is back but cannot be reopened: " + why +
                                                 "; trying again"});
        release();
        return false;
    };
    // The disconnect count is read before opening: an unplug during the reopen is not missed.
    const uint64_t disconnects = impl.library->disconnects(uri);
    if (impl.device.open(uri.c_str()) != openni::STATUS_OK)
        return fail(openniError());
    for (auto& s : impl.streams) {
        const std::string sensor(toString(s->sensor));
        if (s->stream.create(impl.device, sensorType(s->sensor)) != openni::STATUS_OK)
            return fail("creating the " + sensor + " stream: " + openniError());
        const openni::VideoMode current = s->stream.getVideoMode();
        if ((current.getResolutionX() != s->mode.getResolutionX() ||
             current.getResolutionY() != s->mode.getResolutionY() ||
             current.getFps() != s->mode.getFps() ||
             current.getPixelFormat() != s->mode.getPixelFormat()) &&
            s->stream.setVideoMode(s->mode) != openni::STATUS_OK) {
            return fail("setting " + modeText(s->sensor, s->mode) + ": " + openniError());
        }
        if (!s->unmirror && s->stream.getMirroringEnabled() &&
            (s->stream.setMirroringEnabled(false) != openni::STATUS_OK ||
             s->stream.getMirroringEnabled())) {
            return fail("mirroring of " + sensor + " cannot be turned off any more");
        }
    }
    if (options_.registration &&
        impl.device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) !=
            openni::STATUS_OK) {
        return fail("turning registration on: " + openniError());
    }
    const auto has = [&](Sensor sensor) {
        return std::any_of(impl.streams.begin(), impl.streams.end(),
                           [&](const auto& s) { return s->sensor == sensor; });
    };
    if (has(Sensor::kDepth) && has(Sensor::kColor) && options_.sync != 0 &&
        impl.device.setDepthColorSyncEnabled(true) != openni::STATUS_OK && options_.sync == 1) {
        return fail("depth/color sync: " + openniError());
    }
    for (auto& s : impl.streams) {
        if (s->stream.start() != openni::STATUS_OK)
            return fail("starting " + std::string(toString(s->sensor)) + ": " + openniError());
        s->started = true;
        s->sequence_offset = s->last_sequence;
    }
    impl.uri = uri;
    impl.disconnects_seen = disconnects;
    impl.rebase_pending = impl.have_last;
    return true;
}

void OpenNI2Device::countLost(size_t stream, uint64_t frames) {
    dropped_.fetch_add(frames, std::memory_order_relaxed);
    if (graph_ && stream < ids_.size())
        graph_->countLost(ids_[stream], frames);
}

Status OpenNI2Device::connect(Graph& graph) {
    if (graph_)
        return {ErrorCode::kInvalidArgument, "openni2 device '" + name_ + "' connected twice"};
    for (const auto& s : impl_->streams) {
        StreamInfo info;
        info.name = name_ + "/" + std::string(toString(s->sensor));
        info.device = name_;
        info.kind = kindOf(s->sensor);
        info.format = s->desc;
        info.nominal_fps = s->mode.getFps();
        info.clock_domain = options_.clock_domain;
        info.tags["backend"] = "openni2";
        info.tags["openni2_uri"] = impl_->device.getDeviceInfo().getUri();
        if (s->unmirror)
            info.tags["openni2_unmirrored"] = "software";
        // The field of view OpenNI2 reports (a recording replays the recorded one), for
        // consumers that deproject depth (oni_recording.h derives pinhole intrinsics from it).
        const float hfov = s->stream.getHorizontalFieldOfView();
        const float vfov = s->stream.getVerticalFieldOfView();
        if (hfov > 0 && vfov > 0 && std::isfinite(hfov) && std::isfinite(vfov)) {
            char fov[64];
            std::snprintf(fov, sizeof fov, "%.9g,%.9g", static_cast<double>(hfov),
                          static_cast<double>(vfov));
            info.tags[kFieldOfViewTag] = fov;
        }
        auto stream = addPooledStream(graph, info, options_.buffers);
        if (!stream)
            return stream.status().withContext("openni2 device '" + name_ + "'");
        ids_.push_back(stream->id);
        pools_.push_back(std::move(stream->pool));
    }
    graph_ = &graph;
    return Status::ok();
}

Status OpenNI2Device::start() {
    if (!graph_)
        return {ErrorCode::kInvalidArgument, "openni2 device '" + name_ + "': not connected"};
    if (capture_)
        return Status::ok();
    if (!impl_->is_file && !impl_->device.isValid()) {
        // Released when it was lost (and stopped before it came back, or reconnect=false).
        return {ErrorCode::kUnavailable,
                "openni2 device '" + name_ + "' cannot start: " + status().message()};
    }
    if (!impl_->is_file && impl_->streamed) {
        // DummyDevice's stream thread checks its running flag once per frame: a stream started
        // again before the old thread saw it stopped keeps that thread too, and two threads
        // then deliver interleaved frame counts.
        std::this_thread::sleep_until(impl_->stopped_at + kDriverDrain);
    }
    for (auto& s : impl_->streams) {
        if (s->started)
            continue;
        if (s->stream.start() != openni::STATUS_OK) {
            return {ErrorCode::kUnavailable, "openni2 device '" + name_ + "': cannot start " +
                                                 std::string(toString(s->sensor)) + ": " +
                                                 openniError()};
        }
        s->started = true;
        impl_->streamed = true;
    }
    stop_requested_ = false;
    finished_ = false;
    capturing_ = true;
    capture_ = CaptureThreads::run([this] { run(); });
    return Status::ok();
}

void OpenNI2Device::stop() {
    stop_requested_ = true;
    if (capture_) {
        capture_->wait();
        capture_.reset();
    }
    for (auto& s : impl_->streams) {
        if (s->started) {
            s->stream.stop();
            s->started = false;
            impl_->stopped_at = std::chrono::steady_clock::now();
        }
    }
}

void OpenNI2Device::run() {
    runAs(ThreadRole::kCapture);  // a frame late here is a frame lost (thread_priority.h)
    Impl& impl = *impl_;
    const size_t n = impl.streams.size();
    std::vector<openni::VideoStream*> handles;
    for (auto& s : impl.streams)
        handles.push_back(&s->stream);
    // A recording waits for buffers: every frame of a file reaches the graph.
    const bool waits_for_buffers = impl.is_file;
    // Seeking reads and drops frames: OpenNI2's own seek command never returns on recordings
    // it cannot seek (see README.md).
    bool seeking = impl.is_file && options_.seek > 1;
    // Recordings: host stamps follow the frames' own timestamps from the first frame published
    // (divided by the speed), and pace=original waits until each one is due.
    bool clock_started = false;
    int64_t host0_ns = 0;
    int64_t device0_ns = 0;
    const double speed = options_.pace == OpenNI2Options::Pace::kFast ? 1.0 : options_.speed;
    int timeouts_after_end = 0;
    for (auto& s : impl.streams)
        s->done = impl.is_file && s->recorded_frames <= 0;

    // A lost live device is released and reported, then looked for until it is back (true) or
    // the device stops or must not reconnect (false).
    const auto lose = [&](const std::string& why) {
        release();
        resetError({ErrorCode::kUnavailable,
                    "openni2 device '" + name_ + "' (" + impl.uri +
                        (impl.serial.empty() ? "" : ", serial " + impl.serial) + ") was lost (" +
                        why + "); " +
                        (options_.reconnect ? "reopening it when it returns" : "its streams end")});
        if (!options_.reconnect) {
            for (StreamId id : ids_)
                graph_->endStream(id);
            return false;
        }
        std::vector<std::string> known_uris;
        openni::Array<openni::DeviceInfo> list;
        openni::OpenNI::enumerateDevices(&list);
        for (int i = 0; i < list.getSize(); ++i) {
            if (impl.uri != list[i].getUri())
                known_uris.emplace_back(list[i].getUri());
        }
        auto next_try = std::chrono::steady_clock::now();
        while (!stop_requested_) {
            if (std::chrono::steady_clock::now() >= next_try) {
                if (reopen(known_uris)) {
                    reconnects_.fetch_add(1);
                    resetError(Status::ok());
                    return true;
                }
                next_try = std::chrono::steady_clock::now() + kReopenPeriod;
            }
            std::this_thread::sleep_for(kLostSlice);
        }
        return false;
    };

    while (!stop_requested_) {
        if (!impl.is_file && impl.library->disconnects(impl.uri) != impl.disconnects_seen) {
            if (!lose("OpenNI2 reported it disconnected"))
                break;
            continue;
        }
        int index = -1;
        const openni::Status rc =
            openni::OpenNI::waitForAnyStream(handles.data(), static_cast<int>(n), &index, kWaitMs);
        if (rc == openni::STATUS_TIME_OUT) {
            // A recording's player stops at its end; done streams already account for it.
            if (impl.is_file && !options_.loop && ++timeouts_after_end > 50) {
                std::string missing;
                for (size_t i = 0; i < n; ++i) {
                    const Impl::Stream& st = *impl.streams[i];
                    if (st.done || st.last_index >= st.recorded_frames)
                        continue;
                    countLost(i, static_cast<uint64_t>(st.recorded_frames - st.last_index));
                    missing += (missing.empty() ? "" : ", ") +
                               std::to_string(st.recorded_frames - st.last_index) + " of " +
                               std::to_string(st.recorded_frames) + " " +
                               std::string(toString(st.sensor)) + " frames";
                }
                setError({ErrorCode::kCorruptData,
                          "openni2 device '" + name_ +
                              "': the recording stopped delivering frames before its recorded "
                              "count (" +
                              (missing.empty() ? "none" : missing) + " never came)"});
                for (StreamId id : ids_)
                    graph_->endStream(id);
                break;
            }
            continue;
        }
        if (rc != openni::STATUS_OK || index < 0 || static_cast<size_t>(index) >= n) {
            if (!impl.is_file) {
                if (!lose("waiting for frames: " + openniError()))
                    break;
                continue;
            }
            setError({ErrorCode::kUnavailable,
                      "openni2 device '" + name_ + "': waiting for frames: " + openniError()});
            break;
        }
        timeouts_after_end = 0;
        Impl::Stream& s = *impl.streams[static_cast<size_t>(index)];
        openni::VideoFrameRef frame;
        if (s.stream.readFrame(&frame) != openni::STATUS_OK || !frame.isValid()) {
            if (!impl.is_file) {
                if (!lose("reading a frame: " + openniError()))
                    break;
                continue;
            }
            setError({ErrorCode::kUnavailable,
                      "openni2 device '" + name_ + "': reading a frame: " + openniError()});
            break;
        }
        int64_t host_ns = monotonicNowNs();
        const int frame_index = frame.getFrameIndex();
        int64_t device_ns = static_cast<int64_t>(frame.getTimestamp()) * 1000;

        if (impl.is_file) {
            if (frame_index < s.last_index) {
                // OpenNI2's repeat restarted the recording: later passes continue time.
                if (impl.pass_length_ns == 0) {
                    const double fps = s.mode.getFps() > 0 ? s.mode.getFps() : 30.0;
                    impl.pass_length_ns = impl.max_stamp_ns + std::llround(1e9 / fps);
                }
                ++s.pass;
            } else if (frame_index > s.last_index + 1 && !seeking) {
                // Frames OpenNI2 numbered but never handed over: counted and said.
                countLost(static_cast<size_t>(index),
                          static_cast<uint64_t>(frame_index - s.last_index - 1));
            }
            s.last_index = frame_index;
            if (s.pass == 0)
                impl.max_stamp_ns = std::max(impl.max_stamp_ns, device_ns);
            if (seeking) {
                if (index != 0 || frame_index < options_.seek)
                    continue;
                seeking = false;
            }
            device_ns += static_cast<int64_t>(s.pass) * impl.pass_length_ns;
            if (!clock_started) {
                clock_started = true;
                host0_ns = host_ns;
                device0_ns = device_ns;
            }
            host_ns = host0_ns + std::llround(static_cast<double>(device_ns - device0_ns) / speed);
            if (options_.pace == OpenNI2Options::Pace::kOriginal) {
                while (!stop_requested_ && monotonicNowNs() < host_ns) {
                    std::this_thread::sleep_for(std::min<std::chrono::nanoseconds>(
                        std::chrono::nanoseconds(host_ns - monotonicNowNs()), kLostSlice));
                }
                if (stop_requested_)
                    break;
            }
        }
        uint64_t sequence = static_cast<uint64_t>(frame_index) +
                            s.pass * static_cast<uint64_t>(std::max(s.recorded_frames, 0));
        if (!impl.is_file) {
            // After a reconnect the device counts frames and time from its start again: the
            // graph's sequences and stamps continue instead (see the header).
            if (impl.rebase_pending) {
                impl.stamp_offset_ns =
                    impl.last_device_ns + (host_ns - impl.last_host_ns) - device_ns;
                impl.rebase_pending = false;
            }
            device_ns += impl.stamp_offset_ns;
            sequence += s.sequence_offset;
            s.last_sequence = sequence;
            impl.have_last = true;
            impl.last_device_ns = device_ns;
            impl.last_host_ns = host_ns;
        }

        const int width = frame.getWidth();
        const int height = frame.getHeight();
        if (width != s.desc.width || height != s.desc.height) {
            setError({ErrorCode::kCorruptData,
                      "openni2 device '" + name_ + "': " + std::string(toString(s.sensor)) +
                          " frame of " + std::to_string(width) + "x" + std::to_string(height) +
                          " in a stream of " + std::to_string(s.desc.width) + "x" +
                          std::to_string(s.desc.height)});
            break;
        }
        BufferPool& pool = *pools_[static_cast<size_t>(index)];
        WritableFrame out = pool.acquire();
        while (!out && waits_for_buffers && !stop_requested_) {
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
            out = pool.acquire();
        }
        if (!out) {
            if (stop_requested_)
                break;
            countLost(static_cast<size_t>(index), 1);
        } else {
            const auto* src = static_cast<const uint8_t*>(frame.getData());
            const int src_stride = frame.getStrideInBytes();
            MutableImageView dst = out.image();
            const size_t pixel = pixelFormatInfo(s.desc.format).bits_per_pixel / 8;
            const size_t row_bytes = static_cast<size_t>(width) * pixel;
            for (int y = 0; y < height; ++y) {
                const uint8_t* in = src + static_cast<size_t>(y) * src_stride;
                uint8_t* row = dst.row<uint8_t>(y);
                if (!s.unmirror) {
                    std::memcpy(row, in, row_bytes);
                    continue;
                }
                unmirrorRow(in, row, width, pixel);
            }
            FrameMetadata& meta = out.meta();
            meta.stream = ids_[static_cast<size_t>(index)];
            meta.sequence = sequence;
            meta.device_stamp_ns = device_ns;
            meta.host_stamp_ns = host_ns;
            meta.clock_domain = options_.clock_domain;
            graph_->publish(std::move(out).publish());
            published_.fetch_add(1, std::memory_order_relaxed);
        }

        if (impl.is_file && !options_.loop && frame_index >= s.recorded_frames) {
            s.done = true;
            bool all = true;
            for (const auto& other : impl.streams)
                all = all && other->done;
            if (all) {
                for (StreamId id : ids_)
                    graph_->endStream(id);
                break;
            }
        }
    }
    finished_ = true;
    capturing_ = false;
}

Result<std::vector<DeviceDescriptor>> OpenNI2Backend::enumerate() {
    auto library = Library::acquire();
    if (!library)
        return library.status();
    openni::Array<openni::DeviceInfo> list;
    openni::OpenNI::enumerateDevices(&list);
    std::vector<DeviceDescriptor> out;
    for (int i = 0; i < list.getSize(); ++i) {
        const openni::DeviceInfo& info = list[i];
        DeviceDescriptor d;
        d.backend = "openni2";
        d.id = info.getUri();
        d.model = modelOf(info);
        d.location = info.getUri();
        // A device streaming in another process cannot be opened: it is listed without its
        // serial and modes rather than hidden.
        openni::Device device;
        if (device.open(info.getUri()) == openni::STATUS_OK) {
            d.serial = serialOf(device);
            d.modes = supportedModes(device);
            device.close();
        }
        out.push_back(std::move(d));
    }
    return out;
}

Result<std::unique_ptr<Device>> OpenNI2Backend::open(const DeviceConfig& config) {
    if (config.name.empty()) {
        return {ErrorCode::kInvalidArgument,
                "openni2 device without a name (streams are named <name>/<stream>)"};
    }
    auto options = OpenNI2Options::fromConfig(config);
    if (!options)
        return options.status();
    auto library = Library::acquire();
    if (!library)
        return library.status();
    auto impl = std::make_unique<OpenNI2Device::Impl>();
    impl->library = *library;
    const std::string context = "openni2 device '" + config.name + "'";

    // The id is a recording's path, a URI or a serial, tried in that order.
    std::error_code ec;
    if (!config.id.empty() && std::filesystem::is_regular_file(config.id, ec)) {
        const std::string path = std::filesystem::weakly_canonical(config.id, ec).string();
        if (!OpenRecordings::claim(path)) {
            return {ErrorCode::kUnavailable,
                    context + ": '" + config.id +
                        "' is already open in this process (OpenNI2 would share one player "
                        "between the two devices)"};
        }
        impl->claimed_path = path;
        if (impl->device.open(config.id.c_str()) != openni::STATUS_OK) {
            return {ErrorCode::kCorruptData,
                    context + ": OpenNI2 cannot play '" + config.id + "': " + openniError()};
        }
    } else if (config.id.empty()) {
        if (impl->device.open(openni::ANY_DEVICE) != openni::STATUS_OK) {
            return {ErrorCode::kNotFound, context + ": no OpenNI2 device: " + openniError()};
        }
    } else if (impl->device.open(config.id.c_str()) != openni::STATUS_OK) {
        const std::string uri_error = openniError();
        openni::Array<openni::DeviceInfo> list;
        openni::OpenNI::enumerateDevices(&list);
        bool found = false;
        for (int i = 0; i < list.getSize() && !found; ++i) {
            openni::Device candidate;
            if (candidate.open(list[i].getUri()) != openni::STATUS_OK)
                continue;
            found = serialOf(candidate) == config.id;
            candidate.close();
            if (found && impl->device.open(list[i].getUri()) != openni::STATUS_OK) {
                return {ErrorCode::kUnavailable, context + ": cannot open '" +
                                                     std::string(list[i].getUri()) + "' (serial " +
                                                     config.id + "): " + openniError()};
            }
        }
        if (!found) {
            return {ErrorCode::kNotFound, context + ": '" + config.id +
                                              "' is neither a recording, an OpenNI2 URI nor the "
                                              "serial of a connected device (" +
                                              uri_error + ")"};
        }
    }
    impl->is_file = impl->device.isFile();
    OpenNI2Options& o = *options;

    if (impl->is_file && config.options.count("reconnect")) {
        return {ErrorCode::kInvalidArgument,
                context + ": option 'reconnect' applies to live devices only"};
    }
    if (!impl->is_file) {
        impl->uri = impl->device.getDeviceInfo().getUri();
        impl->serial = serialOf(impl->device);
        impl->disconnects_seen = (*library)->disconnects(impl->uri);
        for (const char* key : {"pace", "speed", "loop", "seek"}) {
            if (config.options.count(key)) {
                return {ErrorCode::kInvalidArgument,
                        context + ": option '" + std::string(key) + "' applies to recordings only"};
            }
        }
    }
    if (o.streams.empty()) {
        for (Sensor sensor : {Sensor::kDepth, Sensor::kColor}) {
            if (impl->device.hasSensor(sensorType(sensor))) {
                SensorRequest request;
                request.sensor = sensor;
                o.streams.push_back(request);
            }
        }
        if (o.streams.empty())
            return {ErrorCode::kUnsupported, context + ": the device has no depth or color"};
    }
    for (const SensorRequest& mode : o.modes) {
        auto it = std::find_if(o.streams.begin(), o.streams.end(),
                               [&](const SensorRequest& r) { return r.sensor == mode.sensor; });
        if (it == o.streams.end()) {
            return {ErrorCode::kInvalidArgument, context + ": a mode is given for stream '" +
                                                     std::string(toString(mode.sensor)) +
                                                     "', which is not enabled"};
        }
        *it = mode;
    }

    for (const SensorRequest& request : o.streams) {
        const std::string sensor_name(toString(request.sensor));
        if (!impl->device.hasSensor(sensorType(request.sensor))) {
            return {ErrorCode::kNotFound, context + ": " +
                                              (impl->is_file ? "the recording" : "the device") +
                                              " has no " + sensor_name + " stream"};
        }
        auto s = std::make_unique<OpenNI2Device::Impl::Stream>();
        s->sensor = request.sensor;
        if (s->stream.create(impl->device, sensorType(request.sensor)) != openni::STATUS_OK) {
            return {ErrorCode::kUnavailable,
                    context + ": cannot create the " + sensor_name + " stream: " + openniError()};
        }
        openni::VideoMode mode = s->stream.getVideoMode();
        const auto matches = [&](const openni::VideoMode& m) {
            return (request.width == 0 || m.getResolutionX() == request.width) &&
                   (request.height == 0 || m.getResolutionY() == request.height) &&
                   (request.fps == 0 || m.getFps() == request.fps) &&
                   graphFormat(request.sensor, m.getPixelFormat()) != PixelFormat::kUnknown &&
                   (request.format == PixelFormat::kUnknown ||
                    graphFormat(request.sensor, m.getPixelFormat()) == request.format);
        };
        if (!matches(mode)) {
            if (impl->is_file) {
                return {ErrorCode::kInvalidArgument, context + ": the recording's " + sensor_name +
                                                         " stream is " +
                                                         modeText(request.sensor, mode) +
                                                         " (a recording cannot change its mode)"};
            }
            const auto& list = s->stream.getSensorInfo().getSupportedVideoModes();
            bool chosen = false;
            for (int i = 0; i < list.getSize() && !chosen; ++i) {
                if (!matches(list[i]))
                    continue;
                if (s->stream.setVideoMode(list[i]) != openni::STATUS_OK) {
                    return {ErrorCode::kUnavailable, context + ": cannot set " +
                                                         modeText(request.sensor, list[i]) + ": " +
                                                         openniError()};
                }
                chosen = true;
            }
            if (!chosen) {
                std::string offered;
                for (int i = 0; i < list.getSize(); ++i) {
                    offered += (offered.empty() ? "" : ", ") + modeText(request.sensor, list[i]);
                }
                return {ErrorCode::kUnsupported,
                        context + ": no " + sensor_name +
                            " mode matches the request (offered: " + offered + ")"};
            }
            mode = s->stream.getVideoMode();
        }
        s->mode = mode;
        s->desc = ImageDesc::packed(graphFormat(request.sensor, mode.getPixelFormat()),
                                    mode.getResolutionX(), mode.getResolutionY());
        // Mirroring off; what the device or recording cannot turn off is undone in software.
        if (s->stream.getMirroringEnabled()) {
            if (impl->is_file || s->stream.setMirroringEnabled(false) != openni::STATUS_OK ||
                s->stream.getMirroringEnabled()) {
                s->unmirror = true;
            }
        }
        if (impl->is_file) {
            s->recorded_frames = impl->device.getPlaybackControl()->getNumberOfFrames(s->stream);
        }
        impl->streams.push_back(std::move(s));
    }

    const auto has = [&](Sensor sensor) {
        return std::any_of(o.streams.begin(), o.streams.end(),
                           [&](const SensorRequest& r) { return r.sensor == sensor; });
    };
    if (o.registration) {
        if (!impl->device.isImageRegistrationModeSupported(
                openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
            return {ErrorCode::kUnsupported,
                    context + ": " +
                        (impl->is_file ? "a recording plays what was recorded; it cannot register "
                                         "depth to color"
                                       : "the device cannot register depth to color")};
        }
        if (impl->device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) !=
            openni::STATUS_OK) {
            return {ErrorCode::kUnavailable,
                    context + ": cannot turn registration on: " + openniError()};
        }
    } else if (!impl->is_file &&
               impl->device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_OFF)) {
        (void)impl->device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_OFF);
    }
    if (!impl->is_file && has(Sensor::kDepth) && has(Sensor::kColor)) {
        const bool want = o.sync != 0;
        if (impl->device.setDepthColorSyncEnabled(want) != openni::STATUS_OK && o.sync == 1) {
            return {ErrorCode::kUnsupported,
                    context + ": the device cannot sync depth and color: " + openniError()};
        }
    }

    if (impl->is_file) {
        openni::PlaybackControl* playback = impl->device.getPlaybackControl();
        if (o.seek > impl->streams.front()->recorded_frames) {
            return {ErrorCode::kInvalidArgument,
                    context + ": seek=" + std::to_string(o.seek) + " is past the " +
                        std::to_string(impl->streams.front()->recorded_frames) + " frames of the " +
                        std::string(toString(impl->streams.front()->sensor)) + " stream"};
        }
        // Always OpenNI2's manual playback (speed -1): a frame is produced only when the previous
        // one was read, so none is lost however slow the consumers. OpenNI2's timed playback
        // replaces a frame not yet read by the next one without a word (8 of 12 depth frames
        // of the Kinect recording reached a rig); pace=original is kept by the capture thread,
        // which waits for each frame's own timestamp instead.
        if (playback->setSpeed(-1.0f) != openni::STATUS_OK ||
            playback->setRepeatEnabled(o.loop) != openni::STATUS_OK) {
            return {ErrorCode::kInternal,
                    context + ": OpenNI2 refused the playback settings: " + openniError()};
        }
    }

    std::unique_ptr<OpenNI2Device> device(
        new OpenNI2Device(config.name, std::move(o), std::move(impl)));
    const openni::DeviceInfo& info = device->impl_->device.getDeviceInfo();
    device->descriptor_.backend = "openni2";
    device->descriptor_.id = config.id.empty() ? info.getUri() : config.id;
    device->descriptor_.model =
        device->impl_->is_file ? "OpenNI recording (" + modelOf(info) + ")" : modelOf(info);
    device->descriptor_.serial = serialOf(device->impl_->device);
    device->descriptor_.location = info.getUri();
    for (const auto& s : device->impl_->streams)
        device->descriptor_.modes.push_back(modeText(s->sensor, s->mode));
    return std::unique_ptr<Device>(std::move(device));
}

}  // namespace mixray::openni2
