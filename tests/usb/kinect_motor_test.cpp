// The Kinect v1 motor device against the motor emulated behind umockdev (kinect_motor_emulator.h):
// libfreenect's control transfers reach the emulated usbfs node, the accelerometer it reports
// comes back as the gravity stream, and an unplug and replug while streaming is survived.
#include "mixray/usb/kinect_motor.h"

#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "kinect_motor_emulator.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/imu.h"
#include "mixray/graph/rig.h"
#include "mixray/usb/usb_backend.h"
#include "umockdev_preload.h"
#include "usb_testbed.h"

namespace mixray::usb {
namespace {

using std::chrono::seconds;
using test::ControlRequest;
using test::KinectMotorEmulator;

constexpr double kGravity = 9.80665;  // libfreenect's GRAVITY
constexpr double kCountsPerG = 819;   // FREENECT_COUNTS_PER_G

// A testbed with the root hub and the Kinect (camera, motor, audio), the motor answering
// through the emulator. Members are destroyed in reverse: the emulator before the testbed.
struct MotorBus {
    bool setUp() {
        for (const char* file : {"root_hub.umockdev", "kinect_v1.umockdev"})
            if (!testbed.add(file))
                return false;
        std::string why;
        emulator = KinectMotorEmulator::create(testbed.get(), &why);
        if (!emulator)
            ADD_FAILURE() << why;
        return emulator != nullptr;
    }

