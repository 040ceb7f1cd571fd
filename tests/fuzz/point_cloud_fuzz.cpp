// libFuzzer target for the point cloud readers (PCD ascii/binary/binary_compressed, PLY) and
// the intrinsics texts the cloud writer reads (--intrinsics, PCL's XML sidecar).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "mixray/replay/point_cloud.h"

namespace {

[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "point_cloud_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

// A rejection is kCorruptData naming the input; an accepted cloud is consistent and survives
// being written and read back with the same grid and values.
void check(const mixray::Result<mixray::replay::PointCloud>& cloud, const char* name) {
    using namespace mixray;
    if (!cloud.isOk()) {
        if (cloud.status().code() != ErrorCode::kCorruptData)
            broken("unexpected code", cloud.status().toString());
        if (cloud.status().message().rfind(name, 0) != 0)
            broken("message without file", cloud.status().message());
        return;
    }
    if (cloud->width < 0 || cloud->height < 0 || cloud->xyz.size() != cloud->size() * 3)
        broken("inconsistent cloud", name);
    if (!cloud->rgb.empty() && cloud->rgb.size() != cloud->size() * 3)
        broken("inconsistent colour", name);
    if (cloud->size() == 0)
        return;
    auto again = replay::parsePly(replay::encodePly(*cloud), "again.ply");
    if (!again.isOk())
        broken("own PLY not readable", again.status().toString());
    if (again->width != cloud->width || again->height != cloud->height || again->rgb != cloud->rgb)
        broken("PLY round trip changed the cloud", name);
    for (size_t i = 0; i < cloud->xyz.size(); ++i) {
        const float a = cloud->xyz[i], b = again->xyz[i];
        if (!(a == b || (std::isnan(a) && std::isnan(b))))
            broken("PLY round trip changed a coordinate", name);
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    check(mixray::replay::parsePcd(text, "fuzz.pcd"), "fuzz.pcd");
    check(mixray::replay::parsePly(text, "fuzz.ply"), "fuzz.ply");
    auto xml = mixray::replay::parsePclCameraXml(text, "fuzz.xml");
    if (xml.isOk() && !xml->validate().isOk())
        broken("accepted XML intrinsics fail validate()", "fuzz.xml");
    if (!xml.isOk() && xml.status().code() != mixray::ErrorCode::kCorruptData)
        broken("unexpected XML code", xml.status().toString());
    auto k = mixray::replay::parseIntrinsics(text);
    if (k.isOk()) {
        auto back = mixray::replay::parseIntrinsics(mixray::replay::formatIntrinsics(*k));
        if (!back.isOk() || !(*back == *k))
            broken("intrinsics do not format back", std::string(text));
    } else if (k.status().code() != mixray::ErrorCode::kInvalidArgument) {
        broken("unexpected intrinsics code", k.status().toString());
    }
    return 0;
}
