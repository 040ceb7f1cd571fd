// LiveCalibrationNode: groups each instant's frames, judges every camera's view of the target,
// keeps coverage, tilt and pair counts, draws coverage maps and stores the kept instants.
#include "mixray/calibration/live_calibration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mixray/graph/mkv.h"

namespace mixray::calibration {

namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

const char* const kTiltBins[] = {"frontal", "left", "right", "up", "down"};
const char* const kCornerNames[] = {"top-left", "top-right", "bottom-left", "bottom-right"};

bool isDetectable(PixelFormat f) {
    return f == PixelFormat::kMono8 || f == PixelFormat::kRGB8 || f == PixelFormat::kBGR8 ||
           f == PixelFormat::kMono16 || f == PixelFormat::kIR16;
}

std::string fixed(double v, int digits) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.*f", digits, v);
    return buffer;
}

// Mean distance between the corners two views share (both in point-id order); -1 when they
// share fewer than 4, too few to call the board's pose the same.
double meanShiftPx(const std::vector<Corner>& a, const std::vector<Corner>& b) {
    double sum = 0;
    int n = 0;
    for (size_t i = 0, j = 0; i < a.size() && j < b.size();) {
        if (a[i].id < b[j].id) {
            ++i;
        } else if (b[j].id < a[i].id) {
            ++j;
        } else {
            sum += (a[i].pixel - b[j].pixel).norm();
            ++n;
            ++i;
            ++j;
        }
    }
    return n >= 4 ? sum / n : -1;
}

// The tilt bin of a view, from a planar pose through a rough pinhole (focal length the larger
// image side, centred): the board's normal turned towards the camera, its lean left/right
// and up/down from the optical axis. Empty when the pose cannot be found.
std::string tiltBin(const std::vector<Corner>& corners, const CalibrationTarget& target, int width,
                    int height, double tilt_deg) {
    if (corners.size() < 4)
        return {};
    const std::vector<Eigen::Vector3d> points = target.points();
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (const Corner& c : corners) {
        if (c.id < 0 || c.id >= static_cast<int>(points.size()))
            continue;
        object.emplace_back(points[c.id].x(), points[c.id].y(), 0);
        image.emplace_back(c.pixel.x(), c.pixel.y());
    }
    if (object.size() < 4)
        return {};
    const double f = std::max(width, height);
    const cv::Matx33d K(f, 0, (width - 1) / 2.0, 0, f, (height - 1) / 2.0, 0, 0, 1);
    cv::Vec3d rvec, tvec;
    try {
        if (!cv::solvePnP(object, image, K, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_IPPE))
            return {};
    } catch (const cv::Exception&) {
        return {};
    }
    cv::Matx33d R;
    cv::Rodrigues(rvec, R);
    Eigen::Vector3d n(R(0, 2), R(1, 2), R(2, 2));
    if (n.z() > 0)
        n = -n;
    const double h = std::atan2(n.x(), -n.z()) * 180 / M_PI;
    const double v = std::atan2(n.y(), -n.z()) * 180 / M_PI;
    if (std::abs(h) < tilt_deg && std::abs(v) < tilt_deg)
        return "frontal";
    if (std::abs(h) >= std::abs(v))
        return h < 0 ? "left" : "right";
    return v < 0 ? "up" : "down";
}

}  // namespace

Status LiveCalibrationOptions::validate() const {
    if (Status s = target.validate(); !s)
        return s.withContext("target");
    MIXRAY_RETURN_IF_ERROR(detection.validate());
    if (!(min_corner_shift_px >= 0))
        return {ErrorCode::kInvalidArgument, "min_corner_shift_px must be >= 0"};
    if (grid_cols < 2 || grid_rows < 2 || grid_cols > 64 || grid_rows > 64)
        return {ErrorCode::kInvalidArgument, "grid_cols and grid_rows must lie in 2..64"};
    if (!(tilt_deg > 0 && tilt_deg < 90))
        return {ErrorCode::kInvalidArgument, "tilt_deg must lie in (0, 90)"};
    if (views_wanted < 1 || pair_views_wanted < 0)
        return {ErrorCode::kInvalidArgument,
                "views_wanted must be >= 1 and pair_views_wanted >= 0"};
    if (instant_skew_ns < 0)
        return {ErrorCode::kInvalidArgument, "instant_skew_ns must be >= 0"};
    if (!(group_wait_s >= 0 && group_wait_s <= 10))
        return {ErrorCode::kInvalidArgument, "group_wait_s must lie in [0, 10]"};
    if (coverage_width < 16 || coverage_width > 4096)
        return {ErrorCode::kInvalidArgument, "coverage_width must lie in 16..4096"};
    return Status::ok();
}

