#pragma once
// The keys each kind of object in a scene file accepts ("comment", ignored, is accepted by every
// object), named as the definitions of docs/scene.schema.json. The loader checks every object
// against its list (an unknown key is an error), and tests/scene_schema_test.cpp checks that the
// schema's definitions and these lists are the same, so the schema (and docs/scenes.md, written
// from it) cannot drift from what the loader accepts.
#include <string_view>
#include <vector>

namespace voxtier {

struct SceneObjectKeys {
    std::string_view object; ///< the definition's name in docs/scene.schema.json
    std::vector<std::string_view> keys;
};

/// Every kind of object of a scene file, the top level ("scene") first.
const std::vector<SceneObjectKeys>& sceneObjectKeys();
/// The keys of one kind of object; std::logic_error for a name not in sceneObjectKeys().
const std::vector<std::string_view>& sceneKeysOf(std::string_view object);

} // namespace voxtier
