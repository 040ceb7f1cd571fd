// Markers, diamonds and boards in single images (image_detection.h): detection through
// marker_detection.h and detect.h, and the CSV, JSON and overlay forms `mixray detect` writes.
#include "mixray/calibration/image_detection.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <system_error>
#include <utility>

#include "calibration_file_internal.h"
#include "image_file.h"

namespace mixray::calibration {
namespace {

using Eigen::Vector2d;

std::string fixed4(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.4f", v);
    return buf;
}

// RFC 4180: a field holding a comma, quote or line break is quoted, its quotes doubled.
std::string csvField(const std::string& s) {
    if (s.find_first_of(",\"\r\n") == std::string::npos)
        return s;
    std::string out = "\"";
    for (char c : s) {
        if (c == '"')
            out += '"';
        out += c;
    }
    return out + "\"";
}

std::string diamondId(const DiamondDetection& d) {
    return std::to_string(d.ids[0]) + "_" + std::to_string(d.ids[1]) + "_" +
           std::to_string(d.ids[2]) + "_" + std::to_string(d.ids[3]);
}

// An 8-bit cv::Mat of the image (1 or 3 channels, BGR), 16-bit grey stretched; shares the
// pixels of 8-bit images.
Result<cv::Mat> eightBit(const ImageView& image) {
    const ImageDesc& d = image.desc;
    int type = -1;
    switch (d.format) {
        case PixelFormat::kMono8:
            type = CV_8UC1;
            break;
        case PixelFormat::kRGB8:
        case PixelFormat::kBGR8:
            type = CV_8UC3;
            break;
        case PixelFormat::kMono16:
        case PixelFormat::kIR16:
            type = CV_16UC1;
            break;
        default:
            return Status(ErrorCode::kInvalidArgument,
                          "detection takes mono8, rgb8, bgr8, mono16 or ir16 images, not " +
                              std::string(toString(d.format)));
    }
    const size_t row_bytes = static_cast<size_t>(d.width) * static_cast<size_t>(CV_ELEM_SIZE(type));
    if (d.width <= 0 || d.height <= 0 || !image.data ||
        static_cast<size_t>(d.stride_bytes) < row_bytes ||
        image.size_bytes <
            static_cast<size_t>(d.stride_bytes) * static_cast<size_t>(d.height - 1) + row_bytes)
        return Status(ErrorCode::kInvalidArgument, "image buffer smaller than its " +
                                                       std::to_string(d.width) + "x" +
                                                       std::to_string(d.height) + " description");
    cv::Mat m(d.height, d.width, type, const_cast<uint8_t*>(image.data),
              static_cast<size_t>(d.stride_bytes));
    if (type == CV_16UC1)
        return detail::stretch16(m);
    if (d.format == PixelFormat::kRGB8) {
        cv::Mat bgr;
        cv::cvtColor(m, bgr, cv::COLOR_RGB2BGR);
        return bgr;
    }
    return m;
}

ImageView viewOf(const cv::Mat& m) {
    ImageView v;
    v.desc = ImageDesc{m.channels() == 1 ? PixelFormat::kMono8 : PixelFormat::kBGR8, m.cols, m.rows,
                       static_cast<int>(m.step[0])};
    v.data = m.data;
    v.size_bytes = m.step[0] * static_cast<size_t>(m.rows);
    return v;
}

// Drawing at 1/16 px (cv::LINE_AA with shift 4) in docs/conventions.md pixels, which are
// OpenCV's drawing coordinates.
constexpr int kShift = 4;
cv::Point fixedPoint(const Vector2d& p) {
    return {static_cast<int>(std::lround(p.x() * (1 << kShift))),
            static_cast<int>(std::lround(p.y() * (1 << kShift)))};
}
cv::Point plainPoint(const Vector2d& p) {
    return {static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y()))};
}

// Text with a dark outline, readable on any background.
void label(cv::Mat& img, const std::string& text, const Vector2d& at, double scale,
           const cv::Scalar& colour, bool centred) {
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline);
    cv::Point p = plainPoint(at);
    if (centred)
        p -= cv::Point(size.width / 2, -size.height / 2);
    cv::putText(img, text, p, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
    cv::putText(img, text, p, cv::FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv::LINE_AA);
}

