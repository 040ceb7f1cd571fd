// The "usb" backend: discovery of the rig's USB devices through libusb-1.0, and hot-plug events.
// It identifies devices; the backends that stream them (openni2, v4l2, aravis) open them, except
// the Kinect v1 motor, which it opens itself (mixray/usb/kinect_motor.h).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/device.h"

namespace mixray::usb {

// What a USB device was identified as, from its IDs and interface classes.
struct Identity {
    std::string model;     // "Kinect v1 camera", "UVC camera", ...
    std::string streamer;  // backend that streams it ("usb": this one); empty when none does
};

// Interface class/subclass pairs of a device's configuration, for identify().
struct InterfaceClass {
    uint8_t cls = 0;
    uint8_t subclass = 0;
};

// Kinect v1 (045e:02ae camera, 02b0 motor, 02ad audio) and PrimeSense (1d27:0600, 0601, 0609,
// 0500) by VID:PID; otherwise UVC (interface class 0x0e) and USB3 Vision (0xef/0x05) by class.
// nullopt: not a rig device.
std::optional<Identity> identify(uint16_t vendor, uint16_t product,
                                 const std::vector<InterfaceClass>& interfaces);

// "045e:02ae@1/5": vendor:product@bus/address, what DeviceConfig::id names.
std::string deviceId(uint16_t vendor, uint16_t product, int bus, int address);

class UsbBackend final : public DeviceBackend {
public:
    std::string_view name() const override { return "usb"; }
    // The rig devices present now (other USB devices are left out). id as deviceId(), location
    // the bus/port path ("1-1.3", as in /sys/bus/usb/devices), serial from sysfs or, when sysfs
    // lacks it, the string descriptor (needs permission to open the device; empty otherwise).
    Result<std::vector<DeviceDescriptor>> enumerate() override;
    // Opens the Kinect v1 motor as a KinectMotorDevice (mixray/usb/kinect_motor.h). Any other
    // device fails: kUnsupported naming the backend that streams it (kNotFound when config.id
    // matches no rig device by id or serial).
    Result<std::unique_ptr<Device>> open(const DeviceConfig& config) override;
};

struct HotplugEvent {
    enum class Kind : uint8_t { kArrived, kLeft };
    Kind kind = Kind::kArrived;
    DeviceDescriptor device;  // as enumerate() describes it; serial from sysfs only
};

// Queues arrivals and departures of rig devices, reported by libusb's hot-plug callback on a
// thread that pumps libusb's events. next() may be called from any one thread.
class HotplugMonitor {
public:
    // kUnsupported when this libusb has no hot-plug support; kIoError when libusb fails.
    static Result<std::unique_ptr<HotplugMonitor>> start();
    ~HotplugMonitor();
    HotplugMonitor(const HotplugMonitor&) = delete;
    HotplugMonitor& operator=(const HotplugMonitor&) = delete;

    // The oldest queued event, waiting up to `timeout`; nullopt when none came.
    std::optional<HotplugEvent> next(std::chrono::milliseconds timeout);

    struct State;

private:
    explicit HotplugMonitor(std::unique_ptr<State> state);
    std::unique_ptr<State> state_;
};

}  // namespace mixray::usb
