// mrcal corners caches (corners_cache.h).
#include "mixray/calibration/corners_cache.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <system_error>

namespace mixray::calibration {
namespace {

constexpr std::string_view kLegend = "# filename x y level";
constexpr std::string_view kMagic = "## mixray-corners-cache 1";

std::string number(double v) {
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, r.ptr);
}

bool parseDouble(std::string_view s, double& v) {
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    return r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(v);
}

template <typename Int>
bool parseInt(std::string_view s, Int& v) {
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

std::vector<std::string_view> words(std::string_view line) {
    std::vector<std::string_view> out;
    size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i])))
            ++i;
        const size_t start = i;
        while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i])))
            ++i;
        if (i > start)
            out.push_back(line.substr(start, i - start));
    }
    return out;
}

bool hasSpace(const std::string& s) {
    return std::any_of(s.begin(), s.end(),
                       [](char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; });
}

// The text after the first `n` words of a comment row.
std::string rest(std::string_view line, size_t n) {
    size_t i = 0;
    for (size_t w = 0; w < n; ++w) {
        while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i])))
            ++i;
        while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i])))
            ++i;
    }
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i])))
        ++i;
    return std::string(line.substr(i));
}

std::string sizeText(int width, int height) {
    return std::to_string(width) + "x" + std::to_string(height);
}

// The image a view of a cache names, found as mrcal-calibrate-cameras finds it: an absolute
// name or one that is there from the working directory as it is, else next to the cache.
std::filesystem::path imageOfView(const std::filesystem::path& cache, const std::string& source) {
    const std::filesystem::path name(source);
    std::error_code ec;
    if (name.is_absolute() || std::filesystem::is_regular_file(name, ec))
        return name;
    return cache.parent_path() / name;
}

// The size of the image the cache's first view with corners names (mrcal reads that one image
// too); `camera` has views.
Result<ImageSize> sizeFromImages(const std::filesystem::path& cache, const CameraViews& camera) {
    const std::string why =
        ": mrcal's corners caches have no image size; give it (mixray calibrate --image-size "
        "WxH) or put the images where the cache names them";
    // The first view with corners, as mrcal's first observation.
    const auto first = std::find_if(camera.views.begin(), camera.views.end(),
                                    [](const TargetView& view) { return !view.corners.empty(); });
    const std::filesystem::path image =
        imageOfView(cache, (first != camera.views.end() ? *first : camera.views.front()).source);
    std::error_code ec;
    if (!std::filesystem::is_regular_file(image, ec))
        return Status(ErrorCode::kInvalidArgument, cache.string() + ": the first view's image " +
                                                       image.string() + " is not there" + why);
    cv::Mat decoded;
    try {
        // The whole image is decoded for its size, as mrcal does: one image per cache.
        decoded = cv::imread(image.string(), cv::IMREAD_GRAYSCALE);
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kInvalidArgument,
                      cache.string() + ": " + image.string() + ": " + e.what() + why);
    }
    if (decoded.empty())
        return Status(ErrorCode::kInvalidArgument, cache.string() + ": the first view's image " +
                                                       image.string() + " cannot be read" + why);
    return ImageSize{decoded.cols, decoded.rows};
}

// Gives every camera of a read cache its image size (readCornersCache()).
Status applyImageSize(const std::filesystem::path& path, bool mixray,
                      const std::optional<ImageSize>& image_size,
                      std::vector<CameraViews>& cameras) {
    if (image_size && (image_size->width <= 0 || image_size->height <= 0))
        return {ErrorCode::kInvalidArgument, path.string() + ": image size " +
                                                 sizeText(image_size->width, image_size->height) +
                                                 " must be positive"};
    for (CameraViews& camera : cameras) {
        const bool known = camera.width > 0 && camera.height > 0;
        if (known && image_size &&
            (camera.width != image_size->width || camera.height != image_size->height))
            return {ErrorCode::kInvalidArgument,
                    path.string() + ": camera '" + camera.camera + "' has images of " +
                        sizeText(camera.width, camera.height) + ", not " +
                        sizeText(image_size->width, image_size->height)};
        if (known)
            continue;
        if (image_size) {
            camera.width = image_size->width;
            camera.height = image_size->height;
        } else if (!mixray && !camera.views.empty()) {
            auto size = sizeFromImages(path, camera);
            if (!size)
                return size.status();
            camera.width = size->width;
            camera.height = size->height;
        }
    }
    return Status::ok();
}

}  // namespace

