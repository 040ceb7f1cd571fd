// The V4L2 backend against an emulated UVC camera (umockdev): enumeration, format negotiation,
// controls and USERPTR streaming through a graph, checked byte for byte and stamp for stamp.
#include <gtest/gtest.h>
#include <linux/videodev2.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "mixray/graph/clock.h"
#include "mixray/graph/rig.h"
#include "mixray/v4l2/mjpeg.h"
#include "mixray/v4l2/v4l2_backend.h"
#include "test_data.h"
#include "umockdev_preload.h"
#include "uvc_emulator.h"

namespace mixray::v4l2 {
namespace {

using std::chrono::seconds;
using test::UvcEmulator;

using mixray::test::kUmockdevPreload;

// umockdev redirects /dev and /sys through its preload library, which main() puts in place;
// the emulator is skipped only when umockdev itself is missing.
std::unique_ptr<UvcEmulator> emulator() {
    if (!mixray::test::umockdevPreloaded())
        return nullptr;
    std::string why;
    auto e = UvcEmulator::create(&why);
    EXPECT_TRUE(e) << why;
    return e;
}

#define MIXRAY_REQUIRE_EMULATOR(e)                                                          \
    auto e = emulator();                                                                    \
    if (!e) {                                                                               \
        if (::testing::Test::HasFailure())                                                  \
            return;                                                                         \
        GTEST_SKIP() << "umockdev's preload library (" << kUmockdevPreload                  \
                     << ") is not installed (Debian package umockdev): no emulated camera"; \
    }

DeviceConfig config(std::map<std::string, std::string> options, std::string id = "") {
    DeviceConfig c;
    c.name = "webcam";
    c.driver = "v4l2";
    c.id = std::move(id);
    c.options = std::move(options);
    return c;
}

std::unique_ptr<V4l2Device> openDevice(const DeviceConfig& c) {
    V4l2Backend backend;
    auto device = backend.open(c);
    EXPECT_TRUE(device) << device.status().toString();
    if (!device)
        return nullptr;
    return std::unique_ptr<V4l2Device>(static_cast<V4l2Device*>(device->release()));
}

struct Capture {
    Graph graph;
    V4l2Device* device = nullptr;
    std::shared_ptr<FrameQueue> queue;
};

// Opens the device into a graph with a lossless edge that holds every frame of a short run.
std::unique_ptr<Capture> capture(const DeviceConfig& c) {
    auto cap = std::make_unique<Capture>();
    auto device = openDevice(c);
    if (!device)
        return nullptr;
    cap->device = device.get();
    EXPECT_TRUE(cap->graph.addNode(std::move(device)));
    auto queue =
        cap->graph.subscribe(cap->device->streamId(), {64, QueuePolicy::kLossless, "v4l2_test"});
    EXPECT_TRUE(queue);
    if (!queue)
        return nullptr;
    cap->queue = *queue;
    return cap;
}

std::vector<FrameRef> take(FrameQueue& queue, size_t n) {
    std::vector<FrameRef> out;
    while (out.size() < n) {
        auto frame = queue.pop(seconds(10));
        if (!frame)
            break;
        out.push_back(std::move(*frame));
    }
    return out;
}

TEST(V4l2Backend, EnumeratesTheCaptureNodeOnly) {
    MIXRAY_REQUIRE_EMULATOR(e);
    V4l2Backend backend;
    EXPECT_EQ(backend.name(), "v4l2");
    auto devices = backend.enumerate();
    ASSERT_TRUE(devices) << devices.status().toString();
    // /dev/video1 is the camera's metadata node: it does not capture video.
    ASSERT_EQ(devices->size(), 1u);
    const DeviceDescriptor& d = devices->front();
    EXPECT_EQ(d.backend, "v4l2");
    EXPECT_EQ(d.id, "/dev/video0");
    EXPECT_EQ(d.model, "mixray UVC emulator");
    EXPECT_EQ(d.location, "usb-0000:00:14.0-1");
    EXPECT_EQ(d.modes, (std::vector<std::string>{"yuyv 320x240@30", "yuyv 640x480@30",
                                                 "mjpeg 320x240@30", "mjpeg 1280x720@30"}));
    auto meta = describeNode("/dev/video1");
    ASSERT_FALSE(meta);
    EXPECT_EQ(meta.status().code(), ErrorCode::kUnsupported);

    // By card name, by node name and with no id at all: the same node.
    for (const std::string id : {"mixray UVC emulator", "video0", ""}) {
        auto device = openDevice(config({}, id));
        ASSERT_TRUE(device) << id;
        EXPECT_EQ(device->path(), "/dev/video0");
    }
    auto missing = backend.open(config({}, "No Such Camera"));
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
}

TEST(V4l2Options, RefusesBadValuesAndUnknownKeys) {
    EXPECT_TRUE(V4l2Options::fromConfig(config({})));
    const std::vector<std::map<std::string, std::string>> bad = {
        {{"color.format", "bgr8"}},
        {{"color.width", "7"}},
        {{"io", "dma"}},
        {{"width", "640"}},
        {{"buffers", "1"}},
        {{"color.fps", "-3"}},
        {{"role", "sun"}},
        {{"ctrl.Exposure", "1"}},
        {{"ctrl.brightness", "x"}},
        {{"exposure", "100"}},
        {{"color.width", "321"}},
        {{"exposure_us", "0"}},
        {{"auto_white_balance", "maybe"}},
        {{"role", "environment"}, {"auto_white_balance", "true"}},
    };
    for (const auto& options : bad) {
        auto o = V4l2Options::fromConfig(config(options));
        ASSERT_FALSE(o) << options.begin()->first;
        EXPECT_EQ(o.status().code(), ErrorCode::kInvalidArgument);
        EXPECT_NE(o.status().message().find("webcam"), std::string::npos);
    }
    auto o = V4l2Options::fromConfig(
        config({{"color.format", "rgb8"}, {"io", "userptr"}, {"ctrl.brightness", "-5"}}));
    ASSERT_TRUE(o) << o.status().toString();
    EXPECT_EQ(o->fourcc, V4L2_PIX_FMT_MJPEG);
    EXPECT_TRUE(o->decode_rgb);
    EXPECT_EQ(o->io, IoMethod::kUserPtr);
    EXPECT_EQ(o->controls.at("brightness"), -5);
    EXPECT_EQ(controlKey("White Balance Temperature, Auto"), "white_balance_temperature_auto");
}

TEST(V4l2Device, RefusesAModeTheCameraDoesNotHave) {
    MIXRAY_REQUIRE_EMULATOR(e);
    V4l2Backend backend;
    auto device = backend.open(config({{"color.width", "1280"}, {"color.height", "960"}}));
    ASSERT_FALSE(device);
    EXPECT_EQ(device.status().code(), ErrorCode::kUnsupported);
    EXPECT_NE(device.status().message().find("yuyv 640x480@30"), std::string::npos)
        << device.status().message();
    auto rate = backend.open(
        config({{"color.fps", "60"}, {"color.width", "320"}, {"color.height", "240"}}));
    ASSERT_FALSE(rate);
    EXPECT_EQ(rate.status().code(), ErrorCode::kUnsupported);
}

TEST(V4l2Device, SetsTheFrameRate) {
    MIXRAY_REQUIRE_EMULATOR(e);
    auto cap = capture(config({{"color.fps", "15"}}));
    ASSERT_TRUE(cap);
    EXPECT_EQ(cap->graph.stream(cap->device->streamId()).nominal_fps, 15.0);
    EXPECT_EQ(cap->device->format(), (ImageDesc{PixelFormat::kYUYV, 640, 480, 1280}));
}

TEST(V4l2Device, StreamsYuyvThroughUserPtrBuffers) {
    MIXRAY_REQUIRE_EMULATOR(e);
    auto cap = capture(config({{"io", "userptr"},
                               {"color.width", "320"},
                               {"color.height", "240"},
                               {"color.fps", "30"},
                               {"pool", "16"}}));
    ASSERT_TRUE(cap);
    const StreamInfo info = cap->graph.stream(cap->device->streamId());
    EXPECT_EQ(info.name, "webcam/color");
    EXPECT_EQ(info.kind, StreamKind::kColor);
    EXPECT_EQ(info.format, (ImageDesc{PixelFormat::kYUYV, 320, 240, 640}));
    EXPECT_EQ(info.clock_domain, kHostClockDomain);
    EXPECT_EQ(info.nominal_fps, 30.0);

    // Two start/stop cycles of the device: buffers are requested, queued and freed each time
    // (the graph's own stop closes its queues for good).
    ASSERT_TRUE(cap->graph.start());
    for (int cycle = 0; cycle < 2; ++cycle) {
        if (cycle > 0) {
            ASSERT_TRUE(cap->device->start());
        }
        const auto frames = take(*cap->queue, 8);
        const int64_t after_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                     std::chrono::steady_clock::now().time_since_epoch())
                                     .count();
        cap->device->stop();
        EXPECT_FALSE(e->streaming());
        // Frames published after the eighth, before the stop.
        while (cap->queue->tryPop()) {
        }
        ASSERT_EQ(frames.size(), 8u) << cap->device->error().toString();
        const auto stamps = e->stamps();
        ClockSync sync;
        for (size_t i = 0; i < frames.size(); ++i) {
            const FrameMetadata& m = frames[i].meta();
            const ImageView v = frames[i].image();
            ASSERT_EQ(m.sequence, i);
            EXPECT_EQ(m.status, FrameStatus::kOk);
            EXPECT_EQ(m.clock_domain, kHostClockDomain);
            EXPECT_EQ(m.exposure_us, -1);  // auto exposure: the time is the camera's secret
            ASSERT_TRUE(stamps.count(m.sequence));
            EXPECT_EQ(m.device_stamp_ns, stamps.at(m.sequence));
            // The kernel stamps capture; the frame is dequeued later, and before the test's
            // clock reading.
            EXPECT_GE(m.host_stamp_ns, m.device_stamp_ns);
            EXPECT_LE(m.host_stamp_ns, after_ns);
            EXPECT_EQ(sync.observe(m), m.device_stamp_ns);
            if (i > 0) {
                EXPECT_GT(m.device_stamp_ns, frames[i - 1].meta().device_stamp_ns);
            }
            ASSERT_EQ(v.desc, info.format);
            size_t wrong = 0;
            for (int y = 0; y < 240; ++y) {
                const uint8_t* row = v.row<uint8_t>(y);
                for (int x = 0; x < 640; ++x)
                    wrong += row[x] != test::yuyvByte(m.sequence, x, y);
            }
            EXPECT_EQ(wrong, 0u) << "frame " << i;
        }
        EXPECT_EQ(e->streamOnCount(), static_cast<uint32_t>(cycle + 1));
        EXPECT_EQ(cap->device->sequenceGaps(), 0u);
        EXPECT_TRUE(cap->device->error());
    }
    cap->graph.stop();
}

TEST(V4l2Device, KeepsMjpegCompressedOrDecodesIt) {
    MIXRAY_REQUIRE_EMULATOR(e);
    {
        auto cap = capture(config({{"io", "userptr"},
                                   {"color.format", "mjpeg"},
                                   {"color.width", "320"},
                                   {"color.height", "240"},
                                   {"pool", "16"}}));
        ASSERT_TRUE(cap);
        EXPECT_EQ(cap->device->format().format, PixelFormat::kMJPEG);
        ASSERT_TRUE(cap->graph.start());
        const auto frames = take(*cap->queue, 4);
        cap->graph.stop();
        ASSERT_EQ(frames.size(), 4u);
        for (const auto& f : frames) {
            const auto jpeg = test::mjpegFrame(f.meta().sequence, 320, 240);
            const ImageView v = f.image();
            ASSERT_EQ(v.size_bytes, jpeg.size());
            EXPECT_EQ(std::memcmp(v.data, jpeg.data(), jpeg.size()), 0);
            auto size = mjpegSize(v.data, v.size_bytes);
            ASSERT_TRUE(size);
            EXPECT_EQ(size->width, 320);
            EXPECT_EQ(size->height, 240);
        }
    }
    auto cap = capture(config({{"io", "userptr"},
                               {"color.format", "rgb8"},
                               {"color.width", "320"},
                               {"color.height", "240"},
                               {"pool", "16"}}));
    ASSERT_TRUE(cap);
    EXPECT_EQ(cap->device->format(), ImageDesc::packed(PixelFormat::kRGB8, 320, 240));
    ASSERT_TRUE(cap->graph.start());
    const auto frames = take(*cap->queue, 3);
    cap->graph.stop();
    ASSERT_EQ(frames.size(), 3u);
    for (const auto& f : frames) {
        std::vector<uint8_t> source;
        const auto jpeg = test::mjpegFrame(f.meta().sequence, 320, 240, &source);
        // OpenCV decodes the same bytes with its own libjpeg set-up: the two must agree.
        cv::Mat bgr = cv::imdecode(jpeg, cv::IMREAD_COLOR);
        cv::Mat rgb;
        cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
        const cv::Mat ours(240, 320, CV_8UC3, const_cast<uint8_t*>(f.image().data));
        double max_diff = cv::norm(ours, rgb, cv::NORM_INF);
        EXPECT_LE(max_diff, 1.0) << "sequence " << f.meta().sequence;
        // And the image is the one the camera encoded (JPEG quality 90).
        const cv::Mat original(240, 320, CV_8UC3, source.data());
        EXPECT_GT(cv::PSNR(ours, original), 30.0);
    }
    EXPECT_EQ(cap->device->decodeErrors(), 0u);
}

TEST(V4l2Device, SetsAndReadsBackControls) {
    MIXRAY_REQUIRE_EMULATOR(e);
    auto device = openDevice(config({{"ctrl.brightness", "12"}}));
    ASSERT_TRUE(device);
    std::vector<std::string> keys;
    for (const auto& c : device->controls())
        keys.push_back(c.key);
    EXPECT_EQ(keys, (std::vector<std::string>{"brightness", "white_balance_automatic",
                                              "white_balance_temperature", "auto_exposure",
                                              "exposure_time_absolute"}));
    EXPECT_EQ(e->control(V4L2_CID_BRIGHTNESS), 12);
    ASSERT_TRUE(device->control("brightness"));
    EXPECT_EQ(*device->control("brightness"), 12);
    ASSERT_TRUE(device->setControl("brightness", -30));
    EXPECT_EQ(e->control(V4L2_CID_BRIGHTNESS), -30);
    EXPECT_EQ(device->setControl("brightness", 100).code(), ErrorCode::kInvalidArgument);
    EXPECT_EQ(device->control("gain").status().code(), ErrorCode::kNotFound);
    // Auto exposure is on: the camera refuses a manual exposure time, as uvcvideo does.
    EXPECT_EQ(device->setControl("exposure_time_absolute", 300).code(), ErrorCode::kIoError);
    EXPECT_EQ(e->control(V4L2_CID_EXPOSURE_ABSOLUTE), 156);

    V4l2Backend backend;
    auto unknown = backend.open(config({{"ctrl.gain", "3"}}));
    ASSERT_FALSE(unknown);
    EXPECT_EQ(unknown.status().code(), ErrorCode::kNotFound);
}

TEST(V4l2Device, EnvironmentCameraLocksExposureAndWhiteBalance) {
    MIXRAY_REQUIRE_EMULATOR(e);
    auto device = openDevice(config({{"role", "environment"},
                                     {"ctrl.exposure_time_absolute", "300"},
                                     {"ctrl.white_balance_temperature", "5000"}}));
    ASSERT_TRUE(device);
    EXPECT_EQ(e->control(V4L2_CID_EXPOSURE_AUTO), V4L2_EXPOSURE_MANUAL);
    EXPECT_EQ(e->control(V4L2_CID_AUTO_WHITE_BALANCE), 0);
    EXPECT_EQ(e->control(V4L2_CID_EXPOSURE_ABSOLUTE), 300);
    EXPECT_EQ(e->control(V4L2_CID_WHITE_BALANCE_TEMPERATURE), 5000);
    EXPECT_EQ(*device->control("auto_exposure"), V4L2_EXPOSURE_MANUAL);
}

// The fish-eye environment camera of the tabletop rig fixture, as the rig file asks for it:
// 1280x720@30 MJPEG, exposure 8 ms, automatic white balance off.
TEST(V4l2Device, OpensTheRigFixturesEnvironmentCamera) {
    MIXRAY_REQUIRE_EMULATOR(e);
    auto rig = loadRig(mixray::test::fixturesDir() / "rigs" / "kinect_env.yaml");
    ASSERT_TRUE(rig) << rig.status().toString();
    const RigDevice* env = nullptr;
    for (const auto& d : rig->devices) {
        if (d.config.name == "env")
            env = &d;
    }
    ASSERT_NE(env, nullptr);
    DeviceConfig c = env->config;
    EXPECT_EQ(c.id, "/dev/video2");
    c.id = "/dev/video0";  // the emulated camera's node
    c.options["io"] = "userptr";
    BackendRegistry registry;
    ASSERT_TRUE(registry.add(std::make_unique<V4l2Backend>()));
    auto opened = registry.open(c);
    ASSERT_TRUE(opened) << opened.status().toString();
    Graph graph;
    auto* device = static_cast<V4l2Device*>(opened->get());
    ASSERT_TRUE(graph.addNode(std::move(*opened)));
    EXPECT_EQ(e->control(V4L2_CID_EXPOSURE_AUTO), V4L2_EXPOSURE_MANUAL);
    EXPECT_EQ(e->control(V4L2_CID_EXPOSURE_ABSOLUTE), 80);
    EXPECT_EQ(e->control(V4L2_CID_AUTO_WHITE_BALANCE), 0);
    const auto stream = graph.findStream("env/color");
    ASSERT_TRUE(stream);
    EXPECT_EQ(graph.stream(*stream).format, (ImageDesc{PixelFormat::kMJPEG, 1280, 720, 0}));
    EXPECT_EQ(graph.stream(*stream).nominal_fps, 30.0);
    auto queue = graph.subscribe(*stream, {8, QueuePolicy::kLossless, "v4l2_test"});
    ASSERT_TRUE(queue);
    ASSERT_TRUE(graph.start());
    const auto frames = take(**queue, 2);
    graph.stop();
    ASSERT_EQ(frames.size(), 2u) << device->error().toString();
    for (const auto& f : frames) {
        EXPECT_EQ(f.meta().exposure_us, 8000);
        const auto jpeg = test::mjpegFrame(f.meta().sequence, 1280, 720);
        ASSERT_EQ(f.image().size_bytes, jpeg.size());
        EXPECT_EQ(std::memcmp(f.image().data, jpeg.data(), jpeg.size()), 0);
    }
}

TEST(V4l2Device, FlagsDriverErrorsAndCountsLostFrames) {
    MIXRAY_REQUIRE_EMULATOR(e);
    e->setErrorFrames({2});
    e->setSkippedFrames({4});
    auto cap = capture(config(
        {{"io", "userptr"}, {"color.width", "320"}, {"color.height", "240"}, {"pool", "16"}}));
    ASSERT_TRUE(cap);
    ASSERT_TRUE(cap->graph.start());
    const auto frames = take(*cap->queue, 6);
    cap->graph.stop();
    ASSERT_EQ(frames.size(), 6u);
    std::vector<uint64_t> sequences;
    for (const auto& f : frames) {
        sequences.push_back(f.meta().sequence);
        EXPECT_EQ(f.meta().status,
                  f.meta().sequence == 2 ? FrameStatus::kIncomplete : FrameStatus::kOk);
    }
    EXPECT_EQ(sequences, (std::vector<uint64_t>{0, 1, 2, 3, 5, 6}));
    EXPECT_EQ(cap->device->sequenceGaps(), 1u);
    // The frame the driver skipped is lost where commands report losses, too.
    EXPECT_EQ(cap->graph.lostCount(cap->device->streamId()), 1u);
}

TEST(V4l2Device, StampsThatAreNotMonotonicGetAClockDomain) {
    MIXRAY_REQUIRE_EMULATOR(e);
    e->setUnknownClock(true);
    auto cap = capture(config(
        {{"io", "userptr"}, {"color.width", "320"}, {"color.height", "240"}, {"pool", "16"}}));
    ASSERT_TRUE(cap);
    ASSERT_TRUE(cap->graph.start());
    const auto frames = take(*cap->queue, 4);
    cap->graph.stop();
    ASSERT_EQ(frames.size(), 4u);
    const auto stamps = e->stamps();
    ClockSync sync;
    for (const auto& f : frames) {
        EXPECT_NE(f.meta().clock_domain, kHostClockDomain);
        EXPECT_EQ(f.meta().device_stamp_ns, stamps.at(f.meta().sequence));
        // Counted from streaming on, far from host time: the clock model maps it over.
        EXPECT_LT(f.meta().device_stamp_ns, 1'000'000'000);
        const int64_t common = sync.observe(f.meta());
        EXPECT_LE(common, f.meta().host_stamp_ns);
        EXPECT_GT(common, f.meta().host_stamp_ns - 1'000'000'000);
    }
}

TEST(V4l2Device, MmapNeedsRealHardware) {
    MIXRAY_REQUIRE_EMULATOR(e);
    auto cap = capture(config({{"io", "mmap"}, {"color.width", "320"}, {"color.height", "240"}}));
    ASSERT_TRUE(cap);
    const Status s = cap->graph.start();
    ASSERT_FALSE(s);
    EXPECT_EQ(s.code(), ErrorCode::kUnsupported);
    EXPECT_NE(s.message().find("VIDIOC_REQBUFS (mmap)"), std::string::npos) << s.message();
}

TEST(V4l2Device, AnUnpluggedCameraEndsItsStreamWithoutReconnect) {
    MIXRAY_REQUIRE_EMULATOR(e);
    auto cap = capture(config({{"io", "userptr"},
                               {"color.width", "320"},
                               {"color.height", "240"},
                               {"pool", "16"},
                               {"reconnect", "false"}}));
    ASSERT_TRUE(cap);
    ASSERT_TRUE(cap->graph.start());
    ASSERT_EQ(take(*cap->queue, 2).size(), 2u);
    e->unplug();
    // The stream ends: the queue closes once the frames already in it are taken.
    take(*cap->queue, 1000);
    EXPECT_TRUE(cap->queue->closed());
    const Status error = cap->device->error();
    EXPECT_EQ(error.code(), ErrorCode::kUnavailable) << error.toString();
    cap->graph.stop();
}

// Waits until `done` holds, for at most 10 s (a bound against a hang, not a timing check).
template <typename Predicate>
bool eventually(Predicate done) {
    const auto deadline = std::chrono::steady_clock::now() + seconds(10);
    while (!done()) {
        if (std::chrono::steady_clock::now() > deadline)
            return false;
        usleep(2000);
    }
    return true;
}

TEST(V4l2Device, AnUnpluggedCameraResumesWhenItComesBack) {
    MIXRAY_REQUIRE_EMULATOR(e);
    auto cap = capture(config({{"io", "userptr"},
                               {"color.width", "640"},
                               {"color.height", "480"},
                               {"pool", "16"},
                               {"ctrl.brightness", "12"}}));
    ASSERT_TRUE(cap);
    ASSERT_TRUE(cap->graph.start());
    ASSERT_EQ(take(*cap->queue, 3).size(), 3u);
    e->unplug();
    ASSERT_TRUE(eventually([&] { return !cap->device->error().isOk(); }));
    EXPECT_EQ(cap->device->error().code(), ErrorCode::kUnavailable);
    EXPECT_NE(cap->device->error().message().find("lost"), std::string::npos);
    // Frames dequeued before the loss may still be queued; the stream itself goes on.
    while (cap->queue->tryPop()) {
    }
    EXPECT_FALSE(cap->queue->closed());

    // Plugged in again, the camera has forgotten its format and controls: both are set again.
    e->replug();
    const auto frames = take(*cap->queue, 3);
    ASSERT_EQ(frames.size(), 3u) << cap->device->error().toString();
    EXPECT_TRUE(cap->device->error()) << cap->device->error().toString();
    EXPECT_EQ(cap->device->reconnects(), 1u);
    EXPECT_EQ(e->control(V4L2_CID_BRIGHTNESS), 12);
    EXPECT_EQ(e->streamOnCount(), 2u);
    for (size_t i = 0; i < frames.size(); ++i) {
        // The driver counts from 0 again after the replug.
        EXPECT_EQ(frames[i].meta().sequence, i);
        EXPECT_EQ(frames[i].image().desc, (ImageDesc{PixelFormat::kYUYV, 640, 480, 1280}));
        EXPECT_EQ(frames[i].image().data[640 * 2 * 7 + 100], test::yuyvByte(i, 100, 7));
    }
    cap->graph.stop();
    EXPECT_FALSE(e->streaming());
}

TEST(Mjpeg, RefusesWhatIsNotAJpeg) {
    const std::vector<uint8_t> junk(100, 0x42);
    EXPECT_EQ(mjpegSize(junk.data(), junk.size()).status().code(), ErrorCode::kCorruptData);
    auto jpeg = test::mjpegFrame(0, 32, 16);
    Image out(ImageDesc::packed(PixelFormat::kRGB8, 32, 16));
    EXPECT_TRUE(decodeMjpegToRgb(jpeg.data(), jpeg.size(), out.mutableView()));
    EXPECT_EQ(decodeMjpegToRgb(jpeg.data(), jpeg.size() / 3, out.mutableView()).code(),
              ErrorCode::kCorruptData);
    Image wrong(ImageDesc::packed(PixelFormat::kRGB8, 16, 16));
    EXPECT_EQ(decodeMjpegToRgb(jpeg.data(), jpeg.size(), wrong.mutableView()).code(),
              ErrorCode::kCorruptData);
}

}  // namespace
}  // namespace mixray::v4l2

int main(int argc, char** argv) {
    mixray::test::reexecWithUmockdevPreload(argc, argv);
    testing::InitGoogleTest(&argc, argv);
    return RUN_ALL_TESTS();
}
