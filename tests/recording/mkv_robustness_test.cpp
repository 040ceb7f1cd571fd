// Damaged recordings: cut at many offsets, bytes flipped, unfinished, empty, missing or not
// Matroska at all. Every case ends in exact frames and a clear error, never a crash.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <random>
#include <set>

#include "mixray/graph/mkv.h"
#include "recording_test_util.h"
#include "test_data.h"

namespace mixray {
namespace {

using test::ExpectedFrame;

std::vector<uint8_t> readBytes(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void writeBytes(const std::filesystem::path& path, const std::vector<uint8_t>& bytes, size_t size) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(size));
}

// A small recording of several formats with the file size after each frame.
struct Sample {
    std::filesystem::path path;
    RecordingHeader header;
    std::vector<ExpectedFrame> frames;
    std::vector<uint64_t> offsets;
    uint64_t header_bytes = 0;
    std::vector<uint8_t> bytes;
};

Sample makeSample(const std::filesystem::path& dir) {
    Sample sample;
    sample.path = dir / "sample.mkv";
    sample.header = test::makeHeader({test::makeStream("k/depth", PixelFormat::kDepth16, 24, 16),
                                      test::makeStream("k/color", PixelFormat::kMJPEG, 16, 8),
                                      test::makeStream("k/rgb", PixelFormat::kRGB8, 12, 8),
                                      test::makeStream("k/imu", PixelFormat::kBinary, 0, 1)});
    sample.frames =
        test::writeRecording(sample.path, sample.header, 8, &sample.offsets, &sample.header_bytes);
    sample.bytes = readBytes(sample.path);
    return sample;
}

// Reads `path` to its end; every frame must equal the written one at the same position
// (nothing is skipped before damage), and the end must be a clean status.
struct ReadOutcome {
    bool opened = false;
    Status status;  // the open error, or how reading ended
    size_t frames = 0;
    std::vector<RecordingDamage> damage;  // what the reader skipped
};

ReadOutcome readChecked(const std::filesystem::path& path, const std::vector<ExpectedFrame>& want,
                        bool positional) {
    ReadOutcome outcome;
    MkvReaderOptions options;
    options.decoder_threads = 1;
    auto reader = openMkv(path, options);
    if (!reader) {
        outcome.status = reader.status();
        return outcome;
    }
    outcome.opened = true;
    std::set<std::pair<StreamId, uint64_t>> seen;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame) {
            outcome.status = frame.status();
            break;
        }
        if (positional) {
            if (outcome.frames >= want.size()) {
                ADD_FAILURE() << "more frames than written";
                break;
            }
            EXPECT_TRUE(test::sameFrame(*frame, want[outcome.frames]))
                << "frame " << outcome.frames;
        } else {
            // After damage the reader may resynchronise: any frame it returns must still be
            // one that was written, bit for bit.
            const ExpectedFrame* match = nullptr;
            for (const auto& w : want) {
                if (w.meta.stream == frame->meta().stream &&
                    w.meta.sequence == frame->meta().sequence) {
                    match = &w;
                }
            }
            if (!match) {
                ADD_FAILURE() << "a frame that was never written";
                break;
            }
            EXPECT_TRUE(test::sameFrame(*frame, *match)) << "frame " << outcome.frames;
            EXPECT_TRUE(seen.insert({match->meta.stream, match->meta.sequence}).second)
                << "frame returned twice";
        }
        ++outcome.frames;
    }
    outcome.damage = (*reader)->damage();
    return outcome;
}

class MkvRobustness : public ::testing::Test {
protected:
    static void SetUpTestSuite() { setFfmpegLogging(false); }
};

