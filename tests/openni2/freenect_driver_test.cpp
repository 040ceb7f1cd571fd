// Kinect v1 inside OpenNI2: the project's libfreenect driver plug-in, loaded by OpenNI2 2.2 from
// the build tree's private OpenNI2 folder, against a USB bus umockdev emulates (an empty one,
// and tests/usb/kinect_v1.umockdev with the camera's usbfs node answered by a handler).
#include <OniCAPI.h>
#include <OpenNI.h>
#include <dlfcn.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "kinect_usb_emulator.h"
#include "mixray/openni2/openni2_backend.h"
#include "umockdev_preload.h"

#if defined(__SANITIZE_ADDRESS__)
// OpenNI2 2.2.0.33 and its drivers leak on their own (see openni2_test.cpp); these suppressions
// name those modules only, so the plug-in's and mixray's leaks are still reported.
extern "C" const char* __lsan_default_suppressions() {
    return "leak:libOpenNI2.so\nleak:libOniFile.so\nleak:libDummyDevice.so\nleak:libPS1080.so\n"
           "leak:libPSLink.so\nleak:libjpeg.so\n";
}
#endif

namespace mixray::openni2 {
namespace {

using test::KinectUsbEmulator;

const std::string kPrivateOpenNI2 = MIXRAY_OPENNI2_DIR;
const std::string kPlugin = kPrivateOpenNI2 + "/OpenNI2/Drivers/libFreenectDriver.so.0";
const std::string kKinectUri = std::string("freenect://0/") + KinectUsbEmulator::kCameraSerial;

std::string tree(const char* name) {
    return std::string(MIXRAY_SOURCE_DIR) + "/tests/usb/" + name;
}

#define MIXRAY_REQUIRE_UMOCKDEV()                                                               \
    do {                                                                                        \
        if (!mixray::test::umockdevPreloaded())                                                 \
            GTEST_SKIP() << "umockdev's preload library (" << mixray::test::kUmockdevPreload    \
                         << ", Debian package libumockdev0) is not installed: no emulated USB"; \
    } while (0)

// OpenNI2 initialised for one test: its drivers enumerate USB when it initialises, so each
// test builds its bus first. (No stream waits here, so the re-initialisation the backend
// avoids — see README — is safe.)
class Session {
public:
    Session() { status_ = openni::OpenNI::initialize(); }
    ~Session() { openni::OpenNI::shutdown(); }
    bool ok() const { return status_ == openni::STATUS_OK; }

private:
    openni::Status status_;
};

std::vector<openni::DeviceInfo> devices() {
    openni::Array<openni::DeviceInfo> list;
    openni::OpenNI::enumerateDevices(&list);
    std::vector<openni::DeviceInfo> out;
    for (int i = 0; i < list.getSize(); ++i)
        out.push_back(list[i]);
    return out;
}

TEST(FreenectDriver, LoadsThroughThePrivateOpenNI2AndListsNothingOnABusWithoutKinect) {
    MIXRAY_REQUIRE_UMOCKDEV();
    std::string why;
    auto bus = KinectUsbEmulator::create(tree("root_hub.umockdev"), false, &why);
    ASSERT_TRUE(bus) << why;
    Session session;
    ASSERT_TRUE(session.ok()) << openni::OpenNI::getExtendedError();

    // The test links libOpenNI2.so.0 through its RUNPATH: the private copy, not the system's.
    Dl_info info{};
    ASSERT_NE(dladdr(reinterpret_cast<void*>(&oniInitialize), &info), 0);
    // (The loader names it by the RUNPATH it came through: compare the folders, not the names.)
    EXPECT_EQ(
        std::filesystem::weakly_canonical(std::filesystem::path(info.dli_fname).parent_path()),
        std::filesystem::weakly_canonical(kPrivateOpenNI2))
        << info.dli_fname;
    // OpenNI2 loaded the plug-in from the private Drivers folder and kept it (a driver whose
    // oniDriverInitialize fails is unloaded again).
    void* plugin = dlopen(kPlugin.c_str(), RTLD_NOW | RTLD_NOLOAD);
    ASSERT_NE(plugin, nullptr) << "OpenNI2 did not load " << kPlugin;
    EXPECT_NE(dlsym(plugin, "oniDriverCreate"), nullptr);
    dlclose(plugin);

    for (const auto& d : devices())
        EXPECT_NE(std::string(d.getUri()).rfind("freenect://", 0), 0u) << d.getUri();
    // Opening a Kinect that is not there fails with the plug-in's error, not a crash.
    openni::Device device;
    EXPECT_NE(device.open(kKinectUri.c_str()), openni::STATUS_OK);
}

TEST(FreenectDriver, ListsTheEmulatedKinectCameraWithItsSerialAndUsbIds) {
    MIXRAY_REQUIRE_UMOCKDEV();
    std::string why;
    auto kinect = KinectUsbEmulator::create(tree("kinect_v1.umockdev"), true, &why);
    ASSERT_TRUE(kinect) << why;
    Session session;
    ASSERT_TRUE(session.ok()) << openni::OpenNI::getExtendedError();

    const auto list = devices();
    ASSERT_EQ(list.size(), 1u) << "one Kinect camera (its motor and audio are not cameras)";
    const openni::DeviceInfo& info = list[0];
    EXPECT_EQ(std::string(info.getUri()), kKinectUri);
    EXPECT_EQ(std::string(info.getVendor()), "Microsoft");
    EXPECT_EQ(std::string(info.getName()), "Kinect");
    EXPECT_EQ(info.getUsbVendorId(), 0x045e);
    EXPECT_EQ(info.getUsbProductId(), 0x02ae);

    // libfreenect read the serial from the camera: language ids, then string 3 in en-US.
    const auto requests = kinect->controlRequests();
    EXPECT_NE(std::find(requests.begin(), requests.end(), "80:06:0300:0000"), requests.end());
    EXPECT_NE(std::find(requests.begin(), requests.end(), "80:06:0303:0409"), requests.end());
}

TEST(FreenectDriver, OpeningTheEmulatedKinectReportsLibfreenectsCameraInitFailure) {
    MIXRAY_REQUIRE_UMOCKDEV();
    std::string why;
    auto kinect = KinectUsbEmulator::create(tree("kinect_v1.umockdev"), true, &why);
    ASSERT_TRUE(kinect) << why;
    Session session;
    ASSERT_TRUE(session.ok()) << openni::OpenNI::getExtendedError();

    // The emulated camera stalls libfreenect's camera commands (vendor requests), so
    // freenect_open_device fails after claiming the camera; the plug-in reports it.
    openni::Device device;
    EXPECT_NE(device.open(kKinectUri.c_str()), openni::STATUS_OK);
    EXPECT_NE(std::string(openni::OpenNI::getExtendedError())
                  .find(std::string("libfreenect could not open the Kinect with serial ") +
                        KinectUsbEmulator::kCameraSerial),
              std::string::npos)
        << openni::OpenNI::getExtendedError();
    const auto requests = kinect->controlRequests();
    EXPECT_TRUE(std::any_of(requests.begin(), requests.end(), [](const std::string& r) {
        return r.rfind("40:", 0) == 0;
    })) << "libfreenect sent no camera command";
}

// Last: the backend initialises OpenNI2 once per process and keeps it.
TEST(FreenectDriver, TheOpenNI2BackendListsTheEmulatedKinect) {
    MIXRAY_REQUIRE_UMOCKDEV();
    std::string why;
    auto kinect = KinectUsbEmulator::create(tree("kinect_v1.umockdev"), true, &why);
    ASSERT_TRUE(kinect) << why;
    OpenNI2Backend backend;
    auto list = backend.enumerate();
    ASSERT_TRUE(list) << list.status().message();
    ASSERT_EQ(list->size(), 1u);
    const DeviceDescriptor& d = list->front();
    EXPECT_EQ(d.backend, "openni2");
    EXPECT_EQ(d.id, kKinectUri);
    EXPECT_EQ(d.model, "Microsoft Kinect");
    // It cannot be opened (see above): listed without serial and modes, not hidden.
    EXPECT_TRUE(d.serial.empty());
    EXPECT_TRUE(d.modes.empty());

    DeviceConfig config;
    config.name = "kinect";
    config.id = kKinectUri;
    auto device = backend.open(config);
    ASSERT_FALSE(device);
    EXPECT_NE(device.status().message().find(KinectUsbEmulator::kCameraSerial), std::string::npos)
        << device.status().message();
}

}  // namespace
}  // namespace mixray::openni2

int main(int argc, char** argv) {
    mixray::test::reexecWithUmockdevPreload(argc, argv);
    testing::InitGoogleTest(&argc, argv);
    return RUN_ALL_TESTS();
}