struct LiveCalibrationNode::Impl {
    struct Input {
        StreamId id = kInvalidStream;
        StreamInfo info;
        int camera = -1;  // index into cameras, -1 for a depth stream recorded beside them
        std::shared_ptr<FrameQueue> queue;
        FrameRef pending;
        Clock::time_point arrived;
        bool ended = false;
    };
    struct Camera {
        std::string name;
        size_t input = 0;
        int width = 0, height = 0;
        PooledStream coverage;
        uint64_t coverage_sequence = 0;
        std::vector<int> grid;                        // corners per cell, row-major
        std::vector<std::vector<Corner>> kept_views;  // corners of every kept view
        std::vector<Corner> last_corners;
        bool last_kept = false;
        LiveCameraStatus status;
        std::string overlay = "{}";
    };
    struct Stored {
        size_t input = 0;
        FrameMetadata meta;
        Image image;
    };

    LiveCalibrationOptions options;
    LiveDecisionCallback on_decision;
    Graph* graph = nullptr;
    std::vector<Input> inputs;
    std::vector<Camera> cameras;
    int64_t instant_skew_ns = 0;
    std::vector<LivePairStatus> pairs;

    mutable std::mutex mutex;  // guards cameras' status/overlay, pairs, counters, stored
    uint64_t instants = 0, kept_instants = 0, replaced = 0;
    std::vector<Stored> stored;

    double minShift(const Camera& c) const {
        if (options.min_corner_shift_px > 0)
            return options.min_corner_shift_px;
        return 0.02 * std::hypot(c.width, c.height);
    }

    LivePairStatus* pairOf(int a, int b) {
        for (LivePairStatus& p : pairs)
            if (p.a == cameras[a].name && p.b == cameras[b].name)
                return &p;
        return nullptr;
    }

    void processGroup(const std::vector<size_t>& members, int64_t instant_ns);
    void publishCoverage(Camera& c, const FrameMetadata& meta);
    std::string overlayJson(const LiveDecision& d) const;
    std::vector<std::string> missing() const;
};

LiveCalibrationNode::LiveCalibrationNode(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

LiveCalibrationNode::~LiveCalibrationNode() {
    stop();
}

Result<std::unique_ptr<LiveCalibrationNode>> LiveCalibrationNode::create(
    LiveCalibrationOptions options, LiveDecisionCallback on_decision) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    auto impl = std::make_unique<Impl>();
    impl->options = std::move(options);
    impl->on_decision = std::move(on_decision);
    return std::unique_ptr<LiveCalibrationNode>(new LiveCalibrationNode(std::move(impl)));
}

