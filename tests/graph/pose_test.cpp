// Pose records (mixray/graph/pose.h): round trips, damaged or truncated records refused, and
// version-1 records (the committed sessions', users' recordings) still read.
#include "mixray/graph/pose.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>

#include "mixray/graph/mkv.h"
#include "reference_crc32.h"
#include "test_data.h"

namespace mixray {
namespace {

PoseRecord samplePose() {
    PoseRecord r;
    r.frame_sequence = 0x0123456789abcdefULL;
    r.frame_device_stamp_ns = -1234567890123LL;
    r.status = PoseStatus::kStale;
    r.marker_id = 17;
    r.anchor = "marker:17";
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()).matrix();
    T.translation() = Eigen::Vector3d(0.125, -0.75, 1.5e-3);
    r.setTransform(T);
    r.error = 0.35f;
    r.reason = "marker 17 not seen, 3 frames ago ✓";
    return r;
}

TEST(PoseRecord, RoundTripIsExact) {
    const PoseRecord in = samplePose();
    auto bytes = encodePoseRecord(in);
    ASSERT_TRUE(bytes) << bytes.status().toString();
    auto out = decodePoseRecord(bytes->data(), bytes->size());
    ASSERT_TRUE(out) << out.status().toString();
    EXPECT_EQ(out->frame_sequence, in.frame_sequence);
    EXPECT_EQ(out->frame_device_stamp_ns, in.frame_device_stamp_ns);
    EXPECT_EQ(out->status, PoseStatus::kStale);
    EXPECT_EQ(out->marker_id, 17);
    EXPECT_EQ(out->anchor, "marker:17");
    EXPECT_EQ(out->reason, in.reason);
    EXPECT_EQ(out->error, 0.35f);
    EXPECT_EQ(out->translation, in.translation);  // doubles stored bit for bit
    EXPECT_EQ(out->rotation.coeffs(), in.rotation.coeffs());
    EXPECT_TRUE(out->transform().isApprox(in.transform(), 1e-15));
}

TEST(PoseRecord, LayoutIsLittleEndianAtDocumentedOffsets) {
    PoseRecord r;
    r.frame_sequence = 0x0807060504030201ULL;
    r.anchor = "world";
    r.translation = Eigen::Vector3d(1.0, 0, 0);
    auto bytes = encodePoseRecord(r);
    ASSERT_TRUE(bytes);
    const auto& b = *bytes;
    EXPECT_EQ(b.size(), 256u);
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(b.data()), 4), "MXPO");
    EXPECT_EQ(b[4], 2);  // version
    EXPECT_EQ(b[5], 0);
    for (int i = 0; i < 8; ++i)
        EXPECT_EQ(b[8 + i], i + 1) << "sequence byte " << i;
    EXPECT_EQ(b[24], 0xff);  // marker id -1
    // tx = 1.0 as an IEEE double, little-endian: 00 .. 00 f0 3f.
    EXPECT_EQ(b[32 + 6], 0xf0);
    EXPECT_EQ(b[32 + 7], 0x3f);
    // qw = 1.0 at offset 56 + 24.
    EXPECT_EQ(b[80 + 7], 0x3f);
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(b.data() + 88)), "world");
    EXPECT_EQ(b[120], 0);  // no reason

    r.status = PoseStatus::kLost;
    r.reason = "marker 23 not seen";
    auto lost = encodePoseRecord(r);
    ASSERT_TRUE(lost);
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(lost->data() + 120)), r.reason);
    for (size_t i = 120 + r.reason.size(); i < 252; ++i)
        EXPECT_EQ((*lost)[i], 0) << "byte " << i;
}

TEST(PoseRecord, TruncatedOrLongPayloadsAreRefused) {
    auto bytes = encodePoseRecord(samplePose());
    ASSERT_TRUE(bytes);
    for (size_t size : {size_t{0}, size_t{1}, size_t{64}, size_t{127}, size_t{128}, size_t{255}}) {
        auto out = decodePoseRecord(bytes->data(), size);
        ASSERT_FALSE(out) << size;
        EXPECT_EQ(out.status().code(), ErrorCode::kCorruptData);
    }
    std::vector<uint8_t> longer(bytes->begin(), bytes->end());
    longer.push_back(0);
    EXPECT_FALSE(decodePoseRecord(longer.data(), longer.size()));
    EXPECT_FALSE(decodePoseRecord(nullptr, 256));
    EXPECT_FALSE(decodePoseRecord(nullptr, 128));
}

