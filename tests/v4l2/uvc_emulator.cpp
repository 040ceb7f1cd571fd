// The emulated UVC camera: uvcvideo's answers to the ioctls mixray's V4L2 backend sends.
#include "uvc_emulator.h"

#include <linux/videodev2.h>
#include <umockdev.h>

#include <cerrno>
#include <cstddef>
#include <cstring>
#include <ctime>
#include <deque>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "umockdev_ioctl_data.h"

namespace mixray::v4l2::test {

struct Size {
    uint32_t width;
    uint32_t height;
};

struct Control {
    uint32_t id;
    const char* name;
    uint32_t type;
    int32_t minimum;
    int32_t maximum;
    int32_t step;
    int32_t default_value;
};

const std::vector<Control>& controlTable() {
    static const std::vector<Control> kControls = {
        {V4L2_CID_BRIGHTNESS, "Brightness", V4L2_CTRL_TYPE_INTEGER, -64, 64, 1, 0},
        {V4L2_CID_AUTO_WHITE_BALANCE, "White Balance, Automatic", V4L2_CTRL_TYPE_BOOLEAN, 0, 1, 1,
         1},
        {V4L2_CID_WHITE_BALANCE_TEMPERATURE, "White Balance Temperature", V4L2_CTRL_TYPE_INTEGER,
         2800, 6500, 1, 4600},
        {V4L2_CID_EXPOSURE_AUTO, "Auto Exposure", V4L2_CTRL_TYPE_MENU, 0, 3, 1,
         V4L2_EXPOSURE_APERTURE_PRIORITY},
        {V4L2_CID_EXPOSURE_ABSOLUTE, "Exposure Time, Absolute", V4L2_CTRL_TYPE_INTEGER, 1, 5000, 1,
         156},
    };
    return kControls;
}

struct Queued {
    uint32_t index;
    unsigned long userptr;
    uint32_t length;
};

struct UvcEmulator::State {
    mutable std::mutex mutex;
    uint32_t fourcc = V4L2_PIX_FMT_YUYV;
    Size size{320, 240};
    uint32_t fps = 30;
    std::map<uint32_t, int32_t> values;
    uint32_t buffer_count = 0;
    std::deque<Queued> queue;
    bool streaming = false;
    int64_t t0_ns = 0;
    uint64_t next_frame = 0;  // frames produced since STREAMON
    uint64_t next_sequence = 0;
    std::set<uint64_t> error_frames;
    std::set<uint64_t> skipped_frames;
    bool unknown_clock = false;
    bool unplugged = false;
    uint32_t stream_on_count = 0;
    std::map<uint64_t, int64_t> stamps;