    test::Testbed testbed;
    std::unique_ptr<KinectMotorEmulator> emulator;
};

DeviceConfig motorConfig() {
    DeviceConfig c;
    c.name = "kinect_motor";
    c.driver = "usb";
    c.id = "045e:02b0@1/3";
    return c;
}

Result<std::unique_ptr<KinectMotorDevice>> openMotor(const DeviceConfig& config) {
    UsbBackend backend;
    auto device = backend.open(config);
    if (!device)
        return device.status();
    auto* motor = dynamic_cast<KinectMotorDevice*>(device->get());
    if (!motor)
        return Status(ErrorCode::kInternal, "the usb backend opened something else");
    (void)device->release();
    return std::unique_ptr<KinectMotorDevice>(motor);
}

// Waits up to 10 s (a bound against hangs, not a timing check) for `done`.
bool eventually(const std::function<bool()>& done) {
    const auto deadline = std::chrono::steady_clock::now() + seconds(10);
    while (!done()) {
        if (std::chrono::steady_clock::now() > deadline)
            return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return true;
}

ImuSample popSample(FrameQueue& queue, FrameMetadata* meta = nullptr) {
    auto frame = queue.pop(seconds(10));
    EXPECT_TRUE(frame) << "no gravity sample within 10 s";
    if (!frame)
        return {};
    if (meta)
        *meta = frame->meta();
    auto sample = decodeImuRecord(frame->image());
    EXPECT_TRUE(sample) << sample.status().toString();
    return sample ? *sample : ImuSample{};
}

// The motor of `config` streaming its gravity samples through a started graph.
struct StreamingMotor {
    void start(const DeviceConfig& config) {
        auto motor = openMotor(config);
        ASSERT_TRUE(motor) << motor.status().toString();
        device = motor->get();
        ASSERT_TRUE(graph.addNode(std::move(*motor)));
        auto subscribed = graph.subscribe(*graph.findStream("kinect_motor/gravity"), {});
        ASSERT_TRUE(subscribed);
        queue = *subscribed;
        ASSERT_TRUE(graph.start());
    }

    KinectMotorDevice* device = nullptr;
    Graph graph;
    std::shared_ptr<FrameQueue> queue;
};

TEST(KinectMotorOptions, BadOptionsAreClearErrors) {
    struct Case {
        const char* key;
        const char* value;
        const char* expected;
    };
    const std::vector<Case> cases = {
        {"tilt_deg", "32", "option 'tilt_deg': expected degrees in [-31, 31], got '32'"},
        {"tilt_deg", "level", "option 'tilt_deg': expected degrees in [-31, 31], got 'level'"},
        {"led", "purple",
         "option 'led': expected off, green, red, yellow, blink_green or "
         "blink_red_yellow, got 'purple'"},
        {"rate_hz", "0", "option 'rate_hz': expected a rate in (0, 200] Hz, got '0'"},
        {"buffers", "0", "option 'buffers': expected an integer in [1, 1024], got '0'"},
        {"reconnect", "maybe", "option 'reconnect'"},
        {"tilt", "10", "tilt"},
    };
    for (const Case& c : cases) {
        DeviceConfig config = motorConfig();
        config.options[c.key] = c.value;
        auto options = KinectMotorOptions::fromConfig(config);
        ASSERT_FALSE(options) << c.key;
        EXPECT_EQ(options.status().code(), ErrorCode::kInvalidArgument);
        EXPECT_NE(options.status().message().find(c.expected), std::string::npos)
            << options.status().message();
        EXPECT_NE(options.status().message().find("'kinect_motor'"), std::string::npos)
            << options.status().message();
    }
    DeviceConfig config = motorConfig();
    config.streams = {"depth"};
    auto options = KinectMotorOptions::fromConfig(config);
    ASSERT_FALSE(options);
    EXPECT_NE(options.status().message().find("no stream 'depth'"), std::string::npos);

    config = motorConfig();
    config.options = {{"tilt_deg", "-12.5"}, {"led", "blink_red_yellow"}, {"rate_hz", "50"}};
    options = KinectMotorOptions::fromConfig(config);
    ASSERT_TRUE(options) << options.status().toString();
    EXPECT_EQ(options->tilt_deg, -12.5);
    EXPECT_EQ(options->led, KinectLed::kBlinkRedYellow);
    EXPECT_EQ(options->rate_hz, 50);
    EXPECT_EQ(toString(KinectLed::kBlinkRedYellow), "blink_red_yellow");
    EXPECT_EQ(toString(TiltStatus::kLimit), "limit");
}

TEST(KinectMotor, GravityStreamCarriesTheAccelerometer) {
    MIXRAY_REQUIRE_UMOCKDEV();
    MotorBus bus;
    ASSERT_TRUE(bus.setUp());
    bus.emulator->setAccelerometer(12, 805, -140);
    bus.emulator->setTiltState(-10, 4);  // -5 degrees, moving

    auto motor = openMotor(motorConfig());
    ASSERT_TRUE(motor) << motor.status().toString();
    KinectMotorDevice* device = motor->get();
    EXPECT_EQ(device->descriptor().model, "Kinect v1 motor");
    EXPECT_EQ(device->descriptor().location, "1-1.1");
    EXPECT_EQ(device->descriptor().modes, std::vector<std::string>{"gravity imu@20"});

    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(*motor)));
    auto id = graph.findStream("kinect_motor/gravity");
    ASSERT_TRUE(id);
    const StreamInfo info = graph.stream(*id);
    EXPECT_EQ(info.kind, StreamKind::kImu);
    EXPECT_EQ(info.format.width, static_cast<int>(kImuRecordBytes));
    EXPECT_EQ(info.nominal_fps, 20);
    EXPECT_EQ(info.tags.at("imu_record"), "mixray-imu-1");
    auto queue = graph.subscribe(*id, {});
    ASSERT_TRUE(queue);
    ASSERT_TRUE(graph.start());

    FrameMetadata first;
    const ImuSample sample = popSample(**queue, &first);
    // libfreenect: counts / 819 * 9.80665, axes and signs as the device reports them.
    EXPECT_DOUBLE_EQ(sample.accel.x(), 12 / kCountsPerG * kGravity);
    EXPECT_DOUBLE_EQ(sample.accel.y(), 805 / kCountsPerG * kGravity);
    EXPECT_DOUBLE_EQ(sample.accel.z(), -140 / kCountsPerG * kGravity);
    EXPECT_FALSE(sample.gyro);
    EXPECT_FALSE(sample.temperature_c);
    EXPECT_EQ(first.clock_domain, kHostClockDomain);
    EXPECT_EQ(first.device_stamp_ns, first.host_stamp_ns);