TEST_F(MkvRobustness, TruncatedFilesGiveEveryCompleteFrameThenAnError) {
    const auto dir = test::tempDir();
    const Sample sample = makeSample(dir);
    ASSERT_FALSE(sample.frames.empty());
    const size_t size = sample.bytes.size();

    std::set<size_t> cuts;
    for (size_t i = 0; i < 60; ++i)
        cuts.insert(size * i / 60);  // spread over the file
    for (size_t at = 0; at < sample.header_bytes; at += 97)
        cuts.insert(at);                      // inside the header
    for (uint64_t offset : sample.offsets) {  // at and right around frame boundaries
        cuts.insert(offset - 1);
        cuts.insert(offset);
        cuts.insert(offset + 1);
    }
    cuts.insert(sample.header_bytes);
    cuts.insert(size - 1);

    const auto cut_path = dir / "cut.mkv";
    for (size_t cut : cuts) {
        if (cut >= size)
            continue;
        SCOPED_TRACE("cut at byte " + std::to_string(cut) + " of " + std::to_string(size));
        writeBytes(cut_path, sample.bytes, cut);
        const ReadOutcome outcome = readChecked(cut_path, sample.frames, true);
        if (!outcome.opened) {
            // Only a cut inside the header (or right at its end: FFmpeg's demuxer wants the
            // start of a cluster) may keep the file from opening, with a message naming it.
            EXPECT_LE(cut, sample.header_bytes) << outcome.status.toString();
            EXPECT_NE(outcome.status.message().find(cut_path.string()), std::string::npos)
                << outcome.status.toString();
            continue;
        }
        size_t complete = 0;
        while (complete < sample.offsets.size() && sample.offsets[complete] <= cut)
            ++complete;
        EXPECT_GE(outcome.frames, complete) << outcome.status.toString();
        EXPECT_TRUE(outcome.status.code() == ErrorCode::kCorruptData ||
                    outcome.status.code() == ErrorCode::kEndOfStream)
            << outcome.status.toString();
        if (outcome.frames < sample.frames.size()) {
            // A cut that loses frames is reported as such.
            EXPECT_EQ(outcome.status.code(), ErrorCode::kCorruptData) << outcome.status.toString();
        }
    }
}

TEST_F(MkvRobustness, FlippedBytesGiveExactFramesOrAnErrorNeverGarbage) {
    const auto dir = test::tempDir();
    const Sample sample = makeSample(dir);
    const auto damaged_path = dir / "damaged.mkv";
    std::mt19937 random(20240601);
    size_t errors = 0;
    for (int trial = 0; trial < 80; ++trial) {
        std::vector<uint8_t> bytes = sample.bytes;
        const size_t at = random() % bytes.size();
        bytes[at] ^= static_cast<uint8_t>(1u << (random() % 8));
        if (trial % 4 == 0 && at + 16 < bytes.size()) {
            for (size_t i = 0; i < 16; ++i)
                bytes[at + i] = static_cast<uint8_t>(random());
        }
        writeBytes(damaged_path, bytes, bytes.size());
        SCOPED_TRACE("damage at byte " + std::to_string(at));
        const ReadOutcome outcome = readChecked(damaged_path, sample.frames, false);
        if (!outcome.opened || outcome.status.code() != ErrorCode::kEndOfStream ||
            !outcome.damage.empty())
            ++errors;
        if (outcome.opened) {
            EXPECT_TRUE(outcome.status.code() == ErrorCode::kCorruptData ||
                        outcome.status.code() == ErrorCode::kEndOfStream)
                << outcome.status.toString();
            // Frames lost without an error must have been reported as damage.
            if (outcome.frames < sample.frames.size() &&
                outcome.status.code() == ErrorCode::kEndOfStream) {
                EXPECT_FALSE(outcome.damage.empty())
                    << outcome.frames << " of " << sample.frames.size() << " frames, no damage";
            }
        } else {
            EXPECT_NE(outcome.status.message().find(damaged_path.string()), std::string::npos)
                << outcome.status.toString();
        }
    }
    EXPECT_GT(errors, 0u) << "no damage was ever detected";
}

