// V4L2 capture: node discovery, format negotiation, controls and the streaming loop.
#include "mixray/v4l2/v4l2_backend.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "mixray/graph/clock.h"
#include "mixray/graph/device_options.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/thread_priority.h"
#include "mixray/v4l2/mjpeg.h"

namespace mixray::v4l2 {
namespace {

// Longest wait for a frame before asking the driver again (see V4l2Device::run).
constexpr int kPollTimeoutMs = 5;
// How often a lost camera's node is tried again.
constexpr int kReconnectIntervalMs = 200;

int xioctl(int fd, unsigned long request, void* arg) {
    int r;
    do {
        r = ::ioctl(fd, request, arg);
    } while (r == -1 && errno == EINTR);
    return r;
}

std::string errnoText(int err) {
    return std::strerror(err);
}

std::string fourccText(uint32_t fourcc) {
    // The names the rig's `format` option uses.
    if (fourcc == V4L2_PIX_FMT_MJPEG)
        return "mjpeg";
    std::string s;
    for (int i = 0; i < 4; ++i) {
        const char c = static_cast<char>((fourcc >> (8 * i)) & 0xff);
        if (c != ' ')
            s += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    }
    return s;
}

std::string cString(const uint8_t* text, size_t max) {
    return std::string(reinterpret_cast<const char*>(text),
                       strnlen(reinterpret_cast<const char*>(text), max));
}

std::string formatFps(double fps) {
    char text[32];
    std::snprintf(text, sizeof(text), "%g", fps);
    return text;
}

// The frame rates of one size, highest first; empty when the driver lists none.
std::vector<double> frameRates(int fd, uint32_t fourcc, uint32_t width, uint32_t height) {
    std::vector<double> out;
    v4l2_frmivalenum ival{};
    ival.pixel_format = fourcc;
    ival.width = width;
    ival.height = height;
    for (ival.index = 0; xioctl(fd, VIDIOC_ENUM_FRAMEINTERVALS, &ival) == 0; ++ival.index) {
        if (ival.type == V4L2_FRMIVAL_TYPE_DISCRETE) {
            if (ival.discrete.numerator > 0)
                out.push_back(static_cast<double>(ival.discrete.denominator) /
                              ival.discrete.numerator);
        } else {
            // Continuous or stepwise ranges: the fastest rate says what the mode can do.
            if (ival.stepwise.min.numerator > 0) {
                out.push_back(static_cast<double>(ival.stepwise.min.denominator) /
                              ival.stepwise.min.numerator);
            }
            break;
        }
    }
    std::sort(out.rbegin(), out.rend());
    return out;
}

struct NodeInfo {
    std::string card;
    std::string driver;
    std::string bus;
    uint32_t caps = 0;
};

Result<NodeInfo> queryNode(int fd, const std::string& path) {
    v4l2_capability cap{};
    if (xioctl(fd, VIDIOC_QUERYCAP, &cap) != 0) {
        return {ErrorCode::kUnsupported, path + ": VIDIOC_QUERYCAP: " + errnoText(errno)};
    }
    NodeInfo info;
    info.card = cString(cap.card, sizeof(cap.card));
    info.driver = cString(cap.driver, sizeof(cap.driver));
    info.bus = cString(cap.bus_info, sizeof(cap.bus_info));
    info.caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    if (!(info.caps & V4L2_CAP_VIDEO_CAPTURE)) {
        return {ErrorCode::kUnsupported, path + " ('" + info.card + "') does not capture video"};
    }
    if (!(info.caps & V4L2_CAP_STREAMING)) {
        return {ErrorCode::kUnsupported, path + " ('" + info.card + "') cannot stream"};
    }
    return info;
}

std::vector<std::string> listModes(int fd) {
    std::vector<std::string> modes;
    v4l2_fmtdesc fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    for (fmt.index = 0; xioctl(fd, VIDIOC_ENUM_FMT, &fmt) == 0; ++fmt.index) {
        const std::string name = fourccText(fmt.pixelformat);
        v4l2_frmsizeenum size{};
        size.pixel_format = fmt.pixelformat;
        for (size.index = 0; xioctl(fd, VIDIOC_ENUM_FRAMESIZES, &size) == 0; ++size.index) {
            uint32_t w = size.discrete.width, h = size.discrete.height;
            if (size.type != V4L2_FRMSIZE_TYPE_DISCRETE) {
                w = size.stepwise.max_width;
                h = size.stepwise.max_height;
            }
            std::string mode = name + " " + std::to_string(w) + "x" + std::to_string(h);
            const auto rates = frameRates(fd, fmt.pixelformat, w, h);
            if (!rates.empty())
                mode += "@" + formatFps(rates.front());
            modes.push_back(mode);
            if (size.type != V4L2_FRMSIZE_TYPE_DISCRETE)
                break;
        }
    }
    return modes;
}

// /dev/videoN nodes, in number order: sysfs says which exist (umockdev and udev agree on it);
// without sysfs the directory is read.
std::vector<std::string> videoNodes() {
    namespace fs = std::filesystem;
    std::vector<std::string> names;
    std::error_code ec;
    for (const auto& dir : {fs::path("/sys/class/video4linux"), fs::path("/dev")}) {
        if (!fs::is_directory(dir, ec))
            continue;
        for (const auto& entry : fs::directory_iterator(dir, ec)) {
            const std::string n = entry.path().filename().string();
            if (n.rfind("video", 0) == 0 && n.size() > 5 &&
                std::all_of(n.begin() + 5, n.end(), [](char c) { return c >= '0' && c <= '9'; }))
                names.push_back(n);
        }
        if (!names.empty())
            break;
    }
    std::sort(names.begin(), names.end(), [](const std::string& a, const std::string& b) {
        return std::atoi(a.c_str() + 5) < std::atoi(b.c_str() + 5);
    });
    std::vector<std::string> paths;
    for (const auto& n : names)
        paths.push_back("/dev/" + n);
    return paths;
}

class Fd {
public:
    explicit Fd(int fd) : fd_(fd) {}
    ~Fd() {
        if (fd_ >= 0)
            ::close(fd_);
    }
    Fd(const Fd&) = delete;
    Fd& operator=(const Fd&) = delete;
    int get() const { return fd_; }

private:
    int fd_;
};

// The ctrl.<key> options: any control by its key (controlKey()), as an integer.
Status readControls(DeviceOptionReader& reader, std::map<std::string, int32_t>& out) {
    for (const auto& [key, value] : reader.config().options) {
        if (key.rfind("ctrl.", 0) != 0)
            continue;
        const std::string name = key.substr(5);
        if (name.empty() || controlKey(name) != name)
            return reader.error(key, value, "ctrl.<lowercase control key>");
        int32_t v = 0;
        MIXRAY_RETURN_IF_ERROR(reader.integer<int32_t>(key, v, INT32_MIN, INT32_MAX, "an integer"));
        out[name] = v;
    }
    return Status::ok();
}

}  // namespace

std::string controlKey(std::string_view name) {
    std::string key;
    bool gap = false;
    for (char c : name) {
        const auto u = static_cast<unsigned char>(c);
        if (std::isalnum(u)) {
            if (gap && !key.empty())
                key += '_';
            key += static_cast<char>(std::tolower(u));
            gap = false;
        } else {
            gap = true;
        }
    }
    return key;
}

Result<V4l2Options> V4l2Options::fromConfig(const DeviceConfig& config) {
    V4l2Options o;
    o.fourcc = V4L2_PIX_FMT_YUYV;
    DeviceOptionReader reader(config, "v4l2");
    if (const std::string* text = reader.find("color.format")) {
        if (*text == "yuyv") {
            o.fourcc = V4L2_PIX_FMT_YUYV;
        } else if (*text == "mjpeg" || *text == "rgb8") {
            o.fourcc = V4L2_PIX_FMT_MJPEG;
            o.decode_rgb = *text == "rgb8";
        } else {
            return reader.error("color.format", *text, "yuyv, mjpeg or rgb8 (mjpeg decoded)");
        }
    }
    MIXRAY_RETURN_IF_ERROR(
        reader.integer("color.width", o.width, 16, 16384, "an integer in [16, 16384]"));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer("color.height", o.height, 8, 16384, "an integer in [8, 16384]"));
    if (const std::string* text = reader.find("color.fps")) {
        const char* end = text->data() + text->size();
        auto [ptr, ec] = std::from_chars(text->data(), end, o.fps);
        if (ec != std::errc() || ptr != end || !std::isfinite(o.fps) || o.fps < 0 || o.fps > 1e4)
            return reader.error("color.fps", *text, "a rate in [0, 10000] (0: the driver's)");
    }
    MIXRAY_RETURN_IF_ERROR(reader.choice<IoMethod>(
        "io", o.io, {{"mmap", IoMethod::kMmap}, {"userptr", IoMethod::kUserPtr}},
        "mmap or userptr"));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer<uint32_t>("buffers", o.buffers, 2, 32, "an integer in [2, 32]"));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer<size_t>("pool", o.pool, 1, 1024, "an integer in [1, 1024]"));
    MIXRAY_RETURN_IF_ERROR(reader.choice<Role>(
        "role", o.role, {{"camera", Role::kCamera}, {"environment", Role::kEnvironment}},
        "camera or environment"));
    MIXRAY_RETURN_IF_ERROR(reader.choice<ClockMode>(
        "clock", o.clock, {{"auto", ClockMode::kAuto}, {"device", ClockMode::kDevice}},
        "auto or device"));
    MIXRAY_RETURN_IF_ERROR(reader.integer<int32_t>("exposure_us", o.exposure_us, 1, 100'000'000,
                                                   "microseconds in [1, 1e8]"));
    if (reader.find("auto_white_balance")) {
        bool on = true;
        MIXRAY_RETURN_IF_ERROR(reader.choice<bool>(
            "auto_white_balance", on, {{"true", true}, {"false", false}}, "true or false"));
        o.auto_white_balance = on ? 1 : 0;
    }
    MIXRAY_RETURN_IF_ERROR(reader.integer<int32_t>("white_balance_k", o.white_balance_k, 1000,
                                                   20000, "kelvin in [1000, 20000]"));
    MIXRAY_RETURN_IF_ERROR(reader.choice<bool>(
        "reconnect", o.reconnect, {{"true", true}, {"false", false}}, "true or false"));
    MIXRAY_RETURN_IF_ERROR(readControls(reader, o.controls));
    MIXRAY_RETURN_IF_ERROR(reader.leftovers(
        "color.format, color.width, color.height, color.fps, io, buffers, pool, role, clock, "
        "exposure_us, auto_white_balance, white_balance_k, reconnect, ctrl.<key>"));
    MIXRAY_RETURN_IF_ERROR(o.validate().withContext("v4l2 device '" + config.name + "'"));
    return o;
}

