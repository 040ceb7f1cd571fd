// Marker detection (marker_detection.h): OpenCV's aruco dictionaries and libapriltag's families,
// corners moved to mixray's pixel convention and refined by fitting the marker's outer edges;
// ChArUco corners interpolated from the markers.
#include "mixray/calibration/marker_detection.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <opencv2/aruco.hpp>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <utility>

#include "mixray/graph/srgb.h"

namespace mixray::calibration {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

struct ArucoName {
    std::string_view name;
    cv::aruco::PREDEFINED_DICTIONARY_NAME id;
};
constexpr std::array<ArucoName, 21> kAruco = {{
    {"DICT_4X4_50", cv::aruco::DICT_4X4_50},
    {"DICT_4X4_100", cv::aruco::DICT_4X4_100},
    {"DICT_4X4_250", cv::aruco::DICT_4X4_250},
    {"DICT_4X4_1000", cv::aruco::DICT_4X4_1000},
    {"DICT_5X5_50", cv::aruco::DICT_5X5_50},
    {"DICT_5X5_100", cv::aruco::DICT_5X5_100},
    {"DICT_5X5_250", cv::aruco::DICT_5X5_250},
    {"DICT_5X5_1000", cv::aruco::DICT_5X5_1000},
    {"DICT_6X6_50", cv::aruco::DICT_6X6_50},
    {"DICT_6X6_100", cv::aruco::DICT_6X6_100},
    {"DICT_6X6_250", cv::aruco::DICT_6X6_250},
    {"DICT_6X6_1000", cv::aruco::DICT_6X6_1000},
    {"DICT_7X7_50", cv::aruco::DICT_7X7_50},
    {"DICT_7X7_100", cv::aruco::DICT_7X7_100},
    {"DICT_7X7_250", cv::aruco::DICT_7X7_250},
    {"DICT_7X7_1000", cv::aruco::DICT_7X7_1000},
    {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL},
    {"DICT_APRILTAG_16h5", cv::aruco::DICT_APRILTAG_16h5},
    {"DICT_APRILTAG_25h9", cv::aruco::DICT_APRILTAG_25h9},
    {"DICT_APRILTAG_36h10", cv::aruco::DICT_APRILTAG_36h10},
    {"DICT_APRILTAG_36h11", cv::aruco::DICT_APRILTAG_36h11},
}};

struct AprilFamily {
    std::string_view name;
    apriltag_family_t* (*create)();
    void (*destroy)(apriltag_family_t*);
    // Cells across the black square for the classic families (their quad is the black
    // square's outer edge, as for ArUco); 0 for the newer layouts, whose quad lies inside the
    // code and has no plain edge to fit.
    int cells;
};
// tag36h11 as Kalibr prints its AprilGrids (kalibr_create_target_pdf, borderBits=2): the same
// codes inside a black border two cells wide. Same decoding, the bits one cell further in.
apriltag_family_t* tag36h11b2Create() {
    apriltag_family_t* tf = tag36h11_create();
    if (!tf)
        return nullptr;
    for (uint32_t i = 0; i < tf->nbits; ++i) {
        ++tf->bit_x[i];
        ++tf->bit_y[i];
    }
    tf->width_at_border += 2;
    tf->total_width += 2;
    return tf;
}

constexpr std::array<AprilFamily, 10> kApril = {{
    {"tag16h5", tag16h5_create, tag16h5_destroy, 6},
    {"tag25h9", tag25h9_create, tag25h9_destroy, 7},
    {"tag36h10", tag36h10_create, tag36h10_destroy, 8},
    {"tag36h11", tag36h11_create, tag36h11_destroy, 8},
    {"tag36h11b2", tag36h11b2Create, tag36h11_destroy, 10},
    {"tagCircle21h7", tagCircle21h7_create, tagCircle21h7_destroy, 0},
    {"tagCircle49h12", tagCircle49h12_create, tagCircle49h12_destroy, 0},
    {"tagCustom48h12", tagCustom48h12_create, tagCustom48h12_destroy, 0},
    {"tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy, 0},
    {"tagStandard52h13", tagStandard52h13_create, tagStandard52h13_destroy, 0},
}};
constexpr std::string_view kAprilPrefix = "apriltag:";

const ArucoName* findAruco(std::string_view name) {
    for (const ArucoName& a : kAruco)
        if (a.name == name)
            return &a;
    return nullptr;
}

const AprilFamily* findApril(std::string_view name) {
    if (name.substr(0, kAprilPrefix.size()) != kAprilPrefix)
        return nullptr;
    name.remove_prefix(kAprilPrefix.size());
    for (const AprilFamily& a : kApril)
        if (a.name == name)
            return &a;
    return nullptr;
}

// Bilinear sample of a float image; NaN outside.
double sampleAt(const cv::Mat& f, const Vector2d& p) {
    const double x = p.x(), y = p.y();
    if (f.cols < 2 || f.rows < 2 || !(x >= 0 && y >= 0 && x <= f.cols - 1 && y <= f.rows - 1))
        return std::nan("");
    const int x0 = std::min(static_cast<int>(x), f.cols - 2);
    const int y0 = std::min(static_cast<int>(y), f.rows - 2);
    const double ax = x - x0, ay = y - y0;
    const float* r0 = f.ptr<float>(y0);
    const float* r1 = f.ptr<float>(y0 + 1);
    return (1 - ay) * ((1 - ax) * r0[x0] + ax * r0[x0 + 1]) +
           ay * ((1 - ax) * r1[x0] + ax * r1[x0 + 1]);
}

// A line n·p = c with |n| = 1.
struct Line {
    Vector2d n;
    double c;
};

// Total least squares with one pass of outlier rejection (specular spots, occluders).
std::optional<Line> fitLine(std::vector<Vector2d> pts) {
    for (int pass = 0; pass < 2; ++pass) {
        if (pts.size() < 4)
            return std::nullopt;
        Vector2d mean = Vector2d::Zero();
        for (const Vector2d& p : pts)
            mean += p;
        mean /= static_cast<double>(pts.size());
        Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
        for (const Vector2d& p : pts)
            cov += (p - mean) * (p - mean).transpose();
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
        const Vector2d n = eig.eigenvectors().col(0);
        const Line line{n, n.dot(mean)};
        if (pass == 1)
            return line;
        std::vector<double> res;
        for (const Vector2d& p : pts)
            res.push_back(std::abs(n.dot(p) - line.c));
        std::vector<double> sorted = res;
        std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2),
                         sorted.end());
        const double limit = std::max(4.0 * 1.4826 * sorted[sorted.size() / 2], 1e-9);
        std::vector<Vector2d> kept;
        for (size_t i = 0; i < pts.size(); ++i)
            if (res[i] <= limit)
                kept.push_back(pts[i]);
        pts = std::move(kept);
    }
    return std::nullopt;
}