    uint32_t bytesPerLine() const { return fourcc == V4L2_PIX_FMT_YUYV ? size.width * 2 : 0; }
    uint32_t sizeImage() const {
        // uvcvideo reports the camera's dwMaxVideoFrameSize for MJPEG.
        return fourcc == V4L2_PIX_FMT_YUYV ? size.width * 2 * size.height
                                           : size.width * size.height * 3 / 2 + 65536;
    }
};

namespace {

const std::vector<Size>& sizesOf(uint32_t fourcc) {
    static const std::vector<Size> kYuyv = {{320, 240}, {640, 480}};
    static const std::vector<Size> kMjpeg = {{320, 240}, {1280, 720}};
    return fourcc == V4L2_PIX_FMT_MJPEG ? kMjpeg : kYuyv;
}

int64_t monotonicNs() {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

struct Handler {
    std::shared_ptr<UvcEmulator::State> state;
    bool metadata_node = false;
};

// Resolves the ioctl argument as a T in the client's memory; null when umockdev cannot.
template <typename T>
T* argument(UMockdevIoctlClient* client, mixray::test::IoctlDataRef* data) {
    *data = mixray::test::resolveIoctlData(umockdev_ioctl_client_get_arg(client), 0, sizeof(T));
    return *data ? reinterpret_cast<T*>((*data)->data) : nullptr;
}

int fillFormat(const UvcEmulator::State& s, v4l2_format* f) {
    if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE)
        return EINVAL;
    std::memset(&f->fmt, 0, sizeof(f->fmt));
    f->fmt.pix.width = s.size.width;
    f->fmt.pix.height = s.size.height;
    f->fmt.pix.pixelformat = s.fourcc;
    f->fmt.pix.field = V4L2_FIELD_NONE;
    f->fmt.pix.bytesperline = s.bytesPerLine();
    f->fmt.pix.sizeimage = s.sizeImage();
    f->fmt.pix.colorspace = V4L2_COLORSPACE_SRGB;
    return 0;
}

// Like uvcvideo: an unknown format becomes the first, an unknown size the nearest listed.
void adjustFormat(v4l2_format* f, uint32_t* fourcc, Size* size) {
    *fourcc = f->fmt.pix.pixelformat == V4L2_PIX_FMT_MJPEG ? V4L2_PIX_FMT_MJPEG : V4L2_PIX_FMT_YUYV;
    const auto& sizes = sizesOf(*fourcc);
    *size = sizes.front();
    uint64_t best = UINT64_MAX;
    for (const Size& c : sizes) {
        const int64_t dw = static_cast<int64_t>(c.width) - f->fmt.pix.width;
        const int64_t dh = static_cast<int64_t>(c.height) - f->fmt.pix.height;
        const auto d = static_cast<uint64_t>(dw * dw + dh * dh);
        if (d < best) {
            best = d;
            *size = c;
        }
    }
}

int dequeue(UvcEmulator::State& s, UMockdevIoctlData* data, v4l2_buffer* b) {
    if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_USERPTR)
        return EINVAL;
    if (!s.streaming)
        return EINVAL;
    if (s.queue.empty())
        return EAGAIN;
    const int64_t period = 1'000'000'000 / s.fps;
    const int64_t ready = s.t0_ns + static_cast<int64_t>(s.next_frame + 1) * period;
    if (monotonicNs() < ready)
        return EAGAIN;
    ++s.next_frame;
    while (s.skipped_frames.count(s.next_sequence))
        ++s.next_sequence;
    const uint64_t seq = s.next_sequence++;
    const Queued q = s.queue.front();
    s.queue.pop_front();

