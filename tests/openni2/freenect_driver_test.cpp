// Kinect v1 inside OpenNI2: the project's libfreenect driver plug-in, loaded by OpenNI2 2.2 from
// the build tree's private OpenNI2 folder, against a USB bus umockdev emulates (an empty one,
// and tests/usb/kinect_v1.umockdev with the camera's usbfs node answered by a handler).
#include <OniCAPI.h>
#include <OpenNI.h>
#include <dlfcn.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "kinect_usb_emulator.h"
#include "test_data.h"
#include "umockdev_preload.h"

namespace mixray::openni2 {
namespace {

using test::KinectUsbEmulator;

const std::string kPrivateOpenNI2 = MIXRAY_OPENNI2_DIR;
const std::string kPlugin = kPrivateOpenNI2 + "/OpenNI2/Drivers/libFreenectDriver.so.0";
const std::string kKinectUri = std::string("freenect://0/") + KinectUsbEmulator::kCameraSerial;

std::string tree(const char* name) {
    return (mixray::test::sourceDir() / "tests/usb" / name).string();
}

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

void expectNoFreenectDevice() {
    for (const auto& d : devices())
        EXPECT_NE(std::string(d.getUri()).rfind("freenect://", 0), 0u) << d.getUri();
}

void expectKinectSerial(openni::Device& device) {
    char serial[64] = {};
    int size = sizeof(serial);
    ASSERT_EQ(device.getProperty(ONI_DEVICE_PROPERTY_SERIAL_NUMBER, serial, &size),
              openni::STATUS_OK);
    EXPECT_STREQ(serial, KinectUsbEmulator::kCameraSerial);
}

// The emulated camera sends frames whose bytes all hold one value.
template <typename Pixel>
void expectUniform(const Pixel* data, int count, int step, const char* what, int n) {
    for (int i = 0; i < count; i += step)
        ASSERT_EQ(data[i], data[0]) << "element " << i << " of " << what << " " << n;
}

// Each test emulates its USB bus before OpenNI2 initialises, and tears down in the reverse
// order: device, OpenNI2, bus.
class FreenectDriver : public testing::Test {
protected:
    void SetUp() override { MIXRAY_REQUIRE_UMOCKDEV(); }

    // The bus of tests/usb/<file>; the Kinect camera's usbfs node answered when `camera`.
    void emulate(const char* file, bool camera) {
        std::string why;
        usb_ = KinectUsbEmulator::create(tree(file), camera, &why);
        ASSERT_TRUE(usb_) << why;
    }
    void initialiseOpenNI2() {
        session_.emplace();
        ASSERT_TRUE(session_->ok()) << openni::OpenNI::getExtendedError();
    }
    // The emulated Kinect opened through OpenNI2 as device_.
    void openKinect() {
        ASSERT_NO_FATAL_FAILURE(emulate("kinect_v1.umockdev", true));
        ASSERT_NO_FATAL_FAILURE(initialiseOpenNI2());
        ASSERT_EQ(device_.open(kKinectUri.c_str()), openni::STATUS_OK)
            << openni::OpenNI::getExtendedError();
    }

