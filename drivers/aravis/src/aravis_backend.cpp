// Aravis cameras: opening and configuring, the capture loop with loss and reconnection, and
// the backend that discovers them.
#include "mixray/aravis/aravis_backend.h"

#include <arv.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "mixray/graph/clock.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/thread_priority.h"

namespace mixray::aravis {
namespace {

// Aravis's device list (discovery, opening by id) is global and not thread-safe; backends
// and reconnecting capture threads share it.
std::mutex& aravisListMutex() {
    static std::mutex mutex;
    return mutex;
}

// Takes the message out of a GError and frees it.
std::string takeError(GError*& error) {
    std::string message = error && error->message ? error->message : "unknown Aravis error";
    g_clear_error(&error);
    return message;
}

PixelFormat toPixelFormat(ArvPixelFormat format) {
    switch (format) {
        case ARV_PIXEL_FORMAT_MONO_8:
            return PixelFormat::kMono8;
        case ARV_PIXEL_FORMAT_MONO_16:
            return PixelFormat::kMono16;
        case ARV_PIXEL_FORMAT_RGB_8_PACKED:
            return PixelFormat::kRGB8;
        case ARV_PIXEL_FORMAT_BAYER_RG_8:
            return PixelFormat::kBayerRGGB8;
        case ARV_PIXEL_FORMAT_BAYER_GR_8:
            return PixelFormat::kBayerGRBG8;
        case ARV_PIXEL_FORMAT_BAYER_GB_8:
            return PixelFormat::kBayerGBRG8;
        case ARV_PIXEL_FORMAT_BAYER_BG_8:
            return PixelFormat::kBayerBGGR8;
        default:
            return PixelFormat::kUnknown;
    }
}

bool isBayer(PixelFormat format) {
    return format == PixelFormat::kBayerRGGB8 || format == PixelFormat::kBayerGRBG8 ||
           format == PixelFormat::kBayerGBRG8 || format == PixelFormat::kBayerBGGR8;
}

std::string formatFps(double fps) {
    char text[32];
    std::snprintf(text, sizeof(text), "%g", fps);
    return text;
}

std::string lowered(std::string_view text) {
    std::string out(text);
    for (char& c : out)
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

// The entries of the camera's enumeration `feature`, or an error naming it.
Result<std::vector<std::string>> enumerationEntries(ArvCamera* camera, const char* feature) {
    GError* error = nullptr;
    guint n = 0;
    const char** entries =
        arv_camera_dup_available_enumerations_as_strings(camera, feature, &n, &error);
    if (error) {
        g_free(entries);
        return {ErrorCode::kUnsupported,
                std::string("reading the camera's ") + feature + ": " + takeError(error)};
    }
    std::vector<std::string> out;
    for (guint i = 0; i < n; ++i)
        out.emplace_back(entries[i] ? entries[i] : "");
    g_free(entries);
    return out;
}

std::string joined(const std::vector<std::string>& items) {
    std::string out;
    for (const std::string& item : items)
        out += (out.empty() ? "" : ", ") + item;
    return out;
}

// The camera's TriggerSource entry for the line `requested` names ("line1" -> "Line1").
// kInvalidArgument listing the camera's lines when it has no such line.
Result<std::string> hardwareTriggerSource(ArvCamera* camera, const std::string& requested) {
    if (!arv_camera_is_feature_available(camera, "TriggerSource", nullptr)) {
        return {ErrorCode::kUnsupported,
                "trigger " + requested + ": the camera has no TriggerSource (no hardware trigger)"};
    }
    auto entries = enumerationEntries(camera, "TriggerSource");
    if (!entries)
        return entries.status();
    std::string match;
    std::vector<std::string> lines;
    for (const std::string& entry : *entries) {
        // Software is chosen with trigger=software; it is no line.
        if (lowered(entry) == "software")
            continue;
        lines.push_back(lowered(entry));
        if (lowered(entry) == lowered(requested))
            match = entry;
    }
    if (match.empty()) {
        return {ErrorCode::kInvalidArgument,
                "trigger '" + requested + "': the camera has no such trigger source; it offers " +
                    (lines.empty() ? std::string("no hardware line") : joined(lines)) +
                    " (and free, software)"};
    }
    return match;
}

// Sets TriggerActivation (FrameStart selected) to `activation`, a GenICam name.
Status setTriggerActivation(ArvCamera* camera, const std::string& activation) {
    if (!arv_camera_is_feature_available(camera, "TriggerActivation", nullptr)) {
        return {ErrorCode::kUnsupported,
                "trigger_activation: the camera has no TriggerActivation feature"};
    }
    auto entries = enumerationEntries(camera, "TriggerActivation");
    if (!entries)
        return entries.status();
    if (std::find(entries->begin(), entries->end(), activation) == entries->end()) {
        return {ErrorCode::kInvalidArgument,
                "trigger_activation " + activation + ": the camera offers " + joined(*entries)};
    }
    GError* error = nullptr;
    arv_camera_set_string(camera, "TriggerActivation", activation.c_str(), &error);
    if (error) {
        return {ErrorCode::kUnsupported,
                "trigger_activation " + activation + ": " + takeError(error)};
    }
    return Status::ok();
}

// Features that switch IEEE 1588 on: SFNC 2.x names it PtpEnable, GigE Vision cameras before
// it GevIEEE1588. The status features are read in the same order.
constexpr const char* kPtpEnableFeatures[] = {"PtpEnable", "GevIEEE1588"};
constexpr const char* kPtpStatusFeatures[] = {"PtpStatus", "GevIEEE1588Status"};

Status enablePtp(ArvCamera* camera) {
    for (const char* feature : kPtpEnableFeatures) {
        if (!arv_camera_is_feature_available(camera, feature, nullptr))
            continue;
        GError* error = nullptr;
        arv_camera_set_boolean(camera, feature, TRUE, &error);
        if (error) {
            return {ErrorCode::kUnsupported,
                    std::string("ptp: enabling ") + feature + ": " + takeError(error)};
        }
        return Status::ok();
    }
    return {ErrorCode::kUnsupported,
            "ptp: the camera offers no IEEE 1588 (PTP): it has neither PtpEnable nor GevIEEE1588"};
}

// Opens `id` as Aravis understands it (device id or address), else as a serial number or
// address from discovery. Empty: the first camera found.
Result<ArvCamera*> openCamera(const std::string& id) {
    std::lock_guard lock(aravisListMutex());
    GError* error = nullptr;
    std::string target = id;
    if (target.empty()) {
        arv_update_device_list();
        if (arv_get_n_devices() == 0)
            return {ErrorCode::kNotFound, "no Aravis camera found"};
        target = arv_get_device_id(0);
    }
    if (ArvCamera* camera = arv_camera_new(target.c_str(), &error))
        return camera;
    const std::string first_error = takeError(error);
    arv_update_device_list();
    for (unsigned i = 0; i < arv_get_n_devices(); ++i) {
        const char* serial = arv_get_device_serial_nbr(i);
        const char* address = arv_get_device_address(i);
        if ((serial && target == serial) || (address && target == address)) {
            if (ArvCamera* camera = arv_camera_new(arv_get_device_id(i), &error))
                return camera;
            return {ErrorCode::kUnavailable, "Aravis camera '" + target + "': " + takeError(error)};
        }
    }
    return {ErrorCode::kNotFound, "Aravis camera '" + target + "': " + first_error};
}

// GevHeartbeatTimeout where the camera's description has it, else the bootstrap register every
// GigE Vision device has (Aravis's own simulator describes no such feature).
Status setHeartbeatTimeout(ArvCamera* camera, int64_t timeout_ms) {
    constexpr guint64 kHeartbeatTimeoutRegister = 0x0938;
    GError* error = nullptr;
    ArvDevice* device = arv_camera_get_device(camera);
    if (arv_camera_is_feature_available(camera, "GevHeartbeatTimeout", nullptr)) {
        arv_device_set_integer_feature_value(device, "GevHeartbeatTimeout", timeout_ms, &error);
    } else {
        arv_device_write_register(device, kHeartbeatTimeoutRegister,
                                  static_cast<guint32>(timeout_ms), &error);
    }
    if (error) {
        return {ErrorCode::kUnsupported,
                "heartbeat_timeout_ms " + std::to_string(timeout_ms) + ": " + takeError(error)};
    }
    return Status::ok();
}

// Applies `o` to `camera`. Settings the options leave empty keep the camera's values.
Status configure(ArvCamera* camera, const AravisOptions& o) {
    GError* error = nullptr;
    auto failed = [&](const std::string& what) -> Status {
        return {ErrorCode::kUnsupported, what + ": " + takeError(error)};
    };
    if (!o.pixel_format.empty()) {
        arv_camera_set_pixel_format_from_string(camera, o.pixel_format.c_str(), &error);
        if (error)
            return failed("pixel_format " + o.pixel_format);
    }
    if (o.width > 0 || o.height > 0 || o.offset_x >= 0 || o.offset_y >= 0) {
        gint x = 0, y = 0, w = 0, h = 0;
        arv_camera_get_region(camera, &x, &y, &w, &h, &error);
        if (error)
            return failed("reading the region of interest");
        arv_camera_set_region(camera, o.offset_x >= 0 ? o.offset_x : x,
                              o.offset_y >= 0 ? o.offset_y : y, o.width > 0 ? o.width : w,
                              o.height > 0 ? o.height : h, &error);
        if (error)
            return failed("region of interest");
    }
    if (o.exposure_us > 0) {
        arv_camera_set_exposure_time(camera, o.exposure_us, &error);
        if (error)
            return failed("exposure_us");
    }
    if (o.gain >= 0) {
        arv_camera_set_gain(camera, o.gain, &error);
        if (error)
            return failed("gain");
    }
    // Some cameras switch triggers off when the frame rate is written: rate first.
    if (o.fps > 0) {
        arv_camera_set_frame_rate(camera, o.fps, &error);
        if (error)
            return failed("fps");
    }
    if (o.trigger == TriggerMode::kSoftware) {
        arv_camera_set_trigger(camera, "Software", &error);
        if (error)
            return failed("software trigger");
    } else if (o.trigger == TriggerMode::kHardware) {
        auto source = hardwareTriggerSource(camera, o.trigger_source);
        if (!source)
            return source.status();
        // Aravis sets FrameStart to the line, rising edge, and every other trigger off.
        arv_camera_set_trigger(camera, source->c_str(), &error);
        if (error)
            return failed("trigger " + o.trigger_source);
        if (!o.trigger_activation.empty())
            MIXRAY_RETURN_IF_ERROR(setTriggerActivation(camera, o.trigger_activation));
    } else if (arv_camera_is_feature_available(camera, "TriggerMode", nullptr)) {
        arv_camera_clear_triggers(camera, &error);
        if (error)
            return failed("clearing triggers");
    }
    // A triggered camera in single-frame mode would stop after the first trigger.
    arv_camera_set_acquisition_mode(camera, ARV_ACQUISITION_MODE_CONTINUOUS, &error);
    if (error)
        return failed("continuous acquisition");
    if (o.ptp)
        MIXRAY_RETURN_IF_ERROR(enablePtp(camera));
    if (arv_camera_is_gv_device(camera)) {
        if (o.packet_size > 0) {
            arv_camera_gv_set_packet_size(camera, o.packet_size, &error);
        } else {
            arv_camera_gv_auto_packet_size(camera, &error);
        }
        if (error)
            return failed("packet_size");
        if (o.heartbeat_timeout_ms > 0)
            MIXRAY_RETURN_IF_ERROR(setHeartbeatTimeout(camera, o.heartbeat_timeout_ms));
    }
    return Status::ok();
}

}  // namespace

ClockDomainId defaultClockDomain(std::string_view device_name) {
    return deviceClockDomain("aravis", device_name);
}

// The Aravis objects of one connection to the camera. Owned by the device; the capture
// thread replaces it on reconnection.
struct AravisDevice::Camera {
    ArvCamera* camera = nullptr;
    ArvStream* stream = nullptr;
    gulong lost_handler = 0;
    std::atomic<bool> control_lost{false};

