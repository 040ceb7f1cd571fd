// Light and environment-map records (mixray/tracking/light_record.h): round trips of every
// field, every refusal, estimates' stale flags and reasons, and streams through a recording.
#include "mixray/tracking/light_record.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "mixray/graph/frame.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/pose.h"
#include "reference_crc32.h"
#include "test_data.h"

namespace mixray::tracking {
namespace {

EstimatedLight makeLight(LightSource source, Eigen::Vector3d direction, double scale) {
    EstimatedLight l;
    l.source = source;
    l.to_light_world = direction.normalized();
    l.intensity = Eigen::Vector3d(0.9, 0.8, 0.7) * scale;
    l.angular_radius_rad = 0.0125 * scale;
    l.weight = 311 * scale;
    return l;
}

LightRecord sampleRecord() {
    LightRecord r;
    r.frame_sequence = 0x0123456789abcdefULL;
    r.frame_device_stamp_ns = -1234567890123LL;
    LightGroup render;
    render.name = "render";
    render.stale = false;
    render.stamp_ns = render.good_stamp_ns = 5000000001;
    render.lights.push_back(makeLight(LightSource::kEnvironment, {0.3, -0.4, 0.8}, 1));
    render.lights.back().position_world = Eigen::Vector3d(1.5, -2.25, 2.75);
    render.lights.push_back(makeLight(LightSource::kProbeMirror, {-0.1, 0.2, 0.9}, 0.5));
    LightGroup probe;
    probe.name = "probe:mirror";
    probe.stale = true;
    probe.reason = "marker 23 not seen — pose stale";  // UTF-8 beyond ASCII
    probe.stamp_ns = 5000000001;
    probe.good_stamp_ns = 4900000000;
    probe.lights.push_back(makeLight(LightSource::kProbeMirror, {-0.1, 0.2, 0.9}, 1));
    LightGroup environment;  // stale before any good value: no lights, no reason
    environment.name = "environment";
    LightGroup sun;
    sun.name = "sun";
    sun.stale = false;
    sun.stamp_ns = sun.good_stamp_ns = 7;
    sun.lights.push_back(makeLight(LightSource::kSun, {0, 0.6, 0.8}, 3));
    r.groups = {render, probe, environment, sun};
    return r;
}

void expectSameLight(const EstimatedLight& a, const EstimatedLight& b, const std::string& where) {
    EXPECT_EQ(a.source, b.source) << where;
    EXPECT_EQ(a.to_light_world, b.to_light_world) << where;  // doubles bit for bit
    EXPECT_EQ(a.intensity, b.intensity) << where;
    EXPECT_EQ(a.angular_radius_rad, b.angular_radius_rad) << where;
    ASSERT_EQ(a.position_world.has_value(), b.position_world.has_value()) << where;
    if (a.position_world) {
        EXPECT_EQ(*a.position_world, *b.position_world) << where;
    }
    EXPECT_EQ(a.weight, b.weight) << where;
}

void expectSameRecord(const LightRecord& a, const LightRecord& b) {
    EXPECT_EQ(a.frame_sequence, b.frame_sequence);
    EXPECT_EQ(a.frame_device_stamp_ns, b.frame_device_stamp_ns);
    ASSERT_EQ(a.groups.size(), b.groups.size());
    for (size_t i = 0; i < a.groups.size(); ++i) {
        const LightGroup& x = a.groups[i];
        const LightGroup& y = b.groups[i];
        EXPECT_EQ(x.name, y.name);
        EXPECT_EQ(x.stale, y.stale) << x.name;
        EXPECT_EQ(x.reason, y.reason) << x.name;
        EXPECT_EQ(x.stamp_ns, y.stamp_ns) << x.name;
        EXPECT_EQ(x.good_stamp_ns, y.good_stamp_ns) << x.name;
        ASSERT_EQ(x.lights.size(), y.lights.size()) << x.name;
        for (size_t k = 0; k < x.lights.size(); ++k)
            expectSameLight(x.lights[k], y.lights[k], x.name + " light " + std::to_string(k));
    }
}

using test::referenceCrc32;

void resealCrc(std::vector<uint8_t>& b) {
    const uint32_t crc = referenceCrc32(b.data(), b.size() - 4);
    for (size_t i = 0; i < 4; ++i)
        b[b.size() - 4 + i] = static_cast<uint8_t>(crc >> (8 * i));
}

void putU32(std::vector<uint8_t>& b, size_t at, uint32_t v) {
    for (size_t i = 0; i < 4; ++i)
        b[at + i] = static_cast<uint8_t>(v >> (8 * i));
}

void putF64(std::vector<uint8_t>& b, size_t at, double v) {
    std::memcpy(b.data() + at, &v, 8);  // the test hosts are little-endian
}

std::vector<uint8_t> encoded(const LightRecord& r) {
    auto bytes = encodeLightRecord(r);
    EXPECT_TRUE(bytes) << bytes.status().toString();
    return bytes ? *bytes : std::vector<uint8_t>{};
}

// kCorruptData, with `word` in the message.
::testing::AssertionResult refusedSaying(const std::vector<uint8_t>& b, const std::string& word) {
    auto out = decodeLightRecord(b.data(), b.size());
    if (out)
        return ::testing::AssertionFailure() << "accepted";
    if (out.status().code() != ErrorCode::kCorruptData)
        return ::testing::AssertionFailure() << out.status().toString();
    if (out.status().message().find(word) == std::string::npos)
        return ::testing::AssertionFailure()
               << "'" << out.status().message() << "' lacks '" << word << "'";
    return ::testing::AssertionSuccess();
}

TEST(LightRecord, RoundTripKeepsEveryField) {
    const LightRecord in = sampleRecord();
    const auto bytes = encoded(in);
    auto out = decodeLightRecord(bytes.data(), bytes.size());
    ASSERT_TRUE(out) << out.status().toString();
    expectSameRecord(in, *out);
    EXPECT_EQ(encoded(*out), bytes);

    LightRecord empty;  // a frame with no estimator yet
    const auto none = encoded(empty);
    EXPECT_EQ(none.size(), kLightRecordHeaderBytes + 4);
    auto back = decodeLightRecord(none.data(), none.size());
    ASSERT_TRUE(back);
    EXPECT_TRUE(back->groups.empty());
}

TEST(LightRecord, LayoutIsLittleEndianAtDocumentedOffsets) {
    const auto b = encoded(sampleRecord());
    ASSERT_FALSE(b.empty());
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(b.data()), 4), "MXLI");
    EXPECT_EQ(b[4], 1);  // version
    EXPECT_EQ(b[5], 0);
    EXPECT_EQ(b[6], 4);  // groups
    EXPECT_EQ(b[8] | b[9] << 8 | b[10] << 16, static_cast<int>(b.size()));
    EXPECT_EQ(b[16], 0xef);  // sequence, low byte first
    EXPECT_EQ(b[23], 0x01);
    // Group 0 "render": name length 6, no reason, 2 lights, fresh.
    EXPECT_EQ(b[32], 6);
    EXPECT_EQ(b[33], 0);
    EXPECT_EQ(b[34], 2);
    EXPECT_EQ(b[35], 0);
    EXPECT_EQ(b[40] | b[41] << 8 | b[42] << 16 | b[43] << 24, 5000000001 & 0xffffffff);
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(b.data() + 56), 6), "render");
    EXPECT_EQ(b[62], 0);  // padding to 8
    EXPECT_EQ(b[63], 0);
    // Its first light at 64: environment, with a position.
    EXPECT_EQ(b[64], static_cast<int>(LightSource::kEnvironment));
    EXPECT_EQ(b[65], 1);
    double x = 0;
    std::memcpy(&x, b.data() + 64 + 64, 8);
    EXPECT_EQ(x, 1.5);  // position x
    std::memcpy(&x, b.data() + 64 + 88, 8);
    EXPECT_EQ(x, 311);  // weight
    // Group 1 "probe:mirror" after 2 lights of 96 bytes: stale with its reason.
    const size_t g1 = 64 + 2 * 96;
    EXPECT_EQ(b[g1], 12);
    EXPECT_EQ(static_cast<size_t>(b[g1 + 1]),
              std::string("marker 23 not seen — pose stale").size());
    EXPECT_EQ(b[g1 + 3], 1);
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(b.data() + g1 + 24), 12 + 6),
              "probe:mirrormarker");
    // The CRC is zlib's over everything before it.
    EXPECT_EQ(b[b.size() - 4] | b[b.size() - 3] << 8 | b[b.size() - 2] << 16 |
                  static_cast<uint32_t>(b[b.size() - 1]) << 24,
              referenceCrc32(b.data(), b.size() - 4));
}