Status LiveCalibrationNode::connect(Graph& graph) {
    Impl& m = *impl_;
    m.graph = &graph;
    std::vector<std::string> wanted = m.options.cameras;
    for (const std::string& name : wanted) {
        auto id = graph.findStream(name);
        if (!id)
            return {ErrorCode::kNotFound, "camera " + name + ": no such stream in the rig"};
        if (!isDetectable(graph.stream(*id).format.format))
            return {ErrorCode::kInvalidArgument,
                    "camera " + name + ": " +
                        std::string(toString(graph.stream(*id).format.format)) +
                        " images cannot be searched for the target (mono8, rgb8, bgr8, mono16 "
                        "or ir16)"};
    }
    const auto streams = graph.streams();
    for (StreamId id = 0; id < streams.size(); ++id) {
        const StreamInfo& info = streams[id];
        const bool depth = info.format.format == PixelFormat::kDepth16;
        const bool camera =
            wanted.empty() ? isDetectable(info.format.format) && !depth
                           : std::find(wanted.begin(), wanted.end(), info.name) != wanted.end();
        if (!camera && !depth)
            continue;
        Impl::Input in;
        in.id = id;
        in.info = info;
        QueueOptions q;
        q.capacity = 2;
        q.policy = m.options.lossless ? QueuePolicy::kLossless : QueuePolicy::kLive;
        q.name = name();
        auto queue = graph.subscribe(id, q);
        if (!queue)
            return queue.status();
        in.queue = std::move(queue).value();
        if (camera) {
            in.camera = static_cast<int>(m.cameras.size());
            Impl::Camera c;
            c.name = info.name;
            c.input = m.inputs.size();
            c.width = info.format.width;
            c.height = info.format.height;
            c.grid.assign(static_cast<size_t>(m.options.grid_cols * m.options.grid_rows), 0);
            StreamInfo cov;
            cov.name = "coverage/" + info.name;
            cov.device = "coverage";
            cov.kind = StreamKind::kColor;
            const int w = m.options.coverage_width;
            const int h = std::max(
                1, static_cast<int>(std::lround(static_cast<double>(w) * std::max(1, c.height) /
                                                std::max(1, c.width))));
            cov.format = ImageDesc::packed(PixelFormat::kRGB8, w, h);
            cov.tags["coverage_of"] = info.name;
            auto pooled = addPooledStream(graph, cov, 3);
            if (!pooled)
                return pooled.status();
            c.coverage = std::move(pooled).value();
            c.status.camera = c.name;
            c.status.coverage_stream = cov.name;
            c.status.width = c.width;
            c.status.height = c.height;
            c.status.cells_total = m.options.grid_cols * m.options.grid_rows;
            m.cameras.push_back(std::move(c));
        }
        m.inputs.push_back(std::move(in));
    }
    if (m.cameras.empty())
        return {ErrorCode::kNotFound,
                "no camera to calibrate: the rig has no mono8, rgb8, bgr8, mono16 or ir16 stream"};
    m.instant_skew_ns = m.options.instant_skew_ns;
    if (m.instant_skew_ns == 0) {
        double fastest = 0;
        for (const Impl::Input& in : m.inputs)
            fastest = std::max(fastest, in.info.nominal_fps);
        m.instant_skew_ns =
            fastest > 0 ? static_cast<int64_t>(0.5e9 / fastest) : m.options.detection.max_skew_ns;
    }
    for (size_t a = 0; a < m.cameras.size(); ++a)
        for (size_t b = a + 1; b < m.cameras.size(); ++b)
            m.pairs.push_back({m.cameras[a].name, m.cameras[b].name, 0});
    return Status::ok();
}

Status LiveCalibrationNode::start() {
    stopping_ = false;
    finished_ = false;
    thread_ = std::thread([this] { run(); });
    return Status::ok();
}

void LiveCalibrationNode::stop() {
    stopping_ = true;
    if (thread_.joinable())
        thread_.join();
}

void LiveCalibrationNode::run() {
    Impl& m = *impl_;
    const int64_t skew = m.instant_skew_ns;
    const auto wait = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(m.options.group_wait_s));
    FrameMetadata first;  // empty maps, so the view shows every camera's grid from the start
    first.host_stamp_ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
            .count();
    for (Impl::Camera& c : m.cameras)
        m.publishCoverage(c, first);
    while (!stopping_) {
        const auto now = Clock::now();
        for (Impl::Input& in : m.inputs) {
            if (m.options.lossless && in.pending)
                continue;
            while (auto f = in.queue->tryPop()) {
                if (in.pending) {
                    std::lock_guard lock(m.mutex);
                    ++m.replaced;
                }
                in.pending = std::move(*f);
                in.arrived = now;
                if (m.options.lossless)
                    break;
            }
            if (!in.pending && in.queue->closed() && in.queue->stats().size == 0)
                in.ended = true;
        }
        // The oldest instant waiting, and who has a frame of it.
        int64_t anchor = INT64_MAX;
        for (const Impl::Input& in : m.inputs)
            if (in.pending)
                anchor = std::min(anchor, in.pending.meta().host_stamp_ns);
        if (anchor == INT64_MAX) {
            if (std::all_of(m.inputs.begin(), m.inputs.end(),
                            [](const Impl::Input& in) { return in.ended; }))
                break;
            std::this_thread::sleep_for(std::chrono::milliseconds(3));
            continue;
        }
        std::vector<size_t> members;
        bool complete = true, waited = false;
        for (size_t i = 0; i < m.inputs.size(); ++i) {
            const Impl::Input& in = m.inputs[i];
            if (in.pending && in.pending.meta().host_stamp_ns - anchor <= skew) {
                members.push_back(i);
                waited = waited || now - in.arrived >= wait;
            }
            // A stream whose newer frame is already here will not deliver this instant's.
            complete = complete && (in.pending || in.ended);
        }
        if (!complete && !waited) {
            std::this_thread::sleep_for(std::chrono::milliseconds(3));
            continue;
        }
        m.processGroup(members, anchor);
        for (size_t i : members)
            m.inputs[i].pending.reset();
    }
    for (Impl::Input& in : m.inputs)
        in.pending.reset();
    if (!stopping_)
        for (const Impl::Camera& c : m.cameras)
            m.graph->endStream(c.coverage.id);
    finished_ = true;
}

