// libFuzzer target for the corners-cache reader (mrcal's "filename x y level" vnlog and mixray's
// "##" rows): any file must give cameras or a clean error naming it, every camera of an accepted
// file has the image size given for mrcal's caches, and what is accepted writes out and reads
// back to the same cameras, views and corners.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "mixray/calibration/corners_cache.h"

namespace {

namespace fs = std::filesystem;
using namespace mixray::calibration;

[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "corners_cache_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

const fs::path& scratch() {
    static const fs::path dir = [] {
        fs::path d = fs::temp_directory_path() / ("corners_cache_fuzz." + std::to_string(getpid()));
        fs::create_directories(d);
        return d;
    }();
    return dir;
}

bool sameViews(const std::vector<CameraViews>& a, const std::vector<CameraViews>& b) {
    if (a.size() != b.size())
        return false;
    for (size_t c = 0; c < a.size(); ++c) {
        if (a[c].views.size() != b[c].views.size() || a[c].width != b[c].width ||
            a[c].height != b[c].height)
            return false;
        for (size_t v = 0; v < a[c].views.size(); ++v) {
            const TargetView& x = a[c].views[v];
            const TargetView& y = b[c].views[v];
            // A rejected view's corners are not written (mrcal would use them).
            if (x.rejection != ViewRejection::kNone)
                continue;
            if (x.corners.size() != y.corners.size())
                return false;
            for (size_t k = 0; k < x.corners.size(); ++k)
                if (x.corners[k].id != y.corners[k].id || x.corners[k].pixel != y.corners[k].pixel)
                    return false;
        }
    }
    return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const fs::path path = scratch() / "input.vnl";
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    }
    const auto target = parseTarget("chessboard:3x2:0.02");
    if (!target)
        broken("the fuzzer's target", target.status().toString());
    const ImageSize given{640, 480};
    auto cameras = readCornersCache(path, *target, given);
    if (!cameras.isOk()) {
        const mixray::Status status = cameras.status();
        if (status.code() != mixray::ErrorCode::kCorruptData &&
            status.code() != mixray::ErrorCode::kInvalidArgument)
            broken("unexpected code", status.toString());
        if (status.message().find(path.string()) == std::string::npos)
            broken("message without file", status.message());
        return 0;
    }
    for (const CameraViews& camera : *cameras)
        if (camera.width <= 0 || camera.height <= 0)
            broken("a camera without an image size", camera.camera);
    const fs::path written = scratch() / "written.vnl";
    if (auto status = writeCornersCache(written, *cameras); !status.isOk())
        broken("accepted cameras cannot be written", status.toString());
    auto again = readCornersCache(written);
    if (!again.isOk())
        broken("written cache does not read", again.status().toString());
    if (!sameViews(*cameras, *again))
        broken("written cache reads back different", std::to_string(cameras->size()));
    return 0;
}
