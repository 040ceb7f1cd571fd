// mixray calibrate --live: a calibration session on a rig's devices, with the live view.
#pragma once

#include <functional>
#include <string>

namespace mixray::cli {

struct LiveCalibrateOptions {
    std::string rig;     // RIG.yaml
    std::string target;  // --target spec
    std::string view;    // [ADDR:]PORT; empty: no view
    std::string record;  // the kept views' recording; empty: OUTPUT/live_session.mkv
    // --view-token; empty: none on loopback, a random one for any other address
    std::string view_token;
    std::string output = "out/calibration";
    double duration_s = 0;  // 0: until the devices end or a signal
    double min_shift_px = 0;
    int views_wanted = 10;
    int pair_views_wanted = 3;
};

// Runs the session until the rig's devices end, --duration or Ctrl-C; writes the recording and
// prints what was kept and what is missing. `solve` (may be empty) then runs the offline
// calibration on the recording and its exit code is returned.
int runCalibrateLive(const LiveCalibrateOptions& options,
                     const std::function<int(const std::string& recording)>& solve);

}  // namespace mixray::cli
