#pragma once
// JSON scene files -> Scene (core/scene.hpp). Scene files are untrusted input: every problem is
// an InputError(file, jsonPath, reason) with a one-line message such as
//   scenes/x.json: entities[3].position: expected an array of 3 finite numbers
// Unknown keys are errors (typos must not silently fall back to defaults), and so are
// duplicate keys, non-finite numbers (1e999 overflows while parsing and is reported with its
// path), out-of-range values and degenerate cameras. JSON syntax errors name the line and
// column. Relative paths inside a scene are relative to the scene file's directory.
//
// The format (every key, type, default and range, the entity-id order, the rotation convention)
// is documented in docs/scenes.md, with the JSON Schema docs/scene.schema.json for editors; the
// keys each object accepts are listed once, in core/scene_keys.cpp, and a test keeps the three in
// step. Entity ids: "entities" in file order, then each crowd, then each vox_scene.
#include "core/scene.hpp"
#include "core/vox_reader.hpp"

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace voxtier {

/// Reads, parses and validates a scene file. Scene::source is `file` as given.
Scene loadScene(const std::filesystem::path& file);

/// Parses and validates scene text (what loadScene does after reading the file).
Scene loadSceneText(const std::string& text, const std::string& sourceName,
                    const std::filesystem::path& baseDir);

/// Validates an already parsed document. `sourceName` is used in messages and as
/// Scene::source; relative paths resolve against `baseDir`.
Scene loadSceneJson(const nlohmann::json& j, const std::string& sourceName,
                    const std::filesystem::path& baseDir);

/// q = qY(ry) * qX(rx) * qZ(rz), angles in degrees (see "rotation_deg" above).
glm::dquat quatFromEulerDeg(glm::dvec3 rxyzDeg);

/// The result of flattening one .vox scene graph.
struct FlattenedVoxScene {
    /// One model per distinct (file model, mirror axis) pair actually used, in order of first use.
    std::vector<std::shared_ptr<VoxelModel>> models;
    /// (file model index, mirrored voxel axis or -1) for each entry of `models`.
    std::vector<std::pair<int, int>> modelKeys;
    /// Entity::model indexes `models`.
    std::vector<Entity> entities;
};

/// Flattens the instances of `file` (VoxInstance: signed-permutation rotation R, pivot
/// translation t in voxel units) into entities such that the entity maps every voxel exactly
/// where the instance does: vox-world point = R (p - floor(size/2)) + t, world = position +
/// S (vox-world) * voxelSize * scale, S the voxel->world swizzle (CONTRACT.md §2). So:
/// - anchor = floor(size/2), position = `position` + S t voxelSize scale, Entity::scale = scale;
/// - a proper R becomes the entity quaternion of S R S^-1;
/// - a reflection (det R = -1) is not a rotation: the instance gets a copy of the grid mirrored
///   along voxel axis a (p.a -> size.a - p.a, i.e. voxel index i -> size.a - 1 - i), the
///   rotation R·M_a (proper), and anchor.a = size.a - floor(size.a/2). `a` is the axis with the
///   most negative diagonal entry of R (lowest axis on ties), so a pure mirror needs no rotation.
/// Hidden instances are skipped unless `includeHidden`. A file without a scene graph gives one
/// entity per model at `position` with the default (bottom-centre) anchor. Models are named
/// "<stem>#<model>" ("<stem>#<model>~mirror-x" etc.), entities by the instance's name or
/// "<stem>[<instance>]". Throws InputError(file.source, "instances[i]") for a rotation that is
/// not a signed permutation or a model index out of range.
FlattenedVoxScene flattenVoxScene(const VoxFile& file, glm::dvec3 position, double scale,
                                  bool includeHidden, double voxelSize);

/// The grid mirrored along voxel axis `axis` (0, 1, 2): voxel i -> size - 1 - i on that axis.
VoxelGrid mirrorGrid(const VoxelGrid& grid, int axis);

} // namespace voxtier