    // Point the argument at the client's buffer so that umockdev fetches it and writes it back.
    b->m.userptr = q.userptr;
    const mixray::test::IoctlDataRef pixels =
        mixray::test::resolveIoctlData(data, offsetof(v4l2_buffer, m), q.length);
    if (!pixels)
        return EFAULT;
    size_t used = 0;
    if (s.fourcc == V4L2_PIX_FMT_YUYV) {
        const int stride = static_cast<int>(s.bytesPerLine());
        for (int y = 0; y < static_cast<int>(s.size.height); ++y) {
            for (int x = 0; x < stride; ++x)
                pixels->data[static_cast<size_t>(y) * stride + x] = yuyvByte(seq, x, y);
        }
        used = s.sizeImage();
    } else {
        const auto jpeg =
            mjpegFrame(seq, static_cast<int>(s.size.width), static_cast<int>(s.size.height));
        std::memcpy(pixels->data, jpeg.data(), std::min<size_t>(jpeg.size(), q.length));
        used = jpeg.size();
    }
    // The argument's pointer now names local memory; restore what the client sees.
    b->index = q.index;
    b->bytesused = static_cast<uint32_t>(used);
    b->field = V4L2_FIELD_NONE;
    b->sequence = static_cast<uint32_t>(seq);
    b->length = q.length;
    b->flags = V4L2_BUF_FLAG_TSTAMP_SRC_SOE | (s.unknown_clock ? V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN
                                                               : V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC);
    if (s.error_frames.count(seq))
        b->flags |= V4L2_BUF_FLAG_ERROR;
    const int64_t stamp = s.unknown_clock ? ready - s.t0_ns : ready;
    // Kernel stamps are whole microseconds in struct timeval.
    const int64_t stamp_us = stamp / 1000;
    b->timestamp.tv_sec = stamp_us / 1'000'000;
    b->timestamp.tv_usec = stamp_us % 1'000'000;
    s.stamps[seq] = stamp_us * 1000;
    return 0;
}

int handleCapture(UvcEmulator::State& s, unsigned long request, UMockdevIoctlClient* client) {
    mixray::test::IoctlDataRef data;
    switch (request) {
        case VIDIOC_QUERYCAP: {
            auto* cap = argument<v4l2_capability>(client, &data);
            if (!cap)
                return EFAULT;
            std::memset(cap, 0, sizeof(*cap));
            std::snprintf(reinterpret_cast<char*>(cap->driver), sizeof(cap->driver), "uvcvideo");
            std::snprintf(reinterpret_cast<char*>(cap->card), sizeof(cap->card),
                          "mixray UVC emulator");
            std::snprintf(reinterpret_cast<char*>(cap->bus_info), sizeof(cap->bus_info),
                          "usb-0000:00:14.0-1");
            cap->version = 0x060100;
            cap->device_caps =
                V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING | V4L2_CAP_EXT_PIX_FORMAT;
            cap->capabilities = cap->device_caps | V4L2_CAP_META_CAPTURE | V4L2_CAP_DEVICE_CAPS;
            return 0;
        }
        case VIDIOC_ENUM_FMT: {
            auto* f = argument<v4l2_fmtdesc>(client, &data);
            if (!f)
                return EFAULT;
            if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || f->index > 1)
                return EINVAL;
            const uint32_t index = f->index;
            std::memset(f, 0, sizeof(*f));
            f->index = index;
            f->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
            f->pixelformat = index == 0 ? V4L2_PIX_FMT_YUYV : V4L2_PIX_FMT_MJPEG;
            f->flags = index == 1 ? V4L2_FMT_FLAG_COMPRESSED : 0;
            std::snprintf(reinterpret_cast<char*>(f->description), sizeof(f->description), "%s",
                          index == 0 ? "YUYV 4:2:2" : "Motion-JPEG");
            return 0;
        }
        case VIDIOC_ENUM_FRAMESIZES: {
            auto* f = argument<v4l2_frmsizeenum>(client, &data);
            if (!f)
                return EFAULT;
            if (f->pixel_format != V4L2_PIX_FMT_YUYV && f->pixel_format != V4L2_PIX_FMT_MJPEG)
                return EINVAL;
            const auto& sizes = sizesOf(f->pixel_format);
            if (f->index >= sizes.size())
                return EINVAL;
            f->type = V4L2_FRMSIZE_TYPE_DISCRETE;
            f->discrete.width = sizes[f->index].width;
            f->discrete.height = sizes[f->index].height;
            return 0;
        }
        case VIDIOC_ENUM_FRAMEINTERVALS: {
            auto* f = argument<v4l2_frmivalenum>(client, &data);
            if (!f)
                return EFAULT;
            if (f->index > 1)
                return EINVAL;
            f->type = V4L2_FRMIVAL_TYPE_DISCRETE;
            f->discrete.numerator = 1;
            f->discrete.denominator = f->index == 0 ? 30 : 15;
            return 0;
        }
        case VIDIOC_G_FMT: {
            auto* f = argument<v4l2_format>(client, &data);
            return f ? fillFormat(s, f) : EFAULT;
        }
        case VIDIOC_TRY_FMT:
        case VIDIOC_S_FMT: {
            auto* f = argument<v4l2_format>(client, &data);
            if (!f)
                return EFAULT;
            if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE)
                return EINVAL;
            if (request == VIDIOC_S_FMT && s.buffer_count > 0)
                return EBUSY;
            UvcEmulator::State probe;
            adjustFormat(f, &probe.fourcc, &probe.size);
            if (request == VIDIOC_S_FMT) {
                s.fourcc = probe.fourcc;
                s.size = probe.size;
            }
            return fillFormat(request == VIDIOC_S_FMT ? s : probe, f);
        }
        case VIDIOC_G_PARM:
        case VIDIOC_S_PARM: {
            auto* p = argument<v4l2_streamparm>(client, &data);
            if (!p)
                return EFAULT;
            if (p->type != V4L2_BUF_TYPE_VIDEO_CAPTURE)
                return EINVAL;
            if (request == VIDIOC_S_PARM) {
                const auto& t = p->parm.capture.timeperframe;
                const double fps =
                    t.numerator ? static_cast<double>(t.denominator) / t.numerator : 30;
                s.fps = fps > 22.5 ? 30 : 15;
            }
            std::memset(&p->parm, 0, sizeof(p->parm));
            p->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
            p->parm.capture.timeperframe = {1, s.fps};
            return 0;
        }
        case VIDIOC_QUERYCTRL: {
            auto* q = argument<v4l2_queryctrl>(client, &data);
            if (!q)
                return EFAULT;
            const bool next = (q->id & V4L2_CTRL_FLAG_NEXT_CTRL) != 0;
            const uint32_t id = q->id & ~(V4L2_CTRL_FLAG_NEXT_CTRL | V4L2_CTRL_FLAG_NEXT_COMPOUND);
            const Control* found = nullptr;
            for (const auto& c : controlTable()) {
                if ((next && c.id > id && (!found || c.id < found->id)) || (!next && c.id == id))
                    found = &c;
            }
            if (!found)
                return EINVAL;
            std::memset(q, 0, sizeof(*q));
            q->id = found->id;
            q->type = found->type;
            std::snprintf(reinterpret_cast<char*>(q->name), sizeof(q->name), "%s", found->name);
            q->minimum = found->minimum;
            q->maximum = found->maximum;
            q->step = found->step;
            q->default_value = found->default_value;
            return 0;
        }
        case VIDIOC_G_CTRL:
        case VIDIOC_S_CTRL: {
            auto* c = argument<v4l2_control>(client, &data);
            if (!c)
                return EFAULT;
            auto it = s.values.find(c->id);
            if (it == s.values.end())
                return EINVAL;
            if (request == VIDIOC_S_CTRL) {
                for (const auto& info : controlTable()) {
                    if (info.id == c->id && (c->value < info.minimum || c->value > info.maximum))
                        return ERANGE;
                }
                // uvcvideo refuses manual values while their automatic control is on.
                if (c->id == V4L2_CID_EXPOSURE_ABSOLUTE &&
                    s.values[V4L2_CID_EXPOSURE_AUTO] != V4L2_EXPOSURE_MANUAL)
                    return EACCES;
                if (c->id == V4L2_CID_WHITE_BALANCE_TEMPERATURE &&
                    s.values[V4L2_CID_AUTO_WHITE_BALANCE])
                    return EACCES;
                it->second = c->value;
            } else {
                c->value = it->second;
            }
            return 0;
        }
        case VIDIOC_REQBUFS: {
            auto* r = argument<v4l2_requestbuffers>(client, &data);
            if (!r)
                return EFAULT;
            if (r->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || r->memory != V4L2_MEMORY_USERPTR)
                return EINVAL;
            if (s.streaming)
                return EBUSY;
            s.queue.clear();
            s.buffer_count = std::min<uint32_t>(r->count, 32);
            r->count = s.buffer_count;
            return 0;
        }
        case VIDIOC_QBUF: {
            auto* b = argument<v4l2_buffer>(client, &data);
            if (!b)
                return EFAULT;
            if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_USERPTR ||
                b->index >= s.buffer_count || b->m.userptr == 0 || b->length < s.sizeImage())
                return EINVAL;
            for (const auto& q : s.queue) {
                if (q.index == b->index)
                    return EINVAL;
            }
            s.queue.push_back({b->index, b->m.userptr, b->length});
            b->flags |= V4L2_BUF_FLAG_QUEUED;
            return 0;
        }
        case VIDIOC_DQBUF: {
            auto* b = argument<v4l2_buffer>(client, &data);
            return b ? dequeue(s, data.get(), b) : EFAULT;
        }
        case VIDIOC_STREAMON:
        case VIDIOC_STREAMOFF: {
            auto* type = argument<int>(client, &data);
            if (!type)
                return EFAULT;
            if (*type != V4L2_BUF_TYPE_VIDEO_CAPTURE)
                return EINVAL;
            if (request == VIDIOC_STREAMON) {
                if (s.buffer_count == 0)
                    return EINVAL;
                if (!s.streaming) {
                    s.streaming = true;
                    ++s.stream_on_count;
                    s.t0_ns = monotonicNs();
                    s.next_frame = 0;
                    s.next_sequence = 0;
                }
            } else {
                s.streaming = false;
                s.queue.clear();
            }
            return 0;
        }
        default:
            return ENOTTY;
    }
}