Status V4l2Options::validate() const {
    if (fourcc != V4L2_PIX_FMT_YUYV && fourcc != V4L2_PIX_FMT_MJPEG)
        return {ErrorCode::kInvalidArgument, "format must be yuyv or mjpeg"};
    if (decode_rgb && fourcc != V4L2_PIX_FMT_MJPEG)
        return {ErrorCode::kInvalidArgument, "rgb8 frames are decoded from mjpeg"};
    if (role == Role::kEnvironment && auto_white_balance == 1) {
        return {ErrorCode::kInvalidArgument,
                "role=environment locks white balance: auto_white_balance=true contradicts it"};
    }
    if (fourcc == V4L2_PIX_FMT_YUYV && width % 2 != 0)
        return {ErrorCode::kInvalidArgument, "yuyv needs an even width"};
    if (buffers < 2 || pool < 1)
        return {ErrorCode::kInvalidArgument, "buffers must be >= 2 and pool >= 1"};
    return Status::ok();
}

V4l2Device::V4l2Device(std::string name, std::string path, V4l2Options options)
    : name_(std::move(name)), path_(std::move(path)), options_(std::move(options)) {}

V4l2Device::~V4l2Device() {
    stop();
    if (wake_fd_ >= 0)
        ::close(wake_fd_);
    if (fd_ >= 0)
        ::close(fd_);
}

