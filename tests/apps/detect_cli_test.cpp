// mixray detect end to end: the real photos of ../shared/data (ids against OpenCV's and
// libapriltag's own results), its CSV, JSON and overlay files, and bad input named clearly.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/aruco.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cli_runner.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;
using test::CliRun;
using test::mixray;
using test::q;

const fs::path kAruco = test::sharedDataDir() / "03_aruco_charuco_opencv";
const fs::path kApril = test::sharedDataDir() / "03_apriltag";

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

struct CsvRow {
    std::string image, kind, dictionary, id;
    int corner = 0;
    double x = 0, y = 0;
};

// detections.csv without quoted fields (the test images' names hold no comma).
std::vector<CsvRow> readCsv(const fs::path& path) {
    std::ifstream in(path);
    std::string line;
    std::vector<CsvRow> rows;
    std::getline(in, line);
    EXPECT_EQ(line, "image,kind,dictionary,id,corner,x,y");
    while (std::getline(in, line)) {
        std::vector<std::string> f;
        std::stringstream s(line);
        std::string field;
        while (std::getline(s, field, ','))
            f.push_back(field);
        if (f.size() != 7) {
            ADD_FAILURE() << "bad row: " << line;
            continue;
        }
        rows.push_back({f[0], f[1], f[2], f[3], std::stoi(f[4]), std::stod(f[5]), std::stod(f[6])});
    }
    return rows;
}

// Marker ids per image name, each id once per marker (its corner 0 row).
std::map<std::string, std::multiset<int>> markerIds(const std::vector<CsvRow>& rows) {
    std::map<std::string, std::multiset<int>> ids;
    for (const CsvRow& r : rows)
        if (r.kind == "marker" && r.corner == 0)
            ids[fs::path(r.image).filename().string()].insert(std::stoi(r.id));
    return ids;
}

std::multiset<int> openCvIds(const fs::path& image, const cv::Ptr<cv::aruco::Dictionary>& dict) {
    const cv::Mat grey = cv::imread(image.string(), cv::IMREAD_GRAYSCALE);
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    cv::aruco::detectMarkers(grey, dict, corners, ids);
    return {ids.begin(), ids.end()};
}

TEST(DetectCli, HelpNamesEveryOption) {
    const CliRun help = mixray("detect --help");
    EXPECT_EQ(help.exit_code, 0);
    for (const char* option :
         {"--dictionary", "--board", "--diamond", "--output", "--no-overlay", "--no-refine",
          "--apriltag-decimate", "--no-apriltag-refine-edges", "--apriltag-sigma", "--threads"})
        EXPECT_TRUE(contains(help.output, option)) << option << "\n" << help.output;
}

TEST(DetectCli, ArucoAndCustomDictionaryPhotosMatchOpenCv) {
    MIXRAY_REQUIRE_SHARED_DATA(kAruco / "singlemarkersoriginal.jpg");
    MIXRAY_REQUIRE_SHARED_DATA(kAruco / "tutorial_dict.yml");
    const fs::path out = test::tempDir();
    const CliRun run = mixray("detect " + q(kAruco / "singlemarkersoriginal.jpg") + " " +
                              q(kAruco / "choriginal.jpg") + " -d DICT_6X6_250 -o " + q(out));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_TRUE(contains(run.output, "singlemarkersoriginal.jpg: ")) << run.output;
    const auto ids = markerIds(readCsv(out / "detections.csv"));
    const auto dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250);
    for (const char* name : {"singlemarkersoriginal.jpg", "choriginal.jpg"}) {
        const auto theirs = openCvIds(kAruco / name, dict);
        EXPECT_FALSE(theirs.empty()) << name;
        EXPECT_EQ(ids.count(name) ? ids.at(name) : std::multiset<int>{}, theirs) << name;
        // One overlay per image, as large as the photo.
        const cv::Mat overlay =
            cv::imread((out / (fs::path(name).stem().string() + ".overlay.png")).string());
        EXPECT_EQ(overlay.cols, 640) << name;
        EXPECT_EQ(overlay.rows, 480) << name;
    }
    const auto json = nlohmann::json::parse(test::readText(out / "detections.json"));
    ASSERT_EQ(json["images"].size(), 2u);
    EXPECT_EQ(json["images"][0]["markers"].size(), ids.at("singlemarkersoriginal.jpg").size());

    // gboriginal.png is printed from the tutorial's custom dictionary.
    const fs::path custom = test::tempDir();
    const CliRun gb = mixray("detect " + q(kAruco / "gboriginal.png") + " --dictionary " +
                             q(kAruco / "tutorial_dict.yml") + " -o " + q(custom));
    ASSERT_EQ(gb.exit_code, 0) << gb.output;
    cv::FileStorage fs((kAruco / "tutorial_dict.yml").string(), cv::FileStorage::READ);
    auto tutorial = cv::makePtr<cv::aruco::Dictionary>();
    ASSERT_TRUE(tutorial->readDictionary(fs.root()));
    const auto rows = readCsv(custom / "detections.csv");
    ASSERT_FALSE(rows.empty());
    EXPECT_EQ(rows[0].dictionary, "custom:tutorial_dict");
    EXPECT_EQ(markerIds(rows)["gboriginal.png"], openCvIds(kAruco / "gboriginal.png", tutorial));
}

