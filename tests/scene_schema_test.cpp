// docs/scene.schema.json, docs/scenes.md and the loader stay in step (issue 14): the schema has
// one definition per kind of scene object, with exactly the keys the loader accepts for it
// (core/scene_keys.hpp, which the loader's key checks read), and the reference document names
// every key. Schema.BundledScenesValidate (tools/validate_scenes.py) validates the bundled scenes.
#include "core/error.hpp"
#include "core/scene_keys.hpp"
#include "core/scene_loader.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <set>
#include <string>

namespace voxtier {
namespace {

std::string slurp(const std::string& rel) {
    std::ifstream in(std::filesystem::path(VOXTIER_SOURCE_DIR) / rel);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

const nlohmann::json& schema() {
    static const nlohmann::json s = nlohmann::json::parse(slurp("docs/scene.schema.json"));
    return s;
}

/// The keys of a schema definition that describes an object ("comment" aside: every object
/// accepts it).
std::set<std::string> schemaKeys(const nlohmann::json& def) {
    std::set<std::string> keys;
    for (const auto& [k, v] : def.at("properties").items())
        if (k != "comment") keys.insert(k);
    return keys;
}

TEST(SceneSchema, EveryLoaderObjectIsASchemaDefinitionWithTheSameKeys) {
    const nlohmann::json& defs = schema().at("definitions");
    for (const SceneObjectKeys& o : sceneObjectKeys()) {
        const std::string name(o.object);
        ASSERT_TRUE(defs.contains(name)) << "the schema has no definition '" << name << "'";
        const nlohmann::json& def = defs.at(name);
        EXPECT_EQ(def.value("additionalProperties", true), false)
            << name << ": the schema must reject unknown keys, as the loader does";
        const std::set<std::string> loader(o.keys.begin(), o.keys.end());
        EXPECT_EQ(schemaKeys(def), loader) << "definition '" << name << "'";
        // Required keys are keys.
        for (const auto& r : def.value("required", nlohmann::json::array()))
            EXPECT_TRUE(loader.count(r.get<std::string>())) << name << " requires " << r;
    }
}

TEST(SceneSchema, EverySchemaObjectDefinitionIsALoaderObject) {
    for (const auto& [name, def] : schema().at("definitions").items()) {
        if (!def.contains("properties")) continue; // value shapes: vec3, rgb, ...
        EXPECT_NO_THROW(sceneKeysOf(name))
            << "schema definition '" << name << "' is not a kind of object the loader reads";
    }
    EXPECT_EQ(schema().at("$ref"), "#/definitions/scene");
}

// Every "$ref" points at a definition (a dangling one would make an editor accept anything).
TEST(SceneSchema, EveryReferenceResolves) {
    const nlohmann::json& defs = schema().at("definitions");
    std::size_t refs = 0;
    std::function<void(const nlohmann::json&)> walk = [&](const nlohmann::json& j) {
        if (j.is_object()) {
            if (j.contains("$ref")) {
                const std::string r = j.at("$ref");
                ASSERT_EQ(r.rfind("#/definitions/", 0), 0u) << r;
                EXPECT_TRUE(defs.contains(r.substr(14))) << r;
                ++refs;
            }
            for (const auto& [k, v] : j.items()) walk(v);
        } else if (j.is_array()) {
            for (const auto& v : j) walk(v);
        }
    };
    walk(schema());
    EXPECT_GT(refs, 20u);
}

TEST(SceneSchema, TheReferenceDocumentNamesEveryKey) {
    const std::string doc = slurp("docs/scenes.md");
    ASSERT_FALSE(doc.empty());
    for (const SceneObjectKeys& o : sceneObjectKeys())
        for (std::string_view k : o.keys)
            EXPECT_NE(doc.find("`" + std::string(k) + "`"), std::string::npos)
                << "docs/scenes.md does not mention `" << k << "` (" << o.object << ")";
}

// The loader reads the lists it is compared with: a key outside them is rejected, with the
// closest accepted key suggested.
TEST(SceneSchema, TheLoaderRejectsKeysOutsideItsLists) {
    const auto load = [](const std::string& text) { loadSceneText(text, "t.json", "."); };
    EXPECT_NO_THROW(load(R"({"$schema": "../docs/scene.schema.json",
        "models": [{"name": "b", "generator": "box"}]})"));
    try {
        load(R"({"models": [{"name": "b", "generator": "box"}], "camera": {"fovy": 40}})");
        FAIL() << "accepted camera.fovy";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("did you mean 'fov_y'"), std::string::npos)
            << e.what();
    }
}

} // namespace
} // namespace voxtier