Status writeCornersCache(const std::filesystem::path& path,
                         const std::vector<CameraViews>& cameras) {
    if (cameras.empty())
        return {ErrorCode::kInvalidArgument, path.string() + ": no cameras to write"};
    const CalibrationTarget& target = cameras.front().target;
    MIXRAY_RETURN_IF_ERROR(target.validate().withContext(path.string()));
    const int count = target.pointCount();
    std::ostringstream out;
    out << kLegend << "\n" << kMagic << "\n## target " << target.spec() << "\n";
    for (const CameraViews& cam : cameras) {
        if (cam.target.spec() != target.spec())
            return {ErrorCode::kInvalidArgument,
                    path.string() + ": one cache holds one target; camera '" + cam.camera +
                        "' has " + cam.target.spec() + ", not " + target.spec()};
        out << "## camera " << cam.width << " " << cam.height << " " << cam.camera << "\n";
        for (const TargetView& v : cam.views) {
            if (v.source.empty() || hasSpace(v.source) || v.source[0] == '#')
                return {ErrorCode::kInvalidArgument,
                        path.string() + ": view source '" + v.source +
                            "' cannot be a vnlog filename (empty, spaces, or a leading #)"};
            out << "## view " << v.key << " " << static_cast<int>(v.rejection) << " " << v.why
                << "\n";
            if (v.rejection != ViewRejection::kNone || v.corners.empty()) {
                out << v.source << " - -\n";
                continue;
            }
            std::vector<const Corner*> by_id(static_cast<size_t>(count), nullptr);
            for (const Corner& c : v.corners) {
                if (c.id < 0 || c.id >= count)
                    return {ErrorCode::kInvalidArgument, path.string() + ": " + v.source +
                                                             ": corner id " + std::to_string(c.id) +
                                                             " is not a point of " + target.spec()};
                by_id[static_cast<size_t>(c.id)] = &c;
            }
            for (const Corner* c : by_id) {
                if (!c) {
                    out << v.source << " - - -\n";
                    continue;
                }
                const int level = c->weight >= 1 || !(c->weight > 0)
                                      ? 0
                                      : static_cast<int>(std::lround(-std::log2(c->weight)));
                out << v.source << " " << number(c->pixel.x()) << " " << number(c->pixel.y()) << " "
                    << level << "\n";
            }
        }
    }
    std::ofstream file(path, std::ios::binary | std::ios::trunc);
    if (!file)
        return {ErrorCode::kUnavailable, path.string() + ": cannot be written"};
    file << out.str();
    file.flush();
    if (!file)
        return {ErrorCode::kUnavailable, path.string() + ": write failed"};
    return Status::ok();
}