// Moves a pixel into the plane where straight edges are straight (undistorted, normalised
// coordinates) and back.
struct EdgePlane {
    const CameraModel* camera = nullptr;
    std::optional<Vector2d> to(const Vector2d& px) const {
        if (!camera)
            return px;
        const auto d = camera->unproject(px);
        if (!d || d->z() <= 1e-6)
            return std::nullopt;
        return Vector2d(d->x() / d->z(), d->y() / d->z());
    }
    std::optional<Vector2d> from(const Vector2d& q) const {
        if (!camera)
            return q;
        return camera->project(Vector3d(q.x(), q.y(), 1));
    }
};

// One pass of the edge fit: subpixel points along each side (the step's position from the
// integral of its normalised profile, exact for any symmetric or asymmetric blur that fits the
// window), a line through each side, corners where the lines cross.
std::optional<std::array<Vector2d, 4>> fitEdges(const cv::Mat& lin,
                                                const std::array<Vector2d, 4>& c, int cells,
                                                const EdgePlane& plane) {
    const Vector2d centre = 0.25 * (c[0] + c[1] + c[2] + c[3]);
    std::array<Line, 4> lines;
    for (int k = 0; k < 4; ++k) {
        const Vector2d a = c[static_cast<size_t>(k)], b = c[static_cast<size_t>((k + 1) % 4)];
        const double len = (b - a).norm();
        if (len < 12)
            return std::nullopt;
        const Vector2d d = (b - a) / len;
        Vector2d n(d.y(), -d.x());
        if (n.dot(a - centre) < 0)
            n = -n;
        // The window stays inside the black border cell and the white quiet zone.
        const double cell = len / cells;
        const double inner = std::clamp(0.5 * cell, 1.0, 3.0);
        const double outer = std::clamp(0.5 * cell, 1.0, 3.0);
        const double margin = std::max(outer + 1.5, 0.08 * len);
        constexpr double kStep = 0.25;
        const int nsamples = static_cast<int>(std::lround((inner + outer) / kStep));
        std::vector<Vector2d> pts;
        std::vector<double> prof(static_cast<size_t>(nsamples) + 1);
        for (double s = margin; s <= len - margin; s += 1.0) {
            const Vector2d p = a + s * d;
            bool ok = true;
            for (int i = 0; i <= nsamples && ok; ++i) {
                prof[static_cast<size_t>(i)] = sampleAt(lin, p + (-inner + i * kStep) * n);
                ok = !std::isnan(prof[static_cast<size_t>(i)]);
            }
            if (!ok)
                continue;
            const double dark = 0.5 * (prof[0] + prof[1]);
            const double light = 0.5 * (prof[static_cast<size_t>(nsamples)] +
                                        prof[static_cast<size_t>(nsamples - 1)]);
            if (light - dark < 0.04)
                continue;
            double area = 0;  // trapezoid integral of the normalised profile
            for (int i = 0; i < nsamples; ++i)
                area +=
                    0.5 * kStep *
                    (prof[static_cast<size_t>(i)] + prof[static_cast<size_t>(i + 1)] - 2 * dark) /
                    (light - dark);
            const double e = outer - area;
            if (e <= -inner + 0.25 || e >= outer - 0.25)
                continue;
            if (const auto q = plane.to(p + e * n))
                pts.push_back(*q);
        }
        const auto line = fitLine(std::move(pts));
        if (!line)
            return std::nullopt;
        lines[static_cast<size_t>(k)] = *line;
    }
    std::array<Vector2d, 4> out;
    for (int k = 0; k < 4; ++k) {
        const Line& l0 = lines[static_cast<size_t>((k + 3) % 4)];
        const Line& l1 = lines[static_cast<size_t>(k)];
        const Vector3d h =
            Vector3d(l0.n.x(), l0.n.y(), -l0.c).cross(Vector3d(l1.n.x(), l1.n.y(), -l1.c));
        if (std::abs(h.z()) < 1e-12)
            return std::nullopt;
        const auto px = plane.from(h.head<2>() / h.z());
        if (!px)
            return std::nullopt;
        out[static_cast<size_t>(k)] = *px;
    }
    return out;
}

