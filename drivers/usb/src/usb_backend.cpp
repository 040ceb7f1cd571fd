#include "mixray/usb/usb_backend.h"

#include <libusb.h>

#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <fstream>
#include <map>
#include <mutex>
#include <thread>

#include "mixray/usb/kinect_motor.h"
#include "usb_internal.h"

namespace mixray::usb {

std::string detail::portPath(libusb_device* dev) {
    uint8_t ports[8];
    const int n = libusb_get_port_numbers(dev, ports, sizeof(ports));
    std::string path = std::to_string(libusb_get_bus_number(dev));
    if (n <= 0)
        return "usb" + path;
    for (int i = 0; i < n; ++i)
        path += (i == 0 ? "-" : ".") + std::to_string(ports[i]);
    return path;
}

namespace {

using detail::portPath;

constexpr uint16_t kMicrosoft = 0x045e;
constexpr uint16_t kPrimeSense = 0x1d27;

std::string hex4(uint16_t v) {
    char buf[8];
    std::snprintf(buf, sizeof(buf), "%04x", v);
    return buf;
}

std::vector<InterfaceClass> interfaceClasses(libusb_device* dev) {
    std::vector<InterfaceClass> out;
    libusb_config_descriptor* config = nullptr;
    if (libusb_get_active_config_descriptor(dev, &config) != LIBUSB_SUCCESS &&
        libusb_get_config_descriptor(dev, 0, &config) != LIBUSB_SUCCESS)
        return out;
    for (int i = 0; i < config->bNumInterfaces; ++i) {
        const libusb_interface& itf = config->interface[i];
        for (int a = 0; a < itf.num_altsetting; ++a)
            out.push_back(
                {itf.altsetting[a].bInterfaceClass, itf.altsetting[a].bInterfaceSubClass});
    }
    libusb_free_config_descriptor(config);
    return out;
}

// The kernel keeps the serial string it read at enumeration: no permission on the device needed.
std::string sysfsSerial(const std::string& port_path) {
    std::ifstream in("/sys/bus/usb/devices/" + port_path + "/serial");
    std::string serial;
    std::getline(in, serial);
    return serial;
}

std::string descriptorSerial(libusb_device* dev, uint8_t index) {
    if (index == 0)
        return {};
    libusb_device_handle* handle = nullptr;
    if (libusb_open(dev, &handle) != LIBUSB_SUCCESS)
        return {};
    unsigned char buf[256] = {};
    const int n = libusb_get_string_descriptor_ascii(handle, index, buf, sizeof(buf));
    libusb_close(handle);
    return n > 0 ? std::string(reinterpret_cast<const char*>(buf), static_cast<size_t>(n))
                 : std::string();
}

struct Described {
    DeviceDescriptor descriptor;
    Identity identity;
};

// nullopt for devices that are not rig devices. allow_open: libusb forbids opening a device
// inside its hot-plug callback.
std::optional<Described> describe(libusb_device* dev, bool allow_open) {
    libusb_device_descriptor desc{};
    if (libusb_get_device_descriptor(dev, &desc) != LIBUSB_SUCCESS)
        return std::nullopt;
    auto identity = identify(desc.idVendor, desc.idProduct, interfaceClasses(dev));
    if (!identity)
        return std::nullopt;
    Described out;
    out.identity = *identity;
    DeviceDescriptor& d = out.descriptor;
    d.backend = "usb";
    d.id = deviceId(desc.idVendor, desc.idProduct, libusb_get_bus_number(dev),
                    libusb_get_device_address(dev));
    d.model = identity->model;
    d.location = portPath(dev);
    d.serial = sysfsSerial(d.location);
    if (d.serial.empty() && allow_open)
        d.serial = descriptorSerial(dev, desc.iSerialNumber);
    return out;
}

Result<std::vector<Described>> discover() {
    libusb_context* ctx = nullptr;
    if (const int rc = libusb_init(&ctx); rc != LIBUSB_SUCCESS)
        return Status(ErrorCode::kIoError,
                      std::string("usb: libusb_init failed: ") + libusb_error_name(rc));
    libusb_device** list = nullptr;
    const ssize_t n = libusb_get_device_list(ctx, &list);
    if (n < 0) {
        libusb_exit(ctx);
        return Status(ErrorCode::kIoError, std::string("usb: libusb_get_device_list failed: ") +
                                               libusb_error_name(static_cast<int>(n)));
    }
    std::vector<Described> out;
    for (ssize_t i = 0; i < n; ++i)
        if (auto d = describe(list[i], true))
            out.push_back(std::move(*d));
    libusb_free_device_list(list, 1);
    libusb_exit(ctx);
    return out;
}

}  // namespace

std::optional<Identity> identify(uint16_t vendor, uint16_t product,
                                 const std::vector<InterfaceClass>& interfaces) {
    if (vendor == kMicrosoft) {
        switch (product) {
            case 0x02ae:
                return Identity{"Kinect v1 camera", "openni2"};
            case 0x02b0:
                return Identity{"Kinect v1 motor", "usb"};
            case 0x02ad:
                return Identity{"Kinect v1 audio", ""};
            default:
                break;
        }
    }
    if (vendor == kPrimeSense &&
        (product == 0x0600 || product == 0x0601 || product == 0x0609 || product == 0x0500))
        return Identity{"PrimeSense depth sensor (1d27:" + hex4(product) + ")", "openni2"};
    for (const InterfaceClass& c : interfaces)
        if (c.cls == 0x0e)
            return Identity{"UVC camera", "v4l2"};
    for (const InterfaceClass& c : interfaces)
        if (c.cls == 0xef && c.subclass == 0x05)
            return Identity{"USB3 Vision camera", "aravis"};
    return std::nullopt;
}

std::string deviceId(uint16_t vendor, uint16_t product, int bus, int address) {
    return hex4(vendor) + ":" + hex4(product) + "@" + std::to_string(bus) + "/" +
           std::to_string(address);
}

Result<std::vector<DeviceDescriptor>> UsbBackend::enumerate() {
    auto found = discover();
    if (!found)
        return found.status();
    std::vector<DeviceDescriptor> out;
    for (auto& d : *found)
        out.push_back(std::move(d.descriptor));
    return out;
}

Result<std::unique_ptr<Device>> UsbBackend::open(const DeviceConfig& config) {
    auto found = discover();
    if (!found)
        return found.status();
    for (const Described& d : *found) {
        if (!config.id.empty() && config.id != d.descriptor.id && config.id != d.descriptor.serial)
            continue;
        std::string what = "usb: " + d.descriptor.model + " " + d.descriptor.id + " (device '" +
                           config.name + "')";
        if (d.identity.streamer == "usb") {
            auto motor = KinectMotorDevice::open(config, d.descriptor);
            if (!motor)
                return motor.status();
            return std::unique_ptr<Device>(std::move(*motor));
        }
        if (d.identity.streamer.empty())
            return Status(ErrorCode::kUnsupported,
                          what +
                              " is discovered only: no mixray backend streams it (the Kinect "
                              "microphones are not supported)");
        return Status(ErrorCode::kUnsupported,
                      what + " is discovered here; open it with driver: " + d.identity.streamer);
    }
    return Status(
        ErrorCode::kNotFound,
        "usb: no rig device " +
            (config.id.empty() ? std::string("present") : "with id or serial '" + config.id + "'") +
            " (device '" + config.name + "')");
}

struct HotplugMonitor::State {
    libusb_context* ctx = nullptr;
    libusb_hotplug_callback_handle handle = 0;
    bool registered = false;
    std::atomic<bool> stop{false};
    std::thread pump;
    std::mutex mutex;
    std::condition_variable cv;
    std::deque<HotplugEvent> events;
    // What arrived, by bus and address: a departed device's sysfs entry is gone.
    std::map<std::pair<int, int>, DeviceDescriptor> present;
};

namespace {

int LIBUSB_CALL onHotplug(libusb_context*, libusb_device* dev, libusb_hotplug_event event,
                          void* user) {
    auto* s = static_cast<HotplugMonitor::State*>(user);
    const std::pair<int, int> key{libusb_get_bus_number(dev), libusb_get_device_address(dev)};
    HotplugEvent e;
    {
        std::lock_guard lock(s->mutex);
        if (event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED) {
            auto d = describe(dev, false);
            if (!d)
                return 0;
            e.kind = HotplugEvent::Kind::kArrived;
            e.device = d->descriptor;
            s->present[key] = d->descriptor;
        } else {
            auto it = s->present.find(key);
            if (it == s->present.end()) {
                // Present before the monitor started: describe it from libusb's cached data.
                auto d = describe(dev, false);
                if (!d)
                    return 0;
                e.device = d->descriptor;
            } else {
                e.device = it->second;
                s->present.erase(it);
            }
            e.kind = HotplugEvent::Kind::kLeft;
        }
        s->events.push_back(std::move(e));
    }
    s->cv.notify_all();
    return 0;
}

}  // namespace

HotplugMonitor::HotplugMonitor(std::unique_ptr<State> state) : state_(std::move(state)) {}

Result<std::unique_ptr<HotplugMonitor>> HotplugMonitor::start() {
    auto s = std::make_unique<State>();
    if (const int rc = libusb_init(&s->ctx); rc != LIBUSB_SUCCESS)
        return Status(ErrorCode::kIoError,
                      std::string("usb: libusb_init failed: ") + libusb_error_name(rc));
    if (!libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG)) {
        libusb_exit(s->ctx);
        return Status(ErrorCode::kUnsupported, "usb: this libusb has no hot-plug support");
    }
    const int rc = libusb_hotplug_register_callback(
        s->ctx,
        static_cast<libusb_hotplug_event>(LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED |
                                          LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT),
        static_cast<libusb_hotplug_flag>(0), LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY,
        LIBUSB_HOTPLUG_MATCH_ANY, onHotplug, s.get(), &s->handle);
    if (rc != LIBUSB_SUCCESS) {
        libusb_exit(s->ctx);
        return Status(ErrorCode::kIoError,
                      std::string("usb: hot-plug registration failed: ") + libusb_error_name(rc));
    }
    s->registered = true;
    State* raw = s.get();
    s->pump = std::thread([raw] {
        while (!raw->stop.load()) {
            timeval tv{0, 100000};
            (void)libusb_handle_events_timeout_completed(raw->ctx, &tv, nullptr);
        }
    });
    return std::unique_ptr<HotplugMonitor>(new HotplugMonitor(std::move(s)));
}

HotplugMonitor::~HotplugMonitor() {
    state_->stop.store(true);
    if (state_->registered)
        libusb_hotplug_deregister_callback(state_->ctx, state_->handle);
    libusb_interrupt_event_handler(state_->ctx);
    state_->pump.join();
    libusb_exit(state_->ctx);
}

std::optional<HotplugEvent> HotplugMonitor::next(std::chrono::milliseconds timeout) {
    std::unique_lock lock(state_->mutex);
    if (!state_->cv.wait_for(lock, timeout, [&] { return !state_->events.empty(); }))
        return std::nullopt;
    HotplugEvent e = std::move(state_->events.front());
    state_->events.pop_front();
    return e;
}

}  // namespace mixray::usb
