// The emulated Kinect v1 camera behind its usbfs node: URBs, string descriptors, libfreenect's
// camera protocol and isochronous depth / colour / IR streaming.
#include "kinect_usb_emulator.h"

#include <linux/usbdevice_fs.h>
#include <sys/ioctl.h>
#include <umockdev.h>

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <deque>
#include <fstream>
#include <sstream>

#include "umockdev_ioctl_data.h"

namespace mixray::openni2::test {

// An isochronous URB waiting for its packets.
struct IsoUrb {
    UMockdevIoctlData* urb = nullptr;     // owned ref
    UMockdevIoctlData* buffer = nullptr;  // the URB's child (the URB holds it)
    uint8_t endpoint = 0;
    size_t packet_room = 0;  // bytes per packet slot in the buffer
    gulong client = 0;       // the URB's address in the client
    // The open file it was submitted on (umockdev has one client per connection). As the
    // kernel does, only that file reaps or discards it: libusb opens the camera more than
    // once (listing serials while a handle streams), and a URB reaped through another handle
    // would complete a transfer libusb then frees twice. (umockdev 0.17 does not say when a
    // file closes; libusb reaps every URB of a handle before closing it, and replugCamera()
    // drops what an unplug left.)
    UMockdevIoctlClient* owner = nullptr;
};

// A URB finished and waiting to be reaped by the file it was submitted on.
struct DoneUrb {
    UMockdevIoctlClient* owner = nullptr;
    UMockdevIoctlData* urb = nullptr;  // owned ref
};

struct KinectUsbEmulator::State {
    mutable std::mutex mutex;
    std::deque<DoneUrb> completed;  // URBs to reap, oldest first
    std::vector<std::string> requests;
    std::vector<uint8_t> reply;  // the camera's answer to the last command, until read
    std::map<uint16_t, uint16_t> registers;
    std::vector<uint16_t> commands;
    struct StreamState {
        uint64_t next_packet = 0;
        int64_t start_ns = 0;
        int in_flight = 0;
        uint64_t frames_sent = 0;
        uint64_t frame_cache_index = 0;
        std::vector<uint8_t> frame_cache;
    };
    std::deque<IsoUrb> iso;  // submitted isochronous URBs, oldest first (owned refs)
    std::map<uint8_t, StreamState> streams;  // by endpoint
    bool unplugged = false;
};

namespace {

constexpr uint8_t kGetDescriptor = 6;
constexpr uint8_t kStringDescriptor = 3;
constexpr uint16_t kLangEnglishUs = 0x0409;

// The camera's string descriptors by index, as its device descriptor numbers them.
const char* cameraString(uint8_t index) {
    switch (index) {
        case 1:
            return "Microsoft";
        case 2:
            return "Xbox NUI Camera";
        case 3:
            return KinectUsbEmulator::kCameraSerial;
        default:
            return nullptr;
    }
}

uint16_t le16(const uint8_t* p) {
    return static_cast<uint16_t>(p[0] | (p[1] << 8));
}

void putLe16(std::vector<uint8_t>& out, size_t at, uint16_t v) {
    out[at] = static_cast<uint8_t>(v & 0xff);
    out[at + 1] = static_cast<uint8_t>(v >> 8);
}

void putFloat(std::vector<uint8_t>& out, size_t at, float v) {
    std::memcpy(out.data() + at, &v, sizeof(v));
}

// The camera's payload for command `cmd` (libfreenect's send_cmd: "GM" header + words out,
// "RB" header + words back); false for commands it does not know.
bool commandPayload(KinectUsbEmulator::State& s, uint16_t cmd, const uint8_t* args, size_t size,
                    std::vector<uint8_t>* payload) {
    switch (cmd) {
        case 0x02:  // read register
            if (size < 2)
                return false;
            payload->assign(4, 0);
            putLe16(*payload, 2, s.registers[le16(args)]);
            return true;
        case 0x03:  // write register
            if (size < 4)
                return false;
            s.registers[le16(args)] = le16(args + 2);
            payload->assign(2, 0);
            return true;
        case 0x04:  // fixed parameters: the 1414's 322 bytes, zero-plane floats at byte 94
            payload->assign(322, 0);
            putFloat(*payload, 94, 7.5f);      // depth camera to emitter, cm
            putFloat(*payload, 98, 2.3f);      // depth camera to colour camera, cm
            putFloat(*payload, 102, 120.0f);   // reference plane distance, mm
            putFloat(*payload, 106, 0.1042f);  // reference pixel size, mm
            return true;
        case 0x16: {  // algorithm parameters, by parameter id
            if (size < 2)
                return false;
            const uint16_t id = le16(args);
            if (id == 0x40) {  // registration coefficients: all zero (no shift)
                payload->assign(118, 0);
            } else if (id == 0x41) {  // padding lines
                payload->assign(8, 0);
            } else if (id == 0x00) {  // constant shift
                payload->assign(4, 0);
                putLe16(*payload, 2, 200);
            } else {
                return false;
            }
            return true;
        }
        default:
            return false;
    }
}

// A command written to the camera (vendor OUT request 0): its reply is read next.
int cameraCommand(KinectUsbEmulator::State& s, const uint8_t* data, size_t size) {
    if (size < 8 || data[0] != 0x47 || data[1] != 0x4d)
        return -EPIPE;
    const uint16_t words = le16(data + 2);
    const uint16_t cmd = le16(data + 4);
    const uint16_t tag = le16(data + 6);
    if (8 + 2 * static_cast<size_t>(words) > size)
        return -EPIPE;
    s.commands.push_back(cmd);
    std::vector<uint8_t> payload;
    if (!commandPayload(s, cmd, data + 8, 2 * static_cast<size_t>(words), &payload))
        return -EPIPE;
    s.reply.assign(8 + payload.size(), 0);
    s.reply[0] = 0x52;  // "RB"
    s.reply[1] = 0x42;
    putLe16(s.reply, 2, static_cast<uint16_t>(payload.size() / 2));
    putLe16(s.reply, 4, cmd);
    putLe16(s.reply, 6, tag);
    std::memcpy(s.reply.data() + 8, payload.data(), payload.size());
    return 0;
}

// The reply to a control transfer's setup packet: its data stage, or a stall (-EPIPE).
int controlReply(KinectUsbEmulator::State& s, const uint8_t* setup, const uint8_t* out,
                 std::vector<uint8_t>* reply) {
    const uint8_t request_type = setup[0];
    const uint8_t request = setup[1];
    const uint16_t value = static_cast<uint16_t>(setup[2] | (setup[3] << 8));
    if (request_type == 0x40 && request == 0)
        return cameraCommand(s, out, le16(setup + 6));
    if (request_type == 0xc0 && request == 0) {
        if (s.reply.empty())
            return -EPIPE;
        reply->swap(s.reply);
        s.reply.clear();
        return 0;
    }
    if (request_type != 0x80 || request != kGetDescriptor || (value >> 8) != kStringDescriptor)
        return -EPIPE;
    const uint8_t index = static_cast<uint8_t>(value & 0xff);
    if (index == 0) {
        *reply = {4, kStringDescriptor, kLangEnglishUs & 0xff, kLangEnglishUs >> 8};
        return 0;
    }
    const char* text = cameraString(index);
    if (!text)
        return -EPIPE;
    const size_t n = std::strlen(text);
    reply->assign(2 + 2 * n, 0);
    (*reply)[0] = static_cast<uint8_t>(2 + 2 * n);
    (*reply)[1] = kStringDescriptor;
    for (size_t i = 0; i < n; ++i)
        (*reply)[2 + 2 * i] = static_cast<uint8_t>(text[i]);  // UTF-16LE of ASCII
    return 0;
}

std::string requestText(const uint8_t* setup) {
    char text[32];
    std::snprintf(text, sizeof(text), "%02x:%02x:%04x:%04x", setup[0], setup[1],
                  setup[2] | (setup[3] << 8), setup[4] | (setup[5] << 8));
    return text;
}

int64_t monotonicNs() {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Packs `count` values of `bits` bits, most significant bit first, as the camera packs depth
// and IR; `value(i)` is pixel i in row-major order.
template <typename Value>
std::vector<uint8_t> packBits(Value value, size_t count, int bits) {
    std::vector<uint8_t> out((count * static_cast<size_t>(bits) + 7) / 8, 0);
    size_t bit = 0;
    for (size_t i = 0; i < count; ++i) {
        const uint16_t v = value(i);
        for (int b = bits - 1; b >= 0; --b, ++bit) {
            if ((v >> b) & 1)
                out[bit / 8] |= static_cast<uint8_t>(0x80 >> (bit % 8));
        }
    }
    return out;
}

// What the camera streams on an isochronous endpoint, per the registers libfreenect wrote.
struct StreamFormat {
    uint8_t flag = 0;    // packet flag base: 0x70 depth, 0x80 video
    size_t payload = 0;  // data bytes per packet
    int bits = 0;        // bits per pixel (8: Bayer)
    size_t pixels = 0;
    bool valid = false;
};

StreamFormat formatOf(const KinectUsbEmulator::State& s, uint8_t endpoint) {
    StreamFormat f;
    auto reg = [&](uint16_t r) {
        auto it = s.registers.find(r);
        return it == s.registers.end() ? -1 : it->second;
    };
    if (endpoint == 0x82 && reg(0x06) == 2 && reg(0x12) == 3) {  // depth, 11 bit
        f = {0x70, 1748, 11, 640 * 480, true};
    } else if (endpoint == 0x81 && reg(0x05) == 1 && reg(0x0c) == 0) {  // Bayer
        f = {0x80, 1908, 8, 640 * 480, true};
    } else if (endpoint == 0x81 && reg(0x05) == 3 && reg(0x19) == 0) {  // IR, 10 bit
        f = {0x80, 1908, 10, 640 * 488, true};
    }
    return f;
}

}  // namespace

uint16_t KinectUsbEmulator::pixelValue(Stream stream, uint64_t frame) {
    switch (stream) {
        case Stream::kDepth:
            return static_cast<uint16_t>(kDepthRawBase + 8 * (frame % 32));
        case Stream::kBayer:
            return static_cast<uint16_t>(40 + frame % 200);
        case Stream::kInfrared:
            return static_cast<uint16_t>(100 + 3 * (frame % 300));
    }
    return 0;
}

namespace {

// Fills an isochronous URB with the next packets of its endpoint's stream: "RB" headers
// (flag base|1 start of frame, |2 middle, |5 end; sequence; 60 MHz timestamp) and the frame's
// pixels: every pixel of frame f is KinectUsbEmulator::pixelValue(stream, f), plus x / 64 in IR.
void fillIso(KinectUsbEmulator::State& s, IsoUrb& u) {
    auto* urb = reinterpret_cast<usbdevfs_urb*>(u.urb->data);
    auto& st = s.streams[u.endpoint];
    const StreamFormat f = formatOf(s, u.endpoint);
    const size_t frame_bytes = (f.pixels * static_cast<size_t>(f.bits) + 7) / 8;
    const size_t per_frame = (frame_bytes + f.payload - 1) / f.payload;
    const auto kind = u.endpoint == 0x82 ? KinectUsbEmulator::Stream::kDepth
                      : f.bits == 8      ? KinectUsbEmulator::Stream::kBayer
                                         : KinectUsbEmulator::Stream::kInfrared;
    size_t total = 0;
    for (int i = 0; i < urb->number_of_packets; ++i) {
        const uint64_t packet = st.next_packet++;
        const uint64_t frame = packet / per_frame;
        const size_t k = packet % per_frame;
        if (st.frame_cache_index != frame || st.frame_cache.empty()) {
            const uint16_t v = KinectUsbEmulator::pixelValue(kind, frame);
            if (kind == KinectUsbEmulator::Stream::kBayer) {
                st.frame_cache.assign(frame_bytes, static_cast<uint8_t>(v));
            } else if (kind == KinectUsbEmulator::Stream::kInfrared) {
                st.frame_cache = packBits(
                    [v](size_t pixel) {
                        return static_cast<uint16_t>(v + (pixel % 640) /
                                                             KinectUsbEmulator::kIrColumnsPerStep);
                    },
                    f.pixels, f.bits);
            } else {
                st.frame_cache = packBits([v](size_t) { return v; }, f.pixels, f.bits);
            }
            st.frame_cache_index = frame;
        }
        const size_t offset = k * f.payload;
        const size_t n = std::min(f.payload, frame_bytes - offset);
        uint8_t* p = u.buffer->data + static_cast<size_t>(i) * u.packet_room;
        p[0] = 'R';
        p[1] = 'B';
        p[2] = 0;
        p[3] = static_cast<uint8_t>(f.flag | (k == 0 ? 1 : k == per_frame - 1 ? 5 : 2));
        p[4] = 0;
        p[5] = static_cast<uint8_t>(packet & 0xff);
        p[6] = 0;
        p[7] = 0;
        const uint32_t ticks = KinectUsbEmulator::kFirstTicks +
                               static_cast<uint32_t>(frame * KinectUsbEmulator::kTicksPerFrame);
        std::memcpy(p + 8, &ticks, 4);
        std::memcpy(p + 12, st.frame_cache.data() + offset, n);
        urb->iso_frame_desc[i].actual_length = static_cast<unsigned>(12 + n);
        urb->iso_frame_desc[i].status = 0;
        total += 12 + n;
        if (k == per_frame - 1)
            ++st.frames_sent;
    }
    urb->status = 0;
    urb->actual_length = static_cast<int>(total);
    urb->error_count = 0;
    urb->start_frame = 0;
}

// SUBMITURB. Control URBs complete at once (the reply is written into the client's buffer when
// the ioctl completes) and wait for REAPURB in `completed`; isochronous URBs wait in `iso`
// until their packets are due (frame k of a stream at start + k / 30 s).
int submit(KinectUsbEmulator::State& s, UMockdevIoctlClient* owner, UMockdevIoctlData* arg) {
    const gulong client_urb = *reinterpret_cast<gulong*>(arg->data);
    mixray::test::IoctlDataRef urb_data =
        mixray::test::resolveIoctlData(arg, 0, sizeof(usbdevfs_urb));
    if (!urb_data)
        return EFAULT;
    auto* urb = reinterpret_cast<usbdevfs_urb*>(urb_data->data);
    if (urb->type == USBDEVFS_URB_TYPE_ISO) {
        if ((urb->endpoint != 0x81 && urb->endpoint != 0x82) || urb->number_of_packets <= 0 ||
            urb->buffer_length % urb->number_of_packets != 0) {
            return EINVAL;
        }
        // The packet descriptors follow the URB: fetch it again with them (the first view only
        // told how many there are; reloading the argument drops it).
        const size_t packets = static_cast<size_t>(urb->number_of_packets);
        urb_data.reset();
        *reinterpret_cast<gulong*>(arg->data) = client_urb;
        GError* error = nullptr;
        if (!umockdev_ioctl_data_reload(arg, &error)) {
            g_clear_error(&error);
            return EFAULT;
        }
        urb_data = mixray::test::resolveIoctlData(
            arg, 0, sizeof(usbdevfs_urb) + packets * sizeof(usbdevfs_iso_packet_desc));
        if (!urb_data)
            return EFAULT;
        urb = reinterpret_cast<usbdevfs_urb*>(urb_data->data);
    } else if (urb->type != USBDEVFS_URB_TYPE_CONTROL || (urb->endpoint & 0x7f) != 0 ||
               urb->buffer_length < 8) {
        return EINVAL;
    }
    // The URB keeps its buffer (a child of its data) alive as long as it lives itself.
    const mixray::test::IoctlDataRef buffer = mixray::test::resolveIoctlData(
        urb_data.get(), offsetof(usbdevfs_urb, buffer), static_cast<size_t>(urb->buffer_length));
    if (!buffer)
        return EFAULT;
    if (urb->type == USBDEVFS_URB_TYPE_ISO) {
        auto& st = s.streams[urb->endpoint];
        if (st.in_flight == 0) {  // a stream (re)starts at a frame boundary
            st.next_packet = 0;
            st.start_ns = monotonicNs();
            st.frame_cache.clear();
        }
        ++st.in_flight;
        IsoUrb u;
        u.buffer = buffer.get();
        u.endpoint = urb->endpoint;
        u.packet_room = static_cast<size_t>(urb->buffer_length / urb->number_of_packets);
        u.client = client_urb;
        u.owner = owner;
        u.urb = urb_data.release();
        s.iso.push_back(u);
        return 0;
    }
    uint8_t* setup = buffer->data;
    s.requests.push_back(requestText(setup));
    std::vector<uint8_t> reply;
    const size_t room = static_cast<size_t>(urb->buffer_length) - 8;
    const size_t length = std::min(room, static_cast<size_t>(le16(setup + 6)));
    urb->status = controlReply(s, setup, setup + 8, &reply);
    if (setup[0] & 0x80) {
        const size_t n = urb->status == 0 ? std::min(reply.size(), length) : 0;
        std::memcpy(setup + 8, reply.data(), n);
        urb->actual_length = static_cast<int>(n);
    } else {
        urb->actual_length = urb->status == 0 ? static_cast<int>(length) : 0;
    }
    s.completed.push_back({owner, urb_data.release()});
    return 0;
}

// The next URB to hand back: a discarded one, a completed control transfer, or the oldest
// isochronous URB whose packets are due (and only while its stream is switched on).
UMockdevIoctlData* nextReapable(KinectUsbEmulator::State& s, UMockdevIoctlClient* owner) {
    for (auto it = s.completed.begin(); it != s.completed.end(); ++it) {
        if (it->owner != owner)
            continue;
        UMockdevIoctlData* urb = it->urb;
        s.completed.erase(it);
        return urb;
    }
    const int64_t now = monotonicNs();
    for (auto it = s.iso.begin(); it != s.iso.end(); ++it) {
        if (it->owner != owner)
            continue;
        auto& st = s.streams[it->endpoint];
        const StreamFormat f = formatOf(s, it->endpoint);
        if (!f.valid)
            continue;
        const size_t frame_bytes = (f.pixels * static_cast<size_t>(f.bits) + 7) / 8;
        const uint64_t per_frame = (frame_bytes + f.payload - 1) / f.payload;
        const int64_t due = st.start_ns + static_cast<int64_t>(st.next_packet / per_frame) *
                                              KinectUsbEmulator::kFramePeriodNs;
        if (due > now)
            continue;
        IsoUrb u = *it;
        s.iso.erase(it);
        --st.in_flight;
        fillIso(s, u);
        return u.urb;
    }
    return nullptr;
}

// REAPURB(NDELAY): hands back the client's address of a finished URB.
int reap(KinectUsbEmulator::State& s, UMockdevIoctlClient* owner, UMockdevIoctlData* arg) {
    UMockdevIoctlData* urb = nextReapable(s, owner);
    if (!urb)
        return EAGAIN;
    const mixray::test::IoctlDataRef slot = mixray::test::resolveIoctlData(arg, 0, sizeof(void*));
    if (!slot) {
        g_object_unref(urb);
        return EFAULT;
    }
    // The slot takes a reference of its own, and writes the URB back when the reap completes.
    umockdev_ioctl_data_set_ptr(slot.get(), 0, urb);
    g_object_unref(urb);
    return 0;
}

// DISCARDURB: an isochronous URB in flight is given back, cancelled (-ENOENT), at the next
// reap; anything else has completed already (EINVAL, as the kernel says).
int discard(KinectUsbEmulator::State& s, UMockdevIoctlClient* owner, UMockdevIoctlData* arg) {
    const gulong client_urb = *reinterpret_cast<gulong*>(arg->data);
    for (auto it = s.iso.begin(); it != s.iso.end(); ++it) {
        if (it->client != client_urb || it->owner != owner)
            continue;
        auto* urb = reinterpret_cast<usbdevfs_urb*>(it->urb->data);
        urb->status = -ENOENT;
        urb->actual_length = 0;
        for (int i = 0; i < urb->number_of_packets; ++i)
            urb->iso_frame_desc[i].actual_length = 0;
        --s.streams[it->endpoint].in_flight;
        s.completed.push_back({owner, it->urb});
        s.iso.erase(it);
        return 0;
    }
    return EINVAL;
}

gboolean onIoctl(UMockdevIoctlBase* /*base*/, UMockdevIoctlClient* client, gpointer user) {
    auto& s = *static_cast<KinectUsbEmulator::State*>(user);
    const unsigned long request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    int err = 0;
    {
        std::lock_guard lock(s.mutex);
        // Unplugged: URBs the kernel gave back can still be reaped; then, and for everything
        // else, ENODEV.
        const bool reaping = request == USBDEVFS_REAPURB || request == USBDEVFS_REAPURBNDELAY;
        const bool reapable = std::any_of(s.completed.begin(), s.completed.end(),
                                          [client](const DoneUrb& d) { return d.owner == client; });
        switch (s.unplugged && !(reaping && reapable) ? 0ul : request) {
            case 0:
                err = ENODEV;
                break;
            case USBDEVFS_GET_CAPABILITIES: {
                const mixray::test::IoctlDataRef caps = mixray::test::resolveIoctlData(arg, 0, 4);
                if (!caps) {
                    err = EFAULT;
                    break;
                }
                const uint32_t value = USBDEVFS_CAP_ZERO_PACKET | USBDEVFS_CAP_NO_PACKET_SIZE_LIM;
                std::memcpy(caps->data, &value, sizeof(value));
                break;
            }
            case USBDEVFS_CLAIMINTERFACE:
            case USBDEVFS_RELEASEINTERFACE:
            case USBDEVFS_SETINTERFACE:
            case USBDEVFS_CLEAR_HALT:
            case USBDEVFS_RESETEP:
                break;
            case USBDEVFS_GETDRIVER:
                err = ENODATA;  // no kernel driver bound to the camera's interface
                break;
            case USBDEVFS_SUBMITURB:
                err = submit(s, client, arg);
                break;
            case USBDEVFS_REAPURB:
            case USBDEVFS_REAPURBNDELAY:
                err = reap(s, client, arg);
                break;
            case USBDEVFS_DISCARDURB:
                err = discard(s, client, arg);
                break;
            default:
                err = ENOTTY;
        }
    }
    umockdev_ioctl_client_complete(client, err ? -1 : 0, err);
    return TRUE;
}

}  // namespace

std::unique_ptr<KinectUsbEmulator> KinectUsbEmulator::create(const std::string& tree,
                                                             bool emulate_camera,
                                                             std::string* why) {
    std::unique_ptr<KinectUsbEmulator> e(new KinectUsbEmulator());
    e->state_ = std::make_shared<State>();
    UMockdevTestbed* testbed = umockdev_testbed_new();
    e->testbed_ = testbed;
    GError* error = nullptr;
    if (!umockdev_testbed_add_from_file(testbed, tree.c_str(), &error)) {
        if (why)
            *why = "umockdev: " + tree + ": " + error->message;
        g_clear_error(&error);
        return nullptr;
    }
    if (!emulate_camera)
        return e;
    if (!e->attach(why))
        return nullptr;
    return e;
}

bool KinectUsbEmulator::attach(std::string* why) {
    auto* testbed = static_cast<UMockdevTestbed*>(testbed_);
    UMockdevIoctlBase* base = umockdev_ioctl_base_new();
    handler_ = base;
    g_signal_connect(base, "handle-ioctl", G_CALLBACK(onIoctl), state_.get());
    GError* error = nullptr;
    if (!umockdev_testbed_attach_ioctl(testbed, kCameraNode, base, &error)) {
        if (why)
            *why = std::string("umockdev: attaching ") + kCameraNode + ": " + error->message;
        g_clear_error(&error);
        return false;
    }
    return true;
}

bool KinectUsbEmulator::plug(const std::string& tree, std::string* why) {
    auto* testbed = static_cast<UMockdevTestbed*>(testbed_);
    // The camera's ioctl socket first: a thread listing the bus finds the node as soon as it
    // exists, and umockdev's preload ends the process when the node it opens has no socket.
    if (!handler_ && !attach(why))
        return false;
    GError* error = nullptr;
    if (!umockdev_testbed_add_from_file(testbed, tree.c_str(), &error)) {
        if (why)
            *why = "umockdev: " + tree + ": " + error->message;
        g_clear_error(&error);
        return false;
    }
    umockdev_testbed_uevent(testbed, kCameraSysfs, "add");
    return true;
}

void KinectUsbEmulator::unplugCamera() {
    {
        // The kernel gives every URB in flight back with -ESHUTDOWN.
        std::lock_guard lock(state_->mutex);
        state_->unplugged = true;
        for (const IsoUrb& u : state_->iso) {
            auto* urb = reinterpret_cast<usbdevfs_urb*>(u.urb->data);
            urb->status = -ESHUTDOWN;
            urb->actual_length = 0;
            for (int i = 0; i < urb->number_of_packets; ++i)
                urb->iso_frame_desc[i].actual_length = 0;
            state_->completed.push_back({u.owner, u.urb});
        }
        state_->iso.clear();
    }
    auto* testbed = static_cast<UMockdevTestbed*>(testbed_);
    umockdev_testbed_uevent(testbed, kCameraSysfs, "remove");
    umockdev_testbed_remove_device(testbed, kCameraSysfs);
}

bool KinectUsbEmulator::replugCamera(const std::string& tree, std::string* why) {
    // The camera's own entry of the device file: the hub, motor and audio are still there.
    std::ifstream in(tree);
    std::stringstream camera;
    std::string line;
    bool inside = false;
    const std::string camera_path = std::string(kCameraSysfs).substr(std::strlen("/sys"));
    while (std::getline(in, line)) {
        if (line.rfind("P: ", 0) == 0)
            inside = line.substr(3) == camera_path;
        if (inside && !line.empty())
            camera << line << "\n";
    }
    if (camera.str().empty()) {
        if (why)
            *why = "no camera (" + camera_path + ") in " + tree;
        return false;
    }
    auto* testbed = static_cast<UMockdevTestbed*>(testbed_);
    GError* error = nullptr;
    if (!umockdev_testbed_add_from_string(testbed, camera.str().c_str(), &error)) {
        if (why)
            *why = std::string("umockdev: adding the camera again: ") + error->message;
        g_clear_error(&error);
        return false;
    }
    {
        std::lock_guard lock(state_->mutex);
        for (const DoneUrb& d : state_->completed)
            g_object_unref(d.urb);
        state_->completed.clear();
        state_->streams.clear();
        state_->registers.clear();
        state_->reply.clear();
        state_->unplugged = false;
    }
    umockdev_testbed_uevent(testbed, kCameraSysfs, "add");
    return true;
}

KinectUsbEmulator::~KinectUsbEmulator() {
    auto* testbed = static_cast<UMockdevTestbed*>(testbed_);
    if (handler_) {
        if (testbed)
            (void)umockdev_testbed_detach_ioctl(testbed, kCameraNode, nullptr);
        g_object_unref(handler_);
    }
    for (const DoneUrb& d : state_->completed)
        g_object_unref(d.urb);
    for (const IsoUrb& u : state_->iso)
        g_object_unref(u.urb);
    if (testbed)
        g_object_unref(testbed);
}

std::map<uint16_t, uint16_t> KinectUsbEmulator::registers() const {
    std::lock_guard lock(state_->mutex);
    return state_->registers;
}

uint64_t KinectUsbEmulator::framesSent(uint8_t endpoint) const {
    std::lock_guard lock(state_->mutex);
    auto it = state_->streams.find(endpoint);
    return it == state_->streams.end() ? 0 : it->second.frames_sent;
}

std::vector<uint16_t> KinectUsbEmulator::commands() const {
    std::lock_guard lock(state_->mutex);
    return state_->commands;
}

std::vector<std::string> KinectUsbEmulator::controlRequests() const {
    std::lock_guard lock(state_->mutex);
    return state_->requests;
}

}  // namespace mixray::openni2::test