// Refined corners, or the detector's when the fit fails or wanders off.
std::array<Vector2d, 4> refineCorners(const cv::Mat& lin, const std::array<Vector2d, 4>& corners,
                                      int cells, const EdgePlane& plane) {
    std::array<Vector2d, 4> cur = corners;
    // The second pass centres the profile windows on the edges the first one found.
    for (int pass = 0; pass < 2; ++pass) {
        const auto next = fitEdges(lin, cur, cells, plane);
        if (!next)
            return corners;
        cur = *next;
    }
    for (int k = 0; k < 4; ++k)
        if ((cur[static_cast<size_t>(k)] - corners[static_cast<size_t>(k)]).norm() > 2.5)
            return corners;
    return cur;
}

// The edge fit works on linear intensity: a camera's 8-bit values are sRGB-like, and on them a
// half-covered pixel reads 188, not 128, which pulls every edge towards the dark side (OpenCV's
// cornerSubPix on raw values puts corners 0.2–0.4 px inside the marker).
cv::Mat linearImage(const cv::Mat& grey) {
    const std::array<float, 256>& lut = srgbToLinearTable();
    cv::Mat lin(grey.rows, grey.cols, CV_32F);
    for (int y = 0; y < grey.rows; ++y) {
        const uint8_t* src = grey.ptr<uint8_t>(y);
        float* dst = lin.ptr<float>(y);
        for (int x = 0; x < grey.cols; ++x)
            dst[x] = lut[src[x]];
    }
    return lin;
}