Status V4l2Device::openNode() {
    fd_ = ::open(path_.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) {
        const ErrorCode code = errno == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIoError;
        return {code, "cannot open " + path_ + ": " + errnoText(errno)};
    }
    wake_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
    if (wake_fd_ < 0)
        return {ErrorCode::kInternal, "eventfd: " + errnoText(errno)};
    auto info = queryNode(fd_, path_);
    if (!info)
        return info.status();
    descriptor_.backend = "v4l2";
    descriptor_.id = path_;
    descriptor_.model = info->card;
    descriptor_.location = info->bus.empty() ? path_ : info->bus;
    descriptor_.modes = listModes(fd_);

    // Controls: walk them with NEXT_CTRL so that private and class ids are found too.
    v4l2_queryctrl q{};
    q.id = V4L2_CTRL_FLAG_NEXT_CTRL;
    while (xioctl(fd_, VIDIOC_QUERYCTRL, &q) == 0) {
        if (!(q.flags & V4L2_CTRL_FLAG_DISABLED) && q.type != V4L2_CTRL_TYPE_CTRL_CLASS) {
            ControlInfo c;
            c.id = q.id;
            c.name = cString(q.name, sizeof(q.name));
            c.key = controlKey(c.name);
            c.type = q.type;
            c.minimum = q.minimum;
            c.maximum = q.maximum;
            c.step = q.step;
            c.default_value = q.default_value;
            c.read_only = (q.flags & V4L2_CTRL_FLAG_READ_ONLY) != 0;
            controls_.push_back(c);
        }
        q.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
    }
    return Status::ok();
}