    explicit Camera(ArvCamera* c) : camera(c) {
        // The heartbeat thread of a GigE Vision device emits this when the camera stops
        // answering; the capture thread reads the flag.
        lost_handler = g_signal_connect_swapped(
            arv_camera_get_device(camera), "control-lost",
            G_CALLBACK(+[](Camera* self) { self->control_lost.store(true); }), this);
    }
    ~Camera() {
        closeStream(nullptr, false);
        if (lost_handler)
            g_signal_handler_disconnect(arv_camera_get_device(camera), lost_handler);
        g_object_unref(camera);
    }
    Camera(const Camera&) = delete;
    Camera& operator=(const Camera&) = delete;

    // Adds the stream's counters to `stats`, stops acquisition when the camera still
    // answers, and releases the stream with its buffers.
    void closeStream(AravisStats* stats, bool stop_acquisition) {
        if (!stream)
            return;
        if (stats)
            addCounters(*stats);
        if (stop_acquisition) {
            GError* error = nullptr;
            arv_camera_stop_acquisition(camera, &error);
            g_clear_error(&error);
        }
        g_object_unref(stream);
        stream = nullptr;
    }

    void addCounters(AravisStats& stats) const {
        if (!stream)
            return;
        guint64 completed = 0, failures = 0, underruns = 0;
        arv_stream_get_statistics(stream, &completed, &failures, &underruns);
        stats.underruns += underruns;
        if (ARV_IS_GV_STREAM(stream)) {
            stats.received_packets +=
                arv_stream_get_info_uint64_by_name(stream, "n_received_packets");
            stats.missing_packets +=
                arv_stream_get_info_uint64_by_name(stream, "n_missing_packets");
            stats.resend_requests +=
                arv_stream_get_info_uint64_by_name(stream, "n_resend_requests");
            stats.resent_packets += arv_stream_get_info_uint64_by_name(stream, "n_resent_packets");
        }
    }
};

AravisDevice::AravisDevice(std::string name, AravisOptions options)
    : name_(std::move(name)), options_(std::move(options)) {
    if (options_.clock_domain == kHostClockDomain)
        options_.clock_domain = options_.ptp ? kPtpClockDomain : defaultClockDomain(name_);
}

AravisDevice::~AravisDevice() {
    stop();
    for (Helper& helper : helpers_)
        helper.thread.join();
    camera_.reset();
}

Result<std::unique_ptr<AravisDevice>> AravisDevice::open(std::string name, std::string id,
                                                         AravisOptions options) {
    MIXRAY_RETURN_IF_ERROR(options.validate().withContext("aravis device '" + name + "'"));
    const std::string context = "aravis device '" + name + "'";
    auto opened = openCamera(id);
    if (!opened)
        return opened.status().withContext(context);
    std::unique_ptr<AravisDevice> device(new AravisDevice(std::move(name), std::move(options)));
    device->camera_ = std::make_unique<Camera>(*opened);
    ArvCamera* camera = *opened;
    MIXRAY_RETURN_IF_ERROR(configure(camera, device->options_).withContext(context));

    // What the camera settled on: the stream's fixed layout, and the settings a reconnection
    // restores even if the camera came back with other defaults.
    GError* error = nullptr;
    const ArvPixelFormat arv_format = arv_camera_get_pixel_format(camera, &error);
    gint x = 0, y = 0, w = 0, h = 0;
    if (!error)
        arv_camera_get_region(camera, &x, &y, &w, &h, &error);
    if (error) {
        return {ErrorCode::kUnavailable, context + ": reading the format: " + takeError(error)};
    }
    const PixelFormat format = toPixelFormat(arv_format);
    if (format == PixelFormat::kUnknown) {
        const char* text = arv_camera_get_pixel_format_as_string(camera, nullptr);
        return {ErrorCode::kUnsupported,
                context + ": pixel format " + std::string(text ? text : "?") +
                    " is not one mixray takes (Mono8, Mono16, RGB8, Bayer*8)"};
    }
    if (device->options_.debayer && !isBayer(format)) {
        return {
            ErrorCode::kInvalidArgument,
            context + ": debayer asked for, but the camera sends " + std::string(toString(format))};
    }
    AravisOptions& o = device->options_;
    const char* format_text = arv_camera_get_pixel_format_as_string(camera, nullptr);
    o.pixel_format = format_text ? format_text : "";
    o.offset_x = x;
    o.offset_y = y;
    o.width = w;
    o.height = h;
    const double fps = arv_camera_get_frame_rate(camera, &error);
    g_clear_error(&error);
    if (o.buffers == 0) {
        // Half a second of frames absorbs a consumer's hiccup or a burst of triggers.
        o.buffers = std::max<size_t>(8, static_cast<size_t>(std::ceil(fps * 0.5)));
    }

    const PixelFormat published = o.debayer ? PixelFormat::kRGB8 : format;
    device->camera_desc_ = ImageDesc::packed(format, w, h);
    StreamInfo& info = device->info_;
    const bool mono = format == PixelFormat::kMono8 || format == PixelFormat::kMono16;
    const std::string stream = mono ? "mono" : "color";
    if (!o.stream.empty() && o.stream != stream) {
        return {ErrorCode::kInvalidArgument,
                context + ": stream '" + o.stream + "' asked for, but the camera sends " +
                    std::string(toString(format)) + " ('" + stream + "')"};
    }
    info.name = device->name_ + "/" + stream;
    info.device = device->name_;
    info.kind = mono ? StreamKind::kMono : StreamKind::kColor;
    info.format = ImageDesc::packed(published, w, h);
    info.nominal_fps = o.trigger == TriggerMode::kFreeRun && fps > 0 ? fps : 0;
    info.clock_domain = o.clock_domain;

    DeviceDescriptor& d = device->descriptor_;
    d.backend = "aravis";
    d.id =
        arv_camera_get_device_id(camera, nullptr) ? arv_camera_get_device_id(camera, nullptr) : id;
    const char* vendor = arv_camera_get_vendor_name(camera, nullptr);
    const char* model = arv_camera_get_model_name(camera, nullptr);
    d.model = std::string(vendor ? vendor : "") + (vendor && model ? " " : "") +
              std::string(model ? model : "");
    const char* serial = arv_camera_get_device_serial_number(camera, nullptr);
    d.serial = serial ? serial : "";
    if (arv_camera_is_gv_device(camera)) {
        GSocketAddress* socket_address =
            arv_gv_device_get_device_address(ARV_GV_DEVICE(arv_camera_get_device(camera)));
        GInetAddress* address =
            socket_address && G_IS_INET_SOCKET_ADDRESS(socket_address)
                ? g_inet_socket_address_get_address(G_INET_SOCKET_ADDRESS(socket_address))
                : nullptr;
        if (address) {
            gchar* text = g_inet_address_to_string(address);
            d.location = text ? text : "";
            g_free(text);
        }
    }
    d.modes.push_back(std::string(mono ? "mono " : "color ") + std::to_string(w) + "x" +
                      std::to_string(h) + "@" + formatFps(fps) + " " +
                      std::string(toString(published)));
    // Reconnection opens the camera the way the rig named it.
    device->reopen_id_ = id.empty() ? d.id : id;
    info.tags["model"] = d.model;
    info.tags["serial"] = d.serial;
    info.tags["aravis_pixel_format"] = o.pixel_format;
    if (o.trigger == TriggerMode::kHardware) {
        // The camera's spelling, so a reconnection and the tags name the same line.
        auto source = hardwareTriggerSource(camera, o.trigger_source);
        if (!source)
            return source.status().withContext(context);
        o.trigger_source = *source;
        info.tags["trigger"] = o.trigger_source;
    } else {
        info.tags["trigger"] = o.trigger == TriggerMode::kSoftware ? "software" : "free";
    }
    // Tells the clock model (and a recording's reader) what the device stamps count: PTP time
    // shared with every camera on the grandmaster, or the camera's own free-running clock.
    info.tags["timestamp_clock"] = o.ptp ? "ptp" : "camera";
    if (o.ptp) {
        auto status = device->ptpStatus();
        info.tags["ptp_status"] = status ? *status : "unknown";
    }
    return device;
}

DeviceDescriptor AravisDevice::descriptor() const {
    return descriptor_;
}

Status AravisDevice::connect(Graph& graph) {
    const std::string context = "aravis device '" + name_ + "'";
    if (graph_)
        return {ErrorCode::kInvalidArgument, context + " connected twice"};
    auto stream = addPooledStream(graph, info_, options_.buffers);
    if (!stream)
        return stream.status().withContext(context);
    pool_ = std::move(stream->pool);
    stream_id_ = stream->id;
    graph_ = &graph;
    return Status::ok();
}

Status AravisDevice::startStream() {
    const std::string context = "aravis device '" + name_ + "'";
    ArvCamera* camera = camera_->camera;
    GError* error = nullptr;
    ArvStream* stream = arv_camera_create_stream(camera, nullptr, nullptr, &error);
    if (!stream)
        return {ErrorCode::kUnavailable, context + ": creating the stream: " + takeError(error)};
    if (ARV_IS_GV_STREAM(stream)) {
        // The auto socket buffer holds one whole frame, so a frame survives a capture
        // thread that is late by up to a frame time.
        g_object_set(stream, "packet-resend",
                     options_.packet_resend ? ARV_GV_STREAM_PACKET_RESEND_ALWAYS
                                            : ARV_GV_STREAM_PACKET_RESEND_NEVER,
                     "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO, nullptr);
    }
    const guint payload = arv_camera_get_payload(camera, &error);
    if (error) {
        g_object_unref(stream);
        return {ErrorCode::kUnavailable, context + ": reading the payload: " + takeError(error)};
    }
    for (size_t i = 0; i < options_.buffers; ++i)
        arv_stream_push_buffer(stream, arv_buffer_new_allocate(payload));
    payload_bytes_ = payload;
    camera_->stream = stream;
    arv_camera_start_acquisition(camera, &error);
    if (error) {
        camera_->closeStream(nullptr, false);
        return {ErrorCode::kUnavailable, context + ": starting acquisition: " + takeError(error)};
    }
    have_frame_id_ = false;
    return Status::ok();
}

Status AravisDevice::start() {
    if (!graph_)
        return {ErrorCode::kInvalidArgument, "aravis device '" + name_ + "': not connected"};
    if (thread_.joinable())
        return Status::ok();
    {
        std::lock_guard lock(mutex_);
        stop_requested_ = false;
        if (camera_ && !camera_->stream) {
            MIXRAY_RETURN_IF_ERROR(startStream());
            stats_.connected = true;
        }
    }
    thread_ = std::thread([this] { run(); });
    return Status::ok();
}

void AravisDevice::stop() {
    {
        std::lock_guard lock(mutex_);
        stop_requested_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable())
        thread_.join();
    std::lock_guard lock(mutex_);
    if (camera_)
        camera_->closeStream(&stats_, !camera_->control_lost.load());
}

bool AravisDevice::waitFor(int64_t ms) {
    std::unique_lock lock(mutex_);
    return !wake_.wait_for(lock, std::chrono::milliseconds(ms), [&] { return stop_requested_; });
}

Status AravisDevice::softwareTrigger() {
    if (options_.trigger != TriggerMode::kSoftware) {
        return {ErrorCode::kUnsupported, "aravis device '" + name_ + "' " +
                                             (options_.trigger == TriggerMode::kHardware
                                                  ? "is triggered by " + options_.trigger_source
                                                  : std::string("runs free")) +
                                             "; open it with trigger=software"};
    }
    std::lock_guard lock(mutex_);
    if (!camera_ || !camera_->stream)
        return {ErrorCode::kUnavailable, "aravis device '" + name_ + "': camera not streaming"};
    GError* error = nullptr;
    arv_camera_software_trigger(camera_->camera, &error);
    if (error) {
        return {ErrorCode::kUnavailable,
                "aravis device '" + name_ + "': software trigger: " + takeError(error)};
    }
    return Status::ok();
}

AravisStats AravisDevice::stats() const {
    std::lock_guard lock(mutex_);
    AravisStats s = stats_;
    if (camera_)
        camera_->addCounters(s);
    if (pool_)
        s.pool_exhausted = pool_->exhaustedCount();
    return s;
}

DeviceState AravisDevice::state() const {
    std::lock_guard lock(mutex_);
    if (stats_.connected)
        return DeviceState::kStreaming;
    if (stats_.connection_losses == 0)
        return DeviceState::kUnknown;
    return stop_requested_ ? DeviceState::kLost : DeviceState::kReconnecting;
}

Result<std::string> AravisDevice::feature(const std::string& name) const {
    const std::string context = "aravis device '" + name_ + "': feature " + name;
    std::lock_guard lock(mutex_);
    if (!camera_)
        return {ErrorCode::kUnavailable, context + ": the camera is lost"};
    ArvGcNode* node = arv_device_get_feature(arv_camera_get_device(camera_->camera), name.c_str());
    if (!node || !ARV_IS_GC_FEATURE_NODE(node))
        return {ErrorCode::kNotFound, context + ": the camera has no such feature"};
    GError* error = nullptr;
    const char* value = arv_gc_feature_node_get_value_as_string(ARV_GC_FEATURE_NODE(node), &error);
    if (error)
        return {ErrorCode::kUnavailable, context + ": " + takeError(error)};
    return std::string(value ? value : "");
}

Result<std::string> AravisDevice::ptpStatus() const {
    if (!options_.ptp) {
        return {ErrorCode::kUnsupported,
                "aravis device '" + name_ + "' was opened without ptp; open it with ptp=true"};
    }
    Status last;
    for (const char* feature : kPtpStatusFeatures) {
        auto value = this->feature(feature);
        if (value || value.status().code() != ErrorCode::kNotFound)
            return value;
        last = value.status();
    }
    return last;
}

uint64_t frameIdAdvance(uint64_t previous, uint64_t id) {
    if (id > previous)
        return id - previous;
    // Only a 16-bit id near its end that comes back near 1 has wrapped; anything else going
    // backwards is a count that restarted.
    constexpr uint64_t kLast = 0xFFFF, kNear = 0x1000;
    if (id < previous && previous <= kLast && previous > kLast - kNear && id < kNear)
        return (kLast - previous) + id;
    return 0;
}

void AravisDevice::handleBuffer(ArvBuffer* buffer) {
    const ArvBufferStatus status = arv_buffer_get_status(buffer);
    // Buffers Aravis hands back unfilled, or cut off as acquisition stops, hold no frame and
    // their frame ids mean nothing: neither a failure nor a gap in the camera's count (CI saw
    // two at stop count as 65 400 missing frames).
    if (status == ARV_BUFFER_STATUS_CLEARED || status == ARV_BUFFER_STATUS_ABORTED)
        return;
    const bool complete = status == ARV_BUFFER_STATUS_SUCCESS;
    const bool partial =
        status == ARV_BUFFER_STATUS_MISSING_PACKETS || status == ARV_BUFFER_STATUS_TIMEOUT;

    const uint64_t frame_id = arv_buffer_get_frame_id(buffer);
    if (have_frame_id_) {
        const uint64_t step = frameIdAdvance(last_frame_id_, frame_id);
        if (step > 1)
            graph_->countLost(stream_id_, step - 1);
        std::lock_guard lock(mutex_);
        stats_.missing_frames += step > 0 ? step - 1 : 0;
        next_sequence_ += step > 0 ? step - 1 : 0;
    }
    have_frame_id_ = true;
    last_frame_id_ = frame_id;
    const uint64_t sequence = next_sequence_++;

    // Aravis describes the image of complete buffers only. A partial one is the frame the
    // camera was set up to send, in a buffer of payload_bytes_; the missing packets' bytes
    // are stale.
    size_t size = 0;
    const auto* data = static_cast<const uint8_t*>(arv_buffer_get_data(buffer, &size));
    ImageDesc desc = camera_desc_;
    if (complete) {
        const bool image = arv_buffer_get_payload_type(buffer) == ARV_BUFFER_PAYLOAD_TYPE_IMAGE &&
                           arv_buffer_get_n_parts(buffer) > 0;
        desc = image ? ImageDesc::packed(toPixelFormat(arv_buffer_get_image_pixel_format(buffer)),
                                         arv_buffer_get_image_width(buffer),
                                         arv_buffer_get_image_height(buffer))
                     : ImageDesc{};
    } else {
        size = payload_bytes_;
    }
    // A frame the camera sent that never reaches the graph is lost to it: counted where
    // commands report losses (Graph::lostCount) as well as in the device's own figures.
    const bool fits = data && desc == camera_desc_ && size >= desc.bufferBytes();
    if (!(complete || partial) || !fits) {
        graph_->countLost(stream_id_);
        std::lock_guard lock(mutex_);
        ++stats_.failed;
        return;
    }
    WritableFrame frame = pool_->acquire();
    if (!frame) {
        // A camera does not wait for its consumers: the pool counts it too.
        graph_->countLost(stream_id_);
        return;
    }
    const ImageView source{desc, data, size};
    if (options_.debayer) {
        if (!debayer(source, frame.image())) {
            graph_->countLost(stream_id_);
            std::lock_guard lock(mutex_);
            ++stats_.failed;
            return;
        }
    } else {
        std::memcpy(frame.image().data, data, desc.bufferBytes());
    }

    FrameMetadata& meta = frame.meta();
    meta.stream = stream_id_;
    meta.sequence = sequence;
    // Aravis stamps a frame's first packet with the real-time clock; the graph's host stamps
    // are monotonic.
    const int64_t system_ns = static_cast<int64_t>(arv_buffer_get_system_timestamp(buffer));
    const int64_t mono_now = monotonicNowNs();
    meta.host_stamp_ns = system_ns > 0 ? system_ns - (realtimeNowNs() - mono_now) : mono_now;
    if (meta.host_stamp_ns > mono_now)
        meta.host_stamp_ns = mono_now;
    const int64_t device_ns = static_cast<int64_t>(arv_buffer_get_timestamp(buffer));
    if (device_ns > 0) {
        meta.device_stamp_ns = device_ns;
        meta.clock_domain = options_.clock_domain;
    } else {
        meta.device_stamp_ns = meta.host_stamp_ns;
        meta.clock_domain = kHostClockDomain;
    }
    meta.status = complete ? FrameStatus::kOk : FrameStatus::kIncomplete;
    graph_->publish(std::move(frame).publish());
    std::lock_guard lock(mutex_);
    ++stats_.published;
    if (!complete)
        ++stats_.incomplete;
}

void AravisDevice::spawnAside(std::function<void()> work, std::shared_ptr<std::atomic<bool>> done) {
    for (auto it = helpers_.begin(); it != helpers_.end();) {
        if (it->done->load()) {
            it->thread.join();
            it = helpers_.erase(it);
        } else {
            ++it;
        }
    }
    if (!done)
        done = std::make_shared<std::atomic<bool>>(false);
    std::thread thread([this, done, work = std::move(work)]() mutable {
        work();
        // Whatever the work captured is released here, on this thread.
        work = nullptr;
        {
            std::lock_guard lock(mutex_);
            done->store(true);
        }
        wake_.notify_all();
    });
    helpers_.push_back({std::move(thread), std::move(done)});
}

bool AravisDevice::runAside(std::function<void()> work) {
    auto done = std::make_shared<std::atomic<bool>>(false);
    spawnAside(std::move(work), done);
    std::unique_lock lock(mutex_);
    wake_.wait(lock, [&] { return done->load() || stop_requested_; });
    return done->load();
}

Status AravisDevice::reconnect() {
    struct Attempt {
        std::unique_ptr<Camera> camera;
        Status status;
    };
    auto attempt = std::make_shared<Attempt>();
    const bool finished = runAside([attempt, id = reopen_id_, options = options_] {
        auto opened = openCamera(id);
        if (!opened) {
            attempt->status = opened.status();
            return;
        }
        auto camera = std::make_unique<Camera>(*opened);
        attempt->status = configure(camera->camera, options);
        if (attempt->status)
            attempt->camera = std::move(camera);
    });
    if (!finished)
        return {ErrorCode::kCancelled, "stopped"};
    if (!attempt->camera)
        return attempt->status;
    std::lock_guard lock(mutex_);
    if (stop_requested_)
        return {ErrorCode::kCancelled, "stopped"};
    camera_ = std::move(attempt->camera);
    MIXRAY_RETURN_IF_ERROR(startStream());
    ++stats_.reconnects;
    stats_.connected = true;
    return Status::ok();
}

void AravisDevice::run() {
    runAs(ThreadRole::kCapture);  // a frame late here is a frame lost (thread_priority.h)
    int64_t last_frame_ns = monotonicNowNs();
    while (true) {
        {
            std::lock_guard lock(mutex_);
            if (stop_requested_)
                break;
        }
        if (!camera_ || !camera_->stream) {
            if (!waitFor(options_.reconnect_ms))
                break;
            if (reconnect())
                last_frame_ns = monotonicNowNs();
            continue;
        }
        // A short pop keeps stop() prompt.
        ArvBuffer* buffer = arv_stream_timeout_pop_buffer(camera_->stream, 100'000);
        if (buffer) {
            handleBuffer(buffer);
            arv_stream_push_buffer(camera_->stream, buffer);
            last_frame_ns = monotonicNowNs();
            continue;
        }
        bool lost = camera_->control_lost.load();
        if (!lost && options_.trigger == TriggerMode::kFreeRun &&
            monotonicNowNs() - last_frame_ns > options_.lost_timeout_ms * 1'000'000) {
            // Silence in free run: one register read tells a slow camera from a gone one
            // (address 0 is the bootstrap or ABRM version register of every GigE Vision and
            // USB3 Vision camera; one read costs a single round of Aravis's retries, where a
            // feature may read several registers). It runs aside so stop() need not wait
            // for the retries.
            auto answered = std::make_shared<std::atomic<bool>>(false);
            ArvDevice* device = ARV_DEVICE(g_object_ref(arv_camera_get_device(camera_->camera)));
            if (!runAside([device, answered] {
                    GError* error = nullptr;
                    guint32 version = 0;
                    arv_device_read_register(device, 0, &version, &error);
                    answered->store(error == nullptr);
                    g_clear_error(&error);
                    g_object_unref(device);
                })) {
                break;
            }
            lost = !answered->load();
            last_frame_ns = monotonicNowNs();
        }
        if (lost) {
            std::shared_ptr<Camera> gone;
            {
                std::lock_guard lock(mutex_);
                camera_->addCounters(stats_);
                ++stats_.connection_losses;
                stats_.connected = false;
                gone = std::move(camera_);
            }
            // Releasing a camera that does not answer waits for Aravis's retries (seconds):
            // aside, so that reconnection, stats() and stop() do not wait for it.
            spawnAside([gone = std::move(gone)]() mutable { gone.reset(); });
        }
    }
}

AravisBackend::AravisBackend(const AravisBackendOptions& options) : options_(options) {
    if (options_.fake_interface) {
        std::lock_guard lock(aravisListMutex());
        arv_enable_interface("Fake");
    }
}

Result<std::vector<DeviceDescriptor>> AravisBackend::enumerate() {
    std::lock_guard lock(aravisListMutex());
    arv_update_device_list();
    std::vector<DeviceDescriptor> out;
    for (unsigned i = 0; i < arv_get_n_devices(); ++i) {
        DeviceDescriptor d;
        d.backend = "aravis";
        const char* id = arv_get_device_id(i);
        const char* vendor = arv_get_device_vendor(i);
        const char* model = arv_get_device_model(i);
        const char* serial = arv_get_device_serial_nbr(i);
        const char* address = arv_get_device_address(i);
        const char* protocol = arv_get_device_protocol(i);
        d.id = id ? id : "";
        d.model = std::string(vendor ? vendor : "") + (vendor && model ? " " : "") +
                  std::string(model ? model : "");
        d.serial = serial ? serial : "";
        d.location = std::string(protocol ? protocol : "") + (protocol && address ? " " : "") +
                     std::string(address ? address : "");
        out.push_back(std::move(d));
    }
    return out;
}

Result<std::unique_ptr<Device>> AravisBackend::open(const DeviceConfig& config) {
    if (config.name.empty()) {
        return {ErrorCode::kInvalidArgument,
                "aravis device without a name (streams are named <name>/<stream>)"};
    }
    auto options = AravisOptions::fromConfig(config);
    if (!options)
        return options.status();
    auto device = AravisDevice::open(config.name, config.id, std::move(*options));
    if (!device)
        return device.status();
    return std::unique_ptr<Device>(std::move(*device));
}

}  // namespace mixray::aravis
