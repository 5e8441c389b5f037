#pragma once
// The bench's scenes: a scene file kept with its JSON, and the edits of that JSON behind the
// scaling curves (more or fewer entities, larger or smaller tanks).
#include "core/scene.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>

namespace voxtier::bench {

struct SceneSource {
    std::string file;
    nlohmann::json doc; ///< the file's JSON (already validated by loadScene)
    Scene scene;
};

/// The scene file, loaded (the loader's one-line errors for a bad one) and kept as JSON.
SceneSource loadSource(const std::string& file);
/// `doc` (an edit of src.doc) loaded as src's file would be.
Scene sceneFromJson(const SceneSource& src, const nlohmann::json& doc);

/// The document with its crowds resized so that the scene has `total` entities (plain entities
/// kept, crowds scaled in proportion). nullopt when the scene has no crowd to resize.
std::optional<nlohmann::json> withEntityCount(nlohmann::json doc, int total);

/// The document with every tank generator at `side` x `side` x `side/2` voxels, one animation
/// frame (static: the curve is about the voxel count, not about animation) and the voxel size
/// scaled so the tanks keep their size in metres. nullopt when the scene has no tank.
std::optional<nlohmann::json> withTankSide(nlohmann::json doc, int side);

} // namespace voxtier::bench