Status V4l2Device::negotiate() {
    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    fmt.fmt.pix.width = static_cast<uint32_t>(options_.width);
    fmt.fmt.pix.height = static_cast<uint32_t>(options_.height);
    fmt.fmt.pix.pixelformat = options_.fourcc;
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    if (xioctl(fd_, VIDIOC_S_FMT, &fmt) != 0)
        return {ErrorCode::kIoError, path_ + ": VIDIOC_S_FMT: " + errnoText(errno)};
    // Drivers answer an impossible request with the nearest mode they have; a rig that asked for
    // one size must not silently get another.
    if (fmt.fmt.pix.pixelformat != options_.fourcc ||
        fmt.fmt.pix.width != static_cast<uint32_t>(options_.width) ||
        fmt.fmt.pix.height != static_cast<uint32_t>(options_.height)) {
        std::string modes;
        for (const auto& m : descriptor_.modes)
            modes += (modes.empty() ? "" : ", ") + m;
        return {ErrorCode::kUnsupported,
                path_ + " has no mode " + fourccText(options_.fourcc) + " " +
                    std::to_string(options_.width) + "x" + std::to_string(options_.height) +
                    " (the driver offered " + fourccText(fmt.fmt.pix.pixelformat) + " " +
                    std::to_string(fmt.fmt.pix.width) + "x" + std::to_string(fmt.fmt.pix.height) +
                    "; modes: " + modes + ")"};
    }
    sizeimage_ = fmt.fmt.pix.sizeimage;
    if (options_.fourcc == V4L2_PIX_FMT_YUYV) {
        const uint32_t min_stride = fmt.fmt.pix.width * 2;
        const uint32_t stride = std::max(fmt.fmt.pix.bytesperline, min_stride);
        sizeimage_ = std::max(sizeimage_, stride * fmt.fmt.pix.height);
        desc_ = ImageDesc{PixelFormat::kYUYV, options_.width, options_.height,
                          static_cast<int>(stride)};
    } else if (options_.decode_rgb) {
        desc_ = ImageDesc::packed(PixelFormat::kRGB8, options_.width, options_.height);
    } else {
        desc_ = ImageDesc{PixelFormat::kMJPEG, options_.width, options_.height, 0};
    }
    if (sizeimage_ == 0)
        return {ErrorCode::kInternal, path_ + ": the driver reports a frame size of 0 bytes"};

    if (options_.fps > 0) {
        v4l2_streamparm parm{};
        parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        // A rate as a fraction the driver can match exactly for the usual 30, 29.97, 15 ...
        parm.parm.capture.timeperframe.numerator = 1000;
        parm.parm.capture.timeperframe.denominator =
            static_cast<uint32_t>(std::llround(options_.fps * 1000));
        if (xioctl(fd_, VIDIOC_S_PARM, &parm) != 0)
            return {ErrorCode::kIoError, path_ + ": VIDIOC_S_PARM: " + errnoText(errno)};
        const auto& tpf = parm.parm.capture.timeperframe;
        const double got = tpf.numerator ? static_cast<double>(tpf.denominator) / tpf.numerator : 0;
        if (!(std::abs(got - options_.fps) <= 0.01 * options_.fps)) {
            return {ErrorCode::kUnsupported, path_ + " cannot capture at " +
                                                 formatFps(options_.fps) + " fps (it offered " +
                                                 formatFps(got) + ")"};
        }
    }
    // The rate the driver will run at, for the stream's nominal_fps (0 when it does not say).
    v4l2_streamparm parm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd_, VIDIOC_G_PARM, &parm) == 0 && parm.parm.capture.timeperframe.numerator > 0) {
        const auto& tpf = parm.parm.capture.timeperframe;
        nominal_fps_ = static_cast<double>(tpf.denominator) / tpf.numerator;
    }
    return Status::ok();
}

const ControlInfo* V4l2Device::findControl(std::string_view key) const {
    for (const auto& c : controls_) {
        if (c.key == key)
            return &c;
    }
    return nullptr;
}

Result<int32_t> V4l2Device::control(std::string_view key) const {
    const ControlInfo* c = findControl(key);
    if (!c) {
        std::string known;
        for (const auto& k : controls_)
            known += (known.empty() ? "" : ", ") + k.key;
        return {ErrorCode::kNotFound,
                path_ + " has no control '" + std::string(key) + "' (it has: " + known + ")"};
    }
    v4l2_control ctrl{};
    ctrl.id = c->id;
    if (xioctl(fd_, VIDIOC_G_CTRL, &ctrl) != 0) {
        return {ErrorCode::kIoError,
                path_ + ": reading control '" + c->key + "': " + errnoText(errno)};
    }
    return ctrl.value;
}

Status V4l2Device::setControl(std::string_view key, int32_t value) {
    auto current = control(key);
    if (!current)
        return current.status();
    const ControlInfo& c = *findControl(key);
    if (c.read_only)
        return {ErrorCode::kInvalidArgument, path_ + ": control '" + c.key + "' is read-only"};
    if (value < c.minimum || value > c.maximum) {
        return {ErrorCode::kInvalidArgument,
                path_ + ": control '" + c.key + "': " + std::to_string(value) + " outside [" +
                    std::to_string(c.minimum) + ", " + std::to_string(c.maximum) + "]"};
    }
    v4l2_control ctrl{};
    ctrl.id = c.id;
    ctrl.value = value;
    if (xioctl(fd_, VIDIOC_S_CTRL, &ctrl) != 0) {
        return {ErrorCode::kIoError, path_ + ": setting control '" + c.key + "' to " +
                                         std::to_string(value) + ": " + errnoText(errno)};
    }
    auto readback = control(key);
    if (!readback)
        return readback.status();
    if (*readback != value) {
        return {ErrorCode::kIoError, path_ + ": control '" + c.key + "' set to " +
                                         std::to_string(value) + " reads back " +
                                         std::to_string(*readback)};
    }
    if (c.id == V4L2_CID_EXPOSURE_AUTO || c.id == V4L2_CID_EXPOSURE_ABSOLUTE)
        updateExposure();
    return Status::ok();
}

