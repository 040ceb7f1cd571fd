// The Kinect v1 motor (045e:02b0) emulated behind umockdev: a usbfs node whose ioctls a handler
// answers the way the kernel and the device do, so libusb (and libfreenect on top of it) send
// real control transfers to it.
#pragma once

#include <umockdev.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace mixray::usb::test {

// One control transfer the motor received (other than the state reads it answered).
struct ControlRequest {
    uint8_t request_type = 0;
    uint8_t request = 0;
    uint16_t value = 0;
    uint16_t index = 0;
    uint16_t length = 0;
};

// The motor of tests/usb/kinect_v1.umockdev (sysfs 1-1.1, /dev/bus/usb/001/003), answering
// USBDEVFS_GET_CAPABILITIES, CLAIMINTERFACE/RELEASEINTERFACE, SUBMITURB of control URBs,
// REAPURBNDELAY/REAPURB and DISCARDURB. Control requests, as libfreenect sends them:
//   0xC0 0x32 (10 bytes in): the state: bytes 2..7 the accelerometer x, y, z as big-endian
//     int16 counts (819 per g), byte 8 the tilt angle in half degrees (int8), byte 9 the tilt
//     status (0 stopped, 1 at limit, 4 moving); bytes 0 and 1 zero;
//   0x40 0x31 wValue = 2 * degrees (int16): tilt; recorded, the reported angle follows it;
//   0x40 0x06 wValue = LED mode: recorded.
// Anything else stalls (the URB completes with -EPIPE). URBs complete at once.
// Thread-safe: the handler runs on umockdev's worker thread, tests read from theirs.
class KinectMotorEmulator {
public:
    // Attaches to `testbed`, which must already hold tests/usb/kinect_v1.umockdev (the testbed
    // must outlive the emulator). Null when umockdev refuses (why says so).
    static std::unique_ptr<KinectMotorEmulator> create(UMockdevTestbed* testbed, std::string* why);
    ~KinectMotorEmulator();
    KinectMotorEmulator(const KinectMotorEmulator&) = delete;
    KinectMotorEmulator& operator=(const KinectMotorEmulator&) = delete;

    // What the next state reads report: raw accelerometer counts, the tilt angle in half
    // degrees and the tilt status byte. Setting the angle stops following tilt requests.
    void setAccelerometer(int16_t x, int16_t y, int16_t z);
    void setTiltState(int8_t half_degrees, uint8_t status);

    std::vector<ControlRequest> requests() const;
    uint64_t stateReads() const;
    // usbfs ioctls the handler did not know (answered ENOTTY).
    std::vector<unsigned long> unknownIoctls() const;

    // The motor leaves the bus: every ioctl fails with ENODEV, its sysfs entry and /dev node go
    // and a `remove` uevent is sent.
    void unplug();
    // It comes back on the same port, with the same address, with an `add` uevent.
    bool replug(std::string* why);

    struct State;

private:
    KinectMotorEmulator() = default;
    std::shared_ptr<State> state_;
    UMockdevTestbed* testbed_ = nullptr;
    UMockdevIoctlBase* handler_ = nullptr;
    bool attached_ = false;
};

}  // namespace mixray::usb::test