void LiveCalibrationNode::Impl::processGroup(const std::vector<size_t>& members,
                                             int64_t instant_ns) {
    struct Judged {
        int camera = 0;
        LiveDecision d;
        bool usable = false;
        std::string similar;  // non-empty: too similar, and why
        std::string tilt;
    };
    std::vector<Judged> judged;
    for (size_t i : members) {
        const Input& in = inputs[i];
        if (in.camera < 0)
            continue;
        Camera& c = cameras[in.camera];
        Judged j;
        j.camera = in.camera;
        j.d.camera = c.name;
        j.d.sequence = in.pending.meta().sequence;
        j.d.host_stamp_ns = in.pending.meta().host_stamp_ns;
        if (in.pending.meta().status == FrameStatus::kCorrupt) {
            j.d.reason = "unreadable (the frame is marked corrupt)";
            judged.push_back(std::move(j));
            continue;
        }
        auto view = detectTarget(in.pending.image(), options.target, options.detection);
        if (!view) {
            j.d.reason = "unreadable (" + view.status().message() + ")";
        } else {
            j.d.corners = view->corners;
            if (view->rejection != ViewRejection::kNone) {
                j.d.reason = std::string(toString(view->rejection));
                if (!view->why.empty())
                    j.d.reason += " (" + view->why + ")";
            } else {
                j.usable = true;
                const double min_shift = minShift(c);
                for (size_t k = 0; k < c.kept_views.size(); ++k) {
                    const double shift = meanShiftPx(view->corners, c.kept_views[k]);
                    if (shift >= 0 && shift < min_shift) {
                        j.similar = "too similar to kept view " + std::to_string(k + 1) +
                                    " (corners moved " + fixed(shift, 1) + " px < " +
                                    fixed(min_shift, 0) + " px)";
                        break;
                    }
                }
                j.tilt =
                    tiltBin(view->corners, options.target, c.width, c.height, options.tilt_deg);
            }
        }
        judged.push_back(std::move(j));
    }

    // Keep the novel views; a similar one still helps while its pair lacks views seen by both.
    for (Judged& j : judged)
        j.d.kept = j.usable && j.similar.empty();
    std::unique_lock lock(mutex);
    for (size_t x = 0; x < judged.size(); ++x)
        for (size_t y = x + 1; y < judged.size(); ++y) {
            Judged& a = judged[x];
            Judged& b = judged[y];
            if (!a.usable || !b.usable || (a.d.kept && b.d.kept))
                continue;
            const int lo = std::min(a.camera, b.camera), hi = std::max(a.camera, b.camera);
            const LivePairStatus* pair = pairOf(lo, hi);
            if (pair && pair->views < options.pair_views_wanted) {
                const std::string why = "kept for pair " + pair->a + "+" + pair->b;
                for (Judged* j : {&a, &b})
                    if (!j->d.kept) {
                        j->d.kept = true;
                        j->d.reason = why;
                    }
            }
        }
    for (size_t x = 0; x < judged.size(); ++x)
        for (size_t y = x + 1; y < judged.size(); ++y)
            if (judged[x].d.kept && judged[y].d.kept) {
                const int lo = std::min(judged[x].camera, judged[y].camera);
                const int hi = std::max(judged[x].camera, judged[y].camera);
                if (LivePairStatus* pair = pairOf(lo, hi))
                    ++pair->views;
            }

    if (!judged.empty())
        ++instants;  // an instant of depth frames alone judges nothing
    bool any_kept = false;
    for (Judged& j : judged) {
        Camera& c = cameras[j.camera];
        LiveCameraStatus& s = c.status;
        ++s.judged;
        if (j.d.kept) {
            any_kept = true;
            if (j.d.reason.empty())
                j.d.reason = "kept";
            ++s.kept;
            c.kept_views.push_back(j.d.corners);
            for (const Corner& corner : j.d.corners) {
                const int cx = std::clamp(
                    static_cast<int>((corner.pixel.x() + 0.5) * options.grid_cols / c.width), 0,
                    options.grid_cols - 1);
                const int cy = std::clamp(
                    static_cast<int>((corner.pixel.y() + 0.5) * options.grid_rows / c.height), 0,
                    options.grid_rows - 1);
                ++c.grid[static_cast<size_t>(cy * options.grid_cols + cx)];
            }
            if (!j.tilt.empty())
                ++s.tilts[j.tilt];
        } else {
            if (j.d.reason.empty())
                j.d.reason = j.similar;
            ++s.rejected;
            const std::string rule =
                !j.similar.empty() ? "too similar" : j.d.reason.substr(0, j.d.reason.find(" ("));
            ++s.rejected_by[rule];
        }
        s.last = j.d.reason;
        s.cells_covered = static_cast<int>(
            std::count_if(c.grid.begin(), c.grid.end(), [](int n) { return n > 0; }));
        s.empty_image_corners.clear();
        const int last_col = options.grid_cols - 1, last_row = options.grid_rows - 1;
        const int corner_cells[] = {0, last_col, last_row * options.grid_cols,
                                    last_row * options.grid_cols + last_col};
        for (int k = 0; k < 4; ++k)
            if (c.grid[static_cast<size_t>(corner_cells[k])] == 0)
                s.empty_image_corners.push_back(kCornerNames[k]);
        c.last_corners = j.d.corners;
        c.last_kept = j.d.kept;
        c.overlay = overlayJson(j.d);
    }
    if (any_kept) {
        ++kept_instants;
        for (size_t i : members) {
            const Input& in = inputs[i];
            if (in.camera >= 0 && std::none_of(judged.begin(), judged.end(), [&](const Judged& j) {
                    return j.camera == in.camera && j.d.kept;
                }))
                continue;
            Stored frame{i, in.pending.meta(), Image::copyOf(in.pending.image())};
            frame.meta.host_stamp_ns = instant_ns;
            stored.push_back(std::move(frame));
        }
    }
    lock.unlock();
    // Only this thread changes grids and kept views, so the maps are drawn without the lock.
    for (const Judged& j : judged) {
        publishCoverage(cameras[j.camera], inputs[cameras[j.camera].input].pending.meta());
        if (on_decision)
            on_decision(j.d);
    }
}

