// libFuzzer target for the scene-file parser: any input must give a scene or a clean error.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "mixray/render/scene_file.h"

namespace {

// Stops the run with a message: libFuzzer records the input that got here.
[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "scene_parser_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    auto scene = mixray::render::parseScene(text, "fuzz/scene.yaml");
    if (!scene.isOk()) {
        const mixray::Status status = scene.status();
        // Bad content is kCorruptData naming the file; anything else is a parser bug.
        if (status.code() != mixray::ErrorCode::kCorruptData)
            broken("unexpected code", status.toString());
        if (status.message().rfind("fuzz/scene.yaml", 0) != 0)
            broken("message without file", status.message());
        return 0;
    }
    // An accepted scene is self-consistent: validate() agrees, every object's material exists.
    if (auto status = scene->validate(); !status.isOk())
        broken("accepted scene fails validate()", status.toString());
    for (const auto& object : scene->objects) {
        if (!scene->materials.count(object.material))
            broken("object with an unknown material", object.name);
    }
    return 0;
}