// 5000 bytes overwritten in the middle of a recording: FFmpeg skips to the next cluster it
// finds; the frames before are exact, the skipped stretch is reported as damage with its byte
// offset, and nothing after it is garbage.
TEST_F(MkvRobustness, OverwrittenBytesInTheMiddleAreReportedAsDamageWithWhere) {
    const auto dir = test::tempDir();
    const auto path = dir / "long.mkv";
    const RecordingHeader header =
        test::makeHeader({test::makeStream("k/depth", PixelFormat::kDepth16, 64, 48),
                          test::makeStream("k/rgb", PixelFormat::kRGB8, 64, 48)});
    const auto frames = test::writeRecording(path, header, 60);
    std::vector<uint8_t> bytes = readBytes(path);
    // From the first cluster at or after the middle: the damage breaks the file's structure
    // (damage inside a payload alone costs that frame, see below).
    const uint8_t cluster[] = {0x1F, 0x43, 0xB6, 0x75};
    const size_t at = static_cast<size_t>(
        std::search(bytes.begin() + static_cast<std::ptrdiff_t>(bytes.size() / 2), bytes.end(),
                    std::begin(cluster), std::end(cluster)) -
        bytes.begin());
    ASSERT_LT(at + 5000, bytes.size());
    for (size_t i = 0; i < 5000; ++i)
        bytes[at + i] = static_cast<uint8_t>(0x55 ^ (i * 7));
    const auto damaged = dir / "damaged.mkv";
    writeBytes(damaged, bytes, bytes.size());

    const ReadOutcome outcome = readChecked(damaged, frames, false);
    ASSERT_TRUE(outcome.opened) << outcome.status.toString();
    EXPECT_LT(outcome.frames, frames.size());
    ASSERT_FALSE(outcome.damage.empty())
        << outcome.frames << " of " << frames.size() << " frames, " << outcome.status.toString();
    const RecordingDamage& d = outcome.damage.front();
    EXPECT_GE(d.byte_offset, static_cast<int64_t>(at) - 65536);
    EXPECT_LE(d.byte_offset, static_cast<int64_t>(at + 5000) + 65536);
    EXPECT_FALSE(d.what.empty());
    EXPECT_GE(d.after_stamp_ns, frames.front().meta.host_stamp_ns);
    if (outcome.status.code() == ErrorCode::kEndOfStream) {
        // Reading went on after the damage, from a byte past it.
        EXPECT_GT(d.resumed_at, static_cast<int64_t>(at));
    }
}

// One byte flipped inside a frame's payload, the file's structure intact: that frame fails its
// CRC and is lost, said as damage with where it is; every frame before and after is read, exact.
TEST_F(MkvRobustness, AFrameFailingItsCrcIsSkippedAndSaidAndReadingGoesOn) {
    const auto dir = test::tempDir();
    const Sample sample = makeSample(dir);
    // An MJPEG frame from the middle: stored as it came, so its bytes are in the file as such.
    size_t victim = sample.frames.size() / 2;
    while (victim < sample.frames.size() && sample.frames[victim].meta.stream != 1)
        ++victim;
    ASSERT_LT(victim, sample.frames.size());
    const ImageView image = sample.frames[victim].frame.image();
    std::vector<uint8_t> bytes = sample.bytes;
    const auto payload =
        std::search(bytes.begin(), bytes.end(), image.data, image.data + image.size_bytes);
    ASSERT_NE(payload, bytes.end());
    const auto at = static_cast<int64_t>(payload - bytes.begin());
    const auto flipped = at + static_cast<int64_t>(image.size_bytes / 2);
    bytes[static_cast<size_t>(flipped)] ^= 0x10;
    const auto damaged = dir / "one_frame.mkv";
    writeBytes(damaged, bytes, bytes.size());

    const ReadOutcome outcome = readChecked(damaged, sample.frames, false);
    ASSERT_TRUE(outcome.opened) << outcome.status.toString();
    EXPECT_EQ(outcome.status.code(), ErrorCode::kEndOfStream) << outcome.status.toString();
    EXPECT_EQ(outcome.frames, sample.frames.size() - 1);
    ASSERT_EQ(outcome.damage.size(), 1u);
    const RecordingDamage& d = outcome.damage.front();
    EXPECT_LE(d.byte_offset, at);
    EXPECT_GT(d.resumed_at, flipped);
    EXPECT_NE(d.what.find("stream 'k/color'"), std::string::npos) << d.what;
    EXPECT_NE(d.what.find("payload CRC mismatch"), std::string::npos) << d.what;
}