void LiveCalibrationNode::Impl::publishCoverage(Camera& c, const FrameMetadata& meta) {
    WritableFrame frame = c.coverage.pool->acquire();
    if (!frame) {
        graph->countLost(c.coverage.id);
        return;
    }
    MutableImageView view = frame.image();
    const int w = view.desc.width, h = view.desc.height;
    cv::Mat image(h, w, CV_8UC3, view.data, view.desc.stride_bytes);
    image.setTo(cv::Scalar(24, 24, 24));
    int most = 1;
    for (int n : c.grid)
        most = std::max(most, n);
    const double sx = static_cast<double>(w) / std::max(1, c.width);
    const double sy = static_cast<double>(h) / std::max(1, c.height);
    for (int row = 0; row < options.grid_rows; ++row)
        for (int col = 0; col < options.grid_cols; ++col) {
            const int n = c.grid[static_cast<size_t>(row * options.grid_cols + col)];
            const cv::Point p0(col * w / options.grid_cols, row * h / options.grid_rows);
            const cv::Point p1((col + 1) * w / options.grid_cols - 1,
                               (row + 1) * h / options.grid_rows - 1);
            // RGB: empty cells dark red, covered ones green, brighter with more corners.
            const cv::Scalar colour =
                n == 0 ? cv::Scalar(110, 20, 20) : cv::Scalar(20, 90 + 165 * n / most, 40);
            cv::rectangle(image, p0, p1, colour, cv::FILLED);
            cv::rectangle(image, p0, p1, cv::Scalar(60, 60, 60), 1);
        }
    for (const auto& kept : c.kept_views)
        for (const Corner& corner : kept)
            cv::circle(image, cv::Point(corner.pixel.x() * sx, corner.pixel.y() * sy), 1,
                       cv::Scalar(235, 235, 235), cv::FILLED);
    const cv::Scalar last = c.last_kept ? cv::Scalar(255, 220, 0) : cv::Scalar(255, 80, 80);
    for (const Corner& corner : c.last_corners)
        cv::circle(image, cv::Point(corner.pixel.x() * sx, corner.pixel.y() * sy), 2, last, 1);
    frame.meta() = meta;
    frame.meta().stream = c.coverage.id;
    frame.meta().sequence = c.coverage_sequence++;
    frame.meta().status = FrameStatus::kOk;
    graph->publish(std::move(frame).publish());
}

