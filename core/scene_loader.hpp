#pragma once
// JSON scene files -> Scene (core/scene.hpp). Scene files are untrusted input: every problem is
// an InputError(file, jsonPath, reason) with a one-line message such as
//   scenes/x.json: entities[3].position: expected an array of 3 finite numbers
// Unknown keys are errors (typos must not silently fall back to defaults), and so are
// duplicate keys, non-finite numbers (1e999 overflows while parsing and is reported with its
// path), out-of-range values and degenerate cameras. JSON syntax errors name the line and
// column. Relative paths inside a scene are relative to the scene file's directory.
//
// Schema (every key optional unless marked "required"; defaults are those of core/scene.hpp).
// Any object may also carry a "comment" string, which is ignored (JSON has no comments).
//
//   "description": "..."                      free text
//   "voxel_size": 0.1                         metres per voxel, > 0
//   "sigma": 1                                virtual pixels per voxel, > 0
//   "view_mode": "per_entity" | "parallel"
//   "background": [r, g, b]                   integers 0..255
//   "camera": {"position": [x,y,z], "target": [x,y,z], "up": [x,y,z], "fov_y": deg in (0, 179),
//              "size": [w, h] (1..16384), "near": > 0}
//       target != position and up not parallel to the view direction.
//   "camera_path": {"fps": > 0, "keys": [{"time", "position", "target", "up"?, "fov_y"?}, ...]}
//       keys required, >= 1, strictly increasing times; the interpolated camera (Scene::cameraAt)
//       must be valid at every frame time of the path (at most 1'000'000 frames).
//   "light": {"direction": non-zero [x,y,z] towards the light, "ambient": >= 0, "diffuse": >= 0}
//   "selector": {"metric": "distance" | "radius_px" | "error_px", "near_at": >= 0,
//                "far_at": > near_at, "view_hysteresis_deg": [0, 180), "crossfade_frames": >= 0,
//                "view_set": 26 | 98 | 218}
//       For the pixel metrics (radius_px, error_px) the band is mirrored: near_at > far_at, and
//       their defaults are 24/16 px and 1.0/0.5 px (core/scene.hpp defaultSelectorFor).
//   "models" (required, >= 1 entries, unique non-empty names), each one of:
//       {"name", "vox": path, "model": i}        model i (default 0) of a .vox file
//       {"name", "vox": path, "frames": "all"}    every model of the file, as animation frames
//       {"name", "vox": path, "frames": [i, ...]} the listed models, in that order, as frames
//       {"name", "generator": "box",    "size": [x,y,z] (default [8,8,8]), "index", "color"}
//       {"name", "generator": "sphere", "radius": 1..128 (default 6), "index", "color"}
//       {"name", "generator": "arrow",  "length": 8..256 (default 16)}
//       {"name", "generator": "shell",  "size" (default [16,16,16]), "thickness" (default 1),
//                                       "index", "color"}
//       {"name", "generator": "voxel",  "index", "color"}
//       {"name", "generator": "tank",   "seed": unsigned (default 1), "frames": 1..4096 (default
//       8),
//                                       "size": [x,y,z] each 8..256 (default [32,32,16])}
//     Generators are those of core/procedural.hpp (the tank keeps its own palette and frames).
//     "index" (1..255, default 1) is the palette index the solid uses; "color": [r, g, b] overrides
//     that palette entry for this model.
//   "entities": [{"model": name (required), "position": [x,y,z], "rotation_deg": [rx,ry,rz] |
//                 "quaternion": [w,x,y,z] (non-zero; normalised), "scale": > 0,
//                 "anchor": [x,y,z] (voxel space; default bottom centre), "frame": 0..frames-1,
//                 "fps": >= 0, "name": string}]
//       rotation_deg is intrinsic yaw about world Y, then pitch about X, then roll about Z:
//       q = qY(ry) * qX(rx) * qZ(rz) (right-handed, degrees). Yaw 90 maps world +X to -Z.
//   "crowds": [{"models": [name, ...] (required, >= 1), "layout": "grid" | "random" (default grid),
//               "count": >= 0 (required), "seed": unsigned integer (default 1),
//               "random_yaw": bool (default false), "scale": > 0, "name": prefix,
//               "fps": >= 0 (animation, default 0), "random_frame": bool (default false: frame 0),
//               grid only:   "origin": [x,y,z], "spacing": [dx, dz] (default [2, 2]),
//                            "columns": >= 1 (default ceil(sqrt(count))),
//               random only: "area": {"min": [x, z], "max": [x, z]} (required, min <= max),
//                            "y": height (default 0)}]
//       Grid entity k sits at origin + (dx * (k % columns), 0, dz * (k / columns)) with model
//       models[k % n]. Random entities draw, in this order from a splitmix64 stream seeded with
//       `seed`: model (random layout only), x, z (random layout only), then yaw (if random_yaw),
//       then the start frame (if random_frame: next % the model's frame count).
//       The result depends only on the scene file, never on the standard library.
//   "vox_scenes": [{"vox": path (required), "position": [x,y,z], "scale": > 0,
//                   "include_hidden": false}]
//       Flattens the file's scene graph into entities, see flattenVoxScene().
//   "edits": [{"frame": path frame >= 0 (required), "model": name of a "models" entry (required),
//              "model_frame": 0..frames-1, "op": "set" | "fill" | "clear" (required),
//              set: "at": [x,y,z] (inside the grid), fill/clear: "min", "max" (integers,
//              0 <= min < max <= grid size, max exclusive), set/fill: "index": 0..255 (default 1)}]
//       Scene::edits is sorted by frame (stable: same-frame edits keep file order).
//
// Entity order (entity ids, which break depth ties): "entities" in file order, then each crowd
// in order, then each vox_scene in order. The total, after crowds and vox_scenes expand, is at
// most Limits::kMaxEntities.
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
/// S (vox-world) * voxelSize * scale, S the voxel->world swizzle (DESIGN.md §2). So:
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