Result<std::vector<MarkerDetection>> detectAruco(const cv::Mat& grey,
                                                 const cv::Ptr<cv::aruco::Dictionary>& dictionary,
                                                 const std::string& name,
                                                 const DetectorOptions& options,
                                                 const EdgePlane& plane) {
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    try {
        auto params = cv::aruco::DetectorParameters::create();
        // The edge fit starts from the contour's corners; without it, OpenCV's own refinement.
        params->cornerRefinementMethod = options.refine_corners ? cv::aruco::CORNER_REFINE_NONE
                                                                : cv::aruco::CORNER_REFINE_SUBPIX;
        cv::aruco::detectMarkers(grey, dictionary, corners, ids, params);
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kInternal, std::string("OpenCV marker detection: ") + e.what());
    }
    cv::Mat lin;
    if (options.refine_corners && !ids.empty())
        lin = linearImage(grey);
    std::vector<MarkerDetection> out;
    for (size_t i = 0; i < ids.size(); ++i) {
        MarkerDetection m;
        m.dictionary = name;
        m.id = ids[i];
        for (size_t k = 0; k < 4; ++k)
            m.corners[k] = Vector2d(corners[i][k].x - kOpenCvArucoOffsetPx,
                                    corners[i][k].y - kOpenCvArucoOffsetPx);
        if (options.refine_corners)
            m.corners = refineCorners(lin, m.corners, dictionary->markerSize + 2, plane);
        out.push_back(std::move(m));
    }
    return out;
}

// OpenCV's form of a validated custom dictionary.
Result<cv::Ptr<cv::aruco::Dictionary>> toOpenCv(const MarkerDictionary& dict) {
    MIXRAY_RETURN_IF_ERROR(dict.validate());
    try {
        cv::Mat bytes;
        cv::Mat bits(dict.marker_size, dict.marker_size, CV_8UC1);
        for (const std::string& code : dict.markers) {
            for (size_t j = 0; j < code.size(); ++j)
                bits.at<uint8_t>(static_cast<int>(j)) = code[j] == '1' ? 1 : 0;
            bytes.push_back(cv::aruco::Dictionary::getByteListFromBits(bits));
        }
        return cv::makePtr<cv::aruco::Dictionary>(bytes, dict.marker_size,
                                                  dict.max_correction_bits);
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kInternal, std::string("OpenCV dictionary: ") + e.what());
    }
}

Result<std::vector<MarkerDetection>> detectApril(const cv::Mat& grey, const AprilFamily& family,
                                                 const DetectorOptions& options,
                                                 const EdgePlane& plane) {
    // One detector per call keeps detectMarkers() reentrant; building the family's decode
    // table costs about a millisecond.
    std::unique_ptr<apriltag_family_t, void (*)(apriltag_family_t*)> tf(family.create(),
                                                                        family.destroy);
    std::unique_ptr<apriltag_detector_t, void (*)(apriltag_detector_t*)> td(
        apriltag_detector_create(), apriltag_detector_destroy);
    if (!tf || !td)
        return Status(ErrorCode::kInternal, "libapriltag could not create its detector");
    apriltag_detector_add_family_bits(td.get(), tf.get(), 2);
    td->quad_decimate = options.apriltag_quad_decimate;
    td->refine_edges = options.apriltag_refine_edges;
    td->quad_sigma = options.apriltag_quad_sigma;
    td->nthreads = options.threads;
    image_u8_t im{grey.cols, grey.rows, static_cast<int32_t>(grey.step[0]),
                  const_cast<uint8_t*>(grey.ptr<uint8_t>(0))};
    std::unique_ptr<zarray_t, void (*)(zarray_t*)> dets(apriltag_detector_detect(td.get(), &im),
                                                        apriltag_detections_destroy);
    if (!dets)
        return Status(ErrorCode::kInternal, "libapriltag detection failed");
    const bool refine = options.refine_corners && family.cells > 0;
    cv::Mat lin;
    if (refine && zarray_size(dets.get()) > 0)
        lin = linearImage(grey);
    std::vector<MarkerDetection> out;
    for (int i = 0; i < zarray_size(dets.get()); ++i) {
        apriltag_detection_t* det = nullptr;
        zarray_get(dets.get(), i, &det);
        MarkerDetection m;
        m.dictionary = std::string(kAprilPrefix) + std::string(family.name);
        m.id = det->id;
        // libapriltag wraps p[] the other way round: OpenCV's top-left (of the same tag in
        // DICT_APRILTAG_*) is its p[1], top-right p[0], bottom-right p[3], bottom-left p[2].
        constexpr std::array<int, 4> kFromApril = {1, 0, 3, 2};
        for (size_t k = 0; k < 4; ++k) {
            const double* p = det->p[kFromApril[k]];
            m.corners[k] = Vector2d(p[0] - kAprilTagOffsetPx, p[1] - kAprilTagOffsetPx);
        }
        if (refine)
            m.corners = refineCorners(lin, m.corners, family.cells, plane);
        out.push_back(std::move(m));
    }
    return out;
}