TEST(LightRecord, LargestRecordIsTheStreamBufferSize) {
    LightRecord r;
    for (size_t g = 0; g < kLightRecordMaxGroups; ++g) {
        LightGroup group;
        group.name = std::string(kLightGroupNameMaxChars - 2, 'n') + std::to_string(10 + g);
        group.reason = std::string(kLightReasonMaxBytes, 'r');
        group.lights.assign(kLightGroupMaxLights, makeLight(LightSource::kSun, {0, 0, 1}, 1));
        r.groups.push_back(group);
    }
    const auto b = encoded(r);
    EXPECT_EQ(b.size(), kLightRecordMaxBytes);
    auto out = decodeLightRecord(b.data(), b.size());
    ASSERT_TRUE(out) << out.status().toString();
    expectSameRecord(r, *out);
    EXPECT_EQ(makeLightStreamInfo("lights/estimate", "kinect/color", 30).format.width,
              static_cast<int>(kLightRecordMaxBytes));
}

TEST(LightRecord, TruncatedAndDamagedRecordsAreRefused) {
    const auto bytes = encoded(sampleRecord());
    for (size_t size = 0; size < bytes.size(); ++size) {
        auto out = decodeLightRecord(bytes.data(), size);
        ASSERT_FALSE(out) << size;
        EXPECT_EQ(out.status().code(), ErrorCode::kCorruptData) << size;
    }
    auto longer = bytes;
    longer.push_back(0);
    EXPECT_TRUE(refusedSaying(longer, "says it has"));
    EXPECT_FALSE(decodeLightRecord(nullptr, bytes.size()));
    for (size_t bit = 0; bit < 8 * bytes.size(); ++bit) {
        auto damaged = bytes;
        damaged[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
        auto out = decodeLightRecord(damaged.data(), damaged.size());
        ASSERT_FALSE(out) << "bit " << bit;
        EXPECT_EQ(out.status().code(), ErrorCode::kCorruptData);
    }
}

TEST(LightRecord, WellFormedButInvalidContentIsRefused) {
    // Records with a correct CRC but content a buggy or hostile writer could produce; each
    // error names the field.
    const auto bytes = encoded(sampleRecord());
    const size_t g0 = 32, l0 = 64, g1 = 64 + 2 * 96;
    const auto with = [&](auto change) {
        auto b = bytes;
        change(b);
        resealCrc(b);
        return b;
    };
    EXPECT_TRUE(refusedSaying(with([](auto& b) { b[0] = 'N'; }), "bad magic"));
    EXPECT_TRUE(refusedSaying(with([](auto& b) { b[4] = 2; }), "version 2"));
    EXPECT_TRUE(refusedSaying(with([](auto& b) { b[7] = 1; }), "reserved"));
    EXPECT_TRUE(refusedSaying(with([](auto& b) { b[12] = 1; }), "reserved"));
    EXPECT_TRUE(refusedSaying(with([](auto& b) { b[6] = 17; }), "group count 17"));
    EXPECT_TRUE(refusedSaying(with([](auto& b) { b[6] = 5; }), "group 4: header runs past"));
    EXPECT_TRUE(refusedSaying(with([](auto& b) { b[6] = 3; }), "after the last group"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g0] = 0; }), "name length 0"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g0] = 32; }), "name length 32"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g0 + 1] = 128; }), "reason length 128"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g0 + 2] = 33; }), "light count 33"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g0 + 2] = 32; }), "run past the end"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g0 + 3] = 2; }), "reserved bits"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g0 + 4] = 1; }), "reserved bits"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g0 + 30] = 'x'; }), "padding"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g0 + 24] = ' '; }), "printable ASCII"));
    // A fresh group that carries a reason.
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g1 + 3] = 0; }), "fresh estimate"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g1 + 24 + 12] = 0x01; }), "UTF-8"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[g1 + 24 + 12] = 0xc3; }), "UTF-8"));
    // The first light of group 0.
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[l0] = 4; }), "source 4"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[l0 + 1] = 3; }), "reserved bits"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[l0 + 5] = 1; }), "reserved bits"));
    EXPECT_TRUE(refusedSaying(
        with([&](auto& b) { putF64(b, l0 + 8, std::numeric_limits<double>::quiet_NaN()); }),
        "to_light_world is not finite"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { putF64(b, l0 + 8, 0.9); }), "not a unit"));
    EXPECT_TRUE(refusedSaying(
        with([&](auto& b) { putF64(b, l0 + 32, std::numeric_limits<double>::infinity()); }),
        "intensity"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { putF64(b, l0 + 56, -1); }), "angular_radius"));
    EXPECT_TRUE(refusedSaying(
        with([&](auto& b) { putF64(b, l0 + 64, std::numeric_limits<double>::quiet_NaN()); }),
        "position_world"));
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { putF64(b, l0 + 88, -2); }), "weight"));
    // The second light has no position: its position bytes must be zero.
    EXPECT_TRUE(refusedSaying(with([&](auto& b) { b[l0 + 96 + 64] = 1; }), "absent position"));
    auto untouched = with([](auto&) {});
    EXPECT_TRUE(decodeLightRecord(untouched.data(), untouched.size()));
}

