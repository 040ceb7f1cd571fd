// Objects for the tests of the renderer's internals (render/src/embree_scene.h): a ghost floor
// and exact spheres, built as scene loading builds them, and a scene of them posed.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "embree_scene.h"
#include "mixray/render/assets.h"

namespace mixray::render::test {

using detail::ObjectData;

// A ghost plane z = 0, `side` metres square.
inline ObjectData floorObject(float side) {
    Shape plane;
    plane.type = ShapeType::kPlane;
    plane.size = {side, side, 0};
    ObjectData floor;
    floor.name = "floor";
    floor.role = ObjectRole::kGhost;
    floor.shape = ShapeType::kPlane;
    floor.meshes->push_back(makeShapeMesh(plane));
    return floor;
}

// An exact sphere of `radius` at `centre`.
inline ObjectData ballObject(float radius, const Eigen::Vector3f& centre,
                             ObjectRole role = ObjectRole::kVirtual) {
    ObjectData ball;
    ball.name = role == ObjectRole::kVirtual ? "ball" : "real ball";
    ball.role = role;
    ball.shape = ShapeType::kSphere;
    ball.sphere_radius = radius;
    ball.bound_radius = radius;
    ball.t_world_object = centre;
    return ball;
}

// `objects`, every one active, built into a scene (on Embree's `isa`; "": the widest) and
// posed, as a frame's set-up leaves them.
inline Result<std::unique_ptr<detail::EmbreeScene>> posedScene(std::vector<ObjectData>& objects,
                                                               const std::string& isa = "") {
    for (ObjectData& o : objects)
        o.active = true;
    auto built = detail::EmbreeScene::build(objects, isa);
    if (!built)
        return built;
    if (Status posed = (*built)->setPoses(objects); !posed)
        return posed;
    return built;
}

}  // namespace mixray::render::test
