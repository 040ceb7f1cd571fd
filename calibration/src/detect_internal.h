// detect.cpp's look beyond a chessboard found at the target's size (DetectionOptions::
// check_larger_board), reached by the tests through this private header.
#pragma once

#include <array>
#include <opencv2/core.hpp>
#include <vector>

#include "mixray/calibration/target.h"

namespace mixray::calibration::detail {

// How many lines of X-junctions continue a chessboard's found grid beyond each of its sides
// (left, right, above, below in the grid's numbering): `corners` are the cols × rows corners
// found in `grey` (8-bit), row-major as findChessboardCorners orders them. One square beyond a
// board's outermost corners there is its margin, whose T-junctions and edges are no
// X-junctions; on a larger board the grid goes on. All zero for a grid of another size.
std::array<int, 4> chessboardBeyond(const cv::Mat& grey, const std::vector<Corner>& corners,
                                    int cols, int rows);

}  // namespace mixray::calibration::detail
