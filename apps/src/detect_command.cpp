// mixray detect: markers (ArUco, custom dictionaries, AprilTag), ChArUco diamonds and boards in
// single images; writes detections.csv, detections.json and an overlay picture per image.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "cli.h"
#include "console.h"
#include "mixray/calibration/image_detection.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;

struct DetectCommandOptions {
    std::vector<std::string> images;
    std::string dictionary;
    std::string board;
    double diamond = 0;
    std::string output = "detections";
    bool overlay = true;
    bool refine = true;
    float apriltag_decimate = 1.0f;
    bool apriltag_refine_edges = true;
    float apriltag_sigma = 0.0f;
    int threads = 1;
};

// "<stem>.overlay.png", made unique when two images share a file name.
fs::path overlayPath(const fs::path& dir, const std::string& image, std::set<std::string>& used) {
    const std::string stem = fs::path(image).stem().string();
    std::string name = stem + ".overlay.png";
    for (int n = 2; used.count(name); ++n)
        name = stem + "-" + std::to_string(n) + ".overlay.png";
    used.insert(name);
    return dir / name;
}

std::string summary(const calibration::ImageDetections& d) {
    if (d.empty())
        return "nothing found";
    std::string s = std::to_string(d.markers.size()) + " markers";
    if (!d.diamonds.empty())
        s += ", " + std::to_string(d.diamonds.size()) + " diamonds";
    if (d.board)
        s += ", board " + std::to_string(d.board->corners.size()) + " corners" +
             (d.board->rejection == calibration::ViewRejection::kNone
                  ? std::string(" (usable)")
                  : " (" + std::string(toString(d.board->rejection)) + ": " + d.board->why + ")");
    return s;
}

int runDetect(const DetectCommandOptions& o) {
    calibration::ImageDetectionOptions options;
    if (!o.dictionary.empty()) {
        if (Status s = calibration::setDictionary(options, o.dictionary); !s)
            return fail("detect", s.code() == ErrorCode::kInvalidArgument
                                      ? Status(s.code(), "--dictionary: " + s.message())
                                      : s);
    }
    if (!o.board.empty()) {
        auto target = calibration::parseTarget(o.board);
        if (!target)
            return fail("detect", Status(ErrorCode::kInvalidArgument,
                                         "--board: " + target.status().message()));
        options.board = *target;
    }
    options.diamond_square_to_marker = o.diamond;
    options.detector.refine_corners = o.refine;
    options.detector.apriltag_quad_decimate = o.apriltag_decimate;
    options.detector.apriltag_refine_edges = o.apriltag_refine_edges;
    options.detector.apriltag_quad_sigma = o.apriltag_sigma;
    options.detector.threads = o.threads;
    if (Status s = options.validate(); !s)
        return fail("detect", s);

    const fs::path dir = o.output;
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec)
        return fail("detect", {ErrorCode::kIoError, dir.string() + ": " + ec.message()});

    InterruptFlag interrupt;
    StatusLine status;
    std::vector<calibration::ImageDetections> found;
    std::vector<std::string> unreadable;
    std::vector<std::string> lines;
    std::set<std::string> overlay_names;
    for (size_t i = 0; i < o.images.size() && !interrupt.raised(); ++i) {
        const std::string& name = o.images[i];
        status.update("detect: image " + std::to_string(i + 1) + "/" +
                      std::to_string(o.images.size()) + " " + name);
        auto image = calibration::readImageFile(name);
        if (!image) {
            unreadable.push_back(image.status().message());
            continue;
        }
        auto detections = calibration::detectInImage(image->view(), options);
        if (!detections) {
            status.finish();
            return fail("detect", detections.status().withContext(name));
        }
        detections->image = name;
        if (o.overlay) {
            auto picture = calibration::drawDetections(image->view(), *detections);
            if (!picture) {
                status.finish();
                return fail("detect", picture.status().withContext(name));
            }
            if (Status s =
                    calibration::writePng(overlayPath(dir, name, overlay_names), picture->view());
                !s) {
                status.finish();
                return fail("detect", s);
            }
        }
        lines.push_back(name + ": " + summary(*detections));
        found.push_back(std::move(*detections));
    }
    status.finish();
    if (interrupt.raised()) {
        std::fprintf(stderr, "mixray detect: stopped by %s; nothing written\n",
                     interrupt.signalName().c_str());
        return interrupt.exitCode();
    }
    if (Status s = calibration::writeDetections(dir, found); !s)
        return fail("detect", s);
    for (const std::string& line : lines)
        std::printf("%s\n", line.c_str());
    std::printf("wrote %s and detections.json%s for %zu images\n",
                (dir / "detections.csv").string().c_str(), o.overlay ? " and overlays" : "",
                found.size());
    if (!unreadable.empty()) {
        for (const std::string& why : unreadable)
            std::fprintf(stderr, "mixray detect: unreadable image: %s\n", why.c_str());
        std::fprintf(stderr, "mixray detect: %zu of %zu images could not be read\n",
                     unreadable.size(), o.images.size());
        return kExitBadInput;
    }
    return kExitOk;
}

}  // namespace