// The edge fit's camera model (may be absent) must be the image's size.
Status checkCameraSize(const ImageView& image, const CameraModel* camera) {
    if (camera && (camera->width != image.desc.width || camera->height != image.desc.height))
        return Status(ErrorCode::kInvalidArgument,
                      "image is " + std::to_string(image.desc.width) + "x" +
                          std::to_string(image.desc.height) + ", the camera model " +
                          std::to_string(camera->width) + "x" + std::to_string(camera->height));
    return Status::ok();
}

// The markers `keep` accepts as OpenCV's aruco functions take them: corners back in OpenCV's
// pixel convention, ids beside.
template <typename Keep>
void toOpenCvMarkers(const std::vector<MarkerDetection>& markers, const Keep& keep,
                     std::vector<std::vector<cv::Point2f>>& corners, std::vector<int>& ids) {
    for (const MarkerDetection& d : markers) {
        if (!keep(d))
            continue;
        std::vector<cv::Point2f> c;
        for (const Vector2d& p : d.corners)
            c.emplace_back(static_cast<float>(p.x() + kOpenCvArucoOffsetPx),
                           static_cast<float>(p.y() + kOpenCvArucoOffsetPx));
        corners.push_back(std::move(c));
        ids.push_back(d.id);
    }
}

// An 8-bit grey copy of a kMono8, kRGB8 or kBGR8 image; kInvalidArgument for anything else.
Result<cv::Mat> toGrey(const ImageView& image) {
    const ImageDesc& d = image.desc;
    if (d.format != PixelFormat::kMono8 && d.format != PixelFormat::kRGB8 &&
        d.format != PixelFormat::kBGR8)
        return Status(
            ErrorCode::kInvalidArgument,
            "markers need an 8-bit mono, rgb or bgr image, got " + std::string(toString(d.format)));
    const int channels = d.format == PixelFormat::kMono8 ? 1 : 3;
    if (d.width <= 0 || d.height <= 0 || !image.data)
        return Status(ErrorCode::kInvalidArgument, "markers need a non-empty image");
    if (d.stride_bytes < d.width * channels ||
        image.size_bytes < static_cast<size_t>(d.stride_bytes) * static_cast<size_t>(d.height - 1) +
                               static_cast<size_t>(d.width * channels))
        return Status(ErrorCode::kInvalidArgument, "image buffer smaller than its " +
                                                       std::to_string(d.width) + "x" +
                                                       std::to_string(d.height) + " description");
    const cv::Mat src(d.height, d.width, channels == 1 ? CV_8UC1 : CV_8UC3,
                      const_cast<uint8_t*>(image.data), static_cast<size_t>(d.stride_bytes));
    cv::Mat grey;
    if (channels == 1)
        grey = src.clone();
    else
        cv::cvtColor(src, grey,
                     d.format == PixelFormat::kRGB8 ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
    return grey;
}

}  // namespace

Status DetectorOptions::validate() const {
    if (!(apriltag_quad_decimate >= 1.0f && apriltag_quad_decimate <= 8.0f))
        return {ErrorCode::kInvalidArgument,
                "detector.apriltag_quad_decimate must be in [1, 8], got " +
                    std::to_string(apriltag_quad_decimate)};
    if (!(apriltag_quad_sigma >= -10.0f && apriltag_quad_sigma <= 10.0f))
        return {ErrorCode::kInvalidArgument,
                "detector.apriltag_quad_sigma must be in [-10, 10], got " +
                    std::to_string(apriltag_quad_sigma)};
    if (threads < 1 || threads > 256)
        return {ErrorCode::kInvalidArgument,
                "detector.threads must be in [1, 256], got " + std::to_string(threads)};
    return Status::ok();
}

