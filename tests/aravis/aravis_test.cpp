// The Aravis backend without a network: options, debayering, and Aravis's in-process fake
// camera streaming through the graph.
#include <gtest/gtest.h>

#include <chrono>
#include <memory>

#include "mixray/aravis/aravis_backend.h"
#include "mixray/graph/clock.h"
#include "mixray/graph/graph.h"

namespace mixray::aravis {
namespace {

DeviceConfig configOf(std::map<std::string, std::string> options, std::string id = "Fake_1") {
    DeviceConfig config;
    config.name = "cam";
    config.driver = "aravis";
    config.id = std::move(id);
    config.options = std::move(options);
    return config;
}

// A feature's value, or the error in its place so that a failed read shows in the assertion.
std::string read(const Result<std::string>& value) {
    return value ? *value : "<" + value.status().toString() + ">";
}

TEST(AravisOptions, ParsesEveryOption) {
    auto o = AravisOptions::fromConfig(configOf({{"pixel_format", "BayerRG8"},
                                                 {"debayer", "true"},
                                                 {"exposure_us", "5000"},
                                                 {"gain", "2"},
                                                 {"fps", "50"},
                                                 {"width", "256"},
                                                 {"height", "128"},
                                                 {"offset_x", "8"},
                                                 {"offset_y", "4"},
                                                 {"trigger", "software"},
                                                 {"buffers", "32"},
                                                 {"packet_size", "8000"},
                                                 {"packet_resend", "false"},
                                                 {"lost_timeout_ms", "500"},
                                                 {"reconnect_ms", "100"},
                                                 {"heartbeat_timeout_ms", "10000"},
                                                 {"clock_domain", "7"}}));
    ASSERT_TRUE(o) << o.status().toString();
    EXPECT_EQ(o->pixel_format, "BayerRG8");
    EXPECT_TRUE(o->debayer);
    EXPECT_EQ(o->exposure_us, 5000);
    EXPECT_EQ(o->gain, 2);
    EXPECT_EQ(o->fps, 50);
    EXPECT_EQ(o->width, 256);
    EXPECT_EQ(o->height, 128);
    EXPECT_EQ(o->offset_x, 8);
    EXPECT_EQ(o->offset_y, 4);
    EXPECT_EQ(o->trigger, TriggerMode::kSoftware);
    EXPECT_EQ(o->buffers, 32u);
    EXPECT_EQ(o->packet_size, 8000);
    EXPECT_FALSE(o->packet_resend);
    EXPECT_EQ(o->lost_timeout_ms, 500);
    EXPECT_EQ(o->reconnect_ms, 100);
    EXPECT_EQ(o->heartbeat_timeout_ms, 10000);
    EXPECT_EQ(o->clock_domain, 7u);
}

TEST(AravisOptions, RefusesBadValuesNamingTheOption) {
    auto unknown = AravisOptions::fromConfig(configOf({{"exposure", "10"}}));
    ASSERT_FALSE(unknown);
    EXPECT_NE(unknown.status().message().find("unknown option 'exposure'"), std::string::npos);
    auto format = AravisOptions::fromConfig(configOf({{"pixel_format", "YUV422"}}));
    ASSERT_FALSE(format);
    EXPECT_NE(format.status().message().find("pixel_format"), std::string::npos);
    auto trigger = AravisOptions::fromConfig(configOf({{"trigger", "line-0"}}));
    ASSERT_FALSE(trigger);
    EXPECT_NE(trigger.status().message().find("free, software or a hardware line"),
              std::string::npos);
    auto activation =
        AravisOptions::fromConfig(configOf({{"trigger", "line0"}, {"trigger_activation", "up"}}));
    ASSERT_FALSE(activation);
    EXPECT_NE(activation.status().message().find("falling_edge"), std::string::npos);
    auto free_activation =
        AravisOptions::fromConfig(configOf({{"trigger_activation", "any_edge"}}));
    ASSERT_FALSE(free_activation);
    EXPECT_NE(free_activation.status().message().find("needs a hardware trigger"),
              std::string::npos);
    EXPECT_FALSE(AravisOptions::fromConfig(configOf({{"ptp", "maybe"}})));
    EXPECT_FALSE(AravisOptions::fromConfig(configOf({{"fps", "0"}})));
    EXPECT_FALSE(AravisOptions::fromConfig(configOf({{"buffers", "1"}})));
    EXPECT_FALSE(AravisOptions::fromConfig(configOf({{"clock_domain", "0"}})));
    DeviceConfig two = configOf({});
    two.streams = {"color", "mono"};
    EXPECT_FALSE(AravisOptions::fromConfig(two));
    DeviceConfig depth = configOf({});
    depth.streams = {"depth"};
    EXPECT_FALSE(AravisOptions::fromConfig(depth));
    EXPECT_FALSE(AravisOptions::fromConfig(configOf({{"width", "64"}, {"mono.width", "64"}})));
    EXPECT_FALSE(AravisOptions::fromConfig(configOf({{"mono.format", "yuyv"}})));
    DeviceConfig mismatch = configOf({{"color.width", "64"}});
    mismatch.streams = {"mono"};
    EXPECT_FALSE(AravisOptions::fromConfig(mismatch));
}

TEST(AravisOptions, ParsesHardwareTriggersAndPtp) {
    auto o = AravisOptions::fromConfig(
        configOf({{"trigger", "line1"}, {"trigger_activation", "falling_edge"}, {"ptp", "true"}}));
    ASSERT_TRUE(o) << o.status().toString();
    EXPECT_EQ(o->trigger, TriggerMode::kHardware);
    EXPECT_EQ(o->trigger_source, "line1");
    EXPECT_EQ(o->trigger_activation, "FallingEdge");
    EXPECT_TRUE(o->ptp);
    auto plain = AravisOptions::fromConfig(configOf({}));
    ASSERT_TRUE(plain);
    EXPECT_FALSE(plain->ptp);
    EXPECT_EQ(triggerActivationName("level_low"), "LevelLow");
    EXPECT_EQ(triggerActivationName("LevelLow"), "");
}

// What a rig file's "mode: { mono: 320x240@30 mono16 }" becomes.
TEST(AravisOptions, TakesTheRigsStreamMode) {
    DeviceConfig config = configOf({{"mono.width", "320"},
                                    {"mono.height", "240"},
                                    {"mono.fps", "30"},
                                    {"mono.format", "mono16"}});
    config.streams = {"mono"};
    auto o = AravisOptions::fromConfig(config);
    ASSERT_TRUE(o) << o.status().toString();
    EXPECT_EQ(o->stream, "mono");
    EXPECT_EQ(o->width, 320);
    EXPECT_EQ(o->height, 240);
    EXPECT_EQ(o->fps, 30);
    EXPECT_EQ(o->pixel_format, "Mono16");
    auto bayer = AravisOptions::fromConfig(configOf({{"color.format", "bayer_gbrg8"}}));
    ASSERT_TRUE(bayer);
    EXPECT_EQ(bayer->pixel_format, "BayerGB8");
    EXPECT_EQ(bayer->stream, "color");
    auto debayered =
        AravisOptions::fromConfig(configOf({{"color.format", "rgb8"}, {"debayer", "true"}}));
    ASSERT_TRUE(debayered);
    EXPECT_EQ(debayered->pixel_format, "");
}

// A mosaic of a uniform colour, demosaiced, gives that colour back in every inner pixel,
// whichever of the four layouts: the layout names mean what they say.
TEST(AravisDebayer, UniformColourSurvivesEveryLayout) {
    const uint8_t r = 200, g = 100, b = 30;
    struct Layout {
        PixelFormat format;
        uint8_t top_left, top_right, bottom_left, bottom_right;
    };
    const Layout layouts[] = {{PixelFormat::kBayerRGGB8, r, g, g, b},
                              {PixelFormat::kBayerGRBG8, g, r, b, g},
                              {PixelFormat::kBayerGBRG8, g, b, r, g},
                              {PixelFormat::kBayerBGGR8, b, g, g, r}};
    for (const Layout& layout : layouts) {
        SCOPED_TRACE(std::string(toString(layout.format)));
        Image mosaic(ImageDesc::packed(layout.format, 16, 12));
        for (int y = 0; y < 12; ++y) {
            for (int x = 0; x < 16; ++x) {
                const bool right = x % 2, bottom = y % 2;
                mosaic.mutableView().row<uint8_t>(y)[x] =
                    bottom ? (right ? layout.bottom_right : layout.bottom_left)
                           : (right ? layout.top_right : layout.top_left);
            }
        }
        Image rgb(ImageDesc::packed(PixelFormat::kRGB8, 16, 12));
        ASSERT_TRUE(debayer(mosaic.view(), rgb.mutableView()));
        for (int y = 2; y < 10; ++y) {
            for (int x = 2; x < 14; ++x) {
                const uint8_t* p = rgb.view().row<uint8_t>(y) + 3 * x;
                ASSERT_EQ(p[0], r) << x << "," << y;
                ASSERT_EQ(p[1], g) << x << "," << y;
                ASSERT_EQ(p[2], b) << x << "," << y;
            }
        }
    }
    Image mono(ImageDesc::packed(PixelFormat::kMono8, 16, 12));
    Image rgb(ImageDesc::packed(PixelFormat::kRGB8, 16, 12));
    EXPECT_FALSE(debayer(mono.view(), rgb.mutableView()));
}

TEST(AravisFrameIds, GapsAndWraps) {
    EXPECT_EQ(frameIdAdvance(10, 11), 1u);
    EXPECT_EQ(frameIdAdvance(10, 14), 4u);
    EXPECT_EQ(frameIdAdvance(65535, 1), 1u);  // 16-bit ids skip 0
    EXPECT_EQ(frameIdAdvance(65534, 2), 3u);
    EXPECT_EQ(frameIdAdvance(70000, 70002), 2u);
    EXPECT_EQ(frameIdAdvance(70000, 5), 0u);  // a 64-bit count that restarted
    EXPECT_EQ(frameIdAdvance(3000, 2), 0u);   // a 16-bit count that restarted
    EXPECT_EQ(frameIdAdvance(7, 7), 0u);
}

// Frames of the in-process fake camera, collected through the graph.
struct Capture {
    Graph graph;
    AravisDevice* device = nullptr;
    std::shared_ptr<FrameQueue> queue;

