// The usb backend against USB devices described to umockdev (tests/usb/*.umockdev: sysfs
// attributes and descriptors of a Kinect v1, a UVC webcam and a USB3 Vision camera): libusb
// enumerates them as if they were plugged in, and testbed uevents fire its hot-plug callbacks.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "mixray/usb/usb_backend.h"
#include "umockdev_preload.h"
#include "usb_testbed.h"

namespace mixray::usb {
namespace {

using std::chrono::seconds;

constexpr const char* kBus = "/sys/devices/pci0000:00/0000:00:14.0/usb1";

using test::Testbed;

const DeviceDescriptor* find(const std::vector<DeviceDescriptor>& devices, const std::string& id) {
    auto it = std::find_if(devices.begin(), devices.end(),
                           [&](const DeviceDescriptor& d) { return d.id == id; });
    return it == devices.end() ? nullptr : &*it;
}

TEST(UsbIdentify, ByIdsThenByInterfaceClass) {
    EXPECT_EQ(identify(0x045e, 0x02ae, {})->model, "Kinect v1 camera");
    EXPECT_EQ(identify(0x045e, 0x02ae, {})->streamer, "openni2");
    EXPECT_EQ(identify(0x045e, 0x02b0, {})->streamer, "usb");
    EXPECT_EQ(identify(0x045e, 0x02ad, {})->streamer, "");
    EXPECT_EQ(identify(0x1d27, 0x0609, {})->model, "PrimeSense depth sensor (1d27:0609)");
    EXPECT_FALSE(identify(0x1d27, 0x0700, {}));
    EXPECT_FALSE(identify(0x045e, 0x02bf, {{0xff, 0xff}}));
    EXPECT_EQ(identify(0x1234, 0x5678, {{0x01, 0x01}, {0x0e, 0x02}})->streamer, "v4l2");
    EXPECT_EQ(identify(0x1234, 0x5678, {{0xef, 0x05}})->model, "USB3 Vision camera");
    EXPECT_EQ(identify(0x1234, 0x5678, {{0xef, 0x05}})->streamer, "aravis");
    // Class 0xef is "miscellaneous": only subclass 5 is USB3 Vision.
    EXPECT_FALSE(identify(0x1234, 0x5678, {{0xef, 0x02}}));
    EXPECT_EQ(deviceId(0x045e, 0x02ae, 1, 5), "045e:02ae@1/5");
}

TEST(UsbBackend, EnumeratesTheRigDevicesOnly) {
    MIXRAY_REQUIRE_UMOCKDEV();
    Testbed bed;
    ASSERT_TRUE(bed.add("root_hub.umockdev"));
    ASSERT_TRUE(bed.add("kinect_v1.umockdev"));
    ASSERT_TRUE(bed.add("uvc_camera.umockdev"));
    ASSERT_TRUE(bed.add("usb3_vision_camera.umockdev"));
    UsbBackend backend;
    EXPECT_EQ(backend.name(), "usb");
    auto devices = backend.enumerate();
    ASSERT_TRUE(devices) << devices.status().toString();
    // The root hub and the Kinect's internal hub are not rig devices.
    ASSERT_EQ(devices->size(), 5u);
    const DeviceDescriptor* camera = find(*devices, "045e:02ae@1/5");
    ASSERT_TRUE(camera);
    EXPECT_EQ(camera->backend, "usb");
    EXPECT_EQ(camera->model, "Kinect v1 camera");
    EXPECT_EQ(camera->serial, "A00364A11700045A");
    EXPECT_EQ(camera->location, "1-1.3");
    const DeviceDescriptor* motor = find(*devices, "045e:02b0@1/3");
    ASSERT_TRUE(motor);
    EXPECT_EQ(motor->model, "Kinect v1 motor");
    EXPECT_EQ(motor->serial, "");
    EXPECT_EQ(motor->location, "1-1.1");
    const DeviceDescriptor* audio = find(*devices, "045e:02ad@1/4");
    ASSERT_TRUE(audio);
    EXPECT_EQ(audio->model, "Kinect v1 audio");
    EXPECT_EQ(audio->serial, "A44887C10800045A");
    const DeviceDescriptor* webcam = find(*devices, "046d:0825@1/6");
    ASSERT_TRUE(webcam);
    EXPECT_EQ(webcam->model, "UVC camera");
    EXPECT_EQ(webcam->serial, "8A3F29C0");
    EXPECT_EQ(webcam->location, "1-2");
    const DeviceDescriptor* vision = find(*devices, "2676:ba02@1/7");
    ASSERT_TRUE(vision);
    EXPECT_EQ(vision->model, "USB3 Vision camera");
    EXPECT_EQ(vision->serial, "22841531");
    EXPECT_EQ(vision->location, "1-3");
}

TEST(UsbBackend, OpenNamesTheBackendThatStreams) {
    MIXRAY_REQUIRE_UMOCKDEV();
    Testbed bed;
    ASSERT_TRUE(bed.add("root_hub.umockdev"));
    ASSERT_TRUE(bed.add("kinect_v1.umockdev"));
    ASSERT_TRUE(bed.add("uvc_camera.umockdev"));
    UsbBackend backend;
    DeviceConfig c;
    c.name = "kinect";
    c.driver = "usb";
    c.id = "A00364A11700045A";
    auto kinect = backend.open(c);
    ASSERT_FALSE(kinect);
    EXPECT_EQ(kinect.status().code(), ErrorCode::kUnsupported);
    EXPECT_NE(kinect.status().message().find("driver: openni2"), std::string::npos)
        << kinect.status().message();
    c.id = "046d:0825@1/6";
    auto webcam = backend.open(c);
    ASSERT_FALSE(webcam);
    EXPECT_NE(webcam.status().message().find("driver: v4l2"), std::string::npos)
        << webcam.status().message();
    ASSERT_TRUE(bed.add("usb3_vision_camera.umockdev"));
    c.id = "22841531";
    auto vision = backend.open(c);
    ASSERT_FALSE(vision);
    EXPECT_NE(vision.status().message().find("driver: aravis"), std::string::npos)
        << vision.status().message();
    // The motor opens here (kinect_motor_test.cpp); the microphones nowhere.
    c.id = "045e:02ad@1/4";
    auto audio = backend.open(c);
    ASSERT_FALSE(audio);
    EXPECT_EQ(audio.status().code(), ErrorCode::kUnsupported);
    EXPECT_NE(audio.status().message().find("no mixray backend streams it"), std::string::npos)
        << audio.status().message();
    c.id = "045e:02ae@1/9";
    auto absent = backend.open(c);
    ASSERT_FALSE(absent);
    EXPECT_EQ(absent.status().code(), ErrorCode::kNotFound);
}

TEST(HotplugMonitor, ReportsArrivalAndDepartureOfRigDevices) {
    MIXRAY_REQUIRE_UMOCKDEV();
    Testbed bed;
    ASSERT_TRUE(bed.add("root_hub.umockdev"));
    ASSERT_TRUE(bed.add("kinect_v1.umockdev"));
    auto monitor = HotplugMonitor::start();
    ASSERT_TRUE(monitor) << monitor.status().toString();

    ASSERT_TRUE(bed.add("uvc_camera.umockdev"));
    bed.uevent(std::string(kBus) + "/1-2", "add");
    auto arrived = (*monitor)->next(seconds(10));
    ASSERT_TRUE(arrived);
    EXPECT_EQ(arrived->kind, HotplugEvent::Kind::kArrived);
    EXPECT_EQ(arrived->device.id, "046d:0825@1/6");
    EXPECT_EQ(arrived->device.model, "UVC camera");
    EXPECT_EQ(arrived->device.serial, "8A3F29C0");
    EXPECT_EQ(arrived->device.location, "1-2");

    bed.uevent(std::string(kBus) + "/1-2", "remove");
    bed.remove(std::string(kBus) + "/1-2");
    auto left = (*monitor)->next(seconds(10));
    ASSERT_TRUE(left);
    EXPECT_EQ(left->kind, HotplugEvent::Kind::kLeft);
    EXPECT_EQ(left->device.id, "046d:0825@1/6");
    // Described from what was seen at arrival: the sysfs entry is gone by now.
    EXPECT_EQ(left->device.serial, "8A3F29C0");

    // A device present before the monitor started leaves too.
    bed.uevent(std::string(kBus) + "/1-1/1-1.3", "remove");
    bed.remove(std::string(kBus) + "/1-1/1-1.3");
    left = (*monitor)->next(seconds(10));
    ASSERT_TRUE(left);
    EXPECT_EQ(left->kind, HotplugEvent::Kind::kLeft);
    EXPECT_EQ(left->device.id, "045e:02ae@1/5");
    EXPECT_EQ(left->device.model, "Kinect v1 camera");
}

}  // namespace
}  // namespace mixray::usb

int main(int argc, char** argv) {
    mixray::test::reexecWithUmockdevPreload(argc, argv);
    testing::InitGoogleTest(&argc, argv);
    return RUN_ALL_TESTS();
}