std::string LiveCalibrationNode::Impl::overlayJson(const LiveDecision& d) const {
    const char* colour = d.kept ? "#30D158" : "#FF453A";
    json o = json::object();
    json circles = json::array();
    std::vector<cv::Point2f> points;
    for (const Corner& corner : d.corners) {
        json circle = json::object();
        circle["centre"] = {corner.pixel.x(), corner.pixel.y()};
        circle["radius"] = 3;
        circle["color"] = colour;
        circles.push_back(circle);
        points.emplace_back(static_cast<float>(corner.pixel.x()),
                            static_cast<float>(corner.pixel.y()));
    }
    if (points.size() >= 3) {
        std::vector<cv::Point2f> hull;
        cv::convexHull(points, hull);
        json outline = json::array();
        for (const cv::Point2f& p : hull)
            outline.push_back({p.x, p.y});
        json polygon = json::object();
        polygon["points"] = outline;
        polygon["color"] = colour;
        polygon["label"] = std::to_string(points.size());
        o["polygons"] = json::array();
        o["polygons"].push_back(polygon);
    }
    o["circles"] = circles;
    json text = json::object();
    text["at"] = {8, 20};
    text["text"] = (d.kept ? "" : "rejected: ") + d.reason;
    text["color"] = colour;
    o["texts"] = json::array();
    o["texts"].push_back(text);
    return o.dump();
}

std::vector<std::string> LiveCalibrationNode::Impl::missing() const {
    std::vector<std::string> out;
    for (const Camera& c : cameras) {
        const LiveCameraStatus& s = c.status;
        if (s.kept < static_cast<uint64_t>(options.views_wanted))
            out.push_back(c.name + ": " + std::to_string(s.kept) + " of " +
                          std::to_string(options.views_wanted) + " views kept");
        if (!s.empty_image_corners.empty()) {
            std::string list;
            for (const std::string& k : s.empty_image_corners)
                list += (list.empty() ? "" : ", ") + k;
            out.push_back(c.name + ": no corners yet in the image's " + list);
        }
        if (s.cells_covered < s.cells_total)
            out.push_back(c.name + ": " + std::to_string(s.cells_total - s.cells_covered) + " of " +
                          std::to_string(s.cells_total) + " image cells without corners");
        std::string tilts;
        for (const char* bin : kTiltBins)
            if (!s.tilts.count(bin))
                tilts += (tilts.empty() ? "" : ", ") + std::string(bin);
        if (!tilts.empty())
            out.push_back(c.name + ": tilts not yet seen: " + tilts);
    }
    for (const LivePairStatus& p : pairs)
        if (p.views < options.pair_views_wanted)
            out.push_back(p.a + "+" + p.b + ": " + std::to_string(p.views) + " of " +
                          std::to_string(options.pair_views_wanted) + " views seen by both");
    return out;
}

LiveCalibrationStatus LiveCalibrationNode::status() const {
    const Impl& m = *impl_;
    std::lock_guard lock(m.mutex);
    LiveCalibrationStatus s;
    for (const Impl::Camera& c : m.cameras)
        s.cameras.push_back(c.status);
    s.pairs = m.pairs;
    s.instants = m.instants;
    s.kept_instants = m.kept_instants;
    s.frames_replaced = m.replaced;
    s.missing = m.missing();
    return s;
}

std::string LiveCalibrationNode::overlay(const std::string& camera) const {
    std::lock_guard lock(impl_->mutex);
    for (const Impl::Camera& c : impl_->cameras)
        if (c.name == camera)
            return c.overlay;
    return "{}";
}

std::vector<std::string> LiveCalibrationNode::cameras() const {
    std::vector<std::string> out;
    for (const Impl::Camera& c : impl_->cameras)
        out.push_back(c.name);
    return out;
}