const ControlInfo* V4l2Device::findControlById(uint32_t id) const {
    for (const auto& c : controls_) {
        if (c.id == id)
            return &c;
    }
    return nullptr;
}

Status V4l2Device::setControlById(uint32_t id, int32_t value, std::string_view what) {
    const ControlInfo* c = findControlById(id);
    if (!c)
        return {ErrorCode::kUnsupported, path_ + " has no control for " + std::string(what)};
    return setControl(c->key, value);
}

Status V4l2Device::applyControls() {
    const bool environment = options_.role == V4l2Options::Role::kEnvironment;
    // Light estimation compares frame brightness and colour over time: the environment camera
    // must not rescale either on its own. Manual values are refused by uvcvideo while their
    // automatic control is on, so the automatic ones are switched first.
    if (environment || options_.exposure_us > 0) {
        MIXRAY_RETURN_IF_ERROR(
            setControlById(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, "manual exposure"));
    }
    if (options_.exposure_us > 0) {
        // UVC exposure times are in units of 100 µs.
        MIXRAY_RETURN_IF_ERROR(setControlById(V4L2_CID_EXPOSURE_ABSOLUTE,
                                              (options_.exposure_us + 50) / 100, "exposure_us"));
    }
    if (environment || options_.auto_white_balance >= 0 || options_.white_balance_k > 0) {
        const int32_t on = options_.auto_white_balance == 1 ? 1 : 0;
        MIXRAY_RETURN_IF_ERROR(
            setControlById(V4L2_CID_AUTO_WHITE_BALANCE, on, "automatic white balance"));
    }
    if (options_.white_balance_k > 0) {
        MIXRAY_RETURN_IF_ERROR(setControlById(V4L2_CID_WHITE_BALANCE_TEMPERATURE,
                                              options_.white_balance_k, "white_balance_k"));
    }
    for (const auto& [key, value] : options_.controls)
        MIXRAY_RETURN_IF_ERROR(setControl(key, value));
    return Status::ok();
}

void V4l2Device::updateExposure() {
    int64_t exposure_us = -1;
    const ControlInfo* mode = findControlById(V4L2_CID_EXPOSURE_AUTO);
    const ControlInfo* time = findControlById(V4L2_CID_EXPOSURE_ABSOLUTE);
    if (mode && time) {
        auto m = control(mode->key);
        auto t = control(time->key);
        if (m && t && *m == V4L2_EXPOSURE_MANUAL)
            exposure_us = static_cast<int64_t>(*t) * 100;
    }
    exposure_us_.store(exposure_us);
}

Status V4l2Device::connect(Graph& graph) {
    if (graph_)
        return {ErrorCode::kInvalidArgument, "v4l2 device '" + name_ + "' connected twice"};
    StreamInfo info;
    info.name = name_ + "/color";
    info.device = name_;
    info.kind = StreamKind::kColor;
    info.format = desc_;
    info.nominal_fps = nominal_fps_;
    clock_domain_ = kHostClockDomain;
    if (options_.clock == V4l2Options::ClockMode::kDevice)
        clock_domain_ = deviceClockDomain("v4l2", name_);
    info.clock_domain = clock_domain_;
    info.tags["v4l2_card"] = descriptor_.model;
    info.tags["v4l2_path"] = path_;
    // MJPEG frames vary in size: the driver's sizeimage bounds them.
    auto stream = addPooledStream(graph, info, options_.pool,
                                  desc_.format == PixelFormat::kMJPEG ? sizeimage_ : 0);
    if (!stream)
        return stream.status().withContext("v4l2 device '" + name_ + "'");
    pool_ = std::move(stream->pool);
    stream_ = stream->id;
    graph_ = &graph;
    return Status::ok();
}

