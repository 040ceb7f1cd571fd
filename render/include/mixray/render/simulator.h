// Synthetic rig sessions with ground truth: a Kinect-like RGB-D camera moving over a table with
// a marker and light probes, and a fish-eye environment camera, rendered with the Embree
// renderer; written as an ordinary recording plus truth files (docs/simulation.md).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stop_token>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/render/scene.h"

namespace mixray::render {

enum class SimScenario : uint8_t {
    kTabletop,     // marker, mirror and diffuse probe spheres, boxes; the camera orbits
    kCalibration,  // a ChArUco board in many poses seen by every camera, the marker on the table
};

std::string_view toString(SimScenario scenario);
std::optional<SimScenario> simScenarioFromString(std::string_view name);

// What to simulate. Every field has a working default; validate() names a bad one.
struct SimulatorOptions {
    SimScenario scenario = SimScenario::kTabletop;
    int frames = 0;     // colour frames (calibration: board views); 0: 45 / 20
    uint64_t seed = 1;  // depth noise, calibration board poses, antialiasing jitter
    int width = 640;    // Kinect colour, IR and depth size; intrinsics scale with it
    int height = 480;
    int samples_per_pixel = 4;  // antialiasing, a square number
    int env_every = 0;          // an environment-camera frame every N colour frames; 0: 15 / 1
    int threads = 0;            // render threads; 0: all cores
    int env_map_width = 512;    // equirectangular environment map (height = width / 2)
    // kinect/depth registered to the colour camera (true), or aligned with the IR camera as a
    // Kinect delivers it with registration off (false: what a depth calibration needs); empty:
    // registered for tabletop, IR-aligned for calibration.
    std::optional<bool> register_depth;
    // Where the scene's textures and environment map are written; empty: a temporary folder
    // removed with the Simulator.
    std::filesystem::path asset_dir;
    std::string asset_prefix = "sim";  // file name prefix of those assets
    // Objects (with their materials) placed in the real scene, world frame: rendering with
    // them gives the ground truth a compositor aims for (the virtual objects as if they were
    // real). Their names must not clash with the scenario's; lights are not taken.
    SceneDescription inserted;
    // Cancels the work: once a stop is requested, Simulator::render() returns kCancelled within
    // about one image tile and simulateSession() stops (see there). Default: never.
    std::stop_token stop;

    Status validate() const;
};

// Kinect v1 depth as a structured-light disparity measurement (Khoshelham & Elberink 2012,
// "Accuracy and resolution of Kinect depth data for indoor mapping applications"): disparity
// d = f·b / z between the IR camera and the projector, Gaussian noise on d, quantised to 1/8
// pixel, so depth error and step grow with z². Plain value.
struct KinectDepthModel {
    double focal_px = 580;             // IR camera focal length the disparity is measured with
    double baseline_m = 0.075;         // IR camera to projector, along the IR camera's +x
    double disparity_step_px = 0.125;  // the Kinect's 1/8-pixel disparity units
    double disparity_noise_px = 0.07;  // σ of d: σ_z ≈ 1.6 mm·z² (z in m), as K&E measured
    double min_range_m = 0.5;
    double max_range_m = 4.5;
    double max_incidence_deg = 78;  // grazing surfaces return no pattern
    double edge_jump = 0.03;        // neighbours further than this fraction of z apart: hole

