// A live calibration session as a graph node: detects the target in each camera's newest frame,
// keeps or rejects each view with the rule that decided, tracks coverage, tilts and pair views,
// publishes a coverage map per camera, and writes the kept frames as a recording for the solve.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "mixray/calibration/detect.h"
#include "mixray/calibration/target.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/recording.h"

namespace mixray::calibration {

// What a live session looks for and when a view is worth keeping. Every field but `target` has
// a working default.
struct LiveCalibrationOptions {
    CalibrationTarget target;  // required
    // Image streams to detect the target in (mono8, rgb8, bgr8, mono16, ir16); empty: every such
    // stream of the graph at connect(). Depth16 streams are never cameras: they are recorded
    // beside the kept views (a depth calibration needs them at those instants).
    std::vector<std::string> cameras;
    DetectionOptions detection;
    // A usable view whose corners lie, on average over the corners it shares with a kept view
    // of the same camera, closer than this to where they were in that view adds almost nothing
    // to the solve: rejected as "too similar". 0: 2 % of the image diagonal (16 px at 640x480),
    // well above a hand's tremor while the board is held, below a deliberate move (4 % rejected
    // fish-eye views of sim_calibration.mkv that its solve needs).
    double min_corner_shift_px = 0;
    // The coverage grid over each image: cells in x and y. A cell is covered once a kept view
    // put a corner in it; its four corner cells are the image corners a lens model most needs.
    int grid_cols = 8, grid_rows = 6;
    // Tilt bins: a kept view whose board normal leans at least this far from the optical axis
    // left, right, up or down fills that bin; under it on both axes, "frontal". Focal length
    // and distortion are only observable with tilted views (Zhang 2000).
    double tilt_deg = 20;
    int views_wanted = 10;      // kept views per camera below which the camera is "missing views"
    int pair_views_wanted = 3;  // views seen by both cameras of each pair wanted for extrinsics
    // Frames of different streams whose host stamps lie within this of the instant's first one
    // form one instant (0: half the shortest nominal frame period of the streams, else
    // detection.max_skew_ns). Devices stamp on arrival, and a device delivering several streams
    // hands them over one after another, often more than 10 ms apart under load. The recording
    // stores an instant's frames at its first host stamp, so the offline solve pairs exactly
    // the views the session paired.
    int64_t instant_skew_ns = 0;
    // The node waits at most this long for the other streams' frames of an instant.
    double group_wait_s = 0.15;
    int coverage_width = 320;  // the coverage map's width in pixels (height by the aspect), > 0
    // Lossless input edges: every frame is judged (tests, recordings at fast pace); default
    // live: each camera's newest frame wins and capture never waits for detection.
    bool lossless = false;

    // kInvalidArgument naming the field.
    Status validate() const;
};

// One camera's view judged: what the node decided and why.
struct LiveDecision {
    std::string camera;
    uint64_t sequence = 0;
    int64_t host_stamp_ns = 0;
    bool kept = false;
    // "kept", "kept for pair kinect/color+env/color", or the rule that rejected it:
    // "no target", "partial target (12 of 24 corners, < 25 %)", "blurred (...)", "too similar to
    // kept view 3 (corners moved 4.1 px < 32 px)".
    std::string reason;
    std::vector<Corner> corners;  // found (empty without a target)
};

struct LiveCameraStatus {
    std::string camera;
    std::string coverage_stream;  // "coverage/kinect/color"
    int width = 0, height = 0;
    uint64_t judged = 0;  // views decided
    uint64_t kept = 0;
    uint64_t rejected = 0;
    std::map<std::string, uint64_t> rejected_by;  // rule ("no target", "too similar") -> views
    std::string last;                             // the last decision's reason
    int cells_covered = 0, cells_total = 0;
    std::vector<std::string> empty_image_corners;  // "top-left", "top-right", ...
    std::map<std::string, int> tilts;              // "frontal", "left", ... -> kept views
};

struct LivePairStatus {
    std::string a, b;
    int views = 0;  // instants both kept
};

// A snapshot of the session. Plain value.
struct LiveCalibrationStatus {
    std::vector<LiveCameraStatus> cameras;
    std::vector<LivePairStatus> pairs;
    uint64_t instants = 0;             // groups of frames judged
    uint64_t kept_instants = 0;        // instants with at least one kept view (recorded)
    uint64_t frames_replaced = 0;      // frames superseded by a newer one before being judged
    std::vector<std::string> missing;  // what the session still lacks, one line each

    // The live view's status object: {"messages": missing, "calibration": {...}} (docs).
    std::string json() const;
    // A few lines for the console: per camera kept/rejected by rule, then what is missing.
    std::string summary() const;
};

// Called on the node's thread after each view is judged; must return quickly.
using LiveDecisionCallback = std::function<void(const LiveDecision&)>;

// The session node. connect() subscribes to every camera and depth stream (live edges of
// capacity 2, or lossless) and declares one rgb8 coverage stream per camera; start() starts
// its thread, which groups frames of one instant, detects the target in each camera's frame,
// decides, and publishes the cameras' coverage maps. Rules, in order: the detector's own
// (no target, partial target, blurred, too oblique, larger board), then "too similar" to a
// kept view; a view that would be too similar is still kept when the instant is one of the
// first pair_views_wanted seen by both cameras of a pair. Kept instants are copied (every
// frame of the instant, depth included) so writeRecording() can store them.
// Thread-safety: Node methods by the graph's owner; status(), overlay(), finished() and
// writeRecording() (after stop()) from any thread.
class LiveCalibrationNode : public Node {
public:
    // kInvalidArgument from options.validate().
    static Result<std::unique_ptr<LiveCalibrationNode>> create(LiveCalibrationOptions options,
                                                               LiveDecisionCallback on_decision);
    ~LiveCalibrationNode() override;

    std::string name() const override { return "live-calibration"; }
    // kNotFound for a named camera the graph lacks, kInvalidArgument for one that is not an
    // image the detector reads; kNotFound when the graph has no camera at all.
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    // True once every input stream ended and what was queued has been judged.
    bool finished() const { return finished_.load(); }
    LiveCalibrationStatus status() const;
    // The latest detection of `camera` as a live-view overlay (docs/live-view.md): the corners
    // found, the board's outline, the decision. "{}" before the first.
    std::string overlay(const std::string& camera) const;
    std::vector<std::string> cameras() const;

    // Writes every kept instant's frames, with their recorded stream names and stamps, to a
    // mixray recording that `mixray calibrate RECORDING --target ...` solves offline.
    // kNotFound when nothing was kept; the writer's error naming the file.
    Status writeRecording(const std::filesystem::path& path,
                          const std::vector<Attachment>& attachments = {},
                          const std::map<std::string, std::string>& tags = {}) const;

private:
    struct Impl;
    explicit LiveCalibrationNode(std::unique_ptr<Impl> impl);
    void run();

    std::unique_ptr<Impl> impl_;
    std::thread thread_;
    std::atomic<bool> stopping_{false};
    std::atomic<bool> finished_{false};
};

}  // namespace mixray::calibration