gboolean onIoctl(UMockdevIoctlBase* /*base*/, UMockdevIoctlClient* client, gpointer user) {
    auto* h = static_cast<Handler*>(user);
    const unsigned long request = umockdev_ioctl_client_get_request(client);
    int err = 0;
    {
        std::lock_guard lock(h->state->mutex);
        if (h->state->unplugged) {
            err = ENODEV;
        } else if (h->metadata_node) {
            mixray::test::IoctlDataRef data;
            auto* cap =
                request == VIDIOC_QUERYCAP ? argument<v4l2_capability>(client, &data) : nullptr;
            if (cap) {
                std::memset(cap, 0, sizeof(*cap));
                std::snprintf(reinterpret_cast<char*>(cap->driver), sizeof(cap->driver),
                              "uvcvideo");
                std::snprintf(reinterpret_cast<char*>(cap->card), sizeof(cap->card),
                              "mixray UVC emulator");
                cap->device_caps = V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING;
                cap->capabilities =
                    cap->device_caps | V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_DEVICE_CAPS;
            } else {
                err = ENOTTY;
            }
        } else {
            err = handleCapture(*h->state, request, client);
        }
    }
    umockdev_ioctl_client_complete(client, err ? -1 : 0, err);
    return TRUE;
}

void freeHandler(gpointer data, GClosure* /*closure*/) {
    delete static_cast<Handler*>(data);
}

}  // namespace