    // Depth step (m) between adjacent disparity levels at depth z.
    double depthStep(double z_m) const;
    // σ of depth (m) at z.
    double depthSigma(double z_m) const;
};

// One light probe sphere resting on the table.
struct SimProbe {
    std::string name;
    MaterialType material = MaterialType::kMirror;  // kMirror or kDiffuse
    double radius_m = 0.04;
    Eigen::Vector3d centre_world = Eigen::Vector3d::Zero();
};

// The ChArUco board of the calibration scenario (OpenCV cv::aruco::CharucoBoard; its frame:
// origin at the board's top-left corner, +x right, +y down, +z into the board).
struct SimBoard {
    int squares_x = 7;
    int squares_y = 5;
    double square_m = 0.05;
    double marker_m = 0.037;
    std::string dictionary = "DICT_6X6_250";
};

// Ground truth of one colour frame (calibration: one board view).
struct SimFrameTruth {
    int64_t stamp_ns = 0;  // device and host stamp of the frame's colour image
    Eigen::Isometry3d T_world_color = Eigen::Isometry3d::Identity();
    bool env_frame = false;  // an environment-camera frame was taken with it
    std::optional<Eigen::Isometry3d> T_world_board;  // calibration only
    // Fraction of the board's ChArUco corners each camera sees (in the image, facing it).
    double board_in_color = 0, board_in_ir = 0, board_in_env = 0;
    double marker_in_color = 0;  // fraction of the marker's corners in the colour image
};

// Everything the simulator knows. Plain value.
struct SimTruth {
    SimScenario scenario = SimScenario::kTabletop;
    uint64_t seed = 1;
    double fps = 30;
    int env_every = 1;               // an env/color frame with every N-th colour frame
    calibration::CameraModel color;  // kinect/color
    bool depth_registered = true;    // kinect/depth registered to colour; false: IR-aligned
    calibration::CameraModel ir;     // the Kinect's IR (depth) camera
    calibration::CameraModel env;    // fish-eye environment camera
    Eigen::Isometry3d T_color_ir = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d T_world_env = Eigen::Isometry3d::Identity();
    KinectDepthModel depth_model;
    int marker_id = 23;
    std::string marker_dictionary = "DICT_6X6_250";
    double marker_size_m = 0.10;  // black square's side
    Eigen::Isometry3d T_world_marker = Eigen::Isometry3d::Identity();
    double table_z_m = -0.0005;  // the table top, just under the printed marker
    std::vector<SimProbe> probes;
    std::vector<Light> lights;  // directional; direction = travel direction, world frame
    std::filesystem::path environment_map;  // equirectangular EXR, environment frame = world
    std::optional<SimBoard> board;
    SceneDescription scene;  // the real scene, every object a ghost, for re-rendering
    std::vector<SimFrameTruth> frames;

    // The marker's corners in the world frame, in OpenCV's order (top-left, top-right,
    // bottom-right, bottom-left of the upright marker image).
    std::vector<Eigen::Vector3d> markerCornersWorld() const;
    // The board's inner (ChArUco) corners in the board frame, row by row (OpenCV's ids).
    std::vector<Eigen::Vector3d> boardCorners() const;
};

// One simulated frame: the images and which of them exist this frame.
struct SimFrame {
    int index = 0;
    Image color;  // rgb8, sRGB
    Image depth;  // depth16 mm (registered to colour or IR-aligned), 0 = no measurement
    Image ir;     // ir16 (calibration scenario only), else empty
    Image env;    // rgb8 fish-eye, only on env frames, else empty
};

// Renders the frames of one scenario. Thread-bound; render() parallelises internally.
class Simulator {
public:
    static Result<std::unique_ptr<Simulator>> create(const SimulatorOptions& options);
    virtual ~Simulator() = default;

    virtual const SimTruth& truth() const = 0;
    virtual int frameCount() const = 0;
    // Renders frame `index` (0 ≤ index < frameCount()); deterministic for the seed.
    virtual Result<SimFrame> render(int index) = 0;
    // Only the colour image of frame `index` (as render(index).color).
    virtual Result<Image> renderColor(int index) = 0;
};

// The options a truth file's `simulation:` section records (scenario, frames, seed, size,
// samples, env_every, env_map_width): Simulator::create() with them renders the session again.
// kCorruptData naming the field for a bad or missing section.
Result<SimulatorOptions> readSimulationOptions(std::string_view truth_text,
                                               std::string_view source_name);

struct SimulationSummary {
    int frames = 0;          // colour frames written
    int frames_planned = 0;  // the session's colour frames (truth files describe them all)
    // options.stop ended the session early: the recording holds the first `frames` frames
    // (closed, playable), the truth files every planned one. Stopped before the first frame,
    // no recording is left (a Matroska file without frames is not one a reader accepts).
    bool stopped = false;
    bool recording_written = true;  // false: stopped before the first frame, none left
    int env_frames = 0;
    double seconds = 0;                        // rendering and writing
    std::vector<std::filesystem::path> files;  // everything written, the recording first (when
                                               // recording_written)
};

// Writes `recording` (.mkv, FFV1) with streams kinect/color (rgb8), kinect/depth (depth16,
// registered), env/color (rgb8 fish-eye), kinect/ir (ir16, calibration only) and truth/pose
// (ground-truth T_world_color as pose records), plus beside it NAME.truth.yaml, NAME.tum (TUM
// trajectory of kinect/color), NAME.scene.yaml (the real scene as ghosts), NAME.env.exr and the
// textures. `progress` (may be empty) is called after each frame with (done, total). A stop
// requested through options.stop drops the frame in progress and returns the summary of the
// frames done with `stopped` set.
Result<SimulationSummary> simulateSession(const SimulatorOptions& options,
                                          const std::filesystem::path& recording,
                                          const std::function<void(int, int)>& progress = {});

}  // namespace mixray::render