TEST(DetectCli, CharucoBoardCornersAndAprilTagsAsTheirDetectorsFindThem) {
    MIXRAY_REQUIRE_SHARED_DATA(kAruco / "choriginal.jpg");
    MIXRAY_REQUIRE_SHARED_DATA(kApril / "33369213973_9d9bb4cc96_c.jpg");
    const fs::path board = test::tempDir();
    const CliRun run =
        mixray("detect " + q(kAruco / "choriginal.jpg") +
               " --board charuco:5x7:0.04:0.02:DICT_6X6_250 --no-overlay -o " + q(board));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    int corners = 0;
    for (const CsvRow& r : readCsv(board / "detections.csv"))
        corners += r.kind == "charuco" && r.dictionary == "charuco:5x7:0.04:0.02:DICT_6X6_250";
    EXPECT_GE(corners, 15);  // the 4x6 inner corners of the unoccluded board, a few aside
    EXPECT_FALSE(fs::exists(board / "choriginal.overlay.png"));

    // libapriltag's test settings (its test/test_detection.c): its expected ids.
    const fs::path april = test::tempDir();
    const fs::path photo = kApril / "33369213973_9d9bb4cc96_c.jpg";
    const CliRun tags = mixray("detect " + q(photo) +
                               " -d apriltag:tag36h11 --apriltag-decimate 1 "
                               "--no-apriltag-refine-edges --no-refine --threads 2 -o " +
                               q(april));
    ASSERT_EQ(tags.exit_code, 0) << tags.output;
    std::multiset<int> expected;
    std::ifstream txt(kApril / "33369213973_9d9bb4cc96_c.txt");
    std::string line;
    while (std::getline(txt, line))
        if (!line.empty())
            expected.insert(std::stoi(line));
    EXPECT_EQ(expected.size(), 12u);
    EXPECT_EQ(markerIds(readCsv(april / "detections.csv"))[photo.filename().string()], expected);
}

TEST(DetectCli, BadInputExitsNonZeroNamingTheCause) {
    const fs::path dir = test::tempDir();
    cv::imwrite((dir / "blank.png").string(), cv::Mat(120, 160, CV_8UC1, cv::Scalar(200)));
    test::writeText(dir / "notes.jpg", "not an image");

    const CliRun unknown =
        mixray("detect " + q(dir / "blank.png") + " -d DICT_6X6_251 -o " + q(dir / "o1"));
    EXPECT_EQ(unknown.exit_code, 2) << unknown.output;
    EXPECT_TRUE(contains(unknown.output, "unknown marker dictionary 'DICT_6X6_251'"))
        << unknown.output;

    const CliRun nothing = mixray("detect " + q(dir / "blank.png") + " -o " + q(dir / "o2"));
    EXPECT_EQ(nothing.exit_code, 2) << nothing.output;
    EXPECT_TRUE(contains(nothing.output, "nothing to detect")) << nothing.output;

    test::writeText(dir / "bad.yml", "%YAML:1.0\nnmarkers: 2\nmarkersize: 2\nmarker_0: \"1000\"\n");
    const CliRun bad_dict = mixray("detect " + q(dir / "blank.png") + " -d " + q(dir / "bad.yml") +
                                   " -o " + q(dir / "o3"));
    EXPECT_EQ(bad_dict.exit_code, 3) << bad_dict.output;
    EXPECT_TRUE(contains(bad_dict.output, "bad.yml: marker_1: missing")) << bad_dict.output;

    const CliRun decimate =
        mixray("detect " + q(dir / "blank.png") + " -d apriltag:tag36h11 --apriltag-decimate 0.5");
    EXPECT_EQ(decimate.exit_code, 2) << decimate.output;
    EXPECT_TRUE(contains(decimate.output, "--apriltag-decimate")) << decimate.output;

    // An unreadable image among readable ones: the readable ones are written and reported
    // (nothing found is no error), the run fails naming the bad file.
    const CliRun mixed = mixray("detect " + q(dir / "blank.png") + " " + q(dir / "notes.jpg") +
                                " -d DICT_4X4_50 -o " + q(dir / "o4"));
    EXPECT_EQ(mixed.exit_code, 3) << mixed.output;
    EXPECT_TRUE(contains(mixed.output, "notes.jpg: not an image OpenCV can read")) << mixed.output;
    EXPECT_TRUE(contains(mixed.output, "blank.png: nothing found")) << mixed.output;
    EXPECT_TRUE(fs::exists(dir / "o4" / "blank.overlay.png"));
    const auto json = nlohmann::json::parse(test::readText(dir / "o4" / "detections.json"));
    ASSERT_EQ(json["images"].size(), 1u);
    EXPECT_TRUE(json["images"][0]["markers"].empty());

    const CliRun missing =
        mixray("detect " + q(dir / "nowhere.png") + " -d DICT_4X4_50 -o " + q(dir / "o5"));
    EXPECT_EQ(missing.exit_code, 3) << missing.output;
    EXPECT_TRUE(contains(missing.output, "nowhere.png: no such file")) << missing.output;
}

}  // namespace
}  // namespace mixray