TEST(LightRecord, DuplicateNamesAreRefusedBothWays) {
    LightRecord r = sampleRecord();
    r.groups[3].name = "render";
    EXPECT_EQ(encodeLightRecord(r).status().code(), ErrorCode::kInvalidArgument);
    // Groups "abc" and "abd", the second renamed "abc" in the bytes: the decoder's own refusal.
    LightRecord two;
    LightGroup a;
    a.name = "abc";
    two.groups = {a, a};
    two.groups[1].name = "abd";
    auto b = encoded(two);
    ASSERT_FALSE(b.empty());
    const size_t second = 32 + 24 + 8;  // after group 0's header and padded name
    b[second + 24 + 2] = 'c';
    resealCrc(b);
    EXPECT_TRUE(refusedSaying(b, "used by an earlier group"));
}

TEST(LightRecord, EncodeRefusesWhatCannotBeWritten) {
    const auto refused = [](const LightRecord& r, const std::string& word) {
        auto out = encodeLightRecord(r);
        return !out && out.status().code() == ErrorCode::kInvalidArgument &&
               out.status().message().find(word) != std::string::npos;
    };
    LightRecord r = sampleRecord();
    r.groups[0].name = std::string(32, 'a');
    EXPECT_TRUE(refused(r, "name must have 1 to 31"));
    r.groups[0].name = "";
    EXPECT_TRUE(refused(r, "name must have 1 to 31"));
    r.groups[0].name = "with space";
    EXPECT_TRUE(refused(r, "printable ASCII"));
    r = sampleRecord();
    r.groups[1].reason = std::string(128, 'a');
    EXPECT_TRUE(refused(r, "at most 127 bytes"));
    r.groups[1].reason = "line\nbreak";
    EXPECT_TRUE(refused(r, "UTF-8"));
    r = sampleRecord();
    r.groups[0].reason = "fresh but with a reason";
    EXPECT_TRUE(refused(r, "fresh estimate"));
    r = sampleRecord();
    r.groups[0].lights[0].to_light_world = {0, 0, 2};
    EXPECT_TRUE(refused(r, "group 0 'render': light 0: to_light_world is not a unit"));
    r = sampleRecord();
    r.groups[0].lights[1].to_light_world.x() = std::nan("");
    EXPECT_TRUE(refused(r, "light 1: to_light_world is not finite"));
    r = sampleRecord();
    r.groups[0].lights[0].intensity.y() = -0.5;
    EXPECT_TRUE(refused(r, "intensity"));
    r = sampleRecord();
    r.groups[0].lights[0].source = static_cast<LightSource>(9);
    EXPECT_TRUE(refused(r, "source 9"));
    r = sampleRecord();
    r.groups[0].lights.assign(33, makeLight(LightSource::kSun, {0, 0, 1}, 1));
    EXPECT_TRUE(refused(r, "at most 32 lights"));
    r = sampleRecord();
    r.groups.resize(17);
    for (size_t i = 4; i < r.groups.size(); ++i)
        r.groups[i].name = "g" + std::to_string(i);
    EXPECT_TRUE(refused(r, "at most 16 groups"));
    r.groups.resize(16);
    EXPECT_TRUE(encodeLightRecord(r));
}

