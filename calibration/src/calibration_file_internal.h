// Between the rig calibration file (calibration_file.cpp) and the other formats
// (calibration_formats.cpp): checks, file access and encodings both use.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/calibration_file.h"
#include "mixray/graph/yaml_reader.h"

namespace mixray::calibration::detail {

// Largest file any calibration format is read from: a 1280x1024 per-pixel depth map in base64
// is 7 MB; anything far larger is not a calibration file.
constexpr size_t kMaxCalibrationFileBytes = 64u << 20;
// Deepest YAML nesting any calibration format has, with room to spare.
constexpr int kMaxCalibrationNesting = 16;

// Camera and frame names: 1–128 of letters, digits, '_', '-', '.', '/'. Stream names
// ("kinect/color") and ROS topics without their leading '/' are such names.
bool isFrameName(std::string_view name);

// Everything writeCalibrationFile() refuses, kInvalidArgument naming the camera and field:
// invalid models, duplicate or malformed names, parents forming a cycle, a pose or covariance
// without a parent, depth entries naming cameras the file lacks or maps of the wrong size.
Status validateCalibrationFile(const CalibrationFile& file);

// The whole file; kNotFound when it does not exist, kIoError when it cannot be read,
// kCorruptData when it exceeds `max_bytes`.
Result<std::string> readTextFile(const std::filesystem::path& path, size_t max_bytes);
// Writes through a temporary file renamed over `path`, so a failed write leaves any old file
// intact; kIoError naming the path.
Status writeTextFile(const std::filesystem::path& path, std::string_view text);

std::string base64Encode(const std::vector<uint8_t>& bytes);
// nullopt on a character outside the alphabet or a wrong length; whitespace is skipped.
std::optional<std::vector<uint8_t>> base64Decode(std::string_view text);

// A YAML flow sequence of numbers, each in its shortest exact form: "[1, 0.5]".
std::string yamlList(const std::vector<double>& values);
// A YAML sequence of `min_count`..`max_count` numbers, each in [min, max]; the reader's error
// naming `expectation` otherwise.
Result<std::vector<double>> readNumbers(const yaml::Reader& r, const yaml::Item& item,
                                        size_t min_count, size_t max_count, double min, double max,
                                        std::string_view expectation);

}  // namespace mixray::calibration::detail