    Status open(const DeviceConfig& config) {
        AravisBackend backend({.fake_interface = true});
        auto opened = backend.open(config);
        if (!opened)
            return opened.status();
        device = static_cast<AravisDevice*>(opened->get());
        MIXRAY_RETURN_IF_ERROR(graph.addNode(std::move(*opened)));
        auto q = graph.subscribe(device->streamId(), {64, QueuePolicy::kLive, "test"});
        if (!q)
            return q.status();
        queue = *q;
        return Status::ok();
    }

    std::vector<FrameRef> take(size_t n) {
        std::vector<FrameRef> frames;
        while (frames.size() < n) {
            auto frame = queue->pop(std::chrono::seconds(10));
            if (!frame)
                break;
            frames.push_back(std::move(*frame));
        }
        return frames;
    }
};

TEST(AravisFake, EnumeratesTheFakeCamera) {
    AravisBackend backend({.fake_interface = true});
    auto devices = backend.enumerate();
    ASSERT_TRUE(devices) << devices.status().toString();
    bool found = false;
    for (const auto& d : *devices) {
        EXPECT_EQ(d.backend, "aravis");
        found = found || d.id == "Fake_1";
    }
    EXPECT_TRUE(found);
}

TEST(AravisFake, StreamsMono8WithIncreasingMappedStamps) {
    Capture capture;
    ASSERT_TRUE(capture.open(configOf({{"fps", "100"}, {"width", "320"}, {"height", "240"}})));
    EXPECT_EQ(capture.device->streamInfo().name, "cam/mono");
    EXPECT_EQ(capture.device->streamInfo().format,
              ImageDesc::packed(PixelFormat::kMono8, 320, 240));
    EXPECT_EQ(capture.device->descriptor().backend, "aravis");
    ASSERT_TRUE(capture.graph.start());
    auto frames = capture.take(20);
    capture.graph.stop();
    ASSERT_EQ(frames.size(), 20u);
    ClockSync sync;
    for (size_t i = 0; i < frames.size(); ++i) {
        const FrameMetadata& m = frames[i].meta();
        EXPECT_EQ(frames[i].image().desc, capture.device->streamInfo().format);
        EXPECT_EQ(m.status, FrameStatus::kOk);
        EXPECT_EQ(m.clock_domain, capture.device->options().clock_domain);
        const int64_t host = sync.observe(m);
        // The fake camera stamps frames with the system clock; once mapped they lie within
        // the arrival latency of the host stamps.
        EXPECT_LE(host, m.host_stamp_ns + 1'000'000);
        EXPECT_GT(host, m.host_stamp_ns - 500'000'000);
        if (i > 0) {
            EXPECT_GT(m.sequence, frames[i - 1].meta().sequence);
            EXPECT_GT(m.device_stamp_ns, frames[i - 1].meta().device_stamp_ns);
            EXPECT_GE(m.host_stamp_ns, frames[i - 1].meta().host_stamp_ns);
        }
    }
    const AravisStats stats = capture.device->stats();
    EXPECT_GE(stats.published, 20u);
    EXPECT_EQ(stats.failed, 0u);
}

TEST(AravisFake, PublishesEachPixelFormat) {
    struct Case {
        std::string format;
        bool debayer;
        PixelFormat published;
        std::string stream;
    };
    const Case cases[] = {{"Mono16", false, PixelFormat::kMono16, "cam/mono"},
                          {"RGB8", false, PixelFormat::kRGB8, "cam/color"},
                          {"BayerRG8", false, PixelFormat::kBayerRGGB8, "cam/color"},
                          {"BayerGB8", true, PixelFormat::kRGB8, "cam/color"}};
    for (const Case& c : cases) {
        SCOPED_TRACE(c.format);
        Capture capture;
        ASSERT_TRUE(capture.open(configOf({{"pixel_format", c.format},
                                           {"debayer", c.debayer ? "true" : "false"},
                                           {"fps", "100"},
                                           {"width", "64"},
                                           {"height", "48"}})));
        EXPECT_EQ(capture.device->streamInfo().name, c.stream);
        ASSERT_TRUE(capture.graph.start());
        auto frames = capture.take(3);
        capture.graph.stop();
        ASSERT_EQ(frames.size(), 3u);
        EXPECT_EQ(frames[2].image().desc, ImageDesc::packed(c.published, 64, 48));
    }
    Capture mono_debayer;
    EXPECT_FALSE(mono_debayer.open(configOf({{"pixel_format", "Mono8"}, {"debayer", "true"}})));
    DeviceConfig wrong_stream = configOf({{"pixel_format", "Mono8"}});
    wrong_stream.streams = {"color"};
    Capture mono_as_color;
    const Status refused = mono_as_color.open(wrong_stream);
    EXPECT_EQ(refused.code(), ErrorCode::kInvalidArgument) << refused.toString();
}

// The fake camera's TriggerSource offers Line0 and Software, its TriggerActivation RisingEdge
// only; the settings are read back from the camera's registers through Aravis.
TEST(AravisFake, HardwareTriggerConfiguresTheCamera) {
    Capture capture;
    const Status opened =
        capture.open(configOf({{"trigger", "LINE0"}, {"trigger_activation", "rising_edge"}}));
    ASSERT_TRUE(opened) << opened.toString();
    AravisDevice& device = *capture.device;
    EXPECT_EQ(read(device.feature("TriggerSelector")), "FrameStart");
    EXPECT_EQ(read(device.feature("TriggerMode")), "On");
    EXPECT_EQ(read(device.feature("TriggerSource")), "Line0");
    EXPECT_EQ(read(device.feature("TriggerActivation")), "RisingEdge");
    EXPECT_EQ(device.options().trigger_source, "Line0");
    EXPECT_EQ(device.streamInfo().tags.at("trigger"), "Line0");
    EXPECT_EQ(device.streamInfo().tags.at("timestamp_clock"), "camera");
    EXPECT_EQ(device.streamInfo().nominal_fps, 0);
    const Status software = device.softwareTrigger();
    EXPECT_EQ(software.code(), ErrorCode::kUnsupported);
    EXPECT_NE(software.message().find("triggered by Line0"), std::string::npos);
    EXPECT_EQ(device.feature("NoSuchFeature").status().code(), ErrorCode::kNotFound);
    EXPECT_EQ(device.ptpStatus().status().code(), ErrorCode::kUnsupported);
}

TEST(AravisFake, FreeRunSwitchesTriggersOff) {
    Capture capture;
    ASSERT_TRUE(capture.open(configOf({})));
    EXPECT_EQ(read(capture.device->feature("TriggerMode")), "Off");
    EXPECT_EQ(read(capture.device->feature("AcquisitionMode")), "Continuous");
    EXPECT_EQ(capture.device->streamInfo().tags.at("trigger"), "free");
}

TEST(AravisFake, MissingLineOrActivationIsAClearError) {
    Capture line;
    const Status no_line = line.open(configOf({{"trigger", "line3"}}));
    EXPECT_EQ(no_line.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(no_line.message().find("trigger 'line3': the camera has no such trigger source; "
                                     "it offers line0 (and free, software)"),
              std::string::npos)
        << no_line.toString();
    Capture edge;
    const Status no_edge =
        edge.open(configOf({{"trigger", "line0"}, {"trigger_activation", "falling_edge"}}));
    EXPECT_EQ(no_edge.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(no_edge.message().find("FallingEdge: the camera offers RisingEdge"),
              std::string::npos)
        << no_edge.toString();
}

TEST(AravisFake, PtpOnACameraWithoutPtpIsRefused) {
    Capture capture;
    const Status refused = capture.open(configOf({{"ptp", "true"}}));
    EXPECT_EQ(refused.code(), ErrorCode::kUnsupported);
    EXPECT_NE(refused.message().find("no IEEE 1588 (PTP): it has neither PtpEnable nor "
                                     "GevIEEE1588"),
              std::string::npos)
        << refused.toString();
    EXPECT_NE(refused.message().find("aravis device 'cam'"), std::string::npos);
}

TEST(AravisFake, UnknownCameraIsNotFound) {
    AravisBackend backend({.fake_interface = true});
    auto opened = backend.open(configOf({}, "no-such-camera"));
    ASSERT_FALSE(opened);
    EXPECT_EQ(opened.status().code(), ErrorCode::kNotFound);
}

}  // namespace
}  // namespace mixray::aravis