TEST(LightRecord, GroupsKeepTheEstimatesStaleFlagAndReason) {
    Estimate<std::vector<EstimatedLight>> lights;
    // No value yet: stale, no lights.
    lights.keep("environment image over-exposed", 10);
    LightGroup g = toLightGroup("environment", lights);
    EXPECT_TRUE(g.stale);
    EXPECT_EQ(g.reason, "environment image over-exposed");
    EXPECT_EQ(g.stamp_ns, 10);
    EXPECT_TRUE(g.lights.empty());
    // Fresh: lights, no reason.
    lights.update({makeLight(LightSource::kEnvironment, {0, 1, 1}, 1)}, 20);
    g = toLightGroup("environment", lights);
    EXPECT_FALSE(g.stale);
    EXPECT_TRUE(g.reason.empty());
    EXPECT_EQ(g.good_stamp_ns, 20);
    ASSERT_EQ(g.lights.size(), 1u);
    // Stale again: the last good lights, marked, with the reason and both stamps.
    lights.keep("environment camera lost", 30);
    g = toLightGroup("environment", lights);
    EXPECT_TRUE(g.stale);
    EXPECT_EQ(g.reason, "environment camera lost");
    EXPECT_EQ(g.stamp_ns, 30);
    EXPECT_EQ(g.good_stamp_ns, 20);
    EXPECT_EQ(g.lights.size(), 1u);

    LightRecord r;
    r.groups.push_back(g);
    // A reason too long for the record, with a control character and bad UTF-8: cut at a
    // character boundary, made printable, still encodable.
    Estimate<ProbeResult> probe;
    probe.keep("tab\there \xff " + std::string(60, 'x') + std::string(40, '\xc3') + "é" +
                   std::string(40, 'y'),
               40);
    ProbeResult result;
    result.lights.assign(40, makeLight(LightSource::kProbeMirror, {1, 0, 0}, 1));
    probe.value = result;
    const LightGroup p = toLightGroup("probe:mirror", probe);
    EXPECT_LE(p.reason.size(), kLightReasonMaxBytes);
    EXPECT_EQ(p.reason.substr(0, 12), "tab here   x");
    EXPECT_EQ(p.lights.size(), kLightGroupMaxLights);  // most representative first
    r.groups.push_back(p);

    Estimate<EnvironmentEstimate> env;
    env.update(EnvironmentEstimate{{makeLight(LightSource::kEnvironment, {0, 0, 1}, 2)}, nullptr},
               50);
    r.groups.push_back(toLightGroup("render", env));
    Estimate<EstimatedLight> sun;
    sun.keep("no time of day: give --utc", 60);
    r.groups.push_back(toLightGroup("sun", sun));
    EXPECT_TRUE(r.groups.back().lights.empty());
    sun.update(makeLight(LightSource::kSun, {0, 0.6, 0.8}, 1), 70);
    r.groups.push_back(toLightGroup("sun:now", sun));

    const auto b = encoded(r);
    auto out = decodeLightRecord(b.data(), b.size());
    ASSERT_TRUE(out) << out.status().toString();
    expectSameRecord(r, *out);
    EXPECT_TRUE(out->groups[0].stale);
    EXPECT_EQ(out->groups[0].reason, "environment camera lost");
    EXPECT_EQ(out->groups[3].reason, "no time of day: give --utc");
}