Status V4l2Device::allocateBuffers() {
    const uint32_t memory = options_.io == IoMethod::kMmap ? V4L2_MEMORY_MMAP : V4L2_MEMORY_USERPTR;
    v4l2_requestbuffers req{};
    req.count = options_.buffers;
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = memory;
    if (xioctl(fd_, VIDIOC_REQBUFS, &req) != 0) {
        return {errno == EINVAL ? ErrorCode::kUnsupported : ErrorCode::kIoError,
                path_ + ": VIDIOC_REQBUFS (" +
                    std::string(options_.io == IoMethod::kMmap ? "mmap" : "userptr") +
                    "): " + errnoText(errno)};
    }
    if (req.count < 2) {
        return {ErrorCode::kIoError,
                path_ + ": the driver gave " + std::to_string(req.count) + " buffers"};
    }
    buffers_.assign(req.count, Buffer{});
    for (uint32_t i = 0; i < req.count; ++i) {
        v4l2_buffer buf{};
        buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        buf.memory = memory;
        buf.index = i;
        if (options_.io == IoMethod::kMmap) {
            if (xioctl(fd_, VIDIOC_QUERYBUF, &buf) != 0)
                return {ErrorCode::kIoError, path_ + ": VIDIOC_QUERYBUF: " + errnoText(errno)};
            void* p =
                ::mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
            if (p == MAP_FAILED)
                return {ErrorCode::kIoError, path_ + ": mmap of a buffer: " + errnoText(errno)};
            buffers_[i] = {static_cast<uint8_t*>(p), buf.length, true};
        } else {
            // Page-aligned: drivers that pin user memory for DMA want whole pages.
            const size_t page = static_cast<size_t>(::sysconf(_SC_PAGESIZE));
            const size_t length = (sizeimage_ + page - 1) / page * page;
            void* p = std::aligned_alloc(page, length);
            if (!p)
                return {ErrorCode::kInternal, path_ + ": out of memory for capture buffers"};
            buffers_[i] = {static_cast<uint8_t*>(p), length, false};
            buf.m.userptr = reinterpret_cast<unsigned long>(p);
            buf.length = static_cast<uint32_t>(length);
        }
        if (xioctl(fd_, VIDIOC_QBUF, &buf) != 0)
            return {ErrorCode::kIoError, path_ + ": VIDIOC_QBUF: " + errnoText(errno)};
    }
    return Status::ok();
}

void V4l2Device::freeBuffers() {
    for (auto& b : buffers_) {
        if (!b.data)
            continue;
        if (b.mapped)
            ::munmap(b.data, b.length);
        else
            std::free(b.data);
    }
    buffers_.clear();
    if (fd_ >= 0) {
        v4l2_requestbuffers req{};
        req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        req.memory = options_.io == IoMethod::kMmap ? V4L2_MEMORY_MMAP : V4L2_MEMORY_USERPTR;
        (void)xioctl(fd_, VIDIOC_REQBUFS, &req);
    }
}

Status V4l2Device::start() {
    if (!graph_)
        return {ErrorCode::kInvalidArgument, "v4l2 device '" + name_ + "': not connected"};
    if (thread_.joinable())
        return Status::ok();
    {
        std::lock_guard lock(error_mutex_);
        error_ = Status::ok();
    }
    Status s = allocateBuffers();
    if (s.isOk()) {
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        if (xioctl(fd_, VIDIOC_STREAMON, &type) != 0)
            s = {ErrorCode::kIoError, path_ + ": VIDIOC_STREAMON: " + errnoText(errno)};
    }
    if (!s.isOk()) {
        freeBuffers();
        return s.withContext("v4l2 device '" + name_ + "'");
    }
    streaming_ = true;
    have_sequence_ = false;
    stop_requested_ = false;
    uint64_t drain = 0;
    // A wake-up left from the previous stop() would end this run at once.
    (void)::read(wake_fd_, &drain, sizeof(drain));
    thread_ = std::thread([this] { run(); });
    return Status::ok();
}

void V4l2Device::stop() {
    stop_requested_ = true;
    if (wake_fd_ >= 0) {
        const uint64_t one = 1;
        (void)::write(wake_fd_, &one, sizeof(one));
    }
    if (thread_.joinable())
        thread_.join();
    if (streaming_) {
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        (void)xioctl(fd_, VIDIOC_STREAMOFF, &type);
        streaming_ = false;
    }
    // Also after a reconnection that failed half-way.
    if (!buffers_.empty())
        freeBuffers();
}

Status V4l2Device::error() const {
    std::lock_guard lock(error_mutex_);
    return error_;
}

void V4l2Device::setError(Status status) {
    std::lock_guard lock(error_mutex_);
    error_ = status.isOk() ? status : status.withContext("v4l2 device '" + name_ + "'");
}

void V4l2Device::fail(Status status) {
    setError(std::move(status));
    graph_->endStream(stream_);
}

void V4l2Device::releaseNode() {
    freeBuffers();
    streaming_ = false;
    if (fd_ >= 0)
        ::close(fd_);
    fd_ = -1;
}