    bus.emulator->setAccelerometer(-819, 0, 819);
    bus.emulator->setTiltState(62, 1);  // 31 degrees, at the limit
    ASSERT_TRUE(eventually([&] {
        auto s = device->lastState();
        return s && s->raw[0] == -819;
    }));
    const auto state = device->lastState();
    EXPECT_EQ(state->tilt_deg, 31);
    EXPECT_EQ(state->status, TiltStatus::kLimit);
    EXPECT_DOUBLE_EQ(state->accel_mps2.z(), kGravity);
    // The stream follows: the first sample with the new vector has x = -g.
    FrameMetadata later;
    ImuSample next;
    for (int i = 0; i < 100 && next.accel.x() != -kGravity; ++i)
        next = popSample(**queue, &later);
    EXPECT_DOUBLE_EQ(next.accel.x(), -kGravity);
    EXPECT_DOUBLE_EQ(next.accel.y(), 0);
    EXPECT_GT(later.sequence, first.sequence);
    EXPECT_GT(later.host_stamp_ns, first.host_stamp_ns);
    graph.stop();
    EXPECT_TRUE(bus.emulator->unknownIoctls().empty());
    EXPECT_GE(bus.emulator->stateReads(), 3u);
}

TEST(KinectMotor, TiltAndLedRequestsReachTheDevice) {
    MIXRAY_REQUIRE_UMOCKDEV();
    MotorBus bus;
    ASSERT_TRUE(bus.setUp());
    DeviceConfig config = motorConfig();
    config.options = {{"tilt_deg", "-12.5"}, {"led", "blink_red_yellow"}};
    auto motor = openMotor(config);
    ASSERT_TRUE(motor) << motor.status().toString();
    KinectMotorDevice& device = **motor;

    // Opening sets the rig's tilt (wValue = 2 * degrees as int16) and LED mode.
    auto requests = bus.emulator->requests();
    ASSERT_EQ(requests.size(), 2u);
    EXPECT_EQ(requests[0].request_type, 0x40);
    EXPECT_EQ(requests[0].request, 0x31);
    EXPECT_EQ(static_cast<int16_t>(requests[0].value), -25);
    EXPECT_EQ(requests[0].index, 0);
    EXPECT_EQ(requests[1].request_type, 0x40);
    EXPECT_EQ(requests[1].request, 0x06);
    EXPECT_EQ(requests[1].value, 6);

    ASSERT_TRUE(device.setTilt(20));
    ASSERT_TRUE(device.setLed(KinectLed::kGreen));
    ASSERT_TRUE(device.setLed(KinectLed::kOff));
    requests = bus.emulator->requests();
    ASSERT_EQ(requests.size(), 5u);
    EXPECT_EQ(requests[2].request, 0x31);
    EXPECT_EQ(requests[2].value, 40);
    EXPECT_EQ(requests[3].request, 0x06);
    EXPECT_EQ(requests[3].value, 1);
    EXPECT_EQ(requests[4].value, 0);
    // The emulated encoder follows the request: the state reads 20 degrees.
    auto state = device.readState();
    ASSERT_TRUE(state) << state.status().toString();
    EXPECT_EQ(state->tilt_deg, 20);

    // Out of range: refused before anything is sent.
    const Status refused = device.setTilt(31.5);
    EXPECT_EQ(refused.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(refused.message().find("[-31, 31]"), std::string::npos) << refused.message();
    EXPECT_EQ(bus.emulator->requests().size(), 5u);
    EXPECT_TRUE(bus.emulator->unknownIoctls().empty());
}

TEST(KinectMotor, UnplugIsReportedAndReplugResumes) {
    MIXRAY_REQUIRE_UMOCKDEV();
    MotorBus bus;
    ASSERT_TRUE(bus.setUp());
    bus.emulator->setAccelerometer(0, 819, 0);
    DeviceConfig config = motorConfig();
    config.options = {{"tilt_deg", "10"}, {"rate_hz", "100"}};
    StreamingMotor motor;
    ASSERT_NO_FATAL_FAILURE(motor.start(config));
    KinectMotorDevice* device = motor.device;
    Graph& graph = motor.graph;
    FrameQueue& queue = *motor.queue;
    popSample(queue);
    EXPECT_TRUE(device->error());

    bus.emulator->unplug();
    ASSERT_TRUE(eventually([&] { return !device->error(); }));
    const Status lost = device->error();
    EXPECT_EQ(lost.code(), ErrorCode::kUnavailable);
    EXPECT_NE(lost.message().find("was lost"), std::string::npos) << lost.message();
    // Asked for while lost: refused now, set when the motor returns.
    EXPECT_EQ(device->setTilt(-4).code(), ErrorCode::kUnavailable);
    EXPECT_TRUE(graph.running());
    EXPECT_FALSE(queue.closed());
    while (queue.tryPop()) {
    }
    const uint64_t published = device->publishedSamples();

    bus.emulator->setAccelerometer(100, 700, -50);
    std::string why;
    ASSERT_TRUE(bus.emulator->replug(&why)) << why;
    ASSERT_TRUE(eventually([&] { return device->reconnects() == 1; }));
    EXPECT_TRUE(device->error()) << device->error().toString();
    ImuSample resumed;
    for (int i = 0; i < 100 && resumed.accel.x() == 0; ++i)
        resumed = popSample(queue);
    EXPECT_DOUBLE_EQ(resumed.accel.x(), 100 / kCountsPerG * kGravity);
    EXPECT_DOUBLE_EQ(resumed.accel.z(), -50 / kCountsPerG * kGravity);
    EXPECT_GT(device->publishedSamples(), published);
    // The tilt asked for while it was away reached the motor after the reconnect.
    const auto requests = bus.emulator->requests();
    ASSERT_FALSE(requests.empty());
    EXPECT_EQ(requests.back().request, 0x31);
    EXPECT_EQ(static_cast<int16_t>(requests.back().value), -8);
    graph.stop();
}

TEST(KinectMotor, WithoutReconnectTheStreamEnds) {
    MIXRAY_REQUIRE_UMOCKDEV();
    MotorBus bus;
    ASSERT_TRUE(bus.setUp());
    DeviceConfig config = motorConfig();
    config.options = {{"reconnect", "false"}, {"rate_hz", "100"}};
    StreamingMotor motor;
    ASSERT_NO_FATAL_FAILURE(motor.start(config));
    KinectMotorDevice* device = motor.device;
    FrameQueue& queue = *motor.queue;
    popSample(queue);
    bus.emulator->unplug();
    ASSERT_TRUE(eventually([&] { return queue.closed(); }));
    EXPECT_EQ(device->error().code(), ErrorCode::kUnavailable);
    EXPECT_NE(device->error().message().find("its stream ends"), std::string::npos)
        << device->error().message();
    std::string why;
    ASSERT_TRUE(bus.emulator->replug(&why)) << why;
    EXPECT_EQ(device->reconnects(), 0u);
    motor.graph.stop();
}

TEST(KinectMotor, OpensFromARigFile) {
    MIXRAY_REQUIRE_UMOCKDEV();
    MotorBus bus;
    ASSERT_TRUE(bus.setUp());
    auto rig = parseRig(R"(rig: tabletop
devices:
  - name: tilt
    driver: usb
    id: "045e:02b0@1/3"
    streams: [gravity]
    options: { tilt_deg: 15, led: yellow, rate_hz: 50 }
)",
                        "rig.yaml");
    ASSERT_TRUE(rig) << rig.status().toString();
    BackendRegistry registry;
    ASSERT_TRUE(registry.add(std::make_unique<UsbBackend>()));
    auto device = registry.open(rig->deviceConfigs().at(0));
    ASSERT_TRUE(device) << device.status().toString();
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(*device)));
    auto id = graph.findStream("tilt/gravity");
    ASSERT_TRUE(id);
    EXPECT_EQ(graph.stream(*id).nominal_fps, 50);
    const auto requests = bus.emulator->requests();
    ASSERT_EQ(requests.size(), 2u);
    EXPECT_EQ(requests[0].value, 30);  // 15 degrees
    EXPECT_EQ(requests[1].value, 3);   // yellow
}

TEST(KinectMotor, EnumeratedAndAbsentMotor) {
    MIXRAY_REQUIRE_UMOCKDEV();
    MotorBus bus;
    ASSERT_TRUE(bus.setUp());
    UsbBackend backend;
    auto devices = backend.enumerate();
    ASSERT_TRUE(devices);
    bool listed = false;
    for (const DeviceDescriptor& d : *devices)
        listed |= d.id == "045e:02b0@1/3" && d.model == "Kinect v1 motor";
    EXPECT_TRUE(listed);
    bus.emulator->unplug();
    auto absent = openMotor(motorConfig());
    ASSERT_FALSE(absent);
    EXPECT_EQ(absent.status().code(), ErrorCode::kNotFound);
}

}  // namespace
}  // namespace mixray::usb
