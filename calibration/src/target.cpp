// Calibration targets (target.h): validation, point layouts, the spec strings.
#include "mixray/calibration/target.h"

#include <charconv>
#include <cmath>
#include <string>
#include <system_error>

#include "mixray/calibration/marker_detection.h"

namespace mixray::calibration {
namespace {

// Kalibr's AprilGrid is printed with tag36h11 only; it has 587 codes.
constexpr std::string_view kAprilGridFamily = "apriltag:tag36h11";
constexpr int kTag36h11Codes = 587;

std::string number(double v) {
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, r.ptr);
}

bool positive(double v) {
    return std::isfinite(v) && v > 0;
}

Status invalid(const std::string& what) {
    return {ErrorCode::kInvalidArgument, what};
}

std::vector<std::string_view> split(std::string_view s, char sep) {
    std::vector<std::string_view> out;
    size_t start = 0;
    while (true) {
        const size_t k = s.find(sep, start);
        out.push_back(s.substr(start, k == std::string_view::npos ? k : k - start));
        if (k == std::string_view::npos)
            return out;
        start = k + 1;
    }
}

bool parseDouble(std::string_view s, double& v) {
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    return r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(v);
}

bool parseInt(std::string_view s, int& v) {
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

}  // namespace

std::string_view toString(TargetKind kind) {
    switch (kind) {
        case TargetKind::kChessboard:
            return "chessboard";
        case TargetKind::kCharuco:
            return "charuco";
        case TargetKind::kAprilGrid:
            return "aprilgrid";
    }
    return "unknown";
}

std::string_view toString(ViewRejection rejection) {
    switch (rejection) {
        case ViewRejection::kNone:
            return "used";
        case ViewRejection::kUnreadable:
            return "unreadable";
        case ViewRejection::kWrongSize:
            return "wrong size";
        case ViewRejection::kNoTarget:
            return "no target";
        case ViewRejection::kPartialTarget:
            return "partial target";
        case ViewRejection::kBlurred:
            return "blurred";
        case ViewRejection::kTooOblique:
            return "too oblique";
        case ViewRejection::kOutliers:
            return "outliers";
        case ViewRejection::kLargerBoard:
            return "on a larger board";
    }
    return "unknown";
}

Status CalibrationTarget::validate() const {
    const std::string where = "target " + std::string(toString(kind)) + ": ";
    switch (kind) {
        case TargetKind::kChessboard:
            if (cols < 2 || rows < 2)
                return invalid(where + "cols and rows (inner corners) must be >= 2, got " +
                               std::to_string(cols) + "x" + std::to_string(rows));
            if (!positive(square_m))
                return invalid(where + "square_m must be > 0");
            return Status::ok();
        case TargetKind::kCharuco: {
            if (cols < 2 || rows < 2)
                return invalid(where + "cols and rows (squares) must be >= 2, got " +
                               std::to_string(cols) + "x" + std::to_string(rows));
            if (!positive(square_m))
                return invalid(where + "square_m must be > 0");
            if (!positive(marker_m) || marker_m >= square_m)
                return invalid(where + "marker_m must be > 0 and smaller than square_m");
            if (!openCvDictionaryId(dictionary))
                return invalid(where + "dictionary must be an OpenCV dictionary name, got '" +
                               dictionary + "'");
            const int markers = cols * rows / 2;
            if (markers > openCvDictionarySize(dictionary))
                return invalid(where + std::to_string(markers) + " markers do not fit in " +
                               dictionary);
            return Status::ok();
        }
        case TargetKind::kAprilGrid:
            if (cols < 1 || rows < 1)
                return invalid(where + "cols and rows (tags) must be >= 1, got " +
                               std::to_string(cols) + "x" + std::to_string(rows));
            if (!positive(square_m))
                return invalid(where + "square_m (the tag side) must be > 0");
            if (!positive(tag_spacing))
                return invalid(where + "tag_spacing must be > 0");
            if (dictionary != kAprilGridFamily)
                return invalid(where + "dictionary must be " + std::string(kAprilGridFamily) +
                               ", got '" + dictionary + "'");
            if (cols * rows > kTag36h11Codes)
                return invalid(where + std::to_string(cols * rows) + " tags do not fit in " +
                               std::string(kAprilGridFamily));
            return Status::ok();
    }
    return invalid("target: unknown kind");
}

std::vector<Eigen::Vector3d> CalibrationTarget::points() const {
    std::vector<Eigen::Vector3d> out;
    if (!validate())
        return out;
    switch (kind) {
        case TargetKind::kChessboard:
            for (int r = 0; r < rows; ++r)
                for (int c = 0; c < cols; ++c)
                    out.emplace_back(c * square_m, r * square_m, 0);
            break;
        case TargetKind::kCharuco:
            for (int r = 0; r + 1 < rows; ++r)
                for (int c = 0; c + 1 < cols; ++c)
                    out.emplace_back((c + 1) * square_m, (r + 1) * square_m, 0);
            break;
        case TargetKind::kAprilGrid: {
            const double pitch = (1 + tag_spacing) * square_m;
            for (int r = 0; r < 2 * rows; ++r)
                for (int c = 0; c < 2 * cols; ++c)
                    out.emplace_back((c / 2) * pitch + (c % 2) * square_m,
                                     (r / 2) * pitch + (r % 2) * square_m, 0);
            break;
        }
    }
    return out;
}

int CalibrationTarget::pointCount() const {
    if (!validate())
        return 0;
    switch (kind) {
        case TargetKind::kChessboard:
            return cols * rows;
        case TargetKind::kCharuco:
            return (cols - 1) * (rows - 1);
        case TargetKind::kAprilGrid:
            return 4 * cols * rows;
    }
    return 0;
}

std::string CalibrationTarget::spec() const {
    std::string s = std::string(toString(kind)) + ":" + std::to_string(cols) + "x" +
                    std::to_string(rows) + ":" + number(square_m);
    if (kind == TargetKind::kCharuco)
        s += ":" + number(marker_m) + ":" + dictionary;
    else if (kind == TargetKind::kAprilGrid)
        s += ":" + number(tag_spacing);
    return s;
}

Result<CalibrationTarget> parseTarget(std::string_view spec) {
    const std::string quoted = "target '" + std::string(spec) + "': ";
    const std::vector<std::string_view> parts = split(spec, ':');
    CalibrationTarget t;
    size_t expected = 0;
    if (parts[0] == "chessboard") {
        t.kind = TargetKind::kChessboard;
        expected = 3;
    } else if (parts[0] == "charuco") {
        t.kind = TargetKind::kCharuco;
        expected = 5;
    } else if (parts[0] == "aprilgrid") {
        t.kind = TargetKind::kAprilGrid;
        t.dictionary = std::string(kAprilGridFamily);
        expected = 4;
    } else {
        return invalid(quoted + "the kind must be chessboard, charuco or aprilgrid, got '" +
                       std::string(parts[0]) + "'");
    }
    const char* forms[] = {"chessboard:COLSxROWS:SQUARE_M",
                           "charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT",
                           "aprilgrid:COLSxROWS:TAG_M:SPACING"};
    if (parts.size() != expected)
        return invalid(quoted + "expected " + forms[static_cast<int>(t.kind)]);
    const auto size = split(parts[1], 'x');
    if (size.size() != 2 || !parseInt(size[0], t.cols) || !parseInt(size[1], t.rows))
        return invalid(quoted + "size '" + std::string(parts[1]) + "' is not COLSxROWS");
    if (!parseDouble(parts[2], t.square_m))
        return invalid(quoted + "'" + std::string(parts[2]) + "' is not a length in metres");
    if (t.kind == TargetKind::kCharuco) {
        if (!parseDouble(parts[3], t.marker_m))
            return invalid(quoted + "marker size '" + std::string(parts[3]) +
                           "' is not a length in metres");
        t.dictionary = std::string(parts[4]);
    } else if (t.kind == TargetKind::kAprilGrid && !parseDouble(parts[3], t.tag_spacing)) {
        return invalid(quoted + "spacing '" + std::string(parts[3]) + "' is not a number");
    }
    if (const Status s = t.validate(); !s)
        return invalid(quoted + s.message());
    return t;
}

std::vector<const TargetView*> CameraViews::usable() const {
    std::vector<const TargetView*> out;
    for (const TargetView& v : views)
        if (v.rejection == ViewRejection::kNone)
            out.push_back(&v);
    return out;
}

}  // namespace mixray::calibration