bool isKnownDictionary(std::string_view name) {
    return findAruco(name) != nullptr || findApril(name) != nullptr;
}

std::optional<int> openCvDictionaryId(std::string_view name) {
    const ArucoName* a = findAruco(name);
    if (!a)
        return std::nullopt;
    return static_cast<int>(a->id);
}

int openCvDictionarySize(std::string_view name) {
    const ArucoName* a = findAruco(name);
    if (!a)
        return 0;
    try {
        return cv::aruco::getPredefinedDictionary(a->id)->bytesList.rows;
    } catch (const cv::Exception&) {
        return 0;
    }
}

Result<std::vector<MarkerDetection>> detectMarkers(const ImageView& image,
                                                   std::string_view dictionary,
                                                   const DetectorOptions& options,
                                                   const CameraModel* camera) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    const ArucoName* aruco = findAruco(dictionary);
    const AprilFamily* april = aruco ? nullptr : findApril(dictionary);
    if (!aruco && !april)
        return Status(ErrorCode::kInvalidArgument,
                      "unknown marker dictionary '" + std::string(dictionary) +
                          "' (OpenCV's DICT_* names or apriltag:<family>)");
    MIXRAY_RETURN_IF_ERROR(checkCameraSize(image, camera));
    auto grey = toGrey(image);
    if (!grey)
        return grey.status();
    const EdgePlane plane{camera};
    if (aruco) {
        cv::Ptr<cv::aruco::Dictionary> dict;
        try {
            dict = cv::aruco::getPredefinedDictionary(aruco->id);
        } catch (const cv::Exception& e) {
            return Status(ErrorCode::kInternal, std::string("OpenCV dictionary: ") + e.what());
        }
        return detectAruco(*grey, dict, std::string(aruco->name), options, plane);
    }
    return detectApril(*grey, *april, options, plane);
}

Result<std::vector<MarkerDetection>> detectMarkers(const ImageView& image,
                                                   const MarkerDictionary& dictionary,
                                                   const DetectorOptions& options,
                                                   const CameraModel* camera) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    auto dict = toOpenCv(dictionary);
    if (!dict)
        return dict.status();
    MIXRAY_RETURN_IF_ERROR(checkCameraSize(image, camera));
    auto grey = toGrey(image);
    if (!grey)
        return grey.status();
    return detectAruco(*grey, *dict, dictionary.name, options, EdgePlane{camera});
}

Result<MarkerDictionary> openCvDictionary(std::string_view name) {
    const ArucoName* a = findAruco(name);
    if (!a)
        return Status(ErrorCode::kInvalidArgument,
                      "'" + std::string(name) + "' is not one of OpenCV's DICT_* dictionaries");
    MarkerDictionary out;
    out.name = std::string(a->name);
    try {
        const cv::Ptr<cv::aruco::Dictionary> dict = cv::aruco::getPredefinedDictionary(a->id);
        out.marker_size = dict->markerSize;
        out.max_correction_bits = dict->maxCorrectionBits;
        for (int i = 0; i < dict->bytesList.rows; ++i) {
            const cv::Mat bits = cv::aruco::Dictionary::getBitsFromByteList(dict->bytesList.row(i),
                                                                            dict->markerSize);
            std::string code;
            for (int j = 0; j < static_cast<int>(bits.total()); ++j)
                code += bits.at<uint8_t>(j) ? '1' : '0';
            out.markers.push_back(std::move(code));
        }
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kInternal, std::string("OpenCV dictionary: ") + e.what());
    }
    return out;
}

