// The emulated Kinect motor: the kernel's usbfs answers (claims, URBs) and the device's answers
// to libfreenect's control requests.
#include "kinect_motor_emulator.h"

#include <linux/usbdevice_fs.h>
#include <sys/ioctl.h>

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstring>
#include <deque>
#include <fstream>
#include <mutex>
#include <sstream>

#include "test_data.h"
#include "umockdev_ioctl_data.h"

namespace mixray::usb::test {

namespace {

constexpr const char* kDevNode = "/dev/bus/usb/001/003";
constexpr const char* kSysPath = "/sys/devices/pci0000:00/0000:00:14.0/usb1/1-1/1-1.1";

}  // namespace

struct KinectMotorEmulator::State {
    mutable std::mutex mutex;
    int16_t accel[3] = {0, 819, 0};
    int8_t tilt_half_degrees = 0;
    uint8_t tilt_status = 0;
    bool follow_tilt = true;
    bool unplugged = false;
    uint32_t claimed = 0;  // bit per interface
    // URBs ready to reap: the open file each was submitted on (umockdev has one client per
    // connection) and its address there. As the kernel does, only that file reaps it: a URB
    // reaped through another handle of the same device would complete a transfer twice.
    std::deque<std::pair<UMockdevIoctlClient*, unsigned long>> completed;
    std::vector<ControlRequest> requests;
    uint64_t state_reads = 0;
    std::vector<unsigned long> unknown;
};

namespace {

using State = KinectMotorEmulator::State;

using mixray::test::IoctlDataRef;
using mixray::test::resolveIoctlData;

// The device's side of one control transfer; returns the URB status.
int control(State& s, const uint8_t* setup, uint8_t* data, int capacity, int* actual) {
    ControlRequest r;
    r.request_type = setup[0];
    r.request = setup[1];
    r.value = static_cast<uint16_t>(setup[2] | (setup[3] << 8));
    r.index = static_cast<uint16_t>(setup[4] | (setup[5] << 8));
    r.length = static_cast<uint16_t>(setup[6] | (setup[7] << 8));
    *actual = 0;
    if (r.request_type == 0xC0 && r.request == 0x32) {
        const int n = std::min({10, static_cast<int>(r.length), capacity});
        uint8_t state[10] = {};
        for (int i = 0; i < 3; ++i) {
            const auto v = static_cast<uint16_t>(s.accel[i]);
            state[2 + 2 * i] = static_cast<uint8_t>(v >> 8);
            state[3 + 2 * i] = static_cast<uint8_t>(v & 0xff);
        }
        state[8] = static_cast<uint8_t>(s.tilt_half_degrees);
        state[9] = s.tilt_status;
        std::memcpy(data, state, static_cast<size_t>(n));
        *actual = n;
        ++s.state_reads;
        return 0;
    }
    if (r.request_type == 0x40 && (r.request == 0x31 || r.request == 0x06) && r.length == 0) {
        s.requests.push_back(r);
        if (r.request == 0x31 && s.follow_tilt)
            s.tilt_half_degrees = static_cast<int8_t>(static_cast<int16_t>(r.value));
        return 0;
    }
    return -EPIPE;
}

int submit(State& s, UMockdevIoctlClient* client, UMockdevIoctlData* arg) {
    const IoctlDataRef urb_data = resolveIoctlData(arg, 0, sizeof(usbdevfs_urb));
    if (!urb_data)
        return EFAULT;
    auto* urb = reinterpret_cast<usbdevfs_urb*>(urb_data->data);
    if (urb->type != USBDEVFS_URB_TYPE_CONTROL || (urb->endpoint & 0x7f) != 0)
        return EINVAL;
    if (urb->buffer_length < 8)
        return EINVAL;
    const IoctlDataRef buffer = resolveIoctlData(urb_data.get(), offsetof(usbdevfs_urb, buffer),
                                                 static_cast<size_t>(urb->buffer_length));
    if (!buffer)
        return EFAULT;
    int actual = 0;
    urb->status = control(s, buffer->data, buffer->data + 8, urb->buffer_length - 8, &actual);
    urb->actual_length = actual;
    s.completed.emplace_back(client, urb_data->client_addr);
    return 0;
}

int handle(State& s, unsigned long request, UMockdevIoctlClient* client) {
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    switch (request) {
        case USBDEVFS_GET_CAPABILITIES: {
            const IoctlDataRef caps = resolveIoctlData(arg, 0, sizeof(uint32_t));
            if (!caps)
                return EFAULT;
            const uint32_t value = USBDEVFS_CAP_ZERO_PACKET | USBDEVFS_CAP_BULK_CONTINUATION |
                                   USBDEVFS_CAP_NO_PACKET_SIZE_LIM;
            std::memcpy(caps->data, &value, sizeof value);
            return 0;
        }
        case USBDEVFS_CLAIMINTERFACE:
        case USBDEVFS_RELEASEINTERFACE: {
            const IoctlDataRef number = resolveIoctlData(arg, 0, sizeof(unsigned int));
            if (!number)
                return EFAULT;
            unsigned int n = 0;
            std::memcpy(&n, number->data, sizeof n);
            // The motor has one interface.
            if (n != 0)
                return EINVAL;
            if (request == USBDEVFS_CLAIMINTERFACE)
                s.claimed |= 1u;
            else
                s.claimed &= ~1u;
            return 0;
        }
        case USBDEVFS_SUBMITURB:
            return submit(s, client, arg);
        case USBDEVFS_REAPURB:
        case USBDEVFS_REAPURBNDELAY: {
            // URBs complete at submission, so a blocking reap has nothing to wait for either.
            const auto mine = std::find_if(s.completed.begin(), s.completed.end(),
                                           [client](const auto& c) { return c.first == client; });
            if (mine == s.completed.end())
                return EAGAIN;
            const IoctlDataRef slot = resolveIoctlData(arg, 0, sizeof(void*));
            if (!slot)
                return EFAULT;
            const unsigned long address = mine->second;
            s.completed.erase(mine);
            std::memcpy(slot->data, &address, sizeof address);
            return 0;
        }
        case USBDEVFS_DISCARDURB:
            // Every URB has completed already: the kernel says EINVAL for those.
            return EINVAL;
        default:
            s.unknown.push_back(request);
            return ENOTTY;
    }
}

struct Handler {
    std::shared_ptr<State> state;
};

gboolean onIoctl(UMockdevIoctlBase* /*base*/, UMockdevIoctlClient* client, gpointer user) {
    auto* h = static_cast<Handler*>(user);
    const unsigned long request = umockdev_ioctl_client_get_request(client);
    int err = 0;
    {
        std::lock_guard lock(h->state->mutex);
        err = h->state->unplugged ? ENODEV : handle(*h->state, request, client);
    }
    umockdev_ioctl_client_complete(client, err ? -1 : 0, err);
    return TRUE;
}

void freeHandler(gpointer data, GClosure* /*closure*/) {
    delete static_cast<Handler*>(data);
}

// The motor's block of tests/usb/kinect_v1.umockdev, to add it again after an unplug.
std::string motorDescription() {
    std::ifstream in(mixray::test::sourceDir() / "tests/usb/kinect_v1.umockdev");
    std::stringstream out;
    std::string line;
    bool inside = false;
    while (std::getline(in, line)) {
        if (line.rfind("P: ", 0) == 0)
            inside = line.size() > 5 && line.compare(line.size() - 5, 5, "1-1.1") == 0;
        if (inside && !line.empty())
            out << line << "\n";
    }
    return out.str();
}

}  // namespace

std::unique_ptr<KinectMotorEmulator> KinectMotorEmulator::create(UMockdevTestbed* testbed,
                                                                 std::string* why) {
    std::unique_ptr<KinectMotorEmulator> e(new KinectMotorEmulator());
    e->state_ = std::make_shared<State>();
    e->testbed_ = testbed;
    e->handler_ = umockdev_ioctl_base_new();
    g_signal_connect_data(e->handler_, "handle-ioctl", G_CALLBACK(onIoctl), new Handler{e->state_},
                          freeHandler, static_cast<GConnectFlags>(0));
    GError* error = nullptr;
    if (!umockdev_testbed_attach_ioctl(testbed, kDevNode, e->handler_, &error)) {
        if (why)
            *why = std::string("umockdev: attaching ") + kDevNode + ": " + error->message;
        g_clear_error(&error);
        return nullptr;
    }
    e->attached_ = true;
    return e;
}

KinectMotorEmulator::~KinectMotorEmulator() {
    if (attached_)
        (void)umockdev_testbed_detach_ioctl(testbed_, kDevNode, nullptr);
    if (handler_)
        g_object_unref(handler_);
}

void KinectMotorEmulator::setAccelerometer(int16_t x, int16_t y, int16_t z) {
    std::lock_guard lock(state_->mutex);
    state_->accel[0] = x;
    state_->accel[1] = y;
    state_->accel[2] = z;
}

void KinectMotorEmulator::setTiltState(int8_t half_degrees, uint8_t status) {
    std::lock_guard lock(state_->mutex);
    state_->tilt_half_degrees = half_degrees;
    state_->tilt_status = status;
    state_->follow_tilt = false;
}

std::vector<ControlRequest> KinectMotorEmulator::requests() const {
    std::lock_guard lock(state_->mutex);
    return state_->requests;
}

uint64_t KinectMotorEmulator::stateReads() const {
    std::lock_guard lock(state_->mutex);
    return state_->state_reads;
}

std::vector<unsigned long> KinectMotorEmulator::unknownIoctls() const {
    std::lock_guard lock(state_->mutex);
    return state_->unknown;
}

void KinectMotorEmulator::unplug() {
    {
        std::lock_guard lock(state_->mutex);
        state_->unplugged = true;
        state_->completed.clear();
        state_->claimed = 0;
    }
    // The handler stays attached (answering ENODEV): detached, its socket would refuse the
    // preload's connection from a client that still finds the node, and umockdev aborts then.
    umockdev_testbed_uevent(testbed_, kSysPath, "remove");
    umockdev_testbed_remove_device(testbed_, kSysPath);
}

bool KinectMotorEmulator::replug(std::string* why) {
    GError* error = nullptr;
    if (!umockdev_testbed_add_from_string(testbed_, motorDescription().c_str(), &error)) {
        if (why)
            *why = std::string("umockdev: adding the motor again: ") + error->message;
        g_clear_error(&error);
        return false;
    }
    {
        std::lock_guard lock(state_->mutex);
        state_->unplugged = false;
    }
    umockdev_testbed_uevent(testbed_, kSysPath, "add");
    return true;
}

}  // namespace mixray::usb::test