TEST(PoseRecord, EveryFlippedBitIsCaught) {
    auto bytes = encodePoseRecord(samplePose());
    ASSERT_TRUE(bytes);
    for (size_t bit = 0; bit < 8 * kPoseRecordBytes; ++bit) {
        auto damaged = *bytes;
        damaged[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
        auto out = decodePoseRecord(damaged.data(), damaged.size());
        ASSERT_FALSE(out) << "bit " << bit;
        EXPECT_EQ(out.status().code(), ErrorCode::kCorruptData);
    }
}

using test::referenceCrc32;

template <size_t N>
void resealCrc(std::array<uint8_t, N>& b) {
    const uint32_t crc = referenceCrc32(b.data(), N - 4);
    for (int i = 0; i < 4; ++i)
        b[N - 4 + i] = static_cast<uint8_t>(crc >> (8 * i));
}

TEST(PoseRecord, CrcIsTheIeeeCrcOfTheFirst252Bytes) {
    auto bytes = encodePoseRecord(samplePose());
    ASSERT_TRUE(bytes);
    auto resealed = *bytes;
    resealCrc(resealed);
    EXPECT_EQ(resealed, *bytes);
}

TEST(PoseRecord, WellFormedButInvalidContentIsRefused) {
    // Records with a correct CRC but content a buggy writer could produce.
    auto bytes = encodePoseRecord(samplePose());
    ASSERT_TRUE(bytes);
    const auto refused = [](std::array<uint8_t, kPoseRecordBytes> b) {
        resealCrc(b);
        auto out = decodePoseRecord(b.data(), b.size());
        return !out && out.status().code() == ErrorCode::kCorruptData;
    };
    auto b = *bytes;
    b[80 + 7] = 0x40;  // qw's exponent: |q| far from 1
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[6] = 3;  // status out of range
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[4] = 3;  // version 3
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[4] = 1;  // version 1 in a record of version 2's size
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[7] = 1;  // reserved
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[248] = 1;  // reserved
    EXPECT_TRUE(refused(b));
    b = *bytes;
    for (int i = 120; i < 248; ++i)
        b[i] = 'a';  // reason without its NUL
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[240] = 'x';  // garbage after the reason's NUL
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[120] = 0xff;  // not UTF-8
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[121] = '\n';  // a control character
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[6] = 0;  // a valid pose with a reason
    EXPECT_TRUE(refused(b));
    b = *bytes;
    for (int i = 88; i < 120; ++i)
        b[i] = 'a';  // anchor without its NUL
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[88 + 20] = 'x';  // garbage after the anchor's NUL
    EXPECT_TRUE(refused(b));
    b = *bytes;
    b[88] = 0;  // empty anchor
    EXPECT_TRUE(refused(b));
    b = *bytes;
    EXPECT_FALSE(refused(b));  // the untouched record, resealed, still decodes
}

TEST(PoseRecord, EncodeRefusesInvalidRecords) {
    PoseRecord r = samplePose();
    r.rotation = Eigen::Quaterniond(1, 1, 0, 0);
    EXPECT_EQ(encodePoseRecord(r).status().code(), ErrorCode::kInvalidArgument);
    r = samplePose();
    r.translation.x() = std::nan("");
    EXPECT_FALSE(encodePoseRecord(r));
    r = samplePose();
    r.anchor = "";
    EXPECT_FALSE(encodePoseRecord(r));
    r.anchor = std::string(32, 'a');
    EXPECT_FALSE(encodePoseRecord(r));
    r.anchor = "with space";
    EXPECT_FALSE(encodePoseRecord(r));
    r = samplePose();
    r.error = -2;
    EXPECT_FALSE(encodePoseRecord(r));
    r = samplePose();
    r.reason = std::string(128, 'a');
    EXPECT_EQ(encodePoseRecord(r).status().code(), ErrorCode::kInvalidArgument);
    r.reason = "tab\there";
    EXPECT_FALSE(encodePoseRecord(r));
    r.reason = "\xc3";  // a UTF-8 sequence cut short
    EXPECT_FALSE(encodePoseRecord(r));
    r.reason = "seen";
    r.status = PoseStatus::kValid;
    EXPECT_FALSE(encodePoseRecord(r));
    r = samplePose();
    r.anchor = std::string(31, 'a');
    r.reason = std::string(127, 'a');
    EXPECT_TRUE(encodePoseRecord(r));
}

// A version-1 record built byte by byte as docs/recording-format.md describes it (not by the
// encoder, which writes version 2 now).
std::array<uint8_t, kPoseRecordV1Bytes> handBuiltV1() {
    std::array<uint8_t, kPoseRecordV1Bytes> b{};
    std::memcpy(b.data(), "MXPO", 4);
    b[4] = 1;                    // version 1
    b[6] = 1;                    // stale
    b[8] = 42;                   // sequence 42
    b[16] = 0x10, b[17] = 0x27;  // device stamp 10000 ns
    b[24] = 23;                  // marker 23
    const float error = 0.5f;
    std::memcpy(b.data() + 28, &error, 4);  // the test hosts are little-endian
    const double values[7] = {0.1, -0.2, 1.5, 0, 0, std::sqrt(0.5), std::sqrt(0.5)};
    std::memcpy(b.data() + 32, values, sizeof values);
    std::memcpy(b.data() + 88, "marker:23", 9);
    resealCrc(b);
    return b;
}

TEST(PoseRecord, Version1RecordsStillDecodeWithoutReason) {
    const auto b = handBuiltV1();
    auto out = decodePoseRecord(b.data(), b.size());
    ASSERT_TRUE(out) << out.status().toString();
    EXPECT_EQ(out->frame_sequence, 42u);
    EXPECT_EQ(out->frame_device_stamp_ns, 10000);
    EXPECT_EQ(out->status, PoseStatus::kStale);
    EXPECT_EQ(out->marker_id, 23);
    EXPECT_EQ(out->error, 0.5f);
    EXPECT_EQ(out->anchor, "marker:23");
    EXPECT_EQ(out->translation, Eigen::Vector3d(0.1, -0.2, 1.5));
    EXPECT_EQ(out->rotation.w(), std::sqrt(0.5));
    EXPECT_TRUE(out->reason.empty());

    // Re-encoded it becomes version 2 and decodes to the same pose.
    auto v2 = encodePoseRecord(*out);
    ASSERT_TRUE(v2);
    auto again = decodePoseRecord(v2->data(), v2->size());
    ASSERT_TRUE(again);
    EXPECT_EQ(again->translation, out->translation);
    EXPECT_EQ(again->anchor, out->anchor);

    // Version 1's checks stand: its reserved word, its CRC, a version 2 field in its size.
    auto bad = b;
    bad[120] = 1;
    resealCrc(bad);
    EXPECT_EQ(decodePoseRecord(bad.data(), bad.size()).status().code(), ErrorCode::kCorruptData);
    bad = b;
    bad[4] = 2;
    resealCrc(bad);
    EXPECT_FALSE(decodePoseRecord(bad.data(), bad.size()));
    bad = b;
    bad[40] ^= 1;
    EXPECT_FALSE(decodePoseRecord(bad.data(), bad.size()));
}

// The committed simulated session was recorded with version-1 poses; it must keep reading.
TEST(PoseRecord, CommittedSessionsVersion1PosesDecode) {
    const auto path = test::fixturesDir() / "sessions" / "sim_tabletop.mkv";
    auto reader = openMkv(path);
    ASSERT_TRUE(reader) << reader.status().toString();
    StreamId pose = kInvalidStream;
    for (size_t i = 0; i < (*reader)->streams().size(); ++i)
        if ((*reader)->streams()[i].kind == StreamKind::kPose)
            pose = static_cast<StreamId>(i);
    ASSERT_NE(pose, kInvalidStream);
    EXPECT_EQ((*reader)->streams()[pose].tags.at("pose_record"), "mixray-pose-1");
    int poses = 0;
    for (;;) {
        auto frame = (*reader)->next();
        if (!frame) {
            ASSERT_EQ(frame.status().code(), ErrorCode::kEndOfStream) << frame.status().toString();
            break;
        }
        if (frame->meta().stream != pose)
            continue;
        ASSERT_EQ(frame->image().size_bytes, kPoseRecordV1Bytes);
        auto record = decodePoseRecord(frame->image());
        ASSERT_TRUE(record) << "pose " << poses << ": " << record.status().toString();
        EXPECT_TRUE(record->reason.empty());
        ++poses;
    }
    EXPECT_GT(poses, 0);
}

TEST(PoseRecord, StreamInfoIsABinaryPoseStream) {
    const StreamInfo info = makePoseStreamInfo("truth/pose", "kinect/color", 30, true);
    EXPECT_EQ(info.device, "truth");
    EXPECT_EQ(info.kind, StreamKind::kPose);
    EXPECT_EQ(info.format.format, PixelFormat::kBinary);
    EXPECT_EQ(info.format.width, 256);
    EXPECT_EQ(info.tags.at("pose_of"), "kinect/color");
    EXPECT_EQ(info.tags.at("pose_record"), "mixray-pose-2");
    EXPECT_EQ(info.tags.at("ground_truth"), "true");
    EXPECT_FALSE(makePoseStreamInfo("t/p", "c/c", 30, false).tags.count("ground_truth"));
}

}  // namespace
}  // namespace mixray
