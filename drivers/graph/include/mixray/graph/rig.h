// Rig description files: which devices a rig has, their streams and modes, what to synchronise,
// and where each camera's calibration lives. Parsed into plain structs (docs/rig-format.md).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/device.h"
#include "mixray/graph/frame_queue.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"

namespace mixray {

// Where an entry was written: file name as given to the parser, 1-based line and column
// (0 when unknown, e.g. for entries built in code). Plain value.
struct SourceLocation {
    std::string file;
    int line = 0;
    int column = 0;

    // "rig.yaml:7:12", "rig.yaml:7", or "rig.yaml" as far as known.
    std::string toString() const;
    bool operator==(const SourceLocation&) const = default;
};

// Which of the rig file's keys named the device to open. The value itself is DeviceConfig::id.
enum class DeviceIdKind : uint8_t {
    kAny,     // no id given: the backend opens the first device it finds
    kId,      // `id:`      backend-specific id ("1d27/0600@1/4")
    kSerial,  // `serial:`  serial number
    kUri,     // `uri:`     URI or path ("/dev/video2", "192.168.1.20")
};

std::string_view toString(DeviceIdKind kind);

// Settings of one stream of a device. Unset optionals leave the choice to the backend.
// Plain value.
struct RigStream {
    std::string name;                   // within the device: "depth"; graph name "kinect/depth"
    bool enabled = true;                // false: named in the file but not opened
    std::optional<PixelFormat> format;  // requested pixel format
    std::optional<int> width;           // requested size in pixels, > 0
    std::optional<int> height;
    std::optional<double> fps;  // requested frame rate, > 0
    // How the recorder's queue for this stream behaves when the disk falls behind. Default
    // lossless: a recording should hold every frame, so the capture side waits instead.
    QueuePolicy queue = QueuePolicy::kLossless;
    size_t capacity = 8;  // frames the recorder's queue holds, 1..4096
    SourceLocation where;

    bool operator==(const RigStream&) const = default;
};

// One device of the rig. `config` is what BackendRegistry::open() takes: config.streams lists
// the enabled streams when the file lists streams (empty: all), and config.options holds, as
// strings, the `options:` entries, the device-wide `mode:` settings, and each stream's
// requested mode as "<stream>.width", "<stream>.height", "<stream>.fps", "<stream>.format".
// Plain value.
struct RigDevice {
    DeviceConfig config;
    DeviceIdKind id_kind = DeviceIdKind::kAny;
    std::vector<RigStream> streams;  // streams the file names (under streams: or mode:)
    SourceLocation where;

    const std::string& name() const { return config.name; }
    const RigStream* findStream(std::string_view stream) const;
};

// One "device/stream" reference.
struct RigStreamRef {
    std::string device;
    std::string stream;
    SourceLocation where;

    std::string name() const { return device + "/" + stream; }  // "kinect/depth"
    bool operator==(const RigStreamRef&) const = default;
};

// Which streams the synchroniser groups into framesets. Empty streams: no synchronisation.
struct RigSync {
    std::vector<RigStreamRef> streams;
    double max_skew_ms = 20.0;  // largest spread of stamps within one frameset, > 0
    SourceLocation where;
};

// A calibration file named by the rig: for one stream, one device (stream empty), or the whole
// rig (device and stream empty). The file is not opened or checked by the rig parser.
struct RigCalibrationFile {
    std::string device;
    std::string stream;
    std::string path;                // as written in the rig file
    std::filesystem::path resolved;  // relative paths resolved against the rig file's folder
    SourceLocation where;

    bool operator==(const RigCalibrationFile&) const = default;
};

// Where on Earth the rig stands, and how the world (marker) frame lies there, for the sun's
// direction. The world frame's +z is up.
struct RigSite {
    double latitude_deg = 0;   // north positive, -90..90
    double longitude_deg = 0;  // east positive, -180..180
    // Compass bearing of the world frame's +y axis, clockwise from true north, 0..360.
    double heading_deg = 0;
    double altitude_m = 0;  // above sea level
    // Device orientation (from an IMU and compass): the rotation R_enu_world from the world
    // frame to east-north-up as a unit quaternion w, x, y, z. When given it replaces heading_deg
    // (the file may not give both) and the world's +z need not be up.
    std::optional<std::array<double, 4>> orientation_wxyz;
    SourceLocation where;
};

// A whole rig file as plain data: the input from which apps build device graphs, recorders
// attach the rig to recordings (source_text, byte for byte), and calibration, tracking and the
// renderer find their inputs. Plain value; reentrant.
struct RigDescription {
    int version = 1;   // schema version; only 1 exists
    std::string name;  // `rig:`
    std::vector<RigDevice> devices;
    RigSync sync;
    std::vector<RigCalibrationFile> calibration;  // in file order
    std::optional<RigSite> site;
    std::string source_path;  // file name as given to parseRig() / path given to loadRig()
    std::string source_text;  // the original text

    const RigDevice* findDevice(std::string_view device) const;
    // The calibration file for a stream: the stream's own, else its device's, else the rig's;
    // nullptr when there is none. An empty stream asks for the device's (else the rig's).
    const RigCalibrationFile* findCalibration(std::string_view device,
                                              std::string_view stream = {}) const;
    // The DeviceConfigs to open, in file order.
    std::vector<DeviceConfig> deviceConfigs() const;

    // Cross-entry checks, also run by parseRig(): at least one device; valid, unique device
    // and stream names; a driver for every device; sync and calibration entries that name
    // existing devices and enabled streams; numbers in range. kCorruptData with the entry's
    // location and field path on the first problem. Use it on rigs built in code.
    Status validate() const;
};

// Largest rig file accepted, and deepest nesting of YAML collections: rig files are small, and
// the limits keep malformed input from costing unbounded time or stack.
inline constexpr size_t kMaxRigFileBytes = 1 << 20;
inline constexpr int kMaxRigNesting = 32;

// Parses a rig file's text. `source_name` names the file in messages and locations, and its
// folder is the base for relative calibration paths (a bare file name: the current folder).
// Errors are kCorruptData with "FILE:LINE:COLUMN: FIELD.PATH: what is wrong", e.g.
//   rig.yaml:7:12: devices[1].mode.depth: expected WIDTHxHEIGHT@FPS like 640x480@30 ...,
//   got "640x"
// Never throws.
Result<RigDescription> parseRig(std::string_view text, std::string_view source_name);

// Reads and parses a rig file. Relative calibration paths resolve against the file's folder,
// made absolute. kNotFound when the file does not exist, kIoError when it cannot be read,
// kCorruptData for bad content. Never throws.
Result<RigDescription> loadRig(const std::filesystem::path& path);

}  // namespace mixray