Result<std::vector<CameraViews>> readCornersCache(const std::filesystem::path& path,
                                                  const std::optional<CalibrationTarget>& target,
                                                  const std::optional<ImageSize>& image_size) {
    std::ifstream file(path, std::ios::binary);
    if (!file)
        return Status(ErrorCode::kNotFound, path.string() + ": cannot be opened");
    std::optional<CalibrationTarget> known = target;
    std::vector<CameraViews> cameras;
    struct Pending {
        int64_t key = 0;
        ViewRejection rejection = ViewRejection::kNone;
        std::string why;
    };
    std::optional<Pending> meta;  // the "## view" row before the view's data rows
    bool mixray = false;
    TargetView* view = nullptr;  // the view being filled
    int rows = 0, first_row_line = 0;
    bool empty_marker = false;  // the view's one "- -" row
    int line_no = 0;
    const auto where = [&](int line) { return path.string() + ":" + std::to_string(line) + ": "; };
    const auto finish = [&]() -> Status {
        if (!view)
            return Status::ok();
        const int count = known->pointCount();
        if (!(empty_marker && rows == 1) && rows != count)
            return {ErrorCode::kCorruptData, where(first_row_line) + view->source + " has " +
                                                 std::to_string(rows) + " rows, the target " +
                                                 std::to_string(count) + " points"};
        if (view->corners.empty() && view->rejection == ViewRejection::kNone) {
            view->rejection = ViewRejection::kNoTarget;
            if (view->why.empty())
                view->why = "no corners in the cache";
        }
        view = nullptr;
        return Status::ok();
    };
    const auto camera = [&]() -> CameraViews& {
        if (cameras.empty()) {
            CameraViews c;
            c.camera = path.stem().string();
            c.target = *known;
            cameras.push_back(std::move(c));
        }
        return cameras.back();
    };
    std::string line;
    while (std::getline(file, line)) {
        ++line_no;
        if (!line.empty() && line.back() == '\r')
            line.pop_back();
        const auto w = words(line);
        if (w.empty())
            continue;
        if (w[0][0] == '#') {
            if (line == kMagic) {
                mixray = true;
                continue;
            }
            if (!mixray || w[0] != "##" || w.size() < 2)
                continue;
            if (w[1] == "target" && w.size() == 3) {
                auto t = parseTarget(w[2]);
                if (!t)
                    return t.status().withContext(where(line_no));
                if (known && known->spec() != t->spec())
                    return Status(ErrorCode::kInvalidArgument,
                                  where(line_no) + "the cache's target is " + t->spec() + ", not " +
                                      known->spec());
                known = *t;
            } else if (w[1] == "camera" && w.size() >= 4) {
                MIXRAY_RETURN_IF_ERROR(finish());
                if (!known)
                    return Status(ErrorCode::kInvalidArgument,
                                  where(line_no) + "a camera before the target");
                CameraViews c;
                if (!parseInt(w[2], c.width) || !parseInt(w[3], c.height) || c.width < 0 ||
                    c.height < 0)
                    return Status(ErrorCode::kCorruptData, where(line_no) + "bad camera size");
                c.camera = rest(line, 4);
                c.target = *known;
                cameras.push_back(std::move(c));
            } else if (w[1] == "view" && w.size() >= 4) {
                MIXRAY_RETURN_IF_ERROR(finish());
                Pending p;
                int rejection = 0;
                if (!parseInt(w[2], p.key) || !parseInt(w[3], rejection) || rejection < 0 ||
                    rejection > static_cast<int>(ViewRejection::kLargerBoard))
                    return Status(ErrorCode::kCorruptData, where(line_no) + "bad view row");
                p.rejection = static_cast<ViewRejection>(rejection);
                p.why = rest(line, 4);
                meta = p;
            }
            continue;
        }
        if (!known)
            return Status(ErrorCode::kInvalidArgument,
                          path.string() + ": no target in the file; give the target");
        if (w.size() != 3 && w.size() != 4)
            return Status(ErrorCode::kCorruptData,
                          where(line_no) + "expected 'filename x y [level]'");
        const std::string source(w[0]);
        if (!view || meta || source != view->source) {
            MIXRAY_RETURN_IF_ERROR(finish());
            CameraViews& cam = camera();
            TargetView v;
            v.source = source;
            v.key = meta ? meta->key : static_cast<int64_t>(cam.views.size());
            if (meta) {
                v.rejection = meta->rejection;
                v.why = meta->why;
            }
            meta.reset();
            cam.views.push_back(std::move(v));
            view = &cam.views.back();
            rows = 0;
            first_row_line = line_no;
            empty_marker = false;
        }
        const int id = rows++;
        if (w[1] == "-" || w[2] == "-") {
            if (w.size() == 3 && rows == 1)
                empty_marker = true;
            continue;
        }
        Corner c;
        c.id = id;
        double x = 0, y = 0;
        if (!parseDouble(w[1], x) || !parseDouble(w[2], y))
            return Status(ErrorCode::kCorruptData, where(line_no) + "x and y must be numbers");
        if (x < 0 || y < 0)
            continue;  // mrcal's "not detected"
        if (w.size() == 4) {
            if (w[3] == "-")
                continue;
            double level = 0;
            if (!parseDouble(w[3], level))
                return Status(ErrorCode::kCorruptData, where(line_no) + "bad level");
            if (level < 0)
                continue;
            c.weight = std::pow(0.5, std::floor(level));
        }
        c.pixel = Eigen::Vector2d(x, y);
        view->corners.push_back(c);
    }
    MIXRAY_RETURN_IF_ERROR(finish());
    if (!known)
        return Status(ErrorCode::kInvalidArgument,
                      path.string() + ": no target in the file; give the target");
    if (cameras.empty())
        camera();
    MIXRAY_RETURN_IF_ERROR(applyImageSize(path, mixray, image_size, cameras));
    return cameras;
}

}  // namespace mixray::calibration
