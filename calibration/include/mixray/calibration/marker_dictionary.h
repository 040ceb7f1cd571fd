// Custom ArUco dictionaries in OpenCV's dictionary file (what cv::aruco::Dictionary's
// readDictionary() reads and writeDictionary() writes), parsed into a plain struct first.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/result.h"

namespace mixray::calibration {

// A dictionary of square markers drawn as OpenCV's aruco draws them: `marker_size` × `marker_size`
// code cells inside a black border one cell wide. Plain value.
struct MarkerDictionary {
    // The name detections carry (MarkerDetection::dictionary): "custom:<file stem>" for a file.
    std::string name;
    // Code cells across a marker, without the border (OpenCV's `markersize`). Default 0: unset.
    int marker_size = 0;
    // Bits a detection may correct (OpenCV's `maxCorrectionBits`; absent in a file: 0).
    int max_correction_bits = 0;
    // One string per marker id: marker_size² characters '0' (black) or '1' (white), row by
    // row from the top-left cell of the upright marker (OpenCV's `marker_<id>`).
    std::vector<std::string> markers;

    // kInvalidArgument naming the field: 2 ≤ marker_size ≤ kMaxMarkerSize, 1 to kMaxMarkers
    // markers of the right length and alphabet, 0 ≤ max_correction_bits ≤ marker_size².
    Status validate() const;

    static constexpr int kMaxMarkerSize = 16;
    static constexpr int kMaxMarkers = 100000;
};

// Parses the text of OpenCV's dictionary file (YAML, XML or JSON, as cv::FileStorage reads
// them): `nmarkers`, `markersize` (`marker_size` also accepted), optional `maxCorrectionBits`
// (or `max_correction_bits`), and `marker_0` ... `marker_<nmarkers-1>` as quoted bit strings.
// `file` names the input in messages and gives the dictionary its name. kCorruptData
// "file: field: what is wrong" for anything else, never an exception. Reentrant.
Result<MarkerDictionary> parseMarkerDictionary(std::string_view text, const std::string& file);

// Reads and parses a dictionary file (at most 4 MiB). kNotFound when it cannot be read.
Result<MarkerDictionary> readMarkerDictionary(const std::filesystem::path& path);

// The dictionary as OpenCV's writeDictionary() writes it to a .yml FileStorage (reads back
// with parseMarkerDictionary() and with cv::aruco::Dictionary::readDictionary()).
std::string markerDictionaryYaml(const MarkerDictionary& dictionary);

}  // namespace mixray::calibration