// A light stream written into a recording as a live node would publish it (pooled frames of
// the stream's maximal width, each carrying one record of its own size) reads back identical.
TEST(LightRecord, LightAndMapStreamsRoundTripThroughARecording) {
    const auto path = test::tempDir() / "lights.mkv";
    RecordingHeader header;
    header.streams.push_back(makeLightStreamInfo("lights/estimate", "kinect/color", 30));
    header.streams.push_back(makeEnvironmentMapStreamInfo("lights/map", "env/fisheye", 16, 8));
    std::vector<LightRecord> records;
    std::vector<FloatImage> maps;
    {
        auto writer = createMkvWriter(path, header, {});
        ASSERT_TRUE(writer) << writer.status().toString();
        std::vector<std::shared_ptr<BufferPool>> pools;
        for (const StreamInfo& info : header.streams) {
            BufferPoolOptions po;
            po.desc = info.format;
            po.buffer_count = 2;
            po.name = info.name;
            pools.push_back(BufferPool::create(po));
            ASSERT_TRUE(pools.back());
        }
        for (int i = 0; i < 6; ++i) {
            LightRecord r = sampleRecord();
            r.frame_sequence = static_cast<uint64_t>(i);
            r.frame_device_stamp_ns = 1000 + i;
            r.groups.resize(static_cast<size_t>(i % 5));  // sizes vary frame to frame
            records.push_back(r);
            const auto bytes = encoded(r);
            WritableFrame frame = pools[0]->acquire();
            ASSERT_TRUE(frame);
            std::memcpy(frame.image().data, bytes.data(), bytes.size());
            frame.setPayloadBytes(bytes.size());
            frame.meta().stream = 0;
            frame.meta().sequence = static_cast<uint64_t>(i);
            frame.meta().host_stamp_ns = frame.meta().device_stamp_ns = 1000000 * (i + 1);
            ASSERT_TRUE((*writer)->write(std::move(frame).publish()));

            if (i % 2 == 0) {
                FloatImage map;
                map.width = 16;
                map.height = 8;
                map.pixels.resize(16 * 8 * 3);
                for (size_t k = 0; k < map.pixels.size(); ++k)
                    map.pixels[k] = static_cast<float>(k) * 0.37f - 1.0f + static_cast<float>(i);
                maps.push_back(map);
                EnvironmentMapHeader h;
                h.frame_sequence = static_cast<uint64_t>(i / 2);
                h.stale = i == 4;
                h.reason = i == 4 ? "environment image black" : "";
                WritableFrame m = pools[1]->acquire();
                ASSERT_TRUE(m);
                auto n = encodeEnvironmentMapRecord(map, h, m.image().data, m.capacityBytes());
                ASSERT_TRUE(n) << n.status().toString();
                m.setPayloadBytes(*n);
                m.meta().stream = 1;
                m.meta().sequence = static_cast<uint64_t>(i / 2);
                m.meta().host_stamp_ns = m.meta().device_stamp_ns = 1000000 * (i + 1);
                ASSERT_TRUE((*writer)->write(std::move(m).publish()));
            }
        }
        ASSERT_TRUE((*writer)->close());
    }
    auto reader = openMkv(path);
    ASSERT_TRUE(reader) << reader.status().toString();
    const auto& streams = (*reader)->streams();
    ASSERT_EQ(streams.size(), 2u);
    EXPECT_EQ(streams[0].tags.at("light_record"), "mixray-lights-1");
    EXPECT_EQ(streams[0].tags.at("light_of"), "kinect/color");
    EXPECT_EQ(streams[0].format.width, static_cast<int>(kLightRecordMaxBytes));
    EXPECT_EQ(streams[1].tags.at("environment_map_record"), "mixray-envmap-1");
    EXPECT_EQ(streams[1].tags.at("map_of"), "env/fisheye");
    size_t lights = 0, map_count = 0;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame) {
            EXPECT_EQ(frame.status().code(), ErrorCode::kEndOfStream) << frame.status().toString();
            break;
        }
        if (frame->meta().stream == 0) {
            ASSERT_LT(lights, records.size());
            auto r = decodeLightRecord(frame->image());
            ASSERT_TRUE(r) << "record " << lights << ": " << r.status().toString();
            expectSameRecord(records[lights], *r);
            ++lights;
        } else {
            ASSERT_LT(map_count, maps.size());
            auto m = decodeEnvironmentMapRecord(frame->image());
            ASSERT_TRUE(m) << m.status().toString();
            EXPECT_EQ(m->map.pixels, maps[map_count].pixels);
            EXPECT_EQ(m->header.stale, map_count == 2);
            EXPECT_EQ(m->header.reason, map_count == 2 ? "environment image black" : "");
            ++map_count;
        }
    }
    EXPECT_EQ(lights, records.size());
    EXPECT_EQ(map_count, maps.size());
}