TEST_F(MkvRobustness, RecordingCutOffByACrashReadsToItsLastFrame) {
    const auto dir = test::tempDir();
    RecordingHeader header;
    header.streams = {test::makeStream("c/depth", PixelFormat::kDepth16, 16, 16),
                      test::makeStream("c/imu", PixelFormat::kBinary, 0, 1)};
    auto writer = createMkvWriter(dir / "live.mkv", header);
    ASSERT_TRUE(writer);
    std::vector<ExpectedFrame> written;
    for (int i = 0; i < 10; ++i) {
        for (StreamId s = 0; s < 2; ++s) {
            FrameMetadata meta;
            meta.stream = s;
            meta.sequence = static_cast<uint64_t>(i);
            meta.host_stamp_ns = 5'000'000'000 + i * 10'000'000 + s;
            FrameRef frame = test::makeFrame(header.streams[s], meta, static_cast<uint32_t>(i + s));
            ASSERT_TRUE((*writer)->write(frame));
            written.push_back({frame, meta});
        }
    }
    // What is on disk while the writer is still open is what a crash would leave.
    std::filesystem::copy_file(dir / "live.mkv", dir / "crashed.mkv");
    ASSERT_TRUE((*writer)->close());

    const ReadOutcome crashed = readChecked(dir / "crashed.mkv", written, true);
    ASSERT_TRUE(crashed.opened) << crashed.status.toString();
    EXPECT_EQ(crashed.frames, written.size());
    EXPECT_EQ(crashed.status.code(), ErrorCode::kCorruptData) << crashed.status.toString();
    EXPECT_NE(crashed.status.message().find("never finished"), std::string::npos)
        << crashed.status.toString();

    const ReadOutcome finished = readChecked(dir / "live.mkv", written, true);
    EXPECT_EQ(finished.frames, written.size());
    EXPECT_EQ(finished.status.code(), ErrorCode::kEndOfStream) << finished.status.toString();
}

TEST_F(MkvRobustness, NotARecordingGivesAClearErrorNamingTheFile) {
    const auto dir = test::tempDir();

    auto missing = openMkv(dir / "missing.mkv");
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(missing.status().message().find("missing.mkv"), std::string::npos);

    auto directory = openMkv(dir);
    ASSERT_FALSE(directory);
    EXPECT_EQ(directory.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(directory.status().message().find("directory"), std::string::npos);

    writeBytes(dir / "empty.mkv", {}, 0);
    auto empty = openMkv(dir / "empty.mkv");
    ASSERT_FALSE(empty);
    EXPECT_EQ(empty.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(empty.status().message().find("empty.mkv: empty file"), std::string::npos)
        << empty.status().message();

    const std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n', 0, 0,
                                      0,    13,  'I', 'H', 'D',  'R',  0,    0,    0, 1,
                                      0,    0,   0,   1,   8,    0,    0,    0};
    writeBytes(dir / "image.mkv", png, png.size());
    auto renamed = openMkv(dir / "image.mkv");
    ASSERT_FALSE(renamed);
    EXPECT_EQ(renamed.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(renamed.status().message().find("image.mkv"), std::string::npos);
    EXPECT_NE(renamed.status().message().find("PNG"), std::string::npos)
        << renamed.status().message();

    // EBML magic followed by garbage.
    std::vector<uint8_t> garbage = {0x1A, 0x45, 0xDF, 0xA3};
    for (int i = 0; i < 500; ++i)
        garbage.push_back(static_cast<uint8_t>(i * 37 + 11));
    writeBytes(dir / "garbage.mkv", garbage, garbage.size());
    auto bad = openMkv(dir / "garbage.mkv");
    ASSERT_FALSE(bad);
    EXPECT_NE(bad.status().message().find("garbage.mkv"), std::string::npos);

    // The content decides, not the name: a recording named .png opens.
    const Sample sample = makeSample(dir);
    std::filesystem::copy_file(sample.path, dir / "recording.png");
    const ReadOutcome misnamed = readChecked(dir / "recording.png", sample.frames, true);
    EXPECT_TRUE(misnamed.opened) << misnamed.status.toString();
    EXPECT_EQ(misnamed.frames, sample.frames.size());

    // Matroska, but not ours and not an Azure Kinect file: our tag renamed.
    std::vector<uint8_t> foreign = sample.bytes;
    const std::string tag = "MIXRAY_FORMAT";
    for (size_t i = 0; i + tag.size() < foreign.size(); ++i) {
        if (std::equal(tag.begin(), tag.end(), foreign.begin() + static_cast<std::ptrdiff_t>(i))) {
            foreign[i] = 'X';
        }
    }
    writeBytes(dir / "foreign.mkv", foreign, foreign.size());
    auto other = openMkv(dir / "foreign.mkv");
    ASSERT_FALSE(other);
    EXPECT_EQ(other.status().code(), ErrorCode::kUnsupported) << other.status().toString();
    EXPECT_NE(other.status().message().find("foreign.mkv"), std::string::npos);

    MkvReaderOptions zero;
    zero.buffers_per_stream = 0;
    EXPECT_EQ(openMkv(sample.path, zero).status().code(), ErrorCode::kInvalidArgument);
}

}  // namespace
}  // namespace mixray