void registerDetectCommand(CLI::App& app, Commands& commands) {
    auto o = std::make_shared<DetectCommandOptions>();
    CLI::App* sub = app.add_subcommand(
        "detect",
        "Find markers (ArUco, custom OpenCV dictionaries, AprilTag), ChArUco diamonds and boards "
        "in single images; writes detections.csv, detections.json (ids and corners in mixray's "
        "pixel convention) and an overlay picture per image");
    sub->add_option("images", o->images, "Image files (any format OpenCV reads)")->required();
    sub->add_option("-d,--dictionary", o->dictionary,
                    "Markers to find: an OpenCV dictionary (DICT_6X6_250, DICT_APRILTAG_36h11, "
                    "...), a libapriltag family (apriltag:tag36h11, apriltag:tagStandard41h12, "
                    "...) or an OpenCV dictionary file (nmarkers, markersize, marker_0 ...)");
    sub->add_option(
        "--board", o->board,
        "A board to find: chessboard:COLSxROWS:SQUARE_M, "
        "charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT or aprilgrid:COLSxROWS:TAG_M:SPACING");
    sub->add_option("--diamond", o->diamond,
                    "Also find ChArUco diamonds of the --dictionary markers whose square side is "
                    "this many times the marker side (OpenCV's squareMarkerLengthRate, > 1)");
    sub->add_option("-o,--output", o->output,
                    "Output folder for detections.csv, detections.json and the overlays")
        ->capture_default_str();
    sub->add_flag("!--no-overlay", o->overlay, "Skip the overlay pictures");
    sub->add_flag("!--no-refine", o->refine,
                  "Keep OpenCV's subpixel or libapriltag's corners instead of mixray's fit of "
                  "each marker's edges");
    sub->add_option("--apriltag-decimate", o->apriltag_decimate,
                    "libapriltag quad_decimate: find quads in an image decimated this many times "
                    "(faster, misses small tags; 1 to 8)")
        ->check(CLI::Range(1.0, 8.0))
        ->capture_default_str();
    sub->add_flag("!--no-apriltag-refine-edges", o->apriltag_refine_edges,
                  "libapriltag refine_edges off: keep the quads' edges as segmented");
    sub->add_option("--apriltag-sigma", o->apriltag_sigma,
                    "libapriltag quad_sigma: Gaussian blur (px) before segmenting quads, for "
                    "noisy images; negative sharpens (-10 to 10)")
        ->check(CLI::Range(-10.0, 10.0))
        ->capture_default_str();
    sub->add_option("--threads", o->threads, "libapriltag's worker threads (nthreads, 1 to 256)")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    commands.push_back({sub, [o] { return runDetect(*o); }});
}

}  // namespace mixray::cli