// A quadrilateral with its id in the middle and each corner's index just outside it; corner 0
// gets a box, so the order reads even where the indices crowd.
void drawQuad(cv::Mat& img, const std::array<Vector2d, 4>& c, const std::string& id,
              const cv::Scalar& colour) {
    const Vector2d centre = 0.25 * (c[0] + c[1] + c[2] + c[3]);
    for (size_t k = 0; k < 4; ++k)
        cv::line(img, fixedPoint(c[k]), fixedPoint(c[(k + 1) % 4]), colour, 1, cv::LINE_AA, kShift);
    const double side = std::max(4.0, 0.12 * (c[0] - c[2]).norm());
    cv::rectangle(img, fixedPoint(c[0] - Vector2d(3, 3)), fixedPoint(c[0] + Vector2d(3, 3)),
                  cv::Scalar(0, 0, 255), 1, cv::LINE_AA, kShift);
    for (size_t k = 0; k < 4; ++k) {
        Vector2d out = c[k] - centre;
        out = out.norm() > 1e-9 ? Vector2d(out.normalized()) : Vector2d(1, 0);
        label(img, std::to_string(k), c[k] + side * out, 0.35, cv::Scalar(0, 200, 255), true);
    }
    label(img, id, centre, 0.45, colour, true);
}

}  // namespace

Status ImageDetectionOptions::validate() const {
    const auto invalid = [](std::string what) {
        return Status(ErrorCode::kInvalidArgument, std::move(what));
    };
    if (dictionary.empty() && !custom_dictionary && !board)
        return invalid("nothing to detect: give a marker dictionary or a board");
    if (!dictionary.empty() && custom_dictionary)
        return invalid("dictionary: give one dictionary, '" + dictionary + "' or the custom '" +
                       custom_dictionary->name + "'");
    if (!dictionary.empty() && !isKnownDictionary(dictionary))
        return invalid("unknown marker dictionary '" + dictionary +
                       "' (OpenCV's DICT_* names, apriltag:<family>, or a dictionary file)");
    if (custom_dictionary)
        MIXRAY_RETURN_IF_ERROR(custom_dictionary->validate());
    if (diamond_square_to_marker != 0) {
        if (!(diamond_square_to_marker > 1 && diamond_square_to_marker <= 100))
            return invalid("diamond square/marker ratio must be in (1, 100], got " +
                           std::to_string(diamond_square_to_marker));
        if (!custom_dictionary && !openCvDictionaryId(dictionary))
            return invalid(
                "diamonds need an ArUco dictionary (OpenCV's DICT_* or a dictionary "
                "file), not '" +
                dictionary + "'");
    }
    if (board)
        MIXRAY_RETURN_IF_ERROR(board->validate());
    return detector.validate();
}

Status setDictionary(ImageDetectionOptions& options, const std::string& name_or_file) {
    options.dictionary.clear();
    options.custom_dictionary.reset();
    if (isKnownDictionary(name_or_file)) {
        options.dictionary = name_or_file;
        return Status::ok();
    }
    std::error_code ec;
    if (!std::filesystem::is_regular_file(name_or_file, ec))
        return Status(ErrorCode::kInvalidArgument,
                      "unknown marker dictionary '" + name_or_file +
                          "': not one of OpenCV's DICT_* names (DICT_4X4_50 ... "
                          "DICT_ARUCO_ORIGINAL, DICT_APRILTAG_36h11), not apriltag:<family> "
                          "(tag36h11, tag25h9, tag16h5, tagStandard41h12, ...), and no such "
                          "dictionary file");
    auto dict = readMarkerDictionary(name_or_file);
    if (!dict)
        return dict.status();
    options.custom_dictionary = std::move(*dict);
    return Status::ok();
}

bool ImageDetections::empty() const {
    return markers.empty() && diamonds.empty() && (!board || board->corners.empty());
}