FloatImage randomMap(int width, int height, uint32_t seed) {
    FloatImage map;
    map.width = width;
    map.height = height;
    map.pixels.resize(static_cast<size_t>(width) * height * 3);
    std::mt19937 rng(seed);
    // Random finite bit patterns: every exponent and mantissa, signs, denormals, -0.
    for (float& v : map.pixels) {
        do {
            const uint32_t bits = rng();
            std::memcpy(&v, &bits, 4);
        } while (!std::isfinite(v));
    }
    return map;
}

TEST(EnvironmentMapRecord, RoundTripIsBitExact) {
    const FloatImage map = randomMap(512, 256, 7);
    EnvironmentMapHeader h;
    h.frame_sequence = 99;
    h.frame_device_stamp_ns = -5;
    h.stale = true;
    h.reason = "environment image over-exposed";
    h.stamp_ns = 123;
    h.good_stamp_ns = 100;
    const size_t bytes = environmentMapRecordBytes(512, 256);
    EXPECT_EQ(bytes, 176u + 512 * 256 * 12 + 4);
    std::vector<uint8_t> buffer(bytes + 100, 0xaa);
    auto n = encodeEnvironmentMapRecord(map, h, buffer.data(), buffer.size());
    ASSERT_TRUE(n) << n.status().toString();
    EXPECT_EQ(*n, bytes);
    EXPECT_EQ(buffer[bytes], 0xaa);  // nothing past the record
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(buffer.data()), 4), "MXEM");
    auto out = decodeEnvironmentMapRecord(buffer.data(), *n);
    ASSERT_TRUE(out) << out.status().toString();
    EXPECT_EQ(out->map.width, 512);
    EXPECT_EQ(out->map.height, 256);
    EXPECT_EQ(out->map.channels, 3);
    EXPECT_EQ(std::memcmp(out->map.pixels.data(), map.pixels.data(), map.pixels.size() * 4), 0);
    EXPECT_EQ(out->header.frame_sequence, 99u);
    EXPECT_EQ(out->header.frame_device_stamp_ns, -5);
    EXPECT_TRUE(out->header.stale);
    EXPECT_EQ(out->header.reason, h.reason);
    EXPECT_EQ(out->header.stamp_ns, 123);
    EXPECT_EQ(out->header.good_stamp_ns, 100);

    const StreamInfo info = makeEnvironmentMapStreamInfo("env/map", "env/fisheye", 512, 256);
    EXPECT_EQ(info.kind, StreamKind::kData);
    EXPECT_EQ(info.format.format, PixelFormat::kBinary);
    EXPECT_EQ(static_cast<size_t>(info.format.width), bytes);
    EXPECT_EQ(info.tags.at("map_width"), "512");
}

