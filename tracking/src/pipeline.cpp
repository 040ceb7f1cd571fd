// The tracking half of the AR pipeline (mixray/tracking/pipeline.h).
#include "mixray/tracking/pipeline.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <ctime>
#include <iomanip>
#include <sstream>

namespace mixray::tracking {

namespace fs = std::filesystem;

Result<TrackingSetup> findTrackingSetup(const fs::path& recording, const RecordingReader& reader,
                                        const std::string& explicit_path) {
    if (!explicit_path.empty())
        return loadTrackingSetup(explicit_path);
    for (const Attachment& a : reader.attachments()) {
        if (a.name == "tracking.yaml") {
            const std::string text(a.data.begin(), a.data.end());
            return parseTrackingSetup(text, recording.string() + ":tracking.yaml");
        }
    }
    fs::path beside = recording;
    beside.replace_extension(".tracking.yaml");
    std::error_code ec;
    if (fs::exists(beside, ec))
        return loadTrackingSetup(beside);
    return Status(ErrorCode::kNotFound,
                  "no tracking setup: give --setup FILE (docs/tracking.md#setup-files); the "
                  "recording has no tracking.yaml attachment and " +
                      beside.string() + " does not exist");
}

Result<std::optional<RigSite>> findRigSite(const RecordingReader& reader,
                                           const std::string& rig_path) {
    std::optional<RigDescription> rig;
    if (!rig_path.empty()) {
        auto loaded = loadRig(rig_path);
        if (!loaded)
            return loaded.status();
        rig = std::move(loaded).value();
    } else {
        for (const Attachment& a : reader.attachments()) {
            if (a.name != "rig.yaml")
                continue;
            auto parsed = parseRig(std::string(a.data.begin(), a.data.end()), "rig.yaml");
            if (!parsed)
                return parsed.status().withContext("the recording's rig.yaml");
            rig = std::move(parsed).value();
        }
    }
    if (!rig)
        return std::optional<RigSite>();
    return rig->site;
}

Result<int64_t> parseUtc(const std::string& text) {
    std::tm tm{};
    std::istringstream in(text);
    in >> std::get_time(&tm, "%Y-%m-%dT%H:%M:%S");
    double fraction = 0;
    if (!in.fail() && in.peek() == '.') {
        std::string digits;
        in.get();
        while (std::isdigit(in.peek()))
            digits += static_cast<char>(in.get());
        fraction = digits.empty() ? 0 : std::stod("0." + digits);
    }
    char zone = 0;
    in >> zone;
    if (in.fail() || zone != 'Z' || in.peek() != std::char_traits<char>::eof())
        return Status(ErrorCode::kInvalidArgument,
                      "--utc " + text +
                          ": expected UTC as 2026-06-21T12:00:00Z (seconds may have a fraction)");
    const int64_t seconds = static_cast<int64_t>(timegm(&tm));
    return seconds * 1'000'000'000 + static_cast<int64_t>(std::llround(fraction * 1e9));
}

Result<std::optional<int64_t>> recordingUtcOffset(const RecordingReader& reader) {
    const auto tag = reader.tags().find(std::string(kUtcMinusHostTag));
    if (tag == reader.tags().end())
        return std::optional<int64_t>();
    int64_t offset = 0;
    const std::string& text = tag->second;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), offset);
    if (ec != std::errc() || end != text.data() + text.size())
        return Status(ErrorCode::kCorruptData, "the recording's " + std::string(kUtcMinusHostTag) +
                                                   " tag is not an integer: " + text);
    return std::optional<int64_t>(offset);
}

void estimateFrameProbes(const TrackingSetup& setup, const ImageView& color,
                         const Eigen::Isometry3d& T_world_camera, int64_t stamp,
                         TrackedFrame& frame) {
    for (size_t i = 0; i < frame.probes.size(); ++i) {
        const LightProbe& probe = setup.probes[i];
        auto lights = estimateProbeLights(color, setup.camera.model, T_world_camera, probe,
                                          setup.probe_options);
        if (lights)
            frame.probes[i].update(std::move(lights).value(), stamp);
        else
            frame.probes[i].keep(probe.name + ": " + lights.status().message(), stamp);
    }
    // Strengths of the lights whose directions are known, from a diffuse probe.
    const LightProbe* diffuse = nullptr;
    for (size_t i = 0; i < frame.probes.size(); ++i)
        if (setup.probes[i].material == ProbeMaterial::kDiffuse)
            diffuse = &setup.probes[i];
    if (!diffuse)
        return;
    const std::vector<EstimatedLight> directions = lightDirections(setup, frame);
    if (directions.empty()) {
        frame.intensities.keep("no light directions yet", stamp);
        return;
    }
    std::vector<Eigen::Vector3d> to_light;
    for (const EstimatedLight& l : directions)
        to_light.push_back(l.to_light_world);
    IntensityFitOptions fit_options;
    fit_options.albedo = diffuse->albedo;
    auto fit = fitLightIntensities(color, setup.camera.model, T_world_camera, *diffuse, to_light,
                                   fit_options);
    if (fit)
        frame.intensities.update(std::move(fit).value(), stamp);
    else
        frame.intensities.keep(fit.status().message(), stamp);
}

std::vector<EstimatedLight> lightDirections(const TrackingSetup& setup, const TrackedFrame& frame) {
    if (frame.environment.value && !frame.environment.value->lights.empty())
        return frame.environment.value->lights;
    if (frame.sun.value && !frame.sun.stale)
        return {*frame.sun.value};
    // Without the fish-eye: a mirror probe's highlights (sharp), else a diffuse probe's.
    for (ProbeMaterial material : {ProbeMaterial::kMirror, ProbeMaterial::kDiffuse}) {
        for (size_t i = 0; i < frame.probes.size(); ++i)
            if (setup.probes[i].material == material && frame.probes[i].value &&
                !frame.probes[i].value->lights.empty())
                return frame.probes[i].value->lights;
    }
    return {};
}

std::vector<EstimatedLight> renderLights(const TrackingSetup& setup, const TrackedFrame& frame) {
    std::vector<EstimatedLight> out = lightDirections(setup, frame);
    const bool fitted =
        frame.intensities.value && frame.intensities.value->irradiance.size() == out.size();
    if (fitted)
        for (size_t i = 0; i < out.size(); ++i)
            out[i].intensity = frame.intensities.value->irradiance[i];
    std::erase_if(out, [](const EstimatedLight& l) { return l.intensity.maxCoeff() <= 0; });
    return out;
}

}  // namespace mixray::tracking