Result<Image> readImageFile(const std::filesystem::path& path) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        return Status(ErrorCode::kNotFound, path.string() + ": no such file");
    const detail::ImageFile file = detail::readImageFile(path);
    if (file.format == PixelFormat::kUnknown)
        return Status(ErrorCode::kCorruptData, path.string() + ": " + file.why);
    Image out(ImageDesc::packed(file.format, file.mat.cols, file.mat.rows));
    const ImageView src = file.view();
    const size_t row_bytes = static_cast<size_t>(out.desc().stride_bytes);
    for (int y = 0; y < src.desc.height; ++y)
        std::copy_n(src.row<uint8_t>(y), row_bytes,
                    out.bytes().data() + static_cast<size_t>(y) * row_bytes);
    return out;
}

Result<ImageDetections> detectInImage(const ImageView& image,
                                      const ImageDetectionOptions& options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    auto mat = eightBit(image);
    if (!mat)
        return mat.status();
    const ImageView view = viewOf(*mat);
    ImageDetections out;
    out.width = image.desc.width;
    out.height = image.desc.height;
    if (options.custom_dictionary || !options.dictionary.empty()) {
        auto markers = options.custom_dictionary
                           ? detectMarkers(view, *options.custom_dictionary, options.detector)
                           : detectMarkers(view, options.dictionary, options.detector);
        if (!markers)
            return markers.status();
        out.markers = std::move(*markers);
    }
    if (options.diamond_square_to_marker != 0) {
        auto dict = options.custom_dictionary ? Result<MarkerDictionary>(*options.custom_dictionary)
                                              : openCvDictionary(options.dictionary);
        if (!dict)
            return dict.status();
        auto diamonds = detectDiamonds(view, *dict, options.diamond_square_to_marker, out.markers);
        if (!diamonds)
            return diamonds.status();
        out.diamonds = std::move(*diamonds);
    }
    if (options.board) {
        DetectionOptions board_options;
        board_options.markers = options.detector;
        auto found = detectTarget(view, *options.board, board_options);
        if (!found)
            return found.status();
        out.board = std::move(*found);
        out.board_target = *options.board;
    }
    return out;
}

std::string detectionsCsv(const std::vector<ImageDetections>& images) {
    std::string out = "image,kind,dictionary,id,corner,x,y\n";
    const auto row = [&out](const std::string& image, std::string_view kind,
                            const std::string& dictionary, const std::string& id, size_t corner,
                            const Vector2d& p) {
        out += image + "," + std::string(kind) + "," + csvField(dictionary) + "," + id + "," +
               std::to_string(corner) + "," + fixed4(p.x()) + "," + fixed4(p.y()) + "\n";
    };
    for (const ImageDetections& img : images) {
        const std::string name = csvField(img.image);
        for (const MarkerDetection& m : img.markers)
            for (size_t k = 0; k < 4; ++k)
                row(name, "marker", m.dictionary, std::to_string(m.id), k, m.corners[k]);
        for (const DiamondDetection& d : img.diamonds)
            for (size_t k = 0; k < 4; ++k)
                row(name, "diamond", d.dictionary, diamondId(d), k, d.corners[k]);
        if (img.board)
            for (const Corner& c : img.board->corners)
                row(name, toString(img.board_target.kind), img.board_target.spec(),
                    std::to_string(c.id), 0, c.pixel);
    }
    return out;
}

std::string detectionsJson(const std::vector<ImageDetections>& images) {
    using nlohmann::json;
    const auto point = [](const Vector2d& p) { return json::array({p.x(), p.y()}); };
    json list = json::array();
    for (const ImageDetections& img : images) {
        json j = {{"image", img.image}, {"width", img.width}, {"height", img.height}};
        json markers = json::array();
        for (const MarkerDetection& m : img.markers) {
            json corners = json::array();
            for (const Vector2d& p : m.corners)
                corners.push_back(point(p));
            markers.push_back({{"dictionary", m.dictionary}, {"id", m.id}, {"corners", corners}});
        }
        j["markers"] = markers;
        json diamonds = json::array();
        for (const DiamondDetection& d : img.diamonds) {
            json corners = json::array();
            for (const Vector2d& p : d.corners)
                corners.push_back(point(p));
            diamonds.push_back({{"dictionary", d.dictionary},
                                {"ids", json::array({d.ids[0], d.ids[1], d.ids[2], d.ids[3]})},
                                {"corners", corners}});
        }
        j["diamonds"] = diamonds;
        if (img.board) {
            json corners = json::array();
            for (const Corner& c : img.board->corners)
                corners.push_back({{"id", c.id}, {"x", c.pixel.x()}, {"y", c.pixel.y()}});
            j["board"] = {{"target", img.board_target.spec()},
                          {"corners", corners},
                          {"usable", img.board->rejection == ViewRejection::kNone},
                          {"rejection", std::string(toString(img.board->rejection))},
                          {"why", img.board->why}};
        }
        list.push_back(std::move(j));
    }
    json doc = {
        {"convention", "pixels: (0,0) is the centre of the top-left pixel, x right, y down"},
        {"images", list}};
    return doc.dump(2) + "\n";
}

