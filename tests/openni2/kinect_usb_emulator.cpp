// The emulated Kinect v1 camera's usbfs node: URBs on endpoint 0 answered with its strings.
#include "kinect_usb_emulator.h"

#include <linux/usbdevice_fs.h>
#include <sys/ioctl.h>
#include <umockdev.h>

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <deque>

namespace mixray::openni2::test {

struct KinectUsbEmulator::State {
    mutable std::mutex mutex;
    std::deque<UMockdevIoctlData*> completed;  // URBs to reap, oldest first (owned refs)
    std::vector<std::string> requests;
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

// The reply to a control transfer's setup packet: its data stage, or a stall (-EPIPE).
int controlReply(const uint8_t* setup, std::vector<uint8_t>* reply) {
    const uint8_t request_type = setup[0];
    const uint8_t request = setup[1];
    const uint16_t value = static_cast<uint16_t>(setup[2] | (setup[3] << 8));
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

// SUBMITURB: control URBs complete at once (the reply is written into the client's buffer
// when the ioctl completes); they wait for REAPURB in `completed`.
int submit(KinectUsbEmulator::State& s, UMockdevIoctlData* arg) {
    GError* error = nullptr;
    UMockdevIoctlData* urb_data = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), &error);
    if (!urb_data) {
        g_clear_error(&error);
        return EFAULT;
    }
    auto* urb = reinterpret_cast<usbdevfs_urb*>(urb_data->data);
    if (urb->type != USBDEVFS_URB_TYPE_CONTROL || (urb->endpoint & 0x7f) != 0 ||
        urb->buffer_length < 8) {
        return EINVAL;  // the camera's isochronous endpoints are not emulated
    }
    UMockdevIoctlData* buffer = umockdev_ioctl_data_resolve(
        urb_data, offsetof(usbdevfs_urb, buffer), static_cast<gsize>(urb->buffer_length), &error);
    if (!buffer) {
        g_clear_error(&error);
        return EFAULT;
    }
    uint8_t* setup = buffer->data;
    s.requests.push_back(requestText(setup));
    std::vector<uint8_t> reply;
    urb->status = controlReply(setup, &reply);
    const size_t room = static_cast<size_t>(urb->buffer_length) - 8;
    const size_t length = static_cast<size_t>(setup[6] | (setup[7] << 8));
    const size_t n = urb->status == 0 ? std::min(std::min(reply.size(), room), length) : 0;
    std::memcpy(setup + 8, reply.data(), n);
    urb->actual_length = static_cast<int>(n);
    s.completed.push_back(static_cast<UMockdevIoctlData*>(g_object_ref(urb_data)));
    return 0;
}

// REAPURB(NDELAY): hands back the client's address of the oldest completed URB.
int reap(KinectUsbEmulator::State& s, UMockdevIoctlData* arg) {
    if (s.completed.empty())
        return EAGAIN;
    GError* error = nullptr;
    UMockdevIoctlData* slot = umockdev_ioctl_data_resolve(arg, 0, sizeof(void*), &error);
    if (!slot) {
        g_clear_error(&error);
        return EFAULT;
    }
    UMockdevIoctlData* urb = s.completed.front();
    s.completed.pop_front();
    umockdev_ioctl_data_set_ptr(slot, 0, urb);
    g_object_unref(urb);
    return 0;
}

int discard(KinectUsbEmulator::State& s, UMockdevIoctlData* arg) {
    // Control URBs complete at submission: nothing is ever in flight to discard.
    (void)s;
    (void)arg;
    return EINVAL;
}

gboolean onIoctl(UMockdevIoctlBase* /*base*/, UMockdevIoctlClient* client, gpointer user) {
    auto& s = *static_cast<KinectUsbEmulator::State*>(user);
    const unsigned long request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    int err = 0;
    {
        std::lock_guard lock(s.mutex);
        switch (request) {
            case USBDEVFS_GET_CAPABILITIES: {
                GError* error = nullptr;
                UMockdevIoctlData* caps = umockdev_ioctl_data_resolve(arg, 0, 4, &error);
                if (!caps) {
                    g_clear_error(&error);
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
                err = submit(s, arg);
                break;
            case USBDEVFS_REAPURB:
            case USBDEVFS_REAPURBNDELAY:
                err = reap(s, arg);
                break;
            case USBDEVFS_DISCARDURB:
                err = discard(s, arg);
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
    UMockdevIoctlBase* base = umockdev_ioctl_base_new();
    e->handler_ = base;
    g_signal_connect(base, "handle-ioctl", G_CALLBACK(onIoctl), e->state_.get());
    if (!umockdev_testbed_attach_ioctl(testbed, kCameraNode, base, &error)) {
        if (why)
            *why = std::string("umockdev: attaching ") + kCameraNode + ": " + error->message;
        g_clear_error(&error);
        return nullptr;
    }
    return e;
}

KinectUsbEmulator::~KinectUsbEmulator() {
    auto* testbed = static_cast<UMockdevTestbed*>(testbed_);
    if (handler_) {
        if (testbed)
            (void)umockdev_testbed_detach_ioctl(testbed, kCameraNode, nullptr);
        g_object_unref(handler_);
    }
    for (UMockdevIoctlData* urb : state_->completed)
        g_object_unref(urb);
    if (testbed)
        g_object_unref(testbed);
}

std::vector<std::string> KinectUsbEmulator::controlRequests() const {
    std::lock_guard lock(state_->mutex);
    return state_->requests;
}

}  // namespace mixray::openni2::test
