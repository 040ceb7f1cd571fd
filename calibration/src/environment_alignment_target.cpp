// alignEnvironmentCamera() for a CalibrationTarget: the board's points from the target.
#include "environment_alignment_internal.h"

namespace mixray::calibration {

Result<EnvironmentAlignment> alignEnvironmentCamera(const CameraModel& main, const CameraModel& env,
                                                    const CameraViews& main_board,
                                                    const CameraViews& env_board,
                                                    const std::vector<MarkerView>& marker,
                                                    const EnvironmentAlignmentOptions& options) {
    MIXRAY_RETURN_IF_ERROR(main_board.target.validate().withContext("board target"));
    return detail::alignEnvironmentCamera(main, env, main_board.target.points(), main_board,
                                          env_board, marker, options);
}

}  // namespace mixray::calibration