Status V4l2Device::reopen() {
    const int fd = ::open(path_.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return {ErrorCode::kUnavailable, "cannot open " + path_ + ": " + errnoText(errno)};
    fd_ = fd;
    auto info = queryNode(fd, path_);
    if (!info)
        return info.status();
    const ImageDesc before = desc_;
    MIXRAY_RETURN_IF_ERROR(negotiate());
    if (!(desc_ == before)) {
        // The pool holds the old layout: frames of the new one would not fit its buffers.
        desc_ = before;
        return {ErrorCode::kUnsupported, path_ + " came back with another frame layout"};
    }
    MIXRAY_RETURN_IF_ERROR(applyControls());
    MIXRAY_RETURN_IF_ERROR(allocateBuffers());
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd_, VIDIOC_STREAMON, &type) != 0)
        return {ErrorCode::kIoError, path_ + ": VIDIOC_STREAMON: " + errnoText(errno)};
    streaming_ = true;
    return Status::ok();
}

bool V4l2Device::recover(Status lost) {
    if (!options_.reconnect) {
        fail(std::move(lost));
        return false;
    }
    setError({ErrorCode::kUnavailable, lost.message() + "; reopening it when it answers"});
    // Nothing of the old node can be trusted: its buffers and its file go.
    releaseNode();
    while (!stop_requested_.load()) {
        pollfd wake = {wake_fd_, POLLIN, 0};
        (void)::poll(&wake, 1, kReconnectIntervalMs);
        if (stop_requested_.load())
            return false;
        const Status s = reopen();
        if (s.isOk()) {
            have_sequence_ = false;
            reconnects_.fetch_add(1, std::memory_order_relaxed);
            setError(Status::ok());
            return true;
        }
        releaseNode();
        if (s.code() == ErrorCode::kUnsupported) {
            fail(s);
            return false;
        }
    }
    return false;
}

void V4l2Device::run() {
    runAs(ThreadRole::kCapture);  // a frame late here is a frame lost (thread_priority.h)
    const uint32_t memory = options_.io == IoMethod::kMmap ? V4L2_MEMORY_MMAP : V4L2_MEMORY_USERPTR;
    while (!stop_requested_.load()) {
        // The timeout bounds the wait on nodes whose poll never reports POLLIN (umockdev's
        // emulated nodes); a driver that does wakes us when a buffer is done. Either way the
        // non-blocking DQBUF below decides: EAGAIN means no frame yet.
        pollfd fds[2] = {{fd_, POLLIN, 0}, {wake_fd_, POLLIN, 0}};
        if (::poll(fds, 2, kPollTimeoutMs) < 0 && errno != EINTR) {
            fail({ErrorCode::kIoError, path_ + ": poll: " + errnoText(errno)});
            return;
        }
        if (stop_requested_.load())
            return;
        v4l2_buffer buf{};
        buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        buf.memory = memory;
        if (xioctl(fd_, VIDIOC_DQBUF, &buf) != 0) {
            if (errno == EAGAIN)
                continue;
            const int err = errno;
            if (err == ENODEV) {
                if (recover({ErrorCode::kUnavailable, path_ + " was lost (unplugged?)"}))
                    continue;
                return;
            }
            fail({ErrorCode::kIoError, path_ + ": VIDIOC_DQBUF: " + errnoText(err)});
            return;
        }
        const int64_t host_ns = monotonicNowNs();
        if (buf.index >= buffers_.size()) {
            fail({ErrorCode::kInternal, path_ + ": the driver returned buffer " +
                                            std::to_string(buf.index) + " of " +
                                            std::to_string(buffers_.size())});
            return;
        }
        const Buffer& b = buffers_[buf.index];
        const size_t used = std::min<size_t>(buf.bytesused, b.length);

        // Frames the driver dropped (a gap in its sequence), frames without a free buffer and
        // frames that did not decode are all lost to the graph: counted where commands report
        // losses (Graph::lostCount) as well as in the device's own figures.
        if (have_sequence_ && buf.sequence > last_sequence_ + 1) {
            gaps_.fetch_add(buf.sequence - last_sequence_ - 1, std::memory_order_relaxed);
            graph_->countLost(stream_, buf.sequence - last_sequence_ - 1);
        }
        last_sequence_ = buf.sequence;
        have_sequence_ = true;

        WritableFrame frame = pool_->acquire();
        if (!frame) {
            exhausted_.fetch_add(1, std::memory_order_relaxed);
            graph_->countLost(stream_);
        } else {
            bool ok = true;
            MutableImageView view = frame.image();
            if (desc_.format == PixelFormat::kMJPEG) {
                const size_t n_bytes = std::min(used, frame.capacityBytes());
                std::memcpy(view.data, b.data, n_bytes);
                frame.setPayloadBytes(n_bytes);
            } else if (desc_.format == PixelFormat::kRGB8) {
                if (!decodeMjpegToRgb(b.data, used, view).isOk()) {
                    decode_errors_.fetch_add(1, std::memory_order_relaxed);
                    graph_->countLost(stream_);
                    ok = false;
                }
            } else {
                const size_t row = static_cast<size_t>(desc_.stride_bytes);
                const size_t n_bytes = std::min(used, row * static_cast<size_t>(desc_.height));
                std::memcpy(view.data, b.data, n_bytes);
                if (n_bytes < row * static_cast<size_t>(desc_.height)) {
                    // A short buffer: the rest of the image is stale; say so.
                    std::memset(view.data + n_bytes, 0, row * desc_.height - n_bytes);
                    buf.flags |= V4L2_BUF_FLAG_ERROR;
                }
            }
            if (ok) {
                FrameMetadata& meta = frame.meta();
                meta.stream = stream_;
                meta.sequence = buf.sequence;
                meta.device_stamp_ns = static_cast<int64_t>(buf.timestamp.tv_sec) * 1'000'000'000 +
                                       static_cast<int64_t>(buf.timestamp.tv_usec) * 1000;
                meta.host_stamp_ns = host_ns;
                meta.exposure_us = exposure_us_.load(std::memory_order_relaxed);
                const bool monotonic =
                    (buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
                // Kernel stamps on CLOCK_MONOTONIC are host time already; any other stamp
                // needs the clock model of a domain of its own.
                meta.clock_domain = monotonic ? clock_domain_ : deviceClockDomain("v4l2", name_);
                meta.status =
                    (buf.flags & V4L2_BUF_FLAG_ERROR) ? FrameStatus::kIncomplete : FrameStatus::kOk;
                graph_->publish(std::move(frame).publish());
                published_.fetch_add(1, std::memory_order_relaxed);
            }
        }
        // Give the buffer back at once: the driver fills the next frame while consumers work.
        if (options_.io == IoMethod::kUserPtr) {
            buf.m.userptr = reinterpret_cast<unsigned long>(b.data);
            buf.length = static_cast<uint32_t>(b.length);
        }
        buf.bytesused = 0;
        buf.flags = 0;
        if (xioctl(fd_, VIDIOC_QBUF, &buf) != 0) {
            const int err = errno;
            if (err == ENODEV) {
                if (recover({ErrorCode::kUnavailable, path_ + " was lost (unplugged?)"}))
                    continue;
                return;
            }
            fail({ErrorCode::kIoError, path_ + ": VIDIOC_QBUF: " + errnoText(err)});
            return;
        }
    }
}

Result<DeviceDescriptor> describeNode(const std::string& path) {
    Fd fd(::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC));
    if (fd.get() < 0) {
        return {errno == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIoError,
                "cannot open " + path + ": " + errnoText(errno)};
    }
    auto info = queryNode(fd.get(), path);
    if (!info)
        return info.status();
    DeviceDescriptor d;
    d.backend = "v4l2";
    d.id = path;
    d.model = info->card;
    d.location = info->bus.empty() ? path : info->bus;
    d.modes = listModes(fd.get());
    return d;
}