Status LiveCalibrationNode::writeRecording(const std::filesystem::path& path,
                                           const std::vector<Attachment>& attachments,
                                           const std::map<std::string, std::string>& tags) const {
    const Impl& m = *impl_;
    std::lock_guard lock(m.mutex);
    if (m.stored.empty())
        return {ErrorCode::kNotFound,
                path.string() + ": no view was kept, so there is nothing to record"};
    RecordingHeader header;
    header.attachments = attachments;
    header.tags = tags;
    std::vector<StreamId> index(m.inputs.size(), kInvalidStream);
    std::vector<std::shared_ptr<BufferPool>> pools(m.inputs.size());
    for (const Impl::Stored& s : m.stored) {
        if (index[s.input] != kInvalidStream)
            continue;
        index[s.input] = static_cast<StreamId>(header.streams.size());
        StreamInfo info = m.inputs[s.input].info;
        header.streams.push_back(info);
        BufferPoolOptions pool;
        pool.desc = info.format;
        pool.buffer_count = 1;
        pool.name = info.name;
        pools[s.input] = BufferPool::create(pool);
        if (!pools[s.input])
            return {ErrorCode::kInternal, "cannot allocate a buffer for " + info.name};
    }
    std::vector<const Impl::Stored*> order;
    for (const Impl::Stored& s : m.stored)
        order.push_back(&s);
    std::stable_sort(order.begin(), order.end(), [](const auto* a, const auto* b) {
        return a->meta.host_stamp_ns < b->meta.host_stamp_ns;
    });
    auto writer = createMkvWriter(path, header);
    if (!writer)
        return writer.status();
    for (const Impl::Stored* s : order) {
        FrameMetadata meta = s->meta;
        meta.stream = index[s->input];
        FrameRef frame = copyIntoPool(*pools[s->input], s->image.view(), meta);
        if (!frame)
            return {ErrorCode::kInternal, path.string() + ": a kept frame of " +
                                              m.inputs[s->input].info.name +
                                              " does not fit its stream's buffer"};
        MIXRAY_RETURN_IF_ERROR((*writer)->write(frame));
    }
    return (*writer)->close();
}

std::string LiveCalibrationStatus::json() const {
    nlohmann::json cams = nlohmann::json::array();
    for (const LiveCameraStatus& c : cameras) {
        nlohmann::json tilts = nlohmann::json::object();
        for (const auto& [bin, n] : c.tilts)
            tilts[bin] = n;
        nlohmann::json rejected_by = nlohmann::json::object();
        for (const auto& [rule, n] : c.rejected_by)
            rejected_by[rule] = n;
        cams.push_back({{"camera", c.camera},
                        {"coverage_stream", c.coverage_stream},
                        {"judged", c.judged},
                        {"kept", c.kept},
                        {"rejected", c.rejected},
                        {"rejected_by", rejected_by},
                        {"last", c.last},
                        {"cells_covered", c.cells_covered},
                        {"cells_total", c.cells_total},
                        {"empty_image_corners", c.empty_image_corners},
                        {"tilts", tilts}});
    }
    nlohmann::json pair_list = nlohmann::json::array();
    for (const LivePairStatus& p : pairs)
        pair_list.push_back({{"a", p.a}, {"b", p.b}, {"views", p.views}});
    nlohmann::json o;
    o["messages"] = missing;
    o["calibration"] = {{"cameras", cams},
                        {"pairs", pair_list},
                        {"instants", instants},
                        {"kept_instants", kept_instants},
                        {"frames_replaced", frames_replaced}};
    return o.dump();
}

std::string LiveCalibrationStatus::summary() const {
    std::string out;
    for (const LiveCameraStatus& c : cameras) {
        out += c.camera + ": " + std::to_string(c.kept) + " views kept, " +
               std::to_string(c.rejected) + " rejected";
        std::string rules;
        for (const auto& [rule, n] : c.rejected_by)
            rules += (rules.empty() ? "" : ", ") + rule + " " + std::to_string(n);
        if (!rules.empty())
            out += " (" + rules + ")";
        out += "; corners in " + std::to_string(c.cells_covered) + " of " +
               std::to_string(c.cells_total) + " image cells\n";
    }
    for (const LivePairStatus& p : pairs)
        out += p.a + "+" + p.b + ": " + std::to_string(p.views) + " views seen by both\n";
    if (missing.empty())
        out += "nothing missing\n";
    for (const std::string& line : missing)
        out += "missing: " + line + "\n";
    return out;
}

}  // namespace mixray::calibration