TEST(EnvironmentMapRecord, BadMapsAndRecordsAreRefused) {
    const FloatImage map = randomMap(8, 4, 3);
    EnvironmentMapHeader h;
    const size_t bytes = environmentMapRecordBytes(8, 4);
    std::vector<uint8_t> good(bytes);
    ASSERT_TRUE(encodeEnvironmentMapRecord(map, h, good.data(), good.size()));

    // Encoding.
    std::vector<uint8_t> buffer(bytes);
    const auto encodeRefused = [&](const FloatImage& m, const EnvironmentMapHeader& hh,
                                   size_t capacity, const std::string& word) {
        auto n = encodeEnvironmentMapRecord(m, hh, buffer.data(), capacity);
        return !n && n.status().code() == ErrorCode::kInvalidArgument &&
               n.status().message().find(word) != std::string::npos;
    };
    EXPECT_TRUE(encodeRefused(map, h, bytes - 1, "the buffer holds"));
    FloatImage bad = map;
    bad.pixels[5] = std::nanf("");
    EXPECT_TRUE(encodeRefused(bad, h, bytes, "value 5 is not finite"));
    bad = map;
    bad.pixels.pop_back();
    EXPECT_TRUE(encodeRefused(bad, h, bytes, "3 channels"));
    bad.width = 4096;
    bad.height = 1024;  // over the pixel cap
    EXPECT_TRUE(encodeRefused(bad, h, bytes, "out of bounds"));
    bad.width = 0;
    EXPECT_TRUE(encodeRefused(bad, h, bytes, "out of bounds"));
    EnvironmentMapHeader fresh;
    fresh.stale = false;
    fresh.reason = "why";
    EXPECT_TRUE(encodeRefused(map, fresh, bytes, "fresh estimate"));
    EXPECT_EQ(environmentMapRecordBytes(2049, 1024), 0u);
    EXPECT_EQ(environmentMapRecordBytes(8193, 1), 0u);

    // Decoding.
    const auto decodeRefused = [](std::vector<uint8_t> b, bool reseal, const std::string& word) {
        if (reseal)
            resealCrc(b);
        auto out = decodeEnvironmentMapRecord(b.data(), b.size());
        return !out && out.status().code() == ErrorCode::kCorruptData &&
               out.status().message().find(word) != std::string::npos;
    };
    for (size_t size : {size_t{0}, size_t{100}, bytes - 1}) {
        std::vector<uint8_t> cut(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(size));
        EXPECT_TRUE(decodeRefused(cut, false, "bytes")) << size;
    }
    auto b = good;
    b[0] = 'N';
    EXPECT_TRUE(decodeRefused(b, true, "bad magic"));
    b = good;
    b[200] ^= 4;
    EXPECT_TRUE(decodeRefused(b, false, "CRC mismatch"));
    b = good;
    b[4] = 2;
    EXPECT_TRUE(decodeRefused(b, true, "version 2"));
    b = good;
    b[6] = 2;
    EXPECT_TRUE(decodeRefused(b, true, "flag"));
    b = good;
    b[7] = 4;
    EXPECT_TRUE(decodeRefused(b, true, "channels 4"));
    b = good;
    putU32(b, 8, 9);  // width 9: the size no longer matches
    EXPECT_TRUE(decodeRefused(b, true, "needs"));
    b = good;
    putU32(b, 8, 0xffffffffu);  // a huge width must not be multiplied out
    EXPECT_TRUE(decodeRefused(b, true, "out of bounds"));
    b = good;
    putU32(b, 8, 4096);
    putU32(b, 12, 4096);
    EXPECT_TRUE(decodeRefused(b, true, "out of bounds"));
    b = good;
    putU32(b, 176 + 4 * 7, 0x7f800000u);  // +inf
    EXPECT_TRUE(decodeRefused(b, true, "value 7 is not finite"));
    b = good;
    b[6] = 0;  // fresh
    b[48] = 'x';
    EXPECT_TRUE(decodeRefused(b, true, "fresh estimate"));
    b = good;
    std::memset(b.data() + 48, 'x', 128);
    EXPECT_TRUE(decodeRefused(b, true, "reason is not NUL-terminated"));
    b = good;
    b[48 + 100] = 'x';
    EXPECT_TRUE(decodeRefused(b, true, "reason padding"));
    b = good;
    EXPECT_FALSE(decodeRefused(b, true, ""));
}

