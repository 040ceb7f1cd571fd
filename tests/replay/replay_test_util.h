// Helpers for the replay tests: synthetic and real TUM / PCL folders, reading whole recordings.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "mixray/graph/recording.h"

namespace mixray::test {

// A frame copied out of its pool, so a test can hold every frame of a recording.
struct OwnedFrame {
    FrameMetadata meta;
    Image image;
};

// Reads `reader` to its end (fails the calling test on any error but kEndOfStream).
std::vector<OwnedFrame> readAll(RecordingReader& reader);

// Both lists hold the same frames: metadata field by field and pixels bit-exactly. `what`
// labels failures.
void expectSameFrames(const std::vector<OwnedFrame>& a, const std::vector<OwnedFrame>& b,
                      const std::string& what);

// Writes a synthetic TUM folder: `frames` colour and depth images of w x h at 30 Hz starting
// at 1305031102.175304 s (depth 0.0149 s earlier, as in fr1), depth values that are not
// multiples of 5 (so mm could not hold them), plus accelerometer.txt and groundtruth.txt.
// Returns the rgb stamps in ns.
std::vector<int64_t> writeSyntheticTum(const std::filesystem::path& dir, int frames, int w = 32,
                                       int h = 24);

// Builds a TUM folder from the real TUM frame pair in shared data; false when it is absent.
bool writeRealTum(const std::filesystem::path& dir);
std::filesystem::path realTumColor();
std::filesystem::path realTumDepth();
// The real PCL OpenNI TIFF folder in shared data.
std::filesystem::path realPclDir();

// Pixel values of two image files are identical (any codec; bit depth and channels too).
void expectSamePixels(const std::filesystem::path& a, const std::filesystem::path& b);

std::string readFile(const std::filesystem::path& file);

}  // namespace mixray::test
