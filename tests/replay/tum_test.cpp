// TUM RGB-D folders: exact timestamps, list-file errors with file:line, reading and writing.
#include "mixray/replay/tum.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mixray/replay/convert.h"
#include "mixray/replay/depth_units.h"
#include "replay_test_util.h"
#include "test_data.h"

namespace mixray::replay {
namespace {

using test::readFile;

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

TEST(TumStamp, ParsesDecimalTextExactly) {
    EXPECT_EQ(*parseTumStamp("1305031102.175304"), 1305031102175304000);
    EXPECT_EQ(*parseTumStamp("1305031102.1753045"), 1305031102175304500);
    EXPECT_EQ(*parseTumStamp("12"), 12'000'000'000);
    EXPECT_EQ(*parseTumStamp("0.000000001"), 1);
    EXPECT_EQ(*parseTumStamp("9223372036.854775807"), INT64_MAX);
    EXPECT_FALSE(parseTumStamp("9223372036.854775808"));
    // A double would turn ...175304 into ...175303999 or similar; the text route cannot.
    EXPECT_EQ(*parseTumStamp("1311868164.363181"), 1311868164363181000);
}

TEST(TumStamp, RejectsWhatIsNotDecimalSeconds) {
    for (const char* bad : {"", "-1.5", "+1.5", "1e9", "1.", ".5", "1.0123456789", "abc", "1,5",
                            "99999999999999.0", "1.2.3"}) {
        auto stamp = parseTumStamp(bad);
        ASSERT_FALSE(stamp) << bad;
        EXPECT_EQ(stamp.status().code(), ErrorCode::kCorruptData);
        EXPECT_TRUE(contains(stamp.status().message(), "bad timestamp")) << bad;
    }
}

TEST(TumStamp, FormatsBackToTheSameValue) {
    EXPECT_EQ(formatTumStamp(1305031102175304000, 6), "1305031102.175304");
    EXPECT_EQ(formatTumStamp(1305031102175304000, 9), "1305031102.175304000");
    EXPECT_EQ(formatTumStamp(12'000'000'000, 0), "12");
    EXPECT_EQ(formatTumStamp(5, 9), "0.000000005");
    for (int64_t ns :
         {int64_t{0}, int64_t{1}, int64_t{999'999'999}, int64_t{1305031102175304123}}) {
        EXPECT_EQ(*parseTumStamp(formatTumStamp(ns, 9)), ns);
    }
}

TEST(TumList, ParsesCommentsEntriesAndDigits) {
    const std::string text =
        "# color images\r\n# file: 'x.bag'\n# timestamp filename\n\n"
        "1305031102.175304 rgb/1305031102.175304.png\n"
        "  1305031102.211214\trgb/1305031102.211214.png  \n"
        "1305031102.3 rgb/b.png";  // no final newline
    auto list = parseTumList(text, "rgb.txt");
    ASSERT_TRUE(list) << list.status().toString();
    ASSERT_EQ(list->comments.size(), 3u);
    EXPECT_EQ(list->comments[0], "# color images");
    ASSERT_EQ(list->entries.size(), 3u);
    EXPECT_EQ(list->entries[0].stamp_ns, 1305031102175304000);
    EXPECT_EQ(list->entries[0].file, "rgb/1305031102.175304.png");
    EXPECT_EQ(list->entries[0].line, 5);
    EXPECT_EQ(list->entries[1].stamp_ns, 1305031102211214000);
    EXPECT_EQ(list->entries[1].line, 6);
    EXPECT_EQ(list->entries[2].file, "rgb/b.png");
    EXPECT_EQ(list->stamp_digits, 6);
}

TEST(TumList, MalformedLinesNameFileAndLine) {
    struct Case {
        const char* text;
        const char* expected;  // part of the message
    };
    const Case cases[] = {
        {"# c\n1.0 a.png extra\n", "rgb.txt:2: expected 'timestamp filename', found 3 fields"},
        {"# c\n\n1.0\n", "rgb.txt:3: expected 'timestamp filename', found 1 fields"},
        {"1.0 a.png\nx1.0 b.png\n", "rgb.txt:2: bad timestamp 'x1.0'"},
        {"2.0 a.png\n1.0 b.png\n", "rgb.txt:2: timestamp 1.0 is earlier"},
        {"1.0 /etc/a.png\n", "rgb.txt:1: '/etc/a.png' is absolute"},
        {"1.0 rgb/../../a.png\n", "rgb.txt:1: 'rgb/../../a.png' leaves the folder"},
    };
    for (const Case& c : cases) {
        auto list = parseTumList(c.text, "rgb.txt");
        ASSERT_FALSE(list) << c.text;
        EXPECT_EQ(list.status().code(), ErrorCode::kCorruptData);
        EXPECT_TRUE(contains(list.status().message(), c.expected))
            << "got: " << list.status().message() << "\nexpected: " << c.expected;
    }
}

TEST(TumFolder, ReadsStreamsFramesAndAttachmentsExactly) {
    const auto dir = test::tempDir() / "tum";
    const auto stamps = test::writeSyntheticTum(dir, 5);
    auto reader = openTum(dir);
    ASSERT_TRUE(reader) << reader.status().toString();
    RecordingReader& r = **reader;
    EXPECT_EQ(r.format(), "tum");
    ASSERT_EQ(r.streams().size(), 2u);
    const StreamInfo& color = r.streams()[0];
    const StreamInfo& depth = r.streams()[1];
    EXPECT_EQ(color.name, "tum/color");
    EXPECT_EQ(color.kind, StreamKind::kColor);
    EXPECT_EQ(color.format, ImageDesc::packed(PixelFormat::kRGB8, 32, 24));
    EXPECT_EQ(depth.name, "tum/depth");
    EXPECT_EQ(depth.kind, StreamKind::kDepth);
    EXPECT_EQ(depth.format, ImageDesc::packed(PixelFormat::kDepth16, 32, 24));
    EXPECT_EQ(depth.tags.at(kDepthScaleTag), "5000");
    EXPECT_EQ(*depthScalePerMetre(depth), 5000);
    EXPECT_EQ(*depthScalePerMetre(color), 1000);
    EXPECT_NEAR(color.nominal_fps, 30.0, 0.1);
    ASSERT_EQ(r.attachments().size(), 2u);
    EXPECT_EQ(r.attachments()[0].name, "accelerometer.txt");
    EXPECT_EQ(r.attachments()[1].name, "groundtruth.txt");
    const std::string gt = readFile(dir / "groundtruth.txt");
    EXPECT_EQ(std::string(r.attachments()[1].data.begin(), r.attachments()[1].data.end()), gt);

    const auto frames = test::readAll(r);
    ASSERT_EQ(frames.size(), 10u);
    // Depth is stamped 14.897 ms before its colour image, so the two alternate.
    for (size_t i = 0; i < frames.size(); ++i) {
        const auto& f = frames[i];
        const bool is_depth = i % 2 == 0;
        EXPECT_EQ(f.meta.stream, is_depth ? 1u : 0u);
        EXPECT_EQ(f.meta.sequence, i / 2);
        const int64_t expected = stamps[i / 2] - (is_depth ? 14'897'000 : 0);
        EXPECT_EQ(f.meta.host_stamp_ns, expected);
        EXPECT_EQ(f.meta.device_stamp_ns, expected);
        // Pixels are the PNG's values; colour R,G,B in memory.
        const auto file =
            dir / (is_depth ? "depth/" : "rgb/") / (formatTumStamp(expected, 6) + ".png");
        cv::Mat png = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
        if (is_depth) {
            cv::Mat mine(24, 32, CV_16UC1, const_cast<uint8_t*>(f.image.view().data));
            EXPECT_EQ(cv::norm(mine, png, cv::NORM_INF), 0.0);
            EXPECT_EQ(mine.at<uint16_t>(0, 1), 3);  // below 1 mm: kept
        } else {
            const uint8_t* p = f.image.view().data;
            const cv::Vec3b bgr = png.at<cv::Vec3b>(3, 5);
            const size_t at = (3 * 32 + 5) * 3;
            EXPECT_EQ(p[at + 0], bgr[2]);
            EXPECT_EQ(p[at + 1], bgr[1]);
            EXPECT_EQ(p[at + 2], bgr[0]);
        }
    }
}

TEST(TumFolder, ExportReproducesListsPixelsAndAttachments) {
    const auto tmp = test::tempDir();
    const auto dir = tmp / "tum";
    test::writeSyntheticTum(dir, 4);
    auto reader = openTum(dir);
    ASSERT_TRUE(reader) << reader.status().toString();
    const auto out = tmp / "exported";
    auto summary = exportTum(**reader, out);
    ASSERT_TRUE(summary) << summary.status().toString();
    EXPECT_EQ(summary->frames, 8u);
    EXPECT_EQ(summary->frames_per_stream, (std::vector<uint64_t>{4, 4}));
    EXPECT_GT(summary->bytes_written, 0u);
    for (const char* name : {"rgb.txt", "depth.txt", "accelerometer.txt", "groundtruth.txt"}) {
        EXPECT_EQ(readFile(out / name), readFile(dir / name)) << name;
    }
    auto list = parseTumList(readFile(dir / "depth.txt"), "depth.txt");
    for (const auto& e : list->entries)
        test::expectSamePixels(dir / e.file, out / e.file);
    list = parseTumList(readFile(dir / "rgb.txt"), "rgb.txt");
    for (const auto& e : list->entries)
        test::expectSamePixels(dir / e.file, out / e.file);

    // Writers refuse to mix recordings in one folder.
    auto again = openTum(dir);
    auto refused = exportTum(**again, out);
    ASSERT_FALSE(refused);
    EXPECT_TRUE(contains(refused.status().message(), "not empty"));
}

TEST(TumFolder, MillimetreDepthIsWrittenInTumUnits) {
    RecordingHeader header;
    StreamInfo depth;
    depth.name = "kinect/depth";
    depth.kind = StreamKind::kDepth;
    depth.format = ImageDesc::packed(PixelFormat::kDepth16, 4, 1);
    header.streams.push_back(depth);
    auto pool = BufferPool::create({depth.format, 0, 2, "p"});
    const auto out = test::tempDir() / "tum";
    auto writer = createTumWriter(out, header);
    ASSERT_TRUE(writer) << writer.status().toString();
    WritableFrame w = pool->acquire();
    const uint16_t mm[4] = {0, 1, 1234, 13107};
    std::memcpy(w.image().data, mm, sizeof(mm));
    w.meta().stream = 0;
    w.meta().host_stamp_ns = 1'500'000'000;
    ASSERT_TRUE((*writer)->write(std::move(w).publish()));
    // 13108 mm is 65540 TUM units: more than 16 bits, refused with the pixel named.
    WritableFrame far = pool->acquire();
    const uint16_t too_far[4] = {0, 0, 0, 13108};
    std::memcpy(far.image().data, too_far, sizeof(too_far));
    far.meta().stream = 0;
    far.meta().host_stamp_ns = 1'600'000'000;
    Status status = (*writer)->write(std::move(far).publish());
    EXPECT_EQ(status.code(), ErrorCode::kInvalidArgument);
    EXPECT_TRUE(contains(status.message(), "(3,0)")) << status.message();
    ASSERT_TRUE((*writer)->close());
    EXPECT_FALSE(std::filesystem::exists(out / "rgb.txt"));
    EXPECT_EQ(readFile(out / "depth.txt"),
              "# depth maps\n# file: 'kinect/depth'\n# timestamp filename\n"
              "1.500000 depth/1.500000.png\n");
    cv::Mat png = cv::imread((out / "depth/1.500000.png").string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(png.type(), CV_16UC1);
    EXPECT_EQ(png.at<uint16_t>(0, 0), 0);
    EXPECT_EQ(png.at<uint16_t>(0, 1), 5);
    EXPECT_EQ(png.at<uint16_t>(0, 2), 6170);
    EXPECT_EQ(png.at<uint16_t>(0, 3), 65535);
}

TEST(TumFolder, MissingImageNamesTheListLine) {
    const auto dir = test::tempDir() / "tum";
    test::writeSyntheticTum(dir, 3);
    auto list = parseTumList(readFile(dir / "depth.txt"), "depth.txt");
    std::filesystem::remove(dir / list->entries[1].file);
    auto reader = openTum(dir);
    ASSERT_FALSE(reader);
    EXPECT_EQ(reader.status().code(), ErrorCode::kNotFound);
    EXPECT_TRUE(contains(reader.status().message(),
                         "depth.txt:" + std::to_string(list->entries[1].line) + ": " +
                             list->entries[1].file + ": listed image does not exist"))
        << reader.status().message();
}

TEST(TumFolder, WrongBitDepthIsNamed) {
    const auto dir = test::tempDir() / "tum";
    test::writeSyntheticTum(dir, 2);
    auto list = parseTumList(readFile(dir / "depth.txt"), "depth.txt");
    // An 8-bit depth map (a common mistake when exporting) as the first depth image.
    cv::imwrite((dir / list->entries[0].file).string(), cv::Mat(24, 32, CV_8UC1, cv::Scalar(7)));
    auto reader = openTum(dir);
    ASSERT_FALSE(reader);
    EXPECT_EQ(reader.status().code(), ErrorCode::kCorruptData);
    EXPECT_TRUE(contains(reader.status().message(), "depth.txt:4: "));
    EXPECT_TRUE(
        contains(reader.status().message(), "8-bit 1-channel 32x24 image, expected 16-bit grey"))
        << reader.status().message();
}

TEST(TumFolder, SizeChangeMidwayIsAnErrorOfThatFrame) {
    const auto dir = test::tempDir() / "tum";
    test::writeSyntheticTum(dir, 3);
    auto list = parseTumList(readFile(dir / "rgb.txt"), "rgb.txt");
    cv::imwrite((dir / list->entries[2].file).string(), cv::Mat(10, 10, CV_8UC3, cv::Scalar(1)));
    auto reader = openTum(dir);
    ASSERT_TRUE(reader) << reader.status().toString();  // only the first image is probed
    Status error;
    int good = 0;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame) {
            error = frame.status();
            break;
        }
        ++good;
    }
    EXPECT_EQ(good, 5);  // d0 c0 d1 c1 d2, then c2 is wrong
    EXPECT_EQ(error.code(), ErrorCode::kCorruptData);
    EXPECT_TRUE(contains(error.message(), "rgb.txt:6: " + list->entries[2].file))
        << error.message();
    EXPECT_TRUE(contains(error.message(), "expected 8-bit RGB 32x24")) << error.message();
}

TEST(TumFolder, NoListsIsNotFound) {
    const auto dir = test::tempDir();
    auto reader = openTum(dir);
    ASSERT_FALSE(reader);
    EXPECT_EQ(reader.status().code(), ErrorCode::kNotFound);
    EXPECT_TRUE(contains(reader.status().message(), "neither rgb.txt nor depth.txt"));
}

TEST(TumFolder, SeekLandsOnTheFirstFrameAtOrAfter) {
    const auto dir = test::tempDir() / "tum";
    const auto stamps = test::writeSyntheticTum(dir, 6);
    auto reader = openTum(dir);
    ASSERT_TRUE(reader);
    // Between depth 3 and colour 3: colour 3 comes first, then depth 4.
    ASSERT_TRUE((*reader)->seek(stamps[3] - 1000));
    auto f = (*reader)->next();
    ASSERT_TRUE(f);
    EXPECT_EQ(f->meta().stream, 0u);
    EXPECT_EQ(f->meta().sequence, 3u);
    EXPECT_EQ(f->meta().host_stamp_ns, stamps[3]);
    f = (*reader)->next();
    EXPECT_EQ(f->meta().stream, 1u);
    EXPECT_EQ(f->meta().sequence, 4u);
    // Back to the start, and past the end.
    ASSERT_TRUE((*reader)->seek(0));
    EXPECT_EQ((*reader)->next()->meta().sequence, 0u);
    ASSERT_TRUE((*reader)->seek(stamps.back() + 1));
    EXPECT_EQ((*reader)->next().status().code(), ErrorCode::kEndOfStream);
}

TEST(TumFolder, HeldBuffersMakeTheReaderUnavailable) {
    const auto dir = test::tempDir() / "tum";
    test::writeSyntheticTum(dir, 4);
    auto reader = openTum(dir, {2});
    ASSERT_TRUE(reader);
    std::vector<FrameRef> held;
    for (int i = 0; i < 4; ++i)
        held.push_back(*(*reader)->next());  // d0 c0 d1 c1
    auto blocked = (*reader)->next();
    ASSERT_FALSE(blocked);
    EXPECT_EQ(blocked.status().code(), ErrorCode::kUnavailable);
    held.erase(held.begin());  // give back d0
    auto frame = (*reader)->next();
    ASSERT_TRUE(frame) << frame.status().toString();
    EXPECT_EQ(frame->meta().stream, 1u);
    EXPECT_EQ(frame->meta().sequence, 2u);
}

TEST(TumFolder, RealFramePair) {
    MIXRAY_REQUIRE_SHARED_DATA(test::realTumColor());
    MIXRAY_REQUIRE_SHARED_DATA(test::realTumDepth());
    const auto tmp = test::tempDir();
    const auto dir = tmp / "tum";
    ASSERT_TRUE(test::writeRealTum(dir));
    auto reader = openTum(dir);
    ASSERT_TRUE(reader) << reader.status().toString();
    ASSERT_EQ((*reader)->streams().size(), 2u);
    EXPECT_EQ((*reader)->streams()[0].format, ImageDesc::packed(PixelFormat::kRGB8, 640, 480));
    EXPECT_EQ((*reader)->streams()[1].format, ImageDesc::packed(PixelFormat::kDepth16, 640, 480));
    const auto frames = test::readAll(**reader);
    ASSERT_EQ(frames.size(), 2u);
    EXPECT_EQ(frames[0].meta.stream, 1u);  // depth 1305031102.160407 comes first
    EXPECT_EQ(frames[0].meta.host_stamp_ns, 1305031102160407000);
    EXPECT_EQ(frames[1].meta.host_stamp_ns, 1305031102175304000);

    cv::Mat depth_png = cv::imread(test::realTumDepth().string(), cv::IMREAD_UNCHANGED);
    cv::Mat depth(480, 640, CV_16UC1, const_cast<uint8_t*>(frames[0].image.view().data));
    EXPECT_EQ(cv::norm(depth, depth_png, cv::NORM_INF), 0.0);
    double max_value = 0;
    cv::minMaxLoc(depth, nullptr, &max_value);
    EXPECT_EQ(max_value, 46655);  // MANIFEST.md: TUM_depth.png max 46655 (9.331 m)
    cv::Mat color_png = cv::imread(test::realTumColor().string(), cv::IMREAD_UNCHANGED);
    const cv::Vec3b bgr = color_png.at<cv::Vec3b>(240, 320);
    const uint8_t* rgb = frames[1].image.view().data + (240 * 640 + 320) * 3;
    EXPECT_EQ(rgb[0], bgr[2]);
    EXPECT_EQ(rgb[2], bgr[0]);

    ASSERT_TRUE((*reader)->seek(0));
    const auto out = tmp / "exported";
    ASSERT_TRUE(exportTum(**reader, out));
    EXPECT_EQ(readFile(out / "rgb.txt"), readFile(dir / "rgb.txt"));
    EXPECT_EQ(readFile(out / "depth.txt"), readFile(dir / "depth.txt"));
    test::expectSamePixels(test::realTumColor(), out / "rgb/1305031102.175304.png");
    test::expectSamePixels(test::realTumDepth(), out / "depth/1305031102.160407.png");
}

// What TUM cannot hold is known from the header, before anything is written: the streams
// beyond one colour and one depth stream, attachments other than its side files, and (kept but
// changed) stream names, tags and device stamps.
TEST(TumFolder, LossesNameWhatTheFormatCannotHold) {
    auto stream = [](const char* name, StreamKind kind, PixelFormat format) {
        StreamInfo info;
        info.name = name;
        info.kind = kind;
        info.format = ImageDesc::packed(format, 32, 24);
        info.clock_domain = 7;
        return info;
    };
    RecordingHeader header;
    header.streams = {stream("cam/color", StreamKind::kColor, PixelFormat::kRGB8),
                      stream("cam/depth", StreamKind::kDepth, PixelFormat::kDepth16),
                      stream("mono/mono", StreamKind::kInfrared, PixelFormat::kMono8)};
    header.attachments = {{"rig.yaml", "application/x-yaml", {'x'}},
                          {"groundtruth.txt", "text/plain", {'y'}}};
    header.tags = {{"rig", "r"}};
    auto losses = tumLosses(header);
    ASSERT_TRUE(losses) << losses.status().toString();
    EXPECT_EQ(losses->dropped_streams, (std::vector<StreamId>{2}));
    ASSERT_EQ(losses->dropped.size(), 2u);
    EXPECT_NE(losses->dropped[0].find("mono/mono"), std::string::npos) << losses->dropped[0];
    EXPECT_NE(losses->dropped[1].find("rig.yaml"), std::string::npos) << losses->dropped[1];
    std::string changed;
    for (const auto& line : losses->changed)
        changed += line + "\n";
    EXPECT_NE(changed.find("'cam/color' is read back as 'tum/color'"), std::string::npos)
        << changed;
    EXPECT_NE(changed.find("device stamps"), std::string::npos) << changed;
    EXPECT_NE(changed.find("recording tags (rig)"), std::string::npos) << changed;

    // A TUM folder's own header loses nothing.
    const auto dir = test::tempDir();
    test::writeSyntheticTum(dir / "tum", 2);
    auto reader = openTum(dir / "tum");
    ASSERT_TRUE(reader) << reader.status().toString();
    auto none = tumLosses(headerOf(**reader));
    ASSERT_TRUE(none) << none.status().toString();
    EXPECT_FALSE(none->dropsData());
    EXPECT_TRUE(none->changed.empty()) << none->changed.front();
}

TEST(DepthUnits, RescaleRoundsKeepsZeroAndNeverInventsNoMeasurement) {
    Image src(ImageDesc::packed(PixelFormat::kDepth16, 6, 1));
    const uint16_t raw[6] = {0, 1, 2, 3, 5000, 65535};
    std::memcpy(src.bytes().data(), raw, sizeof(raw));
    Image mm(src.desc());
    ASSERT_TRUE(rescaleDepth(src.view(), 5000, mm.mutableView(), 1000));
    const auto* out = reinterpret_cast<const uint16_t*>(mm.bytes().data());
    EXPECT_EQ(out[0], 0);      // no measurement stays so
    EXPECT_EQ(out[1], 1);      // 0.2 mm rounds to 0 but is a measurement: 1 mm
    EXPECT_EQ(out[2], 1);      // 0.4 mm
    EXPECT_EQ(out[3], 1);      // 0.6 mm
    EXPECT_EQ(out[4], 1000);   // 1 m
    EXPECT_EQ(out[5], 13107);  // 13.107 m
    // Multiples of 5 come back exactly.
    Image back(src.desc());
    ASSERT_TRUE(rescaleDepth(mm.view(), 1000, back.mutableView(), 5000));
    EXPECT_EQ(reinterpret_cast<const uint16_t*>(back.bytes().data())[4], 5000);
    EXPECT_EQ(reinterpret_cast<const uint16_t*>(back.bytes().data())[5], 65535);

    StreamInfo bad;
    bad.tags[kDepthScaleTag] = "5000x";
    EXPECT_EQ(depthScalePerMetre(bad).status().code(), ErrorCode::kCorruptData);
}

}  // namespace
}  // namespace mixray::replay