// mixray info's view of a record: stale, lost, the first reason; damage is the decoder's error.
TEST(RecordDigest, SaysStaleLostAndWhy) {
    EXPECT_EQ(recordStreamKind(makeLightStreamInfo("l/l", "c/c", 30)), RecordStreamKind::kLight);
    EXPECT_EQ(recordStreamKind(makeEnvironmentMapStreamInfo("l/m", "e/e", 8, 4)),
              RecordStreamKind::kEnvironmentMap);
    EXPECT_EQ(recordStreamKind(makePoseStreamInfo("t/p", "c/c", 30, false)),
              RecordStreamKind::kPose);
    StreamInfo colour;
    colour.kind = StreamKind::kColor;
    EXPECT_EQ(recordStreamKind(colour), RecordStreamKind::kNone);

    LightRecord r = sampleRecord();
    r.groups[2].stale = true;  // "environment": stale without a reason, before probe's
    std::swap(r.groups[1], r.groups[2]);
    const auto b = encoded(r);
    auto digest = digestRecord(RecordStreamKind::kLight, {{}, b.data(), b.size()});
    ASSERT_TRUE(digest) << digest.status().toString();
    EXPECT_TRUE(digest->stale);
    EXPECT_FALSE(digest->lost);
    EXPECT_EQ(digest->reason, "probe:mirror: marker 23 not seen — pose stale");
    auto damaged = b;
    damaged[50] ^= 1;
    auto bad = digestRecord(RecordStreamKind::kLight, {{}, damaged.data(), damaged.size()});
    ASSERT_FALSE(bad);
    EXPECT_EQ(bad.status().code(), ErrorCode::kCorruptData);

    PoseRecord pose;
    pose.status = PoseStatus::kLost;
    pose.reason = "marker 23 not seen";
    auto pose_bytes = encodePoseRecord(pose);
    ASSERT_TRUE(pose_bytes);
    digest = digestRecord(RecordStreamKind::kPose, {{}, pose_bytes->data(), pose_bytes->size()});
    ASSERT_TRUE(digest);
    EXPECT_TRUE(digest->lost);
    EXPECT_FALSE(digest->stale);
    EXPECT_EQ(digest->reason, "marker 23 not seen");
    // A pose record is no light record.
    EXPECT_FALSE(
        digestRecord(RecordStreamKind::kLight, {{}, pose_bytes->data(), pose_bytes->size()}));
    EXPECT_EQ(digestRecord(RecordStreamKind::kNone, {}).status().code(),
              ErrorCode::kInvalidArgument);
}

// The fuzzer's seeds (tests/fuzz/corpus/light/, written by hand from the documented layouts)
// are valid records, each of exactly one kind: the documentation and the code agree.
TEST(RecordDigest, FuzzSeedsAreTheDocumentedLayouts) {
    const auto dir = test::sourceDir() / "tests" / "fuzz" / "corpus" / "light";
    int seeds = 0;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        const std::string bytes = test::readText(entry.path());
        const auto* data = reinterpret_cast<const uint8_t*>(bytes.data());
        const std::string name = entry.path().filename().string();
        const bool light = decodeLightRecord(data, bytes.size()).isOk();
        const bool map = decodeEnvironmentMapRecord(data, bytes.size()).isOk();
        const bool pose = decodePoseRecord(data, bytes.size()).isOk();
        EXPECT_EQ(light + map + pose, 1) << name;
        EXPECT_EQ(light, name.rfind("light_", 0) == 0) << name;
        EXPECT_EQ(map, name.rfind("envmap_", 0) == 0) << name;
        EXPECT_EQ(pose, name.rfind("pose_", 0) == 0) << name;
        ++seeds;
    }
    EXPECT_GE(seeds, 5);
    const std::string seed = test::readText(dir / "light_render_probe_env.bin");
    auto r = decodeLightRecord(reinterpret_cast<const uint8_t*>(seed.data()), seed.size());
    ASSERT_TRUE(r) << r.status().toString();
    ASSERT_EQ(r->groups.size(), 3u);
    EXPECT_EQ(r->groups[1].reason, "marker 23 not seen");
    EXPECT_EQ(r->groups[0].lights[0].position_world, Eigen::Vector3d(1.5, -1.2, 2.7));
    const std::string v1 = test::readText(dir / "pose_v1_valid.bin");
    auto p = decodePoseRecord(reinterpret_cast<const uint8_t*>(v1.data()), v1.size());
    ASSERT_TRUE(p) << p.status().toString();
    EXPECT_EQ(p->anchor, "marker:23");
}

}  // namespace
}  // namespace mixray::tracking