Status writeDetections(const std::filesystem::path& dir,
                       const std::vector<ImageDetections>& images) {
    MIXRAY_RETURN_IF_ERROR(detail::writeTextFile(dir / "detections.csv", detectionsCsv(images)));
    return detail::writeTextFile(dir / "detections.json", detectionsJson(images));
}

Result<Image> drawDetections(const ImageView& image, const ImageDetections& found) {
    auto mat = eightBit(image);
    if (!mat)
        return mat.status();
    Image out(ImageDesc::packed(PixelFormat::kBGR8, image.desc.width, image.desc.height));
    cv::Mat img(out.desc().height, out.desc().width, CV_8UC3, out.bytes().data(),
                static_cast<size_t>(out.desc().stride_bytes));
    if (mat->channels() == 1)
        cv::cvtColor(*mat, img, cv::COLOR_GRAY2BGR);
    else
        mat->copyTo(img);
    if (found.board) {
        const std::vector<Corner>& corners = found.board->corners;
        const bool usable = found.board->rejection == ViewRejection::kNone;
        const cv::Scalar colour = usable ? cv::Scalar(255, 160, 0) : cv::Scalar(0, 128, 255);
        for (size_t i = 1; i < corners.size(); ++i)
            cv::line(img, fixedPoint(corners[i - 1].pixel), fixedPoint(corners[i].pixel),
                     colour * 0.6, 1, cv::LINE_AA, kShift);
        for (const Corner& c : corners) {
            cv::circle(img, fixedPoint(c.pixel), 3 << kShift, colour, 1, cv::LINE_AA, kShift);
            label(img, std::to_string(c.id), c.pixel + Vector2d(4, -4), 0.3, colour, false);
        }
    }
    for (const MarkerDetection& m : found.markers)
        drawQuad(img, m.corners, std::to_string(m.id), cv::Scalar(0, 255, 0));
    for (const DiamondDetection& d : found.diamonds)
        drawQuad(img, d.corners, diamondId(d), cv::Scalar(255, 0, 255));
    return out;
}

Status writePng(const std::filesystem::path& path, const ImageView& image) {
    const ImageDesc& d = image.desc;
    if ((d.format != PixelFormat::kMono8 && d.format != PixelFormat::kRGB8 &&
         d.format != PixelFormat::kBGR8) ||
        !image.data || d.width <= 0 || d.height <= 0)
        return Status(ErrorCode::kInvalidArgument,
                      path.string() + ": PNG output takes a non-empty mono8, rgb8 or bgr8 image");
    const int type = d.format == PixelFormat::kMono8 ? CV_8UC1 : CV_8UC3;
    cv::Mat m(d.height, d.width, type, const_cast<uint8_t*>(image.data),
              static_cast<size_t>(d.stride_bytes));
    cv::Mat bgr;
    if (d.format == PixelFormat::kRGB8)
        cv::cvtColor(m, bgr, cv::COLOR_RGB2BGR);
    else
        bgr = m;
    try {
        if (!cv::imwrite(path.string(), bgr))
            return Status(ErrorCode::kIoError, path.string() + ": cannot write the PNG");
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kIoError, path.string() + ": " + e.msg);
    }
    return Status::ok();
}

}  // namespace mixray::calibration