uint8_t yuyvByte(uint64_t sequence, int x_byte, int y) {
    if (y == 0 && x_byte < 8)
        return static_cast<uint8_t>(sequence >> (8 * x_byte));
    return static_cast<uint8_t>(x_byte * 3 + y * 7 + sequence * 11);
}

std::vector<uint8_t> mjpegFrame(uint64_t sequence, int width, int height,
                                std::vector<uint8_t>* rgb) {
    cv::Mat bgr(height, width, CV_8UC3);
    for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
            bgr.at<cv::Vec3b>(y, x) =
                cv::Vec3b(static_cast<uint8_t>(y + sequence * 5), static_cast<uint8_t>(x + y),
                          static_cast<uint8_t>(x + sequence * 3));
        }
    }
    std::vector<uint8_t> jpeg;
    cv::imencode(".jpg", bgr, jpeg, {cv::IMWRITE_JPEG_QUALITY, 90});
    if (rgb) {
        rgb->resize(static_cast<size_t>(width) * height * 3);
        for (int y = 0; y < height; ++y) {
            for (int x = 0; x < width; ++x) {
                const cv::Vec3b p = bgr.at<cv::Vec3b>(y, x);
                uint8_t* o = rgb->data() + (static_cast<size_t>(y) * width + x) * 3;
                o[0] = p[2];
                o[1] = p[1];
                o[2] = p[0];
            }
        }
    }
    return jpeg;
}