Result<std::vector<DeviceDescriptor>> V4l2Backend::enumerate() {
    std::vector<DeviceDescriptor> out;
    for (const auto& path : videoNodes()) {
        auto d = describeNode(path);
        // Metadata nodes and nodes another program holds exclusively are not offered.
        if (d)
            out.push_back(std::move(*d));
    }
    return out;
}

Result<std::unique_ptr<Device>> V4l2Backend::open(const DeviceConfig& config) {
    if (config.name.empty()) {
        return {ErrorCode::kInvalidArgument,
                "v4l2 device without a name (streams are named <name>/color)"};
    }
    if (!config.streams.empty() &&
        (config.streams.size() != 1 || config.streams.front() != "color")) {
        return {ErrorCode::kInvalidArgument,
                "v4l2 device '" + config.name + "': it has one stream, 'color'"};
    }
    auto options = V4l2Options::fromConfig(config);
    if (!options)
        return options.status();
    std::string path;
    if (config.id.empty() || config.id.front() == '/') {
        path = config.id;
    } else if (config.id.rfind("video", 0) == 0) {
        path = "/dev/" + config.id;
    }
    if (path.empty() || config.id.empty()) {
        auto devices = enumerate();
        if (!devices)
            return devices.status();
        for (const auto& d : *devices) {
            if (config.id.empty() || d.model == config.id) {
                path = d.id;
                break;
            }
        }
        if (path.empty()) {
            return {ErrorCode::kNotFound,
                    "v4l2 device '" + config.name + "': no capture device" +
                        (config.id.empty() ? std::string() : " named '" + config.id + "'")};
        }
    }
    std::unique_ptr<V4l2Device> device(new V4l2Device(config.name, path, std::move(*options)));
    const std::string context = "v4l2 device '" + config.name + "'";
    MIXRAY_RETURN_IF_ERROR(device->openNode().withContext(context));
    MIXRAY_RETURN_IF_ERROR(device->negotiate().withContext(context));
    MIXRAY_RETURN_IF_ERROR(device->applyControls().withContext(context));
    device->updateExposure();
    return std::unique_ptr<Device>(std::move(device));
}

}  // namespace mixray::v4l2
