// The Kinect v1 of tests/usb/kinect_v1.umockdev behind umockdev, its camera's usbfs node
// answered by a handler the way the camera answers libfreenect: a Kinect camera in software.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace mixray::openni2::test {

// The camera (045e:02ae, /dev/bus/usb/001/005) answers usbfs as the kernel does for a device
// without a driver: capabilities, claim/release, GETDRIVER (none), URBs submitted, reaped and
// discarded. Control transfers on endpoint 0: GET_DESCRIPTOR(STRING) (language ids,
// manufacturer, product, serial) and libfreenect's camera protocol ("GM" commands written with
// vendor request 0, "RB" replies read back): read/write register, fixed parameters (with the
// 1414's zero-plane figures) and the algorithm parameters libfreenect fetches; other requests
// stall. Isochronous endpoints 0x82 (depth, 11-bit) and 0x81 (Bayer colour, or 10-bit IR),
// while libfreenect's registers switch them on: 'RB' packets of 1748 / 1908 data bytes, a frame
// every 1/30 s of CLOCK_MONOTONIC, every pixel of frame k equal to pixelValue(stream, k) (IR adds
// x / kIrColumnsPerStep, so that its images have a left and a right).
// Thread-safe: the handler runs on umockdev's worker thread, tests read from theirs.
class KinectUsbEmulator {
public:
    static constexpr const char* kCameraNode = "/dev/bus/usb/001/005";
    static constexpr const char* kCameraSysfs =
        "/sys/devices/pci0000:00/0000:00:14.0/usb1/1-1/1-1.3";
    static constexpr const char* kCameraSerial = "A00364A11700045A";

    // `tree`: a umockdev device file (tests/usb/*.umockdev). With `emulate_camera`, the
    // camera node gets the usbfs handler. Null when umockdev cannot build it (why says so).
    static std::unique_ptr<KinectUsbEmulator> create(const std::string& tree, bool emulate_camera,
                                                     std::string* why);
    ~KinectUsbEmulator();
    // Hot-plug: adds the devices of `tree` and announces the camera (a uevent "add", which
    // reaches libusb's hot-plug callbacks), its node answered by the handler from then on.
    bool plug(const std::string& tree, std::string* why);
    // Announces the camera's departure (uevent "remove") and removes it from the bus; its URBs
    // in flight come back with -ESHUTDOWN, then its open node answers ENODEV, as the kernel's.
    void unplugCamera();
    // Plugs the camera in again after unplugCamera(): the camera of `tree` is added to the bus
    // again and announced (uevent "add"); it starts as a camera that has just powered up (no
    // registers set, streams off, frame counts and 60 MHz stamps from the start). Call it once
    // the client has closed the unplugged camera: URBs of that node still unreaped are dropped.
    bool replugCamera(const std::string& tree, std::string* why);
    KinectUsbEmulator(const KinectUsbEmulator&) = delete;
    KinectUsbEmulator& operator=(const KinectUsbEmulator&) = delete;

    // Control requests seen, as "bmRequestType:bRequest:wValue:wIndex" (hex), in order.
    std::vector<std::string> controlRequests() const;
    // Camera commands received (libfreenect's opcodes), in order, and the registers written.
    std::vector<uint16_t> commands() const;
    std::map<uint16_t, uint16_t> registers() const;
    // Frames sent complete on endpoint 0x82 (depth) or 0x81 (colour/IR).
    uint64_t framesSent(uint8_t endpoint) const;

    // The streams and what every pixel of their frame `frame` holds (raw: 11-bit depth
    // disparity, 8-bit Bayer, 10-bit IR). Frame k carries the 60 MHz timestamp
    // kFirstTicks + k * kTicksPerFrame.
    enum class Stream { kDepth, kBayer, kInfrared };
    static uint16_t pixelValue(Stream stream, uint64_t frame);
    static constexpr uint16_t kDepthRawBase = 600;
    static constexpr int kIrColumnsPerStep = 64;
    static constexpr uint32_t kFirstTicks = 0xfff00000u;   // wraps in the first seconds
    static constexpr uint32_t kTicksPerFrame = 2'000'000;  // 60 MHz / 30 fps
    static constexpr int64_t kFramePeriodNs = 33'333'333;

    struct State;

private:
    KinectUsbEmulator() = default;
    bool attach(std::string* why);
    std::shared_ptr<State> state_;
    void* testbed_ = nullptr;
    void* handler_ = nullptr;
};

}  // namespace mixray::openni2::test