    std::unique_ptr<KinectUsbEmulator> usb_;
    std::optional<Session> session_;
    openni::Device device_;
};

TEST_F(FreenectDriver, LoadsThroughThePrivateOpenNI2AndListsNothingOnABusWithoutKinect) {
    ASSERT_NO_FATAL_FAILURE(emulate("root_hub.umockdev", false));
    ASSERT_NO_FATAL_FAILURE(initialiseOpenNI2());

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

    expectNoFreenectDevice();
    // Opening a Kinect that is not there fails with the plug-in's error, not a crash.
    EXPECT_NE(device_.open(kKinectUri.c_str()), openni::STATUS_OK);
}

TEST_F(FreenectDriver, ListsTheEmulatedKinectCameraWithItsSerialAndUsbIds) {
    ASSERT_NO_FATAL_FAILURE(emulate("kinect_v1.umockdev", true));
    ASSERT_NO_FATAL_FAILURE(initialiseOpenNI2());

    const auto list = devices();
    ASSERT_EQ(list.size(), 1u) << "one Kinect camera (its motor and audio are not cameras)";
    const openni::DeviceInfo& info = list[0];
    EXPECT_EQ(std::string(info.getUri()), kKinectUri);
    EXPECT_EQ(std::string(info.getVendor()), "Microsoft");
    EXPECT_EQ(std::string(info.getName()), "Kinect");
    EXPECT_EQ(info.getUsbVendorId(), 0x045e);
    EXPECT_EQ(info.getUsbProductId(), 0x02ae);

    // libfreenect read the serial from the camera: language ids, then string 3 in en-US.
    const auto requests = usb_->controlRequests();
    EXPECT_NE(std::find(requests.begin(), requests.end(), "80:06:0300:0000"), requests.end());
    EXPECT_NE(std::find(requests.begin(), requests.end(), "80:06:0303:0409"), requests.end());
}

TEST_F(FreenectDriver, OpensTheEmulatedKinectWithItsSerialSensorsAndStreamProperties) {
    ASSERT_NO_FATAL_FAILURE(openKinect());
    openni::Device& device = device_;
    // libfreenect's camera set-up: padding lines, fixed parameters, constant shift.
    const auto commands = usb_->commands();
    EXPECT_NE(std::find(commands.begin(), commands.end(), 0x04), commands.end());
    EXPECT_NE(std::find(commands.begin(), commands.end(), 0x16), commands.end());
    ASSERT_NO_FATAL_FAILURE(expectKinectSerial(device));

    struct Expected {
        openni::SensorType sensor;
        openni::PixelFormat format;
        int width, height;
    };
    for (const Expected& e :
         {Expected{openni::SENSOR_DEPTH, openni::PIXEL_FORMAT_DEPTH_1_MM, 640, 480},
          Expected{openni::SENSOR_COLOR, openni::PIXEL_FORMAT_RGB888, 640, 480},
          Expected{openni::SENSOR_IR, openni::PIXEL_FORMAT_GRAY16, 640, 488}}) {
        const openni::SensorInfo* info = device.getSensorInfo(e.sensor);
        ASSERT_NE(info, nullptr);
        ASSERT_EQ(info->getSupportedVideoModes().getSize(), 1);
        const openni::VideoMode& mode = info->getSupportedVideoModes()[0];
        EXPECT_EQ(mode.getPixelFormat(), e.format);
        EXPECT_EQ(mode.getResolutionX(), e.width);
        EXPECT_EQ(mode.getResolutionY(), e.height);
        EXPECT_EQ(mode.getFps(), 30);

        openni::VideoStream stream;
        ASSERT_EQ(stream.create(device, e.sensor), openni::STATUS_OK);
        EXPECT_EQ(stream.getVideoMode().getResolutionX(), e.width);
        const int bytes = e.format == openni::PIXEL_FORMAT_RGB888 ? 3 : 2;
        int stride = 0;
        EXPECT_EQ(stream.getProperty(ONI_STREAM_PROPERTY_STRIDE, &stride), openni::STATUS_OK);
        EXPECT_EQ(stride, e.width * bytes);
        int x = -1, y = -1, w = 0, h = 0;
        EXPECT_FALSE(stream.getCropping(&x, &y, &w, &h));
        EXPECT_GT(stream.getHorizontalFieldOfView(), 0.9f);  // about 58 to 62 degrees
        EXPECT_LT(stream.getHorizontalFieldOfView(), 1.1f);
        EXPECT_FALSE(stream.getMirroringEnabled());
        EXPECT_EQ(stream.setMirroringEnabled(true), openni::STATUS_OK);
        EXPECT_TRUE(stream.getMirroringEnabled());
        openni::VideoMode other = mode;
        other.setResolution(320, 240);
        EXPECT_NE(stream.setVideoMode(other), openni::STATUS_OK);
        EXPECT_EQ(stream.setVideoMode(mode), openni::STATUS_OK);
        stream.destroy();
    }

    EXPECT_TRUE(device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR));
    EXPECT_EQ(device.getImageRegistrationMode(), openni::IMAGE_REGISTRATION_OFF);
    EXPECT_EQ(device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR),
              openni::STATUS_OK);
    EXPECT_EQ(device.getImageRegistrationMode(), openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
    device.close();
}

// Records OpenNI2's device connected / disconnected events.
class DeviceEvents : public openni::OpenNI::DeviceConnectedListener,
                     public openni::OpenNI::DeviceDisconnectedListener {
public:
    void onDeviceConnected(const openni::DeviceInfo* info) override { add(connected_, info); }
    void onDeviceDisconnected(const openni::DeviceInfo* info) override { add(disconnected_, info); }
    // Waits (up to 10 s) until `uri` connected / disconnected; false if it did not.
    bool waitConnected(const std::string& uri) { return wait(connected_, uri); }
    bool waitDisconnected(const std::string& uri) { return wait(disconnected_, uri); }

private:
    void add(std::vector<std::string>& list, const openni::DeviceInfo* info) {
        std::lock_guard lock(mutex_);
        list.push_back(info->getUri());
        changed_.notify_all();
    }
    bool wait(const std::vector<std::string>& list, const std::string& uri) {
        std::unique_lock lock(mutex_);
        return changed_.wait_for(lock, std::chrono::seconds(10), [&] {
            return std::find(list.begin(), list.end(), uri) != list.end();
        });
    }
    std::mutex mutex_;
    std::condition_variable changed_;
    std::vector<std::string> connected_;
    std::vector<std::string> disconnected_;
};

// libusb's hot-plug events (umockdev uevents) reach OpenNI2 as device (dis)connections.
TEST_F(FreenectDriver, ReportsAKinectPluggedInAndOutWhileOpenNI2Runs) {
    ASSERT_NO_FATAL_FAILURE(emulate("root_hub.umockdev", false));
    ASSERT_NO_FATAL_FAILURE(initialiseOpenNI2());
    DeviceEvents events;
    ASSERT_EQ(openni::OpenNI::addDeviceConnectedListener(&events), openni::STATUS_OK);
    ASSERT_EQ(openni::OpenNI::addDeviceDisconnectedListener(&events), openni::STATUS_OK);
    expectNoFreenectDevice();

    std::string why;
    ASSERT_TRUE(usb_->plug(tree("kinect_v1.umockdev"), &why)) << why;
    EXPECT_TRUE(events.waitConnected(kKinectUri)) << "no connection event for " << kKinectUri;
    openni::Device& device = device_;
    ASSERT_EQ(device.open(kKinectUri.c_str()), openni::STATUS_OK)
        << openni::OpenNI::getExtendedError();
    ASSERT_NO_FATAL_FAILURE(expectKinectSerial(device));
    openni::VideoStream color;
    ASSERT_EQ(color.create(device, openni::SENSOR_COLOR), openni::STATUS_OK);
    ASSERT_EQ(color.start(), openni::STATUS_OK);
    openni::VideoFrameRef frame;
    ASSERT_EQ(color.readFrame(&frame), openni::STATUS_OK);

    // Unplugged while streaming: OpenNI2 hears of it, the stream stops delivering, nothing
    // crashes or hangs, and the device still closes.
    usb_->unplugCamera();
    EXPECT_TRUE(events.waitDisconnected(kKinectUri)) << "no disconnection event for " << kKinectUri;
    openni::VideoStream* streams[] = {&color};
    int ready = -1;
    openni::Status status = openni::STATUS_OK;
    for (int n = 0; n < 3 && status == openni::STATUS_OK; ++n) {
        // Frames made before the unplug may still be waiting.
        status = openni::OpenNI::waitForAnyStream(streams, 1, &ready, 2000);
        if (status == openni::STATUS_OK) {
            ASSERT_EQ(color.readFrame(&frame), openni::STATUS_OK);
        }
    }
    EXPECT_EQ(status, openni::STATUS_TIME_OUT);
    color.stop();
    color.destroy();
    device.close();
    for (const auto& d : devices())
        EXPECT_NE(std::string(d.getUri()), kKinectUri);
    openni::OpenNI::removeDeviceConnectedListener(&events);
    openni::OpenNI::removeDeviceDisconnectedListener(&events);
}

// Frames through openni::VideoStream: libfreenect decodes the emulated camera's packets, the
// plug-in hands them to OpenNI2 with its timestamps.
TEST_F(FreenectDriver, StreamsDepthAndColourFromTheEmulatedKinect) {
    ASSERT_NO_FATAL_FAILURE(openKinect());
    openni::Device& device = device_;
    openni::VideoStream depth;
    openni::VideoStream color;
    ASSERT_EQ(depth.create(device, openni::SENSOR_DEPTH), openni::STATUS_OK);
    ASSERT_EQ(color.create(device, openni::SENSOR_COLOR), openni::STATUS_OK);
    ASSERT_EQ(depth.start(), openni::STATUS_OK) << openni::OpenNI::getExtendedError();
    ASSERT_EQ(color.start(), openni::STATUS_OK) << openni::OpenNI::getExtendedError();
    // libfreenect switched the camera's streams on through its registers.
    const auto registers = usb_->registers();
    EXPECT_EQ(registers.at(0x06), 2);  // depth on
    EXPECT_EQ(registers.at(0x05), 1);  // colour (Bayer) on

    // Every pixel of camera frame k holds pixelValue(k): the first frame received (libfreenect
    // drops those that arrive before it marks the stream running) sets where time starts.
    int first_color = -1;
    int first_index = 0;
    uint16_t last_mm = 0;
    uint64_t last_depth_us = 0;
    double first_color_us = 0;
    constexpr double kPeriodUs = 2'000'000 / 60.0;  // 60 MHz ticks per frame, in µs
    for (int n = 0; n < 4; ++n) {
        openni::VideoFrameRef frame;
        ASSERT_EQ(color.readFrame(&frame), openni::STATUS_OK);
        EXPECT_EQ(frame.getWidth(), 640);
        EXPECT_EQ(frame.getHeight(), 480);
        EXPECT_EQ(frame.getStrideInBytes(), 640 * 3);
        const auto* rgb = static_cast<const uint8_t*>(frame.getData());
        const int k = rgb[0] - KinectUsbEmulator::pixelValue(KinectUsbEmulator::Stream::kBayer, 0);
        if (first_color < 0) {
            first_color = k;
            first_index = frame.getFrameIndex();
            first_color_us = static_cast<double>(frame.getTimestamp());
        }
        // The plug-in numbers the frames libfreenect decodes, none lost on the emulated bus
        // (readFrame may skip some when this thread is slow).
        EXPECT_EQ(k - first_color, frame.getFrameIndex() - first_index);
        // The camera's 60 MHz stamps (which wrap to 0 in the second frame) in microseconds.
        EXPECT_NEAR(static_cast<double>(frame.getTimestamp()) - first_color_us,
                    (k - first_color) * kPeriodUs, 1.0);
        ASSERT_NO_FATAL_FAILURE(expectUniform(rgb, 640 * 480 * 3, 997, "colour frame", n));

        ASSERT_EQ(depth.readFrame(&frame), openni::STATUS_OK);
        EXPECT_EQ(frame.getVideoMode().getPixelFormat(), openni::PIXEL_FORMAT_DEPTH_1_MM);
        EXPECT_EQ(frame.getStrideInBytes(), 640 * 2);
        // Every raw disparity of a frame is the same, so libfreenect's conversion gives one
        // distance; larger disparities (later frames) are farther.
        const auto* mm = static_cast<const uint16_t*>(frame.getData());
        ASSERT_NO_FATAL_FAILURE(expectUniform(mm, 640 * 480, 991, "depth frame", n));
        EXPECT_GT(mm[0], 500);
        EXPECT_LT(mm[0], 4000);
        // Depth runs on the same camera clock as colour: whole frame periods apart.
        const double periods =
            (static_cast<double>(frame.getTimestamp()) - first_color_us) / kPeriodUs;
        EXPECT_NEAR(periods, std::round(periods), 1e-3) << frame.getTimestamp();
        if (n > 0) {
            EXPECT_GT(frame.getTimestamp(), last_depth_us);
            EXPECT_GT(mm[0], last_mm);
        }
        last_mm = mm[0];
        last_depth_us = frame.getTimestamp();
    }
    depth.stop();
    color.stop();
    depth.destroy();
    color.destroy();
    device.close();
    EXPECT_GE(usb_->framesSent(0x82), 4u);
}

// IR shares the colour endpoint: one of them at a time; IR frames are 640x488 GRAY16.
TEST_F(FreenectDriver, StreamsInfraredAndRefusesItBesideColour) {
    ASSERT_NO_FATAL_FAILURE(openKinect());
    openni::Device& device = device_;
    openni::VideoStream color;
    openni::VideoStream ir;
    ASSERT_EQ(color.create(device, openni::SENSOR_COLOR), openni::STATUS_OK);
    ASSERT_EQ(ir.create(device, openni::SENSOR_IR), openni::STATUS_OK);
    ASSERT_EQ(color.start(), openni::STATUS_OK);
    EXPECT_NE(ir.start(), openni::STATUS_OK);
    EXPECT_NE(std::string(openni::OpenNI::getExtendedError()).find("colour and IR share"),
              std::string::npos)
        << openni::OpenNI::getExtendedError();
    color.stop();
    ASSERT_EQ(ir.start(), openni::STATUS_OK) << openni::OpenNI::getExtendedError();
    EXPECT_EQ(usb_->registers().at(0x05), 3);  // IR on
    // IR pixel (x, y) of camera frame k is pixelValue(kInfrared, k) + x / 64: frames show the
    // camera's view as sent, then mirrored once mirroring is switched on.
    int last_unmirrored = 0;
    for (int n = 0; n < 4; ++n) {
        const bool mirrored = n >= 2;
        if (n == 2) {
            ASSERT_EQ(ir.setMirroringEnabled(true), openni::STATUS_OK);
        }
        openni::VideoFrameRef frame;
        ASSERT_EQ(ir.readFrame(&frame), openni::STATUS_OK);
        // Frames made (or being made) before the switch may still be waiting to be read.
        while (mirrored && frame.getFrameIndex() < last_unmirrored + 3)
            ASSERT_EQ(ir.readFrame(&frame), openni::STATUS_OK);
        if (!mirrored)
            last_unmirrored = frame.getFrameIndex();
        EXPECT_EQ(frame.getVideoMode().getPixelFormat(), openni::PIXEL_FORMAT_GRAY16);
        EXPECT_EQ(frame.getWidth(), 640);
        EXPECT_EQ(frame.getHeight(), 488);
        const auto* px = static_cast<const uint16_t*>(frame.getData());
        const int left = mirrored ? px[639] : px[0];  // the camera's column 0
        EXPECT_EQ((left - 100) % 3, 0) << left;       // 100 + 3k: a value the camera sends
        for (int y = 0; y < 488; y += 61) {
            for (int x = 0; x < 640; x += 7) {
                const int camera_x = mirrored ? 639 - x : x;
                ASSERT_EQ(px[y * 640 + x], left + camera_x / KinectUsbEmulator::kIrColumnsPerStep)
                    << "pixel (" << x << ", " << y << ") of IR frame " << n;
            }
        }
    }
    ir.stop();
    ir.destroy();
    color.destroy();
    device.close();
}

// OpenNI2's recorder takes the plug-in's streams (it needs their video mode, cropping, stride,
// mirroring and fields of view), and the .oni plays back through OpenNI2 with the same pixels.
TEST_F(FreenectDriver, RecordsAnOniThatPlaysBack) {
    ASSERT_NO_FATAL_FAILURE(emulate("kinect_v1.umockdev", true));
    const auto path = std::filesystem::temp_directory_path() /
                      ("mixray_freenect_" + std::to_string(::getpid()) + ".oni");
    std::vector<uint8_t> recorded;  // the colour value of each recorded frame
    {
        Session session;
        ASSERT_TRUE(session.ok()) << openni::OpenNI::getExtendedError();
        openni::Device device;
        ASSERT_EQ(device.open(kKinectUri.c_str()), openni::STATUS_OK);
        openni::VideoStream depth;
        openni::VideoStream color;
        ASSERT_EQ(depth.create(device, openni::SENSOR_DEPTH), openni::STATUS_OK);
        ASSERT_EQ(color.create(device, openni::SENSOR_COLOR), openni::STATUS_OK);
        openni::Recorder recorder;
        ASSERT_EQ(recorder.create(path.c_str()), openni::STATUS_OK);
        ASSERT_EQ(recorder.attach(depth), openni::STATUS_OK);
        ASSERT_EQ(recorder.attach(color), openni::STATUS_OK);
        ASSERT_EQ(depth.start(), openni::STATUS_OK);
        ASSERT_EQ(color.start(), openni::STATUS_OK);
        ASSERT_EQ(recorder.start(), openni::STATUS_OK);
        openni::VideoFrameRef frame;
        for (int n = 0; n < 5; ++n) {
            ASSERT_EQ(color.readFrame(&frame), openni::STATUS_OK);
            ASSERT_EQ(depth.readFrame(&frame), openni::STATUS_OK);
        }
        recorder.stop();
        recorder.destroy();
        depth.stop();
        color.stop();
        depth.destroy();
        color.destroy();
        device.close();
    }
    Session session;
    ASSERT_TRUE(session.ok());
    openni::Device playback;
    ASSERT_EQ(playback.open(path.c_str()), openni::STATUS_OK) << openni::OpenNI::getExtendedError();
    ASSERT_TRUE(playback.isFile());
    openni::VideoStream color;
    ASSERT_EQ(color.create(playback, openni::SENSOR_COLOR), openni::STATUS_OK);
    const int frames = playback.getPlaybackControl()->getNumberOfFrames(color);
    EXPECT_GE(frames, 3);
    EXPECT_EQ(color.getVideoMode().getResolutionX(), 640);
    EXPECT_EQ(color.getVideoMode().getPixelFormat(), openni::PIXEL_FORMAT_RGB888);
    EXPECT_FALSE(color.getMirroringEnabled());
    playback.getPlaybackControl()->setSpeed(-1);  // manual: every frame on request
    ASSERT_EQ(color.start(), openni::STATUS_OK);
    openni::VideoFrameRef frame;
    int previous = -1;
    for (int n = 0; n < frames; ++n) {
        ASSERT_EQ(color.readFrame(&frame), openni::STATUS_OK);
        ASSERT_EQ(frame.getWidth(), 640);
        const auto* rgb = static_cast<const uint8_t*>(frame.getData());
        ASSERT_NO_FATAL_FAILURE(expectUniform(rgb, 640 * 480 * 3, 997, "played frame", n));
        // Camera frames carry increasing values: playback keeps their order.
        EXPECT_GT(static_cast<int>(rgb[0]), previous);
        previous = rgb[0];
    }
    color.stop();
    color.destroy();
    playback.close();
    std::filesystem::remove(path);
}

}  // namespace
}  // namespace mixray::openni2

int main(int argc, char** argv) {
    mixray::test::reexecWithUmockdevPreload(argc, argv);
#if defined(__SANITIZE_ADDRESS__)
    // Each test shuts OpenNI2 down, which unloads its drivers; LeakSanitizer then cannot name
    // the module of their leaks and the suppressions (support/openni2_lsan_suppressions.cpp)
    // do not apply. The system's drivers stay loaded (never the plug-in: its own leaks must be
    // reported, and the first test checks that OpenNI2 itself loads it).
    for (const char* driver :
         {"libDummyDevice.so.0", "libOniFile.so.0", "libPS1080.so.0", "libPSLink.so.0"}) {
        const std::string path = mixray::openni2::kPrivateOpenNI2 + "/OpenNI2/Drivers/" + driver;
        (void)dlopen(path.c_str(), RTLD_NOW | RTLD_NODELETE);
    }
#endif
    testing::InitGoogleTest(&argc, argv);
    return RUN_ALL_TESTS();
}