std::unique_ptr<UvcEmulator> UvcEmulator::create(std::string* why) {
    std::unique_ptr<UvcEmulator> e(new UvcEmulator());
    e->state_ = std::make_shared<State>();
    for (const auto& c : controlTable())
        e->state_->values[c.id] = c.default_value;
    UMockdevTestbed* testbed = umockdev_testbed_new();
    e->testbed_ = testbed;
    static const char* kTree =
        "P: /devices/pci0000:00/0000:00:14.0/usb1/1-1/1-1:1.0/video4linux/video0\n"
        "N: video0\n"
        "E: DEVNAME=/dev/video0\n"
        "E: SUBSYSTEM=video4linux\n"
        "A: name=mixray UVC emulator\n"
        "A: index=0\n"
        "\n"
        "P: /devices/pci0000:00/0000:00:14.0/usb1/1-1/1-1:1.0/video4linux/video1\n"
        "N: video1\n"
        "E: DEVNAME=/dev/video1\n"
        "E: SUBSYSTEM=video4linux\n"
        "A: name=mixray UVC emulator\n"
        "A: index=1\n";
    GError* error = nullptr;
    if (!umockdev_testbed_add_from_string(testbed, kTree, &error)) {
        if (why)
            *why = std::string("umockdev: ") + error->message;
        g_clear_error(&error);
        return nullptr;
    }
    for (int i = 0; i < 2; ++i) {
        UMockdevIoctlBase* base = umockdev_ioctl_base_new();
        e->handlers_[i] = base;
        auto* h = new Handler{e->state_, i == 1};
        g_signal_connect_data(base, "handle-ioctl", G_CALLBACK(onIoctl), h, freeHandler,
                              static_cast<GConnectFlags>(0));
        const std::string node = "/dev/video" + std::to_string(i);
        if (!umockdev_testbed_attach_ioctl(testbed, node.c_str(), base, &error)) {
            if (why)
                *why = "umockdev: attaching " + node + ": " + error->message;
            g_clear_error(&error);
            return nullptr;
        }
    }
    return e;
}

UvcEmulator::~UvcEmulator() {
    auto* testbed = static_cast<UMockdevTestbed*>(testbed_);
    for (int i = 0; i < 2; ++i) {
        if (!handlers_[i])
            continue;
        const std::string node = "/dev/video" + std::to_string(i);
        if (testbed)
            (void)umockdev_testbed_detach_ioctl(testbed, node.c_str(), nullptr);
        g_object_unref(handlers_[i]);
    }
    if (testbed)
        g_object_unref(testbed);
}

void UvcEmulator::setErrorFrames(std::set<uint64_t> sequences) {
    std::lock_guard lock(state_->mutex);
    state_->error_frames = std::move(sequences);
}

void UvcEmulator::setSkippedFrames(std::set<uint64_t> sequences) {
    std::lock_guard lock(state_->mutex);
    state_->skipped_frames = std::move(sequences);
}

void UvcEmulator::setUnknownClock(bool unknown) {
    std::lock_guard lock(state_->mutex);
    state_->unknown_clock = unknown;
}

void UvcEmulator::unplug() {
    std::lock_guard lock(state_->mutex);
    state_->unplugged = true;
}

void UvcEmulator::replug() {
    std::lock_guard lock(state_->mutex);
    State& s = *state_;
    s.unplugged = false;
    s.streaming = false;
    s.queue.clear();
    s.buffer_count = 0;
    s.fourcc = V4L2_PIX_FMT_YUYV;
    s.size = {320, 240};
    s.fps = 30;
    for (const auto& c : controlTable())
        s.values[c.id] = c.default_value;
}

std::map<uint64_t, int64_t> UvcEmulator::stamps() const {
    std::lock_guard lock(state_->mutex);
    return state_->stamps;
}

uint32_t UvcEmulator::streamOnCount() const {
    std::lock_guard lock(state_->mutex);
    return state_->stream_on_count;
}

bool UvcEmulator::streaming() const {
    std::lock_guard lock(state_->mutex);
    return state_->streaming;
}

int32_t UvcEmulator::control(uint32_t id) const {
    std::lock_guard lock(state_->mutex);
    auto it = state_->values.find(id);
    return it == state_->values.end() ? INT32_MIN : it->second;
}

}  // namespace mixray::v4l2::test
