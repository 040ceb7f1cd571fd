// The openni2 backend against its real peers: OpenNI2 2.2 playing a Kinect v1 recording
// (checked against what OpenNI2's own API reports for the same file) and OpenNI2's DummyDevice
// driver as a live device.
#include <OpenNI.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <map>
#include <memory>
#include <thread>
#include <vector>

#include "mixray/graph/clock.h"
#include "mixray/graph/graph.h"
#include "mixray/openni2/openni2_backend.h"
#include "test_data.h"

namespace mixray::openni2 {
namespace {

using std::chrono::seconds;

// One frame as OpenNI2's own API reports it.
struct RawFrame {
    int index = 0;
    uint64_t timestamp_us = 0;
    int width = 0;
    int height = 0;
    std::vector<uint8_t> pixels;  // packed rows
};

// Reads every frame of the recording directly through openni::Device, in manual playback.
std::map<openni::SensorType, std::vector<RawFrame>> readDirectly(const std::string& path) {
    std::map<openni::SensorType, std::vector<RawFrame>> out;
    // The backend initialises OpenNI2 for the whole process first (see openni2_backend.cpp),
    // so this test's own initialize/shutdown pair never shuts it down.
    EXPECT_TRUE(OpenNI2Backend().enumerate());
    EXPECT_EQ(openni::OpenNI::initialize(), openni::STATUS_OK);
    {
        openni::Device device;
        EXPECT_EQ(device.open(path.c_str()), openni::STATUS_OK);
        openni::PlaybackControl* playback = device.getPlaybackControl();
        EXPECT_NE(playback, nullptr);
        if (!playback) {
            openni::OpenNI::shutdown();
            return out;
        }
        playback->setSpeed(-1);
        playback->setRepeatEnabled(false);
        openni::VideoStream depth;
        openni::VideoStream color;
        EXPECT_EQ(depth.create(device, openni::SENSOR_DEPTH), openni::STATUS_OK);
        EXPECT_EQ(color.create(device, openni::SENSOR_COLOR), openni::STATUS_OK);
        const int depth_count = playback->getNumberOfFrames(depth);
        const int color_count = playback->getNumberOfFrames(color);
        EXPECT_EQ(depth.start(), openni::STATUS_OK);
        EXPECT_EQ(color.start(), openni::STATUS_OK);
        openni::VideoStream* streams[] = {&depth, &color};
        while (static_cast<int>(out[openni::SENSOR_DEPTH].size()) < depth_count ||
               static_cast<int>(out[openni::SENSOR_COLOR].size()) < color_count) {
            int index = -1;
            if (openni::OpenNI::waitForAnyStream(streams, 2, &index, 2000) != openni::STATUS_OK)
                break;
            openni::VideoFrameRef frame;
            EXPECT_EQ(streams[index]->readFrame(&frame), openni::STATUS_OK);
            RawFrame raw;
            raw.index = frame.getFrameIndex();
            raw.timestamp_us = frame.getTimestamp();
            raw.width = frame.getWidth();
            raw.height = frame.getHeight();
            const size_t row = static_cast<size_t>(frame.getDataSize() / frame.getHeight());
            const auto* data = static_cast<const uint8_t*>(frame.getData());
            for (int y = 0; y < raw.height; ++y) {
                const uint8_t* in = data + static_cast<size_t>(y) * frame.getStrideInBytes();
                raw.pixels.insert(raw.pixels.end(), in, in + row);
            }
            out[frame.getSensorType()].push_back(std::move(raw));
        }
        depth.stop();
        color.stop();
        depth.destroy();
        color.destroy();
        device.close();
    }
    openni::OpenNI::shutdown();
    return out;
}

DeviceConfig kinectConfig(std::map<std::string, std::string> options) {
    DeviceConfig config;
    config.name = "kinect";
    config.driver = "openni2";
    config.id = test::kinectV1Oni().string();
    config.options = std::move(options);
    return config;
}

// A graph with one openni2 device and a lossless queue per stream.
struct Session {
    Graph graph;
    OpenNI2Device* device = nullptr;
    std::map<std::string, std::shared_ptr<FrameQueue>> queues;
};

Status startSession(Session& session, const DeviceConfig& config) {
    OpenNI2Backend backend;
    auto opened = backend.open(config);
    if (!opened)
        return opened.status();
    session.device = static_cast<OpenNI2Device*>(opened->get());
    MIXRAY_RETURN_IF_ERROR(session.graph.addNode(std::move(*opened)));
    for (const StreamInfo& info : session.graph.streams()) {
        auto queue = session.graph.subscribe(*session.graph.findStream(info.name),
                                             {64, QueuePolicy::kLossless, "test"});
        if (!queue)
            return queue.status();
        session.queues[info.name] = *queue;
    }
    return session.graph.start();
}

// A private copy of `frame` (the test holds frames longer than the device's few buffers).
FrameRef copyFrame(const FrameRef& frame) {
    const ImageView view = frame.image();
    auto pool = BufferPool::create({view.desc, view.size_bytes, 1, "copy"});
    WritableFrame out = pool->acquire();
    std::memcpy(out.image().data, view.data, view.size_bytes);
    out.meta() = frame.meta();
    return std::move(out).publish();
}

std::vector<FrameRef> drain(FrameQueue& queue, size_t at_most = 1000) {
    std::vector<FrameRef> out;
    while (out.size() < at_most) {
        auto frame = queue.pop(seconds(10));
        if (!frame)
            break;
        out.push_back(std::move(*frame));
    }
    return out;
}

// Pixel (x, y) of the un-mirrored frame is pixel (width-1-x, y) of the recorded one.
bool equalsUnmirrored(const FrameRef& frame, const RawFrame& raw) {
    const ImageView view = frame.image();
    const size_t pixel = pixelFormatInfo(view.desc.format).bits_per_pixel / 8;
    const size_t row = static_cast<size_t>(raw.width) * pixel;
    for (int y = 0; y < raw.height; ++y) {
        const uint8_t* ours = view.row<uint8_t>(y);
        const uint8_t* theirs = raw.pixels.data() + static_cast<size_t>(y) * row;
        for (int x = 0; x < raw.width; ++x) {
            if (std::memcmp(ours + static_cast<size_t>(x) * pixel,
                            theirs + static_cast<size_t>(raw.width - 1 - x) * pixel, pixel) != 0) {
                return false;
            }
        }
    }
    return true;
}

TEST(OpenNI2Options, RefusesUnknownKeysAndBadValues) {
    DeviceConfig config;
    config.name = "k";
    config.options = {{"mirror", "off"}};
    EXPECT_EQ(OpenNI2Options::fromConfig(config).status().code(), ErrorCode::kInvalidArgument);
    config.options = {{"registration", "maybe"}};
    auto bad = OpenNI2Options::fromConfig(config);
    ASSERT_FALSE(bad);
    EXPECT_NE(bad.status().message().find("registration"), std::string::npos);
    config.options = {{"pace", "fast"}, {"speed", "2"}};
    EXPECT_EQ(OpenNI2Options::fromConfig(config).status().code(), ErrorCode::kInvalidArgument);
    config.options = {{"streams", "depth,sonar"}};
    EXPECT_EQ(OpenNI2Options::fromConfig(config).status().code(), ErrorCode::kInvalidArgument);
    config.options = {{"depth.width", "-3"}};
    EXPECT_EQ(OpenNI2Options::fromConfig(config).status().code(), ErrorCode::kInvalidArgument);
    config.options = {{"depth.fps", "29.97"}};
    EXPECT_EQ(OpenNI2Options::fromConfig(config).status().code(), ErrorCode::kInvalidArgument);
    config.options = {{"color.format", "rgb9"}};
    EXPECT_EQ(OpenNI2Options::fromConfig(config).status().code(), ErrorCode::kInvalidArgument);
    config.options = {{"streams", "depth"}, {"color.fps", "30"}};
    EXPECT_EQ(OpenNI2Options::fromConfig(config).status().code(), ErrorCode::kInvalidArgument);
    config.options = {{"reconnect", "later"}};
    auto reconnect = OpenNI2Options::fromConfig(config);
    ASSERT_FALSE(reconnect);
    EXPECT_NE(reconnect.status().message().find("reconnect"), std::string::npos);
    config.options = {};
    EXPECT_TRUE(OpenNI2Options::fromConfig(config)->reconnect);
    config.options = {{"reconnect", "false"}};
    EXPECT_FALSE(OpenNI2Options::fromConfig(config)->reconnect);

    config.options = {{"streams", "ir, depth"}, {"depth.width", "640"}, {"seek", "3"},
                      {"loop", "on"},           {"buffers", "16"},      {"clock_domain", "7"}};
    auto good = OpenNI2Options::fromConfig(config);
    ASSERT_TRUE(good) << good.status().toString();
    ASSERT_EQ(good->streams.size(), 2u);
    EXPECT_EQ(good->streams[0].sensor, Sensor::kInfrared);
    EXPECT_EQ(good->streams[1].sensor, Sensor::kDepth);
    EXPECT_EQ(good->streams[1].width, 0);
    ASSERT_EQ(good->modes.size(), 1u);
    EXPECT_EQ(good->modes[0].sensor, Sensor::kDepth);
    EXPECT_EQ(good->modes[0].width, 640);
    EXPECT_EQ(good->seek, 3);
    EXPECT_TRUE(good->loop);
    EXPECT_EQ(good->buffers, 16u);
    EXPECT_EQ(good->clock_domain, 7u);
}

// The Kinect v1 recording plays through the backend exactly as OpenNI2 itself reads it.
TEST(OpenNI2Recording, PlaysLikeOpenNI2ReadsIt) {
    MIXRAY_REQUIRE_SHARED_DATA(test::kinectV1Oni());
    const auto raw = readDirectly(test::kinectV1Oni().string());
    ASSERT_EQ(raw.at(openni::SENSOR_DEPTH).size(), 12u);
    ASSERT_EQ(raw.at(openni::SENSOR_COLOR).size(), 12u);

    Session session;
    ASSERT_TRUE(startSession(session, kinectConfig({{"pace", "fast"}, {"buffers", "32"}})));
    ASSERT_TRUE(session.device->isRecording());
    EXPECT_EQ(session.device->recordedFrameCounts(), (std::vector<int>{12, 12}));
    // The recording was made with mirroring on, which playback cannot turn off.
    EXPECT_EQ(session.device->softwareUnmirror(), (std::vector<bool>{true, true}));
    const auto depth = drain(*session.queues.at("kinect/depth"));
    const auto color = drain(*session.queues.at("kinect/color"));
    session.graph.stop();
    EXPECT_TRUE(session.device->status()) << session.device->status().toString();
    EXPECT_TRUE(session.device->finished());
    EXPECT_EQ(session.device->droppedFrames(), 0u);

    const StreamInfo depth_info = session.graph.stream(*session.graph.findStream("kinect/depth"));
    EXPECT_EQ(depth_info.kind, StreamKind::kDepth);
    EXPECT_EQ(depth_info.format, ImageDesc::packed(PixelFormat::kDepth16, 640, 480));
    EXPECT_EQ(depth_info.nominal_fps, 30);
    EXPECT_EQ(depth_info.clock_domain, defaultClockDomain("kinect"));
    const StreamInfo color_info = session.graph.stream(*session.graph.findStream("kinect/color"));
    EXPECT_EQ(color_info.format, ImageDesc::packed(PixelFormat::kRGB8, 640, 480));

    ASSERT_EQ(depth.size(), 12u);
    ASSERT_EQ(color.size(), 12u);
    for (const auto& [frames, reference] : {std::pair{&depth, &raw.at(openni::SENSOR_DEPTH)},
                                            std::pair{&color, &raw.at(openni::SENSOR_COLOR)}}) {
        for (size_t i = 0; i < frames->size(); ++i) {
            const FrameRef& f = (*frames)[i];
            const RawFrame& r = (*reference)[i];
            EXPECT_EQ(f.meta().sequence, static_cast<uint64_t>(r.index));
            EXPECT_EQ(f.meta().device_stamp_ns, static_cast<int64_t>(r.timestamp_us) * 1000);
            EXPECT_EQ(f.meta().clock_domain, defaultClockDomain("kinect"));
            EXPECT_EQ(f.image().desc.width, r.width);
            EXPECT_EQ(f.image().desc.height, r.height);
            EXPECT_TRUE(equalsUnmirrored(f, r)) << "frame " << r.index;
        }
    }
    // OpenNI2 numbers playback frames from 1 and rebases time to the first frame (colour).
    EXPECT_EQ(depth.front().meta().sequence, 1u);
    EXPECT_EQ(color.front().meta().device_stamp_ns, 0);
    EXPECT_EQ(depth.front().meta().device_stamp_ns, 11'680'000);
    EXPECT_EQ(depth.back().meta().device_stamp_ns, 378'742'000);

    // MANIFEST.md's numbers for the first depth frame.
    const ImageView first = depth.front().image();
    uint64_t valid = 0;
    uint64_t sum = 0;
    uint16_t max = 0;
    for (int y = 0; y < first.desc.height; ++y) {
        const uint16_t* row = first.row<uint16_t>(y);
        for (int x = 0; x < first.desc.width; ++x) {
            if (row[x] == 0)
                continue;
            ++valid;
            sum += row[x];
            max = std::max(max, row[x]);
        }
    }
    EXPECT_EQ(valid, 234942u);
    EXPECT_NEAR(static_cast<double>(sum) / static_cast<double>(valid), 2591.1, 0.05);
    EXPECT_EQ(max, 4521);
    // The recorded pixel (320, 240) is (319, 240) once un-mirrored.
    EXPECT_EQ(first.row<uint16_t>(240)[319], 2869);
}

// Device time goes through the graph's clock model: every mapped stamp is at or before the
// frame's arrival (the model fits the lower envelope), in device-time order.
TEST(OpenNI2Recording, DeviceStampsMapThroughTheClockModel) {
    MIXRAY_REQUIRE_SHARED_DATA(test::kinectV1Oni());
    Session session;
    ASSERT_TRUE(startSession(session, kinectConfig({{"speed", "1"}, {"buffers", "32"}})));
    const auto depth = drain(*session.queues.at("kinect/depth"));
    session.graph.stop();
    EXPECT_TRUE(session.device->status()) << session.device->status().toString();
    ASSERT_GE(depth.size(), 2u);
    EXPECT_LE(depth.size(), 12u);

    ClockSync sync;
    int64_t previous_device = -1;
    int64_t previous_common = INT64_MIN;
    for (const FrameRef& f : depth) {
        EXPECT_GT(f.meta().device_stamp_ns, previous_device);
        previous_device = f.meta().device_stamp_ns;
        const int64_t common = sync.observe(f.meta());
        EXPECT_GE(common, previous_common);
        previous_common = common;
    }
    for (const FrameRef& f : depth) {
        const auto mapped = sync.toHost(f.meta().clock_domain, f.meta().device_stamp_ns);
        ASSERT_TRUE(mapped);
        EXPECT_LE(*mapped, f.meta().host_stamp_ns);
    }
    const auto estimate = sync.estimate(defaultClockDomain("kinect"));
    ASSERT_TRUE(estimate);
    EXPECT_EQ(estimate->samples, depth.size());
}

// Both paces deliver every frame of the recording with its own stamps: host stamps keep the
// recorded intervals (OpenNI2's timed playback used to replace frames not yet read, and 8 of
// 12 depth frames reached the graph; fast playback stamped frames when they were read).
TEST(OpenNI2Recording, EveryFrameReachesTheGraphWithItsOwnTimingAtEitherPace) {
    MIXRAY_REQUIRE_SHARED_DATA(test::kinectV1Oni());
    for (const char* pace : {"original", "fast"}) {
        SCOPED_TRACE(pace);
        Session session;
        ASSERT_TRUE(startSession(session, kinectConfig({{"pace", pace}, {"buffers", "4"}})));
        const auto t0 = std::chrono::steady_clock::now();
        // A slow consumer: frames wait in the pool and the queue.
        std::vector<FrameRef> depth;
        std::vector<FrameRef> color;
        for (;;) {
            auto d = session.queues.at("kinect/depth")->pop(seconds(10));
            if (d) {
                depth.push_back(copyFrame(*d));
                std::this_thread::sleep_for(std::chrono::milliseconds(40));
            }
            auto c = session.queues.at("kinect/color")->pop(std::chrono::milliseconds(0));
            while (c) {
                color.push_back(copyFrame(*c));
                c = session.queues.at("kinect/color")->pop(std::chrono::milliseconds(0));
            }
            if (!d)
                break;
        }
        for (auto c = session.queues.at("kinect/color")->pop(seconds(1)); c;
             c = session.queues.at("kinect/color")->pop(seconds(1))) {
            color.push_back(copyFrame(*c));
        }
        const double wall_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        session.graph.stop();
        EXPECT_TRUE(session.device->status()) << session.device->status().toString();
        EXPECT_EQ(session.device->droppedFrames(), 0u);
        for (StreamId id : session.device->streamIds())
            EXPECT_EQ(session.graph.lostCount(id), 0u);
        ASSERT_EQ(depth.size(), 12u);
        ASSERT_EQ(color.size(), 12u);
        for (const auto* frames : {&depth, &color}) {
            for (size_t i = 0; i < frames->size(); ++i) {
                EXPECT_EQ((*frames)[i].meta().sequence, i + 1);
                // Host time between frames is the recorded device time between them.
                EXPECT_EQ(
                    (*frames)[i].meta().host_stamp_ns - depth.front().meta().host_stamp_ns,
                    (*frames)[i].meta().device_stamp_ns - depth.front().meta().device_stamp_ns);
            }
        }
        EXPECT_EQ(depth.back().meta().device_stamp_ns, 378'742'000);
        // Original pace takes the recording's 0.379 s at least.
        if (std::string(pace) == "original") {
            EXPECT_GE(wall_s, 0.36);
        }
    }
}

TEST(OpenNI2Recording, RepeatContinuesSequenceAndTime) {
    MIXRAY_REQUIRE_SHARED_DATA(test::kinectV1Oni());
    Session session;
    ASSERT_TRUE(startSession(
        session,
        kinectConfig(
            {{"pace", "fast"}, {"loop", "true"}, {"streams", "depth"}, {"buffers", "40"}})));
    const auto depth = drain(*session.queues.at("kinect/depth"), 30);
    session.graph.stop();
    ASSERT_EQ(depth.size(), 30u);
    for (size_t i = 0; i < depth.size(); ++i) {
        EXPECT_EQ(depth[i].meta().sequence, i + 1);
        if (i > 0) {
            EXPECT_GT(depth[i].meta().device_stamp_ns, depth[i - 1].meta().device_stamp_ns);
        }
    }
    // The second pass repeats the first frame's pixels one pass later: the last depth stamp
    // (378.742 ms) plus one frame at 30 fps.
    const ImageView a = depth[0].image();
    const ImageView b = depth[12].image();
    EXPECT_EQ(std::memcmp(a.data, b.data, a.size_bytes), 0);
    EXPECT_EQ(depth[12].meta().device_stamp_ns - depth[0].meta().device_stamp_ns,
              378'742'000 + 33'333'333);
}

TEST(OpenNI2Recording, SeekStartsAtTheFrame) {
    MIXRAY_REQUIRE_SHARED_DATA(test::kinectV1Oni());
    std::vector<FrameRef> depth;
    std::vector<FrameRef> color;
    {
        Session session;
        ASSERT_TRUE(startSession(
            session, kinectConfig({{"pace", "fast"}, {"seek", "5"}, {"buffers", "32"}})));
        depth = drain(*session.queues.at("kinect/depth"));
        color = drain(*session.queues.at("kinect/color"));
        session.graph.stop();
        EXPECT_TRUE(session.device->status()) << session.device->status().toString();
    }
    ASSERT_EQ(depth.size(), 8u);
    EXPECT_EQ(depth.front().meta().sequence, 5u);
    EXPECT_EQ(depth.front().meta().device_stamp_ns, 145'157'000);
    // Colour frames recorded before depth frame 5 are skipped with it.
    ASSERT_FALSE(color.empty());
    EXPECT_GT(color.front().meta().device_stamp_ns, depth.front().meta().device_stamp_ns);
    EXPECT_EQ(color.back().meta().sequence, 12u);

    // Timed playback skips to the frame at its own pace.
    OpenNI2Backend backend;
    {
        Session timed;
        ASSERT_TRUE(startSession(timed, kinectConfig({{"seek", "5"}, {"buffers", "32"}})));
        const auto timed_depth = drain(*timed.queues.at("kinect/depth"));
        timed.graph.stop();
        EXPECT_TRUE(timed.device->status()) << timed.device->status().toString();
        ASSERT_FALSE(timed_depth.empty());
        EXPECT_EQ(timed_depth.front().meta().sequence, 5u);
        EXPECT_EQ(timed_depth.front().meta().device_stamp_ns, 145'157'000);
        EXPECT_LE(timed_depth.size(), 8u);
        // OpenNI2 would give a second device on the same file the first one's player.
        auto twice = backend.open(kinectConfig({}));
        ASSERT_FALSE(twice);
        EXPECT_EQ(twice.status().code(), ErrorCode::kUnavailable);
    }
    EXPECT_EQ(backend.open(kinectConfig({{"seek", "13"}})).status().code(),
              ErrorCode::kInvalidArgument);
}

TEST(OpenNI2Recording, RefusesWhatARecordingCannotDo) {
    MIXRAY_REQUIRE_SHARED_DATA(test::kinectV1Oni());
    OpenNI2Backend backend;
    auto registered = backend.open(kinectConfig({{"registration", "on"}}));
    ASSERT_FALSE(registered);
    EXPECT_EQ(registered.status().code(), ErrorCode::kUnsupported);
    auto resized = backend.open(kinectConfig({{"depth.width", "320"}}));
    ASSERT_FALSE(resized);
    EXPECT_EQ(resized.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(resized.status().message().find("640x480@30"), std::string::npos);
    auto mono = backend.open(kinectConfig({{"color.format", "mono8"}}));
    ASSERT_FALSE(mono);
    EXPECT_EQ(mono.status().code(), ErrorCode::kInvalidArgument);
    auto ir = backend.open(kinectConfig({{"streams", "ir"}}));
    ASSERT_FALSE(ir);
    EXPECT_EQ(ir.status().code(), ErrorCode::kNotFound);
    // A recording is never unplugged.
    auto reconnect = backend.open(kinectConfig({{"reconnect", "true"}}));
    ASSERT_FALSE(reconnect);
    EXPECT_EQ(reconnect.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(reconnect.status().message().find("reconnect"), std::string::npos);
    // What was recorded is accepted.
    auto same = backend.open(
        kinectConfig({{"depth.width", "640"}, {"depth.fps", "30.0"}, {"depth.format", "depth16"}}));
    ASSERT_TRUE(same) << same.status().toString();
    EXPECT_EQ((*same)->descriptor().modes,
              (std::vector<std::string>{"depth 640x480@30 depth16", "color 640x480@30 rgb8"}));
}

TEST(OpenNI2Recording, AnEmptyRecordingFailsCleanly) {
    const auto empty =
        test::sharedDataDir() / "01_oni" / "negative" / "bloyot_empty_image_only.oni";
    MIXRAY_REQUIRE_SHARED_DATA(empty);
    OpenNI2Backend backend;
    DeviceConfig config;
    config.name = "empty";
    config.id = empty.string();
    auto device = backend.open(config);
    ASSERT_FALSE(device);
    EXPECT_EQ(device.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(device.status().message().find("bloyot_empty_image_only.oni"), std::string::npos);

    config.id = (test::sharedDataDir() / "01_oni" / "no_such_file.oni").string();
    auto missing = backend.open(config);
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
}

// OpenNI2's DummyDevice driver (Debian's libopenni2-0 ships it) is a live device: URI "Dummy",
// depth and colour at 320x240, frame i stamped i * 33 ms, the top depth row at 2000 mm.
TEST(OpenNI2Live, DummyDeviceStreamsThroughTheGraph) {
    const auto driver =
        std::filesystem::path("/usr/lib/x86_64-linux-gnu/OpenNI2/Drivers") / "libDummyDevice.so.0";
    if (!std::filesystem::exists(driver))
        GTEST_SKIP() << "OpenNI2's DummyDevice driver is not installed: " << driver;
    DeviceConfig config;
    config.name = "dummy";
    config.driver = "openni2";
    config.id = "Dummy";
    config.options = {{"buffers", "16"}};

    OpenNI2Backend backend;
    config.options["registration"] = "on";
    EXPECT_EQ(backend.open(config).status().code(), ErrorCode::kUnsupported);
    config.options.erase("registration");
    config.options["pace"] = "fast";
    EXPECT_EQ(backend.open(config).status().code(), ErrorCode::kInvalidArgument);
    config.options.erase("pace");
    config.options["depth.width"] = "640";
    auto too_wide = backend.open(config);
    ASSERT_FALSE(too_wide);
    EXPECT_EQ(too_wide.status().code(), ErrorCode::kUnsupported);
    EXPECT_NE(too_wide.status().message().find("depth 320x240@30 depth16"), std::string::npos);
    config.options.erase("depth.width");

    Session session;
    ASSERT_TRUE(startSession(session, config));
    EXPECT_FALSE(session.device->isRecording());
    EXPECT_EQ(session.device->descriptor().modes,
              (std::vector<std::string>{"depth 320x240@30 depth16", "color 320x240@30 rgb8"}));
    EXPECT_EQ(session.device->softwareUnmirror(), (std::vector<bool>{false, false}));
    std::vector<FrameRef> depth;
    std::vector<FrameRef> color;
    while (depth.size() < 5 || color.size() < 5) {
        auto d = session.queues.at("dummy/depth")->pop(seconds(10));
        auto c = session.queues.at("dummy/color")->pop(seconds(10));
        ASSERT_TRUE(d && c) << "the Dummy device stopped delivering";
        depth.push_back(std::move(*d));
        color.push_back(std::move(*c));
    }
    session.graph.stop();
    EXPECT_TRUE(session.device->status()) << session.device->status().toString();

    for (const auto* frames : {&depth, &color}) {
        for (size_t i = 0; i < frames->size(); ++i) {
            const FrameMetadata& meta = (*frames)[i].meta();
            EXPECT_EQ(meta.device_stamp_ns, static_cast<int64_t>(meta.sequence) * 33'000'000);
            EXPECT_EQ(meta.clock_domain, defaultClockDomain("dummy"));
            if (i > 0) {
                EXPECT_GT(meta.sequence, (*frames)[i - 1].meta().sequence);
            }
        }
    }
    const ImageView first = depth.front().image();
    EXPECT_EQ(first.desc, ImageDesc::packed(PixelFormat::kDepth16, 320, 240));
    for (int x = 0; x < first.desc.width; ++x)
        ASSERT_EQ(first.row<uint16_t>(0)[x], 2000) << "x " << x;
    EXPECT_EQ(color.front().image().row<uint8_t>(0)[2], 255);  // blue of pixel (0, 0)

    // Once OpenNI2 knows the device, enumerate() lists it with its modes.
    auto devices = backend.enumerate();
    ASSERT_TRUE(devices) << devices.status().toString();
    auto it = std::find_if(devices->begin(), devices->end(),
                           [](const DeviceDescriptor& d) { return d.id == "Dummy"; });
    ASSERT_NE(it, devices->end());
    EXPECT_EQ(it->backend, "openni2");
    EXPECT_EQ(it->modes,
              (std::vector<std::string>{"depth 320x240@30 depth16", "color 320x240@30 rgb8"}));
}

}  // namespace
}  // namespace mixray::openni2