Result<std::vector<DiamondDetection>> detectDiamonds(const ImageView& image,
                                                     const MarkerDictionary& dictionary,
                                                     double square_to_marker,
                                                     const std::vector<MarkerDetection>& markers) {
    if (!(square_to_marker > 1.0 && square_to_marker <= 100.0))
        return Status(ErrorCode::kInvalidArgument,
                      "diamond square/marker ratio must be in (1, 100], got " +
                          std::to_string(square_to_marker));
    auto dict = toOpenCv(dictionary);
    if (!dict)
        return dict.status();
    auto grey = toGrey(image);
    if (!grey)
        return grey.status();
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    toOpenCvMarkers(
        markers, [&](const MarkerDetection& d) { return d.dictionary == dictionary.name; }, corners,
        ids);
    std::vector<DiamondDetection> out;
    if (ids.size() < 4)  // OpenCV asserts on an empty list; a diamond has four markers
        return out;
    std::vector<std::vector<cv::Point2f>> diamond_corners;
    std::vector<cv::Vec4i> diamond_ids;
    try {
        cv::aruco::detectCharucoDiamond(*grey, corners, ids, static_cast<float>(square_to_marker),
                                        diamond_corners, diamond_ids, cv::noArray(), cv::noArray(),
                                        *dict);
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kInternal, std::string("OpenCV diamond detection: ") + e.what());
    }
    for (size_t i = 0; i < diamond_ids.size() && i < diamond_corners.size(); ++i) {
        if (diamond_corners[i].size() != 4)
            continue;
        DiamondDetection d;
        d.dictionary = dictionary.name;
        for (size_t k = 0; k < 4; ++k) {
            d.ids[k] = diamond_ids[i][static_cast<int>(k)];
            // interpolateCornersCharuco gives these, with its half-pixel offset.
            d.corners[k] = Vector2d(diamond_corners[i][k].x - kCharucoOffsetPx,
                                    diamond_corners[i][k].y - kCharucoOffsetPx);
        }
        out.push_back(d);
    }
    return out;
}

Result<std::vector<Corner>> charucoCorners(const ImageView& image, const CharucoBoardSpec& spec,
                                           const std::vector<MarkerDetection>& markers) {
    const ArucoName* dict = findAruco(spec.dictionary);
    if (!dict)
        return Status(ErrorCode::kInvalidArgument,
                      "ChArUco boards need an OpenCV dictionary, not '" + spec.dictionary + "'");
    if (spec.squares_x < 2 || spec.squares_y < 2 || !(spec.square_m > spec.marker_m) ||
        !(spec.marker_m > 0) || spec.first_id < 0)
        return Status(ErrorCode::kInvalidArgument,
                      "ChArUco board: at least 2x2 squares, 0 < marker_m < square_m, first_id >= "
                      "0");
    auto grey = toGrey(image);
    if (!grey)
        return grey.status();
    cv::Ptr<cv::aruco::CharucoBoard> board;
    try {
        board = cv::aruco::CharucoBoard::create(
            spec.squares_x, spec.squares_y, static_cast<float>(spec.square_m),
            static_cast<float>(spec.marker_m), cv::aruco::getPredefinedDictionary(dict->id));
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kInvalidArgument, std::string("ChArUco board: ") + e.what());
    }
    // Its markers are numbered from 0; a board printed with later ids shifts them all.
    for (int& id : board->ids)
        id += spec.first_id;
    if (spec.first_id + static_cast<int>(board->ids.size()) > board->dictionary->bytesList.rows)
        return Status(ErrorCode::kInvalidArgument,
                      "ChArUco board: its marker ids do not all exist in " + spec.dictionary);
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    toOpenCvMarkers(
        markers,
        [&](const MarkerDetection& d) {
            return d.dictionary == spec.dictionary &&
                   std::find(board->ids.begin(), board->ids.end(), d.id) != board->ids.end();
        },
        corners, ids);
    std::vector<Corner> out;
    if (ids.size() < 2)
        return out;
    std::vector<cv::Point2f> charuco;
    std::vector<int> charuco_ids;
    try {
        cv::aruco::interpolateCornersCharuco(corners, ids, *grey, board, charuco, charuco_ids);
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kInternal,
                      std::string("OpenCV ChArUco interpolation: ") + e.what());
    }
    const auto count = static_cast<int>(board->chessboardCorners.size());
    for (size_t i = 0; i < charuco_ids.size(); ++i) {
        if (charuco_ids[i] < 0 || charuco_ids[i] >= count)
            continue;
        Corner c;
        c.id = charuco_ids[i];
        c.pixel = Vector2d(charuco[i].x - kCharucoOffsetPx, charuco[i].y - kCharucoOffsetPx);
        out.push_back(c);
    }
    return out;
}

}  // namespace mixray::calibration
