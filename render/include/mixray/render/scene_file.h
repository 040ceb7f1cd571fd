// Scene files: the AR scene (materials, virtual and ghost objects, lights, an optional fixed
// camera) as strict YAML, parsed into a SceneDescription (docs/scene-format.md).
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/result.h"
#include "mixray/render/scene.h"

namespace mixray::render {

// Largest scene file accepted, and deepest nesting of YAML collections: scene files are small,
// and the limits keep malformed input from costing unbounded time or stack.
inline constexpr size_t kMaxSceneFileBytes = 1 << 20;
inline constexpr int kMaxSceneNesting = 32;

// Parses a scene file's text. `source_name` names the file in messages and locations, and its
// folder is the base for relative mesh, texture and environment paths (a bare file name: the
// current folder). Unknown keys, wrong types, out-of-range numbers, unknown material names,
// duplicate names and bad anchors are kCorruptData with "FILE:LINE:COLUMN: FIELD.PATH: what is
// wrong", e.g.
//   scene.yaml:12:9: objects[0].shape.sphere.radius: expected a number above 0 up to 1000,
//   got "-1"
// The result has passed SceneDescription::validate(). Never throws; reentrant.
Result<SceneDescription> parseScene(std::string_view text, std::string_view source_name);

// Reads and parses a scene file. Relative paths in it resolve against the file's folder, made
// absolute. kNotFound when the file does not exist, kIoError when it cannot be read,
// kCorruptData for bad content. Never throws; reentrant.
Result<SceneDescription> loadScene(const std::filesystem::path& path);

// An AR scene put together from two files, as mixray demo and mixray run use it.
struct ComposedArScene {
    // The real scene's objects as ghosts (its lights and camera left out: those are estimated
    // and tracked), the virtual objects with both files' materials, and the objects file's
    // lights and fixed camera, if it has any.
    SceneDescription scene;
    // The virtual objects and their materials alone (what a simulator adds to render the truth).
    SceneDescription inserted;
    // What was substituted, one line each ("FILE not found; a metal sphere stands in for X").
    std::vector<std::string> notes;
};

// Loads `real_scene_path` (the modelled real surroundings, e.g. a session's NAME.scene.yaml)
// and `objects_path` (the virtual objects) and composes them. A virtual mesh whose file is
// missing (shared data absent) becomes a sphere of its material, radius 4 cm, standing on
// the same spot, with a note, so the demo runs without the shared data. Errors: the files' own
// load errors; kInvalidArgument when a material name is in both files. Reentrant.
Result<ComposedArScene> composeArScene(const std::filesystem::path& real_scene_path,
                                       const std::filesystem::path& objects_path);

}  // namespace mixray::render
