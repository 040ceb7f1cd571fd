// Helpers shared by the usb backend's sources (not installed).
#pragma once

#include <libusb.h>

#include <string>

namespace mixray::usb::detail {

// "1-1.3": the kernel's name for the device, also its directory in /sys/bus/usb/devices.
std::string portPath(libusb_device* dev);

}  // namespace mixray::usb::detail
