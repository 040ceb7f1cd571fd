// The Kinect v1 of tests/usb/kinect_v1.umockdev behind umockdev, with its camera's usbfs node
// answered by a handler: enough USB for libfreenect to find the camera and read its serial.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace mixray::openni2::test {

// The camera (045e:02ae, /dev/bus/usb/001/005) answers usbfs as the kernel does for a device
// without a driver: capabilities, claim/release, GETDRIVER (none), and control transfers on
// endpoint 0 submitted and reaped as URBs. Of the control requests it answers the standard
// GET_DESCRIPTOR(STRING) — language ids, manufacturer, product, serial — and stalls the rest
// (-EPIPE), as a device does for requests it does not know; libfreenect's camera commands are
// not emulated, so opening the camera fails (see drivers/openni2/README.md).
// Thread-safe: the handler runs on umockdev's worker thread, tests read from theirs.
class KinectUsbEmulator {
public:
    static constexpr const char* kCameraNode = "/dev/bus/usb/001/005";
    static constexpr const char* kCameraSerial = "A00364A11700045A";

    // `tree`: a umockdev device file (tests/usb/*.umockdev). With `emulate_camera`, the
    // camera node gets the usbfs handler. Null when umockdev cannot build it (why says so).
    static std::unique_ptr<KinectUsbEmulator> create(const std::string& tree, bool emulate_camera,
                                                     std::string* why);
    ~KinectUsbEmulator();
    KinectUsbEmulator(const KinectUsbEmulator&) = delete;
    KinectUsbEmulator& operator=(const KinectUsbEmulator&) = delete;

    // Control requests seen, as "bmRequestType:bRequest:wValue:wIndex" (hex), in order.
    std::vector<std::string> controlRequests() const;

    struct State;

private:
    KinectUsbEmulator() = default;
    std::shared_ptr<State> state_;
    void* testbed_ = nullptr;
    void* handler_ = nullptr;
};

}  // namespace mixray::openni2::test
