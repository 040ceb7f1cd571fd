// mixray calibrate --live: opens a rig's devices as a monitor graph, adds the live calibration
// node and the browser view, and records the kept views for the offline solve.
#include "calibrate_live.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "backends.h"
#include "cli.h"
#include "console.h"
#include "mixray/calibration/live_calibration.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/rig.h"
#include "mixray/liveview/live_view.h"
#include "mixray/render/ar_pipeline.h"

namespace mixray::cli {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string statusText(double seconds, const calibration::LiveCalibrationStatus& s) {
    std::string text = std::to_string(static_cast<int>(seconds)) + " s:";
    for (const auto& c : s.cameras)
        text += " " + c.camera + " " + std::to_string(c.kept) + " kept/" +
                std::to_string(c.rejected) + " rejected (" + c.last + ");";
    text += " " + std::to_string(s.missing.size()) + " things missing";
    return text;
}

}  // namespace

int runCalibrateLive(const LiveCalibrateOptions& o,
                     const std::function<int(const std::string& recording)>& solve) {
    setFfmpegLogging(false);
    registerRecordingFormats();
    auto target = calibration::parseTarget(o.target);
    if (!target)
        return fail("calibrate", target.status().withContext("--target"));
    auto rig = loadRig(o.rig);
    if (!rig)
        return fail("calibrate", rig.status());
    const std::string rig_text = rig->source_text;
    liveview::LiveViewOptions view_options;
    if (!o.view.empty())
        if (Status s = liveview::parseViewAddress(o.view, &view_options); !s)
            return fail("calibrate", s.withContext("--view"));
    view_options.token = o.view_token;
    const fs::path record =
        o.record.empty() ? fs::path(o.output) / "live_session.mkv" : fs::path(o.record);
    std::error_code ec;
    if (record.has_parent_path())
        fs::create_directories(record.parent_path(), ec);

    render::ArSource source;
    source.rig = std::move(rig).value();
    auto pipeline = render::ArPipeline::create(makeBackendRegistry(), source, {});
    if (!pipeline)
        return fail("calibrate", pipeline.status().withContext(o.rig));
    render::ArPipeline& p = **pipeline;

    calibration::LiveCalibrationOptions live;
    live.target = *target;
    live.min_corner_shift_px = o.min_shift_px;
    live.views_wanted = o.views_wanted;
    live.pair_views_wanted = o.pair_views_wanted;
    liveview::LiveView* view = nullptr;
    calibration::LiveCalibrationNode* node = nullptr;
    auto created = calibration::LiveCalibrationNode::create(
        live, [&view, &node](const calibration::LiveDecision& d) {
            // Every camera is a tile (the view shows every image stream), and the overlay is
            // the node's own JSON object, so the view has no reason to refuse it.
            if (view)
                static_cast<void>(view->setOverlay(d.camera, node->overlay(d.camera)));
        });
    if (!created)
        return fail("calibrate", created.status());
    node = created->get();
    if (Status s = p.graph().addNode(std::move(created).value()); !s)
        return fail("calibrate", s.withContext(o.rig));
    if (!o.view.empty()) {
        view_options.title = "mixray calibrate --live";
        auto made = liveview::LiveView::create(view_options);
        if (!made)
            return fail("calibrate", made.status().withContext("--view"));
        liveview::LiveView* raw = made->get();
        raw->setStatusProvider([&p, node] {
            json figures = json::parse(p.stats().json());
            const json calib = json::parse(node->status().json());
            figures["calibration"] = calib["calibration"];
            json& messages = figures["messages"];
            if (!messages.is_array())
                messages = json::array();
            for (const json& m : calib["messages"])
                messages.push_back("missing: " + m.get<std::string>());
            return figures.dump();
        });
        if (Status s = p.graph().addNode(std::move(made).value()); !s)
            return fail("calibrate", s.withContext("--view"));
        view = raw;
    }

    InterruptFlag interrupt;
    if (Status s = p.start(); !s)
        return fail("calibrate", s);
    if (view)
        printLiveViewUrls(*view, "live view at ");
    std::fflush(stdout);
    StatusLine status;
    const auto started = std::chrono::steady_clock::now();
    const auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    };
    std::string stopped_by = "the end of the devices' streams";
    while (!(p.waitDone(std::chrono::milliseconds(250)) && node->finished())) {
        status.update(statusText(elapsed(), node->status()));
        if (interrupt.raised()) {
            stopped_by = interrupt.signalName();
            break;
        }
        if (!p.status()) {
            stopped_by = "an error";
            break;
        }
        if (o.duration_s > 0 && elapsed() >= o.duration_s) {
            stopped_by = "--duration";
            break;
        }
    }
    p.stop();
    const calibration::LiveCalibrationStatus final_status = node->status();
    status.update(statusText(elapsed(), final_status));
    status.finish();
    if (Status s = p.status(); !s)
        return fail("calibrate", s);
    std::printf("session stopped by %s after %.1f s\n%s", stopped_by.c_str(), elapsed(),
                final_status.summary().c_str());
    Attachment rig_file{"rig.yaml", "application/x-yaml",
                        std::vector<uint8_t>(rig_text.begin(), rig_text.end())};
    if (Status s = node->writeRecording(record, {rig_file},
                                        {{"recorded_by",
                                          "mixray calibrate "
                                          "--live"}});
        !s)
        return fail("calibrate", s);
    std::printf(
        "recorded %llu kept instants in %s; solve them with: mixray calibrate %s "
        "--target %s\n",
        static_cast<unsigned long long>(final_status.kept_instants), record.string().c_str(),
        record.string().c_str(), o.target.c_str());
    std::fflush(stdout);
    if (solve)
        return solve(record.string());
    return kExitOk;
}

}  // namespace mixray::cli
