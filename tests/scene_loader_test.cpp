// Scene files are untrusted input: every scene we ship must load, and every malformed variant
// must be a one-line InputError naming the file and the JSON path of the problem.
#include "core/error.hpp"
#include "core/procedural.hpp"
#include "core/scene_loader.hpp"
#include "core/sprite.hpp"
#include "lod/error_budget.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <ostream>
#include <set>
#include <string>
#include <vector>

namespace voxtier {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

const fs::path kSource = VOXTIER_SOURCE_DIR;
const fs::path kScenes = kSource / "scenes";

/// A per-test scratch directory (tests may run in parallel processes under CTest).
fs::path scratchDir() {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    const fs::path dir = fs::temp_directory_path() / "voxtier_scene_loader_test" /
                         (std::string(info->test_suite_name()) + "." + info->name());
    fs::create_directories(dir);
    return dir;
}

fs::path writeFile(const std::string& name, const std::string& text) {
    const fs::path p = scratchDir() / name;
    std::ofstream(p, std::ios::binary) << text;
    return p;
}

/// A small valid scene using only generators, so it does not need the .vox reader.
json baseScene() {
    return json::parse(R"({
      "voxel_size": 0.1,
      "camera": {"position": [0, 2, 10], "target": [0, 0, 0], "size": [64, 48]},
      "models": [
        {"name": "b", "generator": "box", "size": [4, 4, 4]},
        {"name": "a", "generator": "arrow"}
      ],
      "entities": [
        {"model": "b", "position": [0, 0, 0]},
        {"model": "a", "position": [1, 0, -2], "rotation_deg": [0, 90, 0]}
      ]
    })");
}

Scene loadJson(const json& j) {
    return loadSceneJson(j, "test.json", kScenes);
}

/// Loads `text` from a file and returns the InputError it must raise.
InputError errorFromText(const std::string& text) {
    const fs::path p = writeFile("scene.json", text);
    try {
        loadScene(p);
    } catch (const InputError& e) {
        return e;
    }
    ADD_FAILURE() << "no InputError for:\n" << text;
    return InputError("", "", "");
}

void expectWellFormed(const InputError& e, const std::string& file) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    EXPECT_EQ(what.rfind(file, 0), 0u) << "message does not start with the file: " << what;
    EXPECT_EQ(e.file(), file);
    EXPECT_FALSE(e.reason().empty());
}

// ---------------------------------------------------------------------------------------------
// Every shipped scene loads.

std::vector<fs::path> shippedScenes() {
    std::vector<fs::path> out;
    for (const auto& entry : fs::recursive_directory_iterator(kScenes)) {
        const fs::path rel = fs::relative(entry.path(), kScenes);
        if (*rel.begin() == "vox") continue; // assets, not scenes
        if (entry.is_regular_file() && entry.path().extension() == ".json")
            out.push_back(entry.path());
    }
    std::sort(out.begin(), out.end());
    return out;
}

TEST(SceneLoader, EveryShippedSceneLoads) {
    const auto scenes = shippedScenes();
    ASSERT_FALSE(scenes.empty());
    EXPECT_TRUE(std::find(scenes.begin(), scenes.end(), kScenes / "default.json") != scenes.end());
    for (const auto& p : scenes) {
        SCOPED_TRACE(p.string());
        try {
            const Scene s = loadScene(p);
            EXPECT_FALSE(s.models.empty());
            EXPECT_FALSE(s.entities.empty());
            EXPECT_EQ(s.source, p.string());
            for (const Entity& e : s.entities) {
                ASSERT_GE(e.model, 0);
                ASSERT_LT(e.model, int(s.models.size()));
                ASSERT_LT(e.frame, s.models[std::size_t(e.model)]->frameCount());
            }
        } catch (const std::exception& e) {
            ADD_FAILURE() << e.what();
        }
    }
}

TEST(SceneLoader, GoldenScenesAreSmallAndSelfContained) {
    // Golden scenes compare tiers pixel for pixel: keep them procedural (no .vox dependency)
    // and small enough to render in milliseconds.
    int count = 0;
    for (const auto& entry : fs::directory_iterator(kScenes / "golden")) {
        if (entry.path().extension() != ".json") continue;
        ++count;
        SCOPED_TRACE(entry.path().string());
        const Scene s = loadScene(entry.path());
        EXPECT_LE(s.camera.width * s.camera.height, 320 * 240);
        EXPECT_LE(s.entities.size(), 200u);
        for (const auto& m : s.models) EXPECT_EQ(m->palette(), proceduralPalette()) << m->name();
    }
    EXPECT_GE(count, 3);
}

// ---------------------------------------------------------------------------------------------
// The default scene, loaded once for the tests that read it.

const Scene& defaultScene() {
    static const Scene s = loadScene(kScenes / "default.json");
    return s;
}

TEST(DefaultScene, Is960By540AtVoxelSizeOneTenthAndSigmaOne) {
    const Scene& s = defaultScene();
    EXPECT_EQ(s.camera.width, 960);
    EXPECT_EQ(s.camera.height, 540);
    EXPECT_DOUBLE_EQ(s.render.voxelSize, 0.1);
    EXPECT_DOUBLE_EQ(s.render.sigma, 1.0);
}

TEST(DefaultScene, SelectsByAnErrorBudgetOfOneVirtualPixel) {
    const Scene& s = defaultScene();
    EXPECT_EQ(s.selector.metric, SelectorMetric::ErrorBudget);
    EXPECT_DOUBLE_EQ(s.selector.budgetVpx, 1.0);
    EXPECT_GT(s.selector.nearAt, s.selector.farAt);
}

TEST(DefaultScene, HoldsOneToFourHundredEntities) {
    const Scene& s = defaultScene();
    EXPECT_LE(s.entities.size(), 400u);
    EXPECT_GE(s.entities.size(), 100u);
}

TEST(DefaultScene, HasAPathOfAboutFiveSeconds) {
    const Scene& s = defaultScene();
    ASSERT_TRUE(s.path.has_value());
    EXPECT_NEAR(s.path->duration(), 5.0, 1.0);
}

/// From `cam`, some visible entities of the default scene are near (their best view's predicted
/// displacement past near_at of the budget) and some far (below far_at), and the far ones reach
/// hundreds of metres.
void expectBothTiersFrom(const Scene& s, const Camera& cam) {
    const CameraFrame frame = makeCameraFrame(cam);
    Scene probe = s;
    probe.path.reset();
    probe.camera = cam;
    const auto sprites = setupSprites(probe, frame, 0.0);
    int nearCount = 0, farCount = 0;
    double maxDistance = 0.0;
    for (const auto& sp : sprites) {
        if (!sp.visible()) continue;
        const double share = bestBudgetUnits(sp, s.selector) / s.selector.budgetVpx;
        nearCount += share > s.selector.nearAt;
        farCount += share < s.selector.farAt;
        maxDistance = std::max(maxDistance, sp.distance);
    }
    EXPECT_GE(nearCount, 3);
    EXPECT_GE(farCount, 50);
    EXPECT_GT(maxDistance, 200.0);
}

TEST(DefaultScene, SpansBothTiersFromTheStaticCamera) {
    expectBothTiersFrom(defaultScene(), defaultScene().camera);
}

TEST(DefaultScene, SpansBothTiersAtThePathStart) {
    const Scene& s = defaultScene();
    ASSERT_TRUE(s.path.has_value());
    expectBothTiersFrom(s, s.cameraAt(0.0));
}

TEST(DefaultScene, SpansBothTiersAtThePathEnd) {
    const Scene& s = defaultScene();
    ASSERT_TRUE(s.path.has_value());
    expectBothTiersFrom(s, s.cameraAt(s.path->keys.back().time));
}

TEST(DefaultScene, PathFliesFromFarToNear) {
    // The eye ends much closer to the field than it starts.
    const Scene& s = defaultScene();
    ASSERT_TRUE(s.path.has_value());
    const glm::dvec3 start = s.path->keys.front().position, end = s.path->keys.back().position;
    EXPECT_GT(glm::length(start - end), 30.0);
}

// ---------------------------------------------------------------------------------------------
// Malformed scenes: one line, names file and JSON path.

struct BadCase {
    std::string what;
    std::function<void(json&)> mutate;
    std::string path;   ///< expected InputError::field()
    std::string reason; ///< expected substring of the reason
};

void PrintTo(const BadCase& c, std::ostream* os) {
    *os << c.what;
}

/// The case's `what` as a test name: "far_at below near_at" -> FarAtBelowNearAt.
std::string caseName(const testing::TestParamInfo<BadCase>& info) {
    std::string name;
    bool wordStart = true;
    for (char ch : info.param.what) {
        if (!std::isalnum(static_cast<unsigned char>(ch))) {
            wordStart = true;
            continue;
        }
        name += wordStart ? char(std::toupper(static_cast<unsigned char>(ch))) : ch;
        wordStart = false;
    }
    return name;
}

/// One malformed variant of baseScene() per test, the cases grouped by the part of the scene
/// they break.
class MalformedScene : public testing::TestWithParam<BadCase> {};

TEST_P(MalformedScene, IsOneLineNamingTheFileJsonPathAndReason) {
    const BadCase& c = GetParam();
    json j = baseScene();
    c.mutate(j);
    // Through a file, so the whole path (read, parse, validate) is exercised.
    const InputError e = errorFromText(j.dump(2));
    expectWellFormed(e, (scratchDir() / "scene.json").string());
    EXPECT_EQ(e.field(), c.path) << e.what();
    EXPECT_NE(std::string(e.what()).find(": " + c.path + (c.path.empty() ? "" : ": ")),
              std::string::npos)
        << e.what();
    EXPECT_NE(e.reason().find(c.reason), std::string::npos) << e.what();
}

// Entities: their keys, model, placement, rotation, scale and frame.
const std::vector<BadCase> kEntityCases = {
    {"typo key",
     [](json& j) {
         j["entities"][0]["positon"] = {1, 2, 3};
     },
     "entities[0].positon", "unknown key 'positon' (did you mean 'position'?)"},
    {"missing model", [](json& j) { j["entities"][1]["model"] = "tank"; }, "entities[1].model",
     "unknown model 'tank'"},
    {"position too short",
     [](json& j) {
         j["entities"][1]["position"] = {1, 2};
     },
     "entities[1].position", "expected an array of 3 finite numbers"},
    {"position not numbers",
     [](json& j) {
         j["entities"][0]["position"] = {1, "2", 3};
     },
     "entities[0].position", "expected an array of 3 finite numbers"},
    {"zero quaternion",
     [](json& j) {
         j["entities"][0]["quaternion"] = {0, 0, 0, 0};
     },
     "entities[0].quaternion", "non-zero quaternion"},
    {"quaternion of 3",
     [](json& j) {
         j["entities"][0]["quaternion"] = {1, 0, 0};
     },
     "entities[0].quaternion", "array of 4"},
    {"rotation and quaternion",
     [](json& j) {
         j["entities"][1]["quaternion"] = {1, 0, 0, 0};
     },
     "entities[1].quaternion", "either rotation_deg or quaternion"},
    {"zero scale", [](json& j) { j["entities"][0]["scale"] = 0; }, "entities[0].scale", "positive"},
    {"frame out of range", [](json& j) { j["entities"][0]["frame"] = 1; }, "entities[0].frame",
     "[0, 0]"},
    {"fractional frame", [](json& j) { j["entities"][0]["frame"] = 0.5; }, "entities[0].frame",
     "integer"},
    {"entity not an object", [](json& j) { j["entities"][1] = 3; }, "entities[1]",
     "expected an object"},
    {"comment must be a string", [](json& j) { j["entities"][0]["comment"] = 3; },
     "entities[0].comment", "expected a string"},
};
INSTANTIATE_TEST_SUITE_P(Entities, MalformedScene, ::testing::ValuesIn(kEntityCases), caseName);

// The selector: its thresholds, view set, metric and budget.
const std::vector<BadCase> kSelectorCases = {
    {"far_at equal to near_at",
     [](json& j) {
         j["selector"] = {{"near_at", 30}, {"far_at", 30}};
     },
     "selector.far_at", "far_at must be greater than near_at"},
    {"far_at below near_at",
     [](json& j) {
         j["selector"] = {{"near_at", 50}};
     },
     "selector.near_at", "far_at must be greater than near_at"},
    {"bad view set",
     [](json& j) {
         j["selector"] = {{"view_set", 27}};
     },
     "selector.view_set", "26, 98 or 218"},
    {"zero error budget",
     [](json& j) {
         j["selector"] = {{"metric", "error_budget"}, {"budget_vpx", 0}};
     },
     "selector.budget_vpx", "positive"},
    {"ladder cap off the ladder",
     [](json& j) {
         j["selector"] = {{"metric", "error_budget"}, {"ladder_cap", 3}};
     },
     "selector.ladder_cap", "1, 2, 4, 8, 16, 32 or 64"},
    {"bad metric",
     [](json& j) {
         j["selector"] = {{"metric", "distanse"}};
     },
     "selector.metric", "did you mean 'distance'"},
};
INSTANTIATE_TEST_SUITE_P(Selector, MalformedScene, ::testing::ValuesIn(kSelectorCases), caseName);

// The camera path and its keys.
const std::vector<BadCase> kCameraPathCases = {
    {"path times not increasing",
     [](json& j) {
         j["camera_path"] = {{"keys",
                              {{{"time", 0}, {"position", {0, 2, 10}}, {"target", {0, 0, 0}}},
                               {{"time", 0}, {"position", {0, 2, 8}}, {"target", {0, 0, 0}}}}}};
     },
     "camera_path.keys[1].time", "strictly increasing"},
    {"path without keys",
     [](json& j) {
         j["camera_path"] = {{"keys", json::array()}};
     },
     "camera_path.keys", "at least one key"},
    {"path key missing target",
     [](json& j) {
         j["camera_path"] = {{"keys", {{{"time", 0}, {"position", {0, 2, 10}}}}}};
     },
     "camera_path.keys[0]", "missing required key 'target'"},
    {"path key degenerate",
     [](json& j) {
         j["camera_path"] = {
             {"keys", {{{"time", 0}, {"position", {1, 1, 1}}, {"target", {1, 1, 1}}}}}};
     },
     "camera_path.keys[0].target", "target equals position"},
};
INSTANTIATE_TEST_SUITE_P(CameraPath, MalformedScene, ::testing::ValuesIn(kCameraPathCases),
                         caseName);

// Models: their list, names, sources and generator parameters.
const std::vector<BadCase> kModelCases = {
    {"unknown generator",
     [](json& j) {
         j["models"][0] = {{"name", "b"}, {"generator", "cube"}};
     },
     "models[0].generator", "unknown value 'cube'"},
    {"generator key of another generator",
     [](json& j) {
         j["models"][0] = {{"name", "b"}, {"generator", "box"}, {"radius", 3}};
     },
     "models[0].radius", "unknown key 'radius'"},
    {"model without source",
     [](json& j) {
         j["models"][0] = {{"name", "b"}};
     },
     "models[0]", "missing 'vox'"},
    {"duplicate model name", [](json& j) { j["models"][1]["name"] = "b"; }, "models[1].name",
     "duplicate model name 'b'"},
    {"no models", [](json& j) { j["models"] = json::array(); }, "models", "at least one model"},
    {"models missing", [](json& j) { j.erase("models"); }, "", "missing required key 'models'"},
    {"vox file not found",
     [](json& j) {
         j["models"][0] = {{"name", "b"}, {"vox", "vox/nope/missing.vox"}};
     },
     "models[0].vox", "file not found"},
    {"box too big",
     [](json& j) {
         j["models"][0]["size"] = {4, 300, 4};
     },
     "models[0].size[1]", "expected an integer in [1, 256]"},
    {"sphere radius zero",
     [](json& j) {
         j["models"][0] = {{"name", "b"}, {"generator", "sphere"}, {"radius", 0}};
     },
     "models[0].radius", "[1, 128]"},
};
INSTANTIATE_TEST_SUITE_P(Models, MalformedScene, ::testing::ValuesIn(kModelCases), caseName);

// Top-level render settings: keys, voxel size, sigma, background, view mode, light.
const std::vector<BadCase> kRenderCases = {
    {"top-level typo", [](json& j) { j["voxelsize"] = 0.1; }, "voxelsize", "unknown key"},
    {"negative voxel size", [](json& j) { j["voxel_size"] = -0.1; }, "voxel_size",
     "expected a positive number"},
    {"zero sigma", [](json& j) { j["sigma"] = 0; }, "sigma", "expected a positive number"},
    {"sigma over the limit", [](json& j) { j["sigma"] = 17; }, "sigma", "at most 16"},
    {"background out of range",
     [](json& j) {
         j["background"] = {0, 256, 0};
     },
     "background[1]", "[0, 255]"},
    {"view mode", [](json& j) { j["view_mode"] = "ortho"; }, "view_mode", "unknown value"},
    {"zero light",
     [](json& j) {
         j["light"] = {{"direction", {0, 0, 0}}};
     },
     "light.direction", "non-zero"},
};
INSTANTIATE_TEST_SUITE_P(RenderSettings, MalformedScene, ::testing::ValuesIn(kRenderCases),
                         caseName);

// The camera: image size, orientation, field of view and near plane.
const std::vector<BadCase> kCameraCases = {
    {"image too wide",
     [](json& j) {
         j["camera"]["size"] = {16385, 10};
     },
     "camera.size[0]", "[1, 16384]"},
    {"image empty",
     [](json& j) {
         j["camera"]["size"] = {0, 10};
     },
     "camera.size[0]", "[1, 16384]"},
    {"camera target equals position",
     [](json& j) { j["camera"]["target"] = j["camera"]["position"]; }, "camera.target",
     "target equals position"},
    {"camera up parallel to view",
     [](json& j) {
         j["camera"]["target"] = {0, -5, 0};
         j["camera"]["position"] = {0, 5, 0};
     },
     "camera.up", "parallel"},
    {"camera fov", [](json& j) { j["camera"]["fov_y"] = 180; }, "camera.fov_y", "(0, 179)"},
    {"camera near", [](json& j) { j["camera"]["near"] = 0; }, "camera.near", "positive"},
};
INSTANTIATE_TEST_SUITE_P(Camera, MalformedScene, ::testing::ValuesIn(kCameraCases), caseName);

// Crowds: their count, models, layout keys, area and seed.
const std::vector<BadCase> kCrowdCases = {
    {"too many entities",
     [](json& j) {
         j["crowds"] = {{{"models", {"b"}}, {"count", Limits::kMaxEntities - 1}}};
     },
     "crowds[0].count", "limit is 1000000"},
    {"crowd count over the limit",
     [](json& j) {
         j["crowds"] = {{{"models", {"b"}}, {"count", Limits::kMaxEntities + 1}}};
     },
     "crowds[0].count", "[0, 1000000]"},
    {"crowd unknown model",
     [](json& j) {
         j["crowds"] = {{{"models", {"b", "c"}}, {"count", 3}}};
     },
     "crowds[0].models[1]", "unknown model 'c'"},
    {"grid crowd with random keys",
     [](json& j) {
         j["crowds"] = {{{"models", {"b"}}, {"count", 3}, {"y", 1}}};
     },
     "crowds[0].y", "unknown key 'y'"},
    {"random crowd area inverted",
     [](json& j) {
         j["crowds"] = {{{"models", {"b"}},
                         {"layout", "random"},
                         {"count", 3},
                         {"area", {{"min", {0, 0}}, {"max", {-1, 5}}}}}};
     },
     "crowds[0].area.max", "max >= min"},
    {"random crowd without area",
     [](json& j) {
         j["crowds"] = {{{"models", {"b"}}, {"layout", "random"}, {"count", 3}}};
     },
     "crowds[0]", "missing required key 'area'"},
    {"negative seed",
     [](json& j) {
         j["crowds"] = {{{"models", {"b"}}, {"count", 3}, {"seed", -1}}};
     },
     "crowds[0].seed", "unsigned"},
};
INSTANTIATE_TEST_SUITE_P(Crowds, MalformedScene, ::testing::ValuesIn(kCrowdCases), caseName);

// Scripted edits: their voxel or box, model frame, keys and op.
const std::vector<BadCase> kEditCases = {
    {"edit outside the model",
     [](json& j) {
         j["edits"] = {{{"frame", 0}, {"model", "b"}, {"op", "set"}, {"at", {4, 0, 0}}}};
     },
     "edits[0].at", "outside the 4x4x4 model"},
    {"edit box beyond the model",
     [](json& j) {
         j["edits"] = {{{"frame", 0},
                        {"model", "b"},
                        {"op", "fill"},
                        {"min", {0, 0, 0}},
                        {"max", {2, 2, 5}}}};
     },
     "edits[0].max", "outside the 4x4x4 model"},
    {"edit box empty",
     [](json& j) {
         j["edits"] = {{{"frame", 0},
                        {"model", "b"},
                        {"op", "clear"},
                        {"min", {1, 1, 1}},
                        {"max", {1, 2, 2}}}};
     },
     "edits[0].max", "max > min"},
    {"edit model frame out of range",
     [](json& j) {
         j["edits"] = {
             {{"frame", 0}, {"model", "b"}, {"model_frame", 2}, {"op", "set"}, {"at", {0, 0, 0}}}};
     },
     "edits[0].model_frame", "[0, 0]"},
    {"clear with an index",
     [](json& j) {
         j["edits"] = {{{"frame", 0},
                        {"model", "b"},
                        {"op", "clear"},
                        {"min", {0, 0, 0}},
                        {"max", {1, 1, 1}},
                        {"index", 3}}};
     },
     "edits[0].index", "unknown key 'index'"},
    {"edit op typo",
     [](json& j) {
         j["edits"] = {{{"frame", 0}, {"model", "b"}, {"opp", "set"}}};
     },
     "edits[0].opp", "did you mean 'op'"},
};
INSTANTIATE_TEST_SUITE_P(Edits, MalformedScene, ::testing::ValuesIn(kEditCases), caseName);

// .vox scenes.
const std::vector<BadCase> kVoxSceneCases = {
    {"vox scene not found",
     [](json& j) {
         j["vox_scenes"] = {{{"vox", "nothing.vox"}}};
     },
     "vox_scenes[0].vox", "file not found"},
};
INSTANTIATE_TEST_SUITE_P(VoxScenes, MalformedScene, ::testing::ValuesIn(kVoxSceneCases), caseName);

TEST(SceneLoader, NumberOverflowIsReportedWithItsJsonPath) {
    std::string text = baseScene().dump(2);
    const std::string needle = "\"voxel_size\": 0.1";
    ASSERT_NE(text.find(needle), std::string::npos);
    text.replace(text.find(needle), needle.size(), "\"voxel_size\": 1e999");
    const InputError e = errorFromText(text);
    expectWellFormed(e, (scratchDir() / "scene.json").string());
    EXPECT_EQ(e.field(), "voxel_size");
    EXPECT_NE(e.reason().find("finite number"), std::string::npos) << e.what();

    // Inside arrays too, with the element index.
    const InputError e2 = errorFromText(R"({"models": [{"name": "b", "generator": "box"}],
        "entities": [{"model": "b"}, {"model": "b", "position": [0, -1e400, 0]}]})");
    EXPECT_EQ(e2.field(), "entities[1].position[1]") << e2.what();
}

// Every model is within 256³, yet 4096 frames of a 256³ tank would be 64 GiB of grids: the
// scene-wide voxel budget refuses it before anything is allocated (this would hang or OOM).
TEST(SceneLoader, SceneWideVoxelBudgetRefusesHugeModelsBeforeAllocating) {
    const InputError e = errorFromText(R"({"models": [{"name": "t", "generator": "tank",
        "size": [256, 256, 256], "frames": 4096}], "entities": [{"model": "t"}]})");
    expectWellFormed(e, (scratchDir() / "scene.json").string());
    EXPECT_EQ(e.field(), "models[0]") << e.what();
    EXPECT_NE(e.reason().find("68719476736 voxel cells; the limit is 1073741824"),
              std::string::npos)
        << e.what();
}

TEST(SceneLoader, JsonSyntaxErrorsNameLineAndColumn) {
    const InputError e = errorFromText(
        "{\n  \"voxel_size\": 0.1,\n  \"models\": [\n    {\"name\": \"b\",, }\n  ]\n}\n");
    expectWellFormed(e, (scratchDir() / "scene.json").string());
    EXPECT_NE(e.reason().find("line 4, column 18"), std::string::npos) << e.what();
    EXPECT_EQ(e.field(), "models[0]");

    const InputError eof = errorFromText("{\"models\": [");
    EXPECT_NE(eof.reason().find("line 1"), std::string::npos) << eof.what();

    const InputError nan = errorFromText(R"({"voxel_size": NaN})");
    EXPECT_EQ(nan.field(), "voxel_size") << nan.what();
    EXPECT_NE(nan.reason().find("invalid JSON"), std::string::npos);
}

TEST(SceneLoader, DuplicateKeysAreErrors) {
    const InputError e =
        errorFromText(R"({"models": [{"name": "b", "generator": "box", "name": "c"}]})");
    EXPECT_EQ(e.field(), "models[0].name");
    EXPECT_NE(e.reason().find("duplicate key 'name'"), std::string::npos) << e.what();
}

TEST(SceneLoader, MissingSceneFileIsNamed) {
    const fs::path p = scratchDir() / "does_not_exist.json";
    try {
        loadScene(p);
        FAIL() << "no error";
    } catch (const InputError& e) {
        expectWellFormed(e, p.string());
        EXPECT_NE(e.reason().find("not found"), std::string::npos);
    }
}

TEST(SceneLoader, TopLevelMustBeAnObject) {
    const InputError e = errorFromText("[1, 2, 3]");
    EXPECT_NE(e.reason().find("expected a JSON object"), std::string::npos) << e.what();
}

// ---------------------------------------------------------------------------------------------
// Values and conventions.

TEST(SceneLoader, DefaultsComeFromSceneHpp) {
    const Scene s = loadJson(json::parse(R"({"models": [{"name": "v", "generator": "voxel"}]})"));
    const Scene d;
    EXPECT_EQ(s.render.voxelSize, d.render.voxelSize);
    EXPECT_EQ(s.render.sigma, d.render.sigma);
    EXPECT_EQ(s.render.background, d.render.background);
    EXPECT_EQ(s.camera.position, d.camera.position);
    EXPECT_EQ(s.camera.width, d.camera.width);
    EXPECT_EQ(s.selector.nearAt, d.selector.nearAt);
    EXPECT_EQ(s.selector.farAt, d.selector.farAt);
    EXPECT_EQ(s.light.direction, d.light.direction);
    EXPECT_FALSE(s.path.has_value());
    EXPECT_TRUE(s.entities.empty());
    EXPECT_EQ(s.source, "test.json");
}

TEST(SceneLoader, ParsesEveryTopLevelSetting) {
    const Scene s = loadJson(json::parse(R"({
      "description": "all settings",
      "voxel_size": 0.25, "sigma": 2, "view_mode": "parallel", "background": [1, 2, 3],
      "camera": {"position": [1, 2, 3], "target": [1, 2, -3], "up": [0, 1, 0], "fov_y": 40,
                 "size": [320, 200], "near": 0.5},
      "light": {"direction": [0, 1, 0], "ambient": 0.3, "diffuse": 0.7, "comment": "noon"},
      "selector": {"metric": "error_px", "near_at": 3, "far_at": 2, "view_hysteresis_deg": 5,
                   "crossfade_frames": 8, "view_set": 98},
      "models": [{"name": "v", "generator": "voxel", "index": 5, "color": [10, 20, 30]}]
    })"));
    EXPECT_EQ(s.render.voxelSize, 0.25);
    EXPECT_EQ(s.render.sigma, 2.0);
    EXPECT_EQ(s.render.viewMode, ViewMode::Parallel);
    EXPECT_EQ(s.render.background, packRgba(1, 2, 3));
    EXPECT_EQ(s.camera.position, glm::dvec3(1, 2, 3));
    EXPECT_EQ(s.camera.fovYDeg, 40.0);
    EXPECT_EQ(s.camera.width, 320);
    EXPECT_EQ(s.camera.height, 200);
    EXPECT_EQ(s.camera.zNear, 0.5);
    EXPECT_EQ(s.light.ambient, 0.3);
    EXPECT_EQ(s.selector.metric, SelectorMetric::ErrorPx);
    EXPECT_EQ(s.selector.viewHysteresisDeg, 5.0);
    EXPECT_EQ(s.selector.crossfadeFrames, 8);
    EXPECT_EQ(s.selector.viewSetSize, 98);
    ASSERT_EQ(s.models.size(), 1u);
    EXPECT_EQ(s.models[0]->name(), "v");
    EXPECT_EQ(s.models[0]->frame(0).at({0, 0, 0}), 5);
    EXPECT_EQ(s.models[0]->palette().colors[5], packRgba(10, 20, 30));
    EXPECT_EQ(s.models[0]->palette().colors[4], proceduralPalette().colors[4]);
}

TEST(SceneLoader, GeneratorsBuildTheProceduralModels) {
    const Scene s = loadJson(json::parse(R"({"models": [
        {"name": "b", "generator": "box", "size": [3, 4, 5], "index": 9},
        {"name": "s", "generator": "sphere", "radius": 4},
        {"name": "a", "generator": "arrow", "length": 12},
        {"name": "h", "generator": "shell", "size": [6, 6, 6], "thickness": 2},
        {"name": "v", "generator": "voxel"}]})"));
    ASSERT_EQ(s.models.size(), 5u);
    EXPECT_EQ(s.models[0]->frame(0).data(), makeBox({3, 4, 5}, 9)->frame(0).data());
    EXPECT_EQ(s.models[1]->frame(0).data(), makeSphere(4)->frame(0).data());
    EXPECT_EQ(s.models[2]->frame(0).data(), makeArrow(12)->frame(0).data());
    EXPECT_EQ(s.models[3]->frame(0).data(), makeShell({6, 6, 6}, 2)->frame(0).data());
    EXPECT_EQ(s.models[4]->frame(0).data(), makeSingleVoxel()->frame(0).data());
    EXPECT_EQ(s.models[2]->name(), "a");
}

TEST(SceneLoader, TankGeneratorKeepsItsFramesSeedAndSize) {
    const Scene s = loadJson(json::parse(R"({"models": [
        {"name": "t", "generator": "tank", "seed": 4, "frames": 3, "size": [16, 16, 8]},
        {"name": "d", "generator": "tank"}]})"));
    ASSERT_EQ(s.models.size(), 2u);
    const auto expected = makeTank(4, 3, {16, 16, 8});
    ASSERT_EQ(s.models[0]->frameCount(), 3);
    for (int f = 0; f < 3; ++f) EXPECT_EQ(s.models[0]->frame(f).data(), expected->frame(f).data());
    EXPECT_EQ(s.models[0]->name(), "t");
    EXPECT_EQ(s.models[0]->palette(), tankPalette());
    EXPECT_EQ(s.models[1]->frameCount(), 8);
    EXPECT_EQ(s.models[1]->frame(0).data(), makeTank(1)->frame(0).data());
    EXPECT_THROW(loadJson(json::parse(
                     R"({"models": [{"name": "t", "generator": "tank", "size": [4, 32, 16]}]})")),
                 InputError);
    EXPECT_THROW(
        loadJson(json::parse(R"({"models": [{"name": "t", "generator": "tank", "radius": 3}]})")),
        InputError);
}

glm::dvec3 rotate(const glm::dquat& q, glm::dvec3 v) {
    return q * v;
}

void expectNear(glm::dvec3 a, glm::dvec3 b) {
    EXPECT_NEAR(a.x, b.x, 1e-12);
    EXPECT_NEAR(a.y, b.y, 1e-12);
    EXPECT_NEAR(a.z, b.z, 1e-12);
}

TEST(SceneLoader, RotationDegIsYawThenPitchThenRollAboutWorldAxes) {
    // Yaw 90 maps world +X to -Z (right-handed rotation about +Y).
    expectNear(rotate(quatFromEulerDeg({0, 90, 0}), {1, 0, 0}), {0, 0, -1});
    // Pitch 90 about X maps +Y to +Z; roll 90 about Z maps +X to +Y.
    expectNear(rotate(quatFromEulerDeg({90, 0, 0}), {0, 1, 0}), {0, 0, 1});
    expectNear(rotate(quatFromEulerDeg({0, 0, 90}), {1, 0, 0}), {0, 1, 0});
    // q = qY * qX * qZ: roll is applied first, then pitch, then yaw.
    // +Y -(pitch 90)-> +Z -(yaw 90)-> +X.
    expectNear(rotate(quatFromEulerDeg({90, 90, 0}), {0, 1, 0}), {1, 0, 0});
    // +X -(roll 90)-> +Y -(pitch 90)-> +Z -(yaw 90)-> +X.
    expectNear(rotate(quatFromEulerDeg({90, 90, 90}), {1, 0, 0}), {1, 0, 0});
    // +Y -(roll 90)-> -X -(pitch)-> -X -(yaw 90)-> +Z.
    expectNear(rotate(quatFromEulerDeg({90, 90, 90}), {0, 1, 0}), {0, 0, 1});

    // The loaded entity carries the same rotation.
    const Scene s = loadJson(baseScene());
    expectNear(rotate(s.entities[1].rotation, {1, 0, 0}), {0, 0, -1});
}

TEST(SceneLoader, QuaternionIsWxyzAndNormalised) {
    json j = baseScene();
    j["entities"][0]["quaternion"] = {2, 0, 0, 0};
    j["entities"][1].erase("rotation_deg");
    const double h = std::sqrt(0.5);
    j["entities"][1]["quaternion"] = {h * 3, 0, h * 3, 0}; // 90 degrees about +Y, scaled by 3
    const Scene s = loadJson(j);
    EXPECT_EQ(s.entities[0].rotation, glm::dquat(1, 0, 0, 0));
    EXPECT_NEAR(glm::length(s.entities[1].rotation), 1.0, 1e-15);
    expectNear(rotate(s.entities[1].rotation, {1, 0, 0}), {0, 0, -1});
}

TEST(SceneLoader, EntityFieldsAreLoaded) {
    json j = baseScene();
    j["entities"][0] = {{"model", "a"},  {"position", {1.5, -2, 3}},
                        {"scale", 2.5},  {"anchor", {0, 0, 0}},
                        {"frame", 0},    {"fps", 12},
                        {"name", "hero"}};
    const Scene s = loadJson(j);
    const Entity& e = s.entities[0];
    EXPECT_EQ(e.model, 1);
    EXPECT_EQ(e.position, glm::dvec3(1.5, -2, 3));
    EXPECT_EQ(e.scale, 2.5);
    ASSERT_TRUE(e.anchor.has_value());
    EXPECT_EQ(*e.anchor, glm::dvec3(0.0));
    EXPECT_EQ(e.fps, 12.0);
    EXPECT_EQ(e.name, "hero");
    EXPECT_FALSE(s.entities[1].anchor.has_value()); // default: bottom centre, resolved later
}

/// baseScene() with a camera fov of 50 and a path of three keys from t = 1 s to 4 s at 10 fps
/// (the second key sets fov 30, the third an up vector), loaded once for the tests that read it.
const Scene& keyedPathScene() {
    static const Scene s = [] {
        json j = baseScene();
        j["camera"]["fov_y"] = 50;
        j["camera_path"] = json::parse(R"({"fps": 10, "keys": [
            {"time": 1, "position": [0, 2, 10], "target": [0, 0, 0]},
            {"time": 3, "position": [0, 2, 30], "target": [0, 0, 20], "fov_y": 30},
            {"time": 4, "position": [10, 2, 30], "target": [10, 0, 20], "up": [1, 1, 0]}]})");
        return loadJson(j);
    }();
    return s;
}

TEST(CameraPath, FramesRunFromTheFirstKeyToTheLastAtItsFps) {
    const Scene& s = keyedPathScene();
    ASSERT_TRUE(s.path.has_value());
    EXPECT_EQ(s.path->fps, 10.0);
    EXPECT_EQ(s.path->duration(), 3.0);
    EXPECT_EQ(s.path->frameCount(), 31);
    EXPECT_EQ(s.timeOfFrame(0), 1.0);
    EXPECT_EQ(s.timeOfFrame(30), 4.0);
}

TEST(CameraPath, IsClampedBeforeTheFirstKeyAndAfterTheLast) {
    const Scene& s = keyedPathScene();
    ASSERT_TRUE(s.path.has_value());
    EXPECT_EQ(s.cameraAt(0.0).position, glm::dvec3(0, 2, 10));
    EXPECT_EQ(s.cameraAt(9.0).position, glm::dvec3(10, 2, 30));
}

TEST(CameraPath, InterpolatesPositionTargetAndFovBetweenKeys) {
    // Halfway between keys 0 and 1 (key 0 has the camera's fov, 50).
    const Scene& s = keyedPathScene();
    ASSERT_TRUE(s.path.has_value());
    const Camera mid = s.cameraAt(2.0);
    expectNear(mid.position, {0, 2, 20});
    expectNear(mid.target, {0, 0, 10});
    EXPECT_NEAR(mid.fovYDeg, 40.0, 1e-12);
    EXPECT_EQ(mid.width, 64); // image size always from "camera"
}

TEST(CameraPath, MixesUpFromTheCamerasToTheKeys) {
    // A quarter into the last segment; up mixes from the camera's up to the key's.
    const Scene& s = keyedPathScene();
    ASSERT_TRUE(s.path.has_value());
    const Camera q = s.cameraAt(3.25);
    expectNear(q.position, {2.5, 2, 30});
    expectNear(q.up, {0.25, 1, 0});
    EXPECT_NEAR(q.fovYDeg, 30.0 + (50.0 - 30.0) * 0.25, 1e-12);
}

TEST(SceneLoader, CameraPathThatDegeneratesBetweenKeysIsRejected) {
    // The eye passes through the target exactly at frame 15 (t = 0.5 s).
    json j = baseScene();
    j["camera_path"] = json::parse(R"({"fps": 30, "keys": [
        {"time": 0, "position": [0, 0, 1], "target": [0, 0, 0]},
        {"time": 1, "position": [0, 0, -1], "target": [0, 0, 0]}]})");
    try {
        loadJson(j);
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "camera_path");
        EXPECT_NE(e.reason().find("frame 15"), std::string::npos) << e.what();
    }
}

// ---------------------------------------------------------------------------------------------
// Crowds.

json crowdScene(std::uint64_t seed, const std::string& layout) {
    json j = baseScene();
    j["models"].push_back({{"name", "s"}, {"generator", "sphere"}, {"radius", 2}});
    json crowd = {{"models", {"b", "a", "s"}}, {"count", 50}, {"seed", seed}, {"random_yaw", true}};
    crowd["layout"] = layout;
    if (layout == "random") {
        crowd["area"] = {{"min", {-20, -40}}, {"max", {20, -10}}};
        crowd["y"] = 0.5;
    }
    j["crowds"] = {crowd};
    return j;
}

bool sameEntities(const std::vector<Entity>& a, const std::vector<Entity>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (a[i].model != b[i].model || a[i].position != b[i].position ||
            a[i].rotation != b[i].rotation || a[i].name != b[i].name)
            return false;
    return true;
}

TEST(SceneLoader, CrowdsAreDeterministicForASeedAndDifferAcrossSeeds) {
    for (const std::string layout : {"random", "grid"}) {
        SCOPED_TRACE(layout);
        const Scene a = loadJson(crowdScene(7, layout));
        const Scene b = loadJson(crowdScene(7, layout));
        const Scene c = loadJson(crowdScene(8, layout));
        ASSERT_EQ(a.entities.size(), 52u); // 2 plain entities + 50
        EXPECT_TRUE(sameEntities(a.entities, b.entities));
        EXPECT_FALSE(sameEntities(a.entities, c.entities));
    }
}

TEST(SceneLoader, RandomCrowdStaysInsideItsAreaAndUsesEveryModel) {
    const Scene s = loadJson(crowdScene(3, "random"));
    std::set<int> models;
    for (std::size_t i = 2; i < s.entities.size(); ++i) {
        const Entity& e = s.entities[i];
        EXPECT_GE(e.position.x, -20.0);
        EXPECT_LT(e.position.x, 20.0);
        EXPECT_GE(e.position.z, -40.0);
        EXPECT_LT(e.position.z, -10.0);
        EXPECT_EQ(e.position.y, 0.5);
        EXPECT_NEAR(glm::length(e.rotation), 1.0, 1e-12);
        // Yaw only: the world up axis is unchanged.
        expectNear(rotate(e.rotation, {0, 1, 0}), {0, 1, 0});
        models.insert(e.model);
    }
    EXPECT_EQ(models, (std::set<int>{0, 1, 2}));
}

TEST(SceneLoader, RandomCrowdIsPinnedToSplitMix64) {
    // Expected values computed independently from the splitmix64 reference (seed 1234567
    // yields 6457827717110365317, 3203168211198807973, 9817491932198370423, ...): per entity
    // model = next % 3, x = (next >> 11) * 2^-53, z = (next >> 11) * 2^-53. Pinned so that a
    // crowd is the same on every platform, compiler and standard library.
    json j = baseScene();
    j["models"].push_back({{"name", "s"}, {"generator", "sphere"}, {"radius", 2}});
    j["entities"] = json::array();
    j["crowds"] = {{{"models", {"b", "a", "s"}},
                    {"layout", "random"},
                    {"count", 3},
                    {"seed", 1234567},
                    {"area", {{"min", {0, 0}}, {"max", {1, 1}}}}}};
    const Scene s = loadJson(j);
    ASSERT_EQ(s.entities.size(), 3u);
    EXPECT_EQ(s.entities[0].model, 0);
    EXPECT_EQ(s.entities[0].position, glm::dvec3(0.17364409667091263, 0, 0.5322073040624192));
    EXPECT_EQ(s.entities[1].model, 1);
    EXPECT_EQ(s.entities[1].position, glm::dvec3(0.889529490618583, 0, 0.4230879388274831));
    EXPECT_EQ(s.entities[2].model, 0);
    EXPECT_EQ(s.entities[2].position, glm::dvec3(0.27528749941108965, 0, 0.43779353926260767));
    EXPECT_EQ(s.entities[2].rotation, glm::dquat(1, 0, 0, 0)); // random_yaw defaults to false
}

TEST(SceneLoader, CrowdAnimationAddsTheStartFrameLastInTheStream) {
    // The same crowd with and without random_frame: the first entity is placed identically (its
    // frame is drawn after its position and yaw), the crowd is deterministic, frames stay within
    // each model's frame count, fps is copied.
    auto scene = [](bool randomFrame) {
        json j = {{"models",
                   {{{"name", "t"}, {"generator", "tank"}, {"frames", 5}},
                    {{"name", "b"}, {"generator", "box"}}}},
                  {"crowds",
                   {{{"models", {"t", "b"}},
                     {"layout", "random"},
                     {"count", 40},
                     {"seed", 9},
                     {"random_yaw", true},
                     {"fps", 6},
                     {"random_frame", randomFrame},
                     {"area", {{"min", {0, 0}}, {"max", {10, 10}}}}}}}};
        return loadJson(j);
    };
    const Scene a = scene(true), b = scene(false);
    ASSERT_EQ(a.entities.size(), 40u);
    EXPECT_TRUE(sameEntities({a.entities[0]}, {b.entities[0]}));
    EXPECT_TRUE(sameEntities(a.entities, scene(true).entities));
    for (std::size_t i = 0; i < a.entities.size(); ++i)
        EXPECT_EQ(a.entities[i].frame, scene(true).entities[i].frame);
    std::set<int> starts;
    for (const Entity& e : a.entities) {
        EXPECT_EQ(e.fps, 6.0);
        EXPECT_GE(e.frame, 0);
        EXPECT_LT(e.frame, a.models[std::size_t(e.model)]->frameCount());
        if (e.model == 0) starts.insert(e.frame);
    }
    for (const Entity& e : b.entities) EXPECT_EQ(e.frame, 0);
    EXPECT_GT(starts.size(), 1u);
}

TEST(SceneLoader, GridCrowdCyclesModelsRowByRow) {
    json j = baseScene();
    j["crowds"] = {{{"models", {"b", "a"}},
                    {"count", 7},
                    {"origin", {1, 0.5, -2}},
                    {"spacing", {1.5, -3}},
                    {"columns", 3},
                    {"name", "squad"}}};
    const Scene s = loadJson(j);
    ASSERT_EQ(s.entities.size(), 9u);
    for (int k = 0; k < 7; ++k) {
        const Entity& e = s.entities[std::size_t(2 + k)];
        EXPECT_EQ(e.model, k % 2) << k;
        EXPECT_EQ(e.position, glm::dvec3(1 + 1.5 * (k % 3), 0.5, -2 - 3.0 * (k / 3))) << k;
        EXPECT_EQ(e.rotation, glm::dquat(1, 0, 0, 0));
        EXPECT_EQ(e.name, "squad#" + std::to_string(k));
    }
}

TEST(SceneLoader, EntitiesThenCrowdsKeepFileOrder) {
    json j = crowdScene(1, "grid");
    j["crowds"].push_back({{"models", {"s"}}, {"count", 2}});
    const Scene s = loadJson(j);
    ASSERT_EQ(s.entities.size(), 54u);
    EXPECT_EQ(s.entities[0].model, 0);
    EXPECT_EQ(s.entities[1].model, 1);
    EXPECT_EQ(s.entities[2].name, "crowds[0]#0");
    EXPECT_EQ(s.entities[52].name, "crowds[1]#0");
}

// ---------------------------------------------------------------------------------------------
// Edits.

TEST(SceneLoader, EditsAreParsedAndSortedByFrameStably) {
    json j = baseScene();
    j["edits"] = json::parse(R"([
        {"frame": 5, "model": "b", "op": "fill", "min": [0, 0, 0], "max": [2, 3, 4], "index": 7},
        {"frame": 2, "model": "a", "op": "set", "at": [3, 2, 2], "index": 255},
        {"frame": 5, "model": "b", "op": "clear", "min": [1, 1, 1], "max": [4, 4, 4]},
        {"frame": 0, "model": "b", "op": "set", "at": [0, 0, 0]}])");
    const Scene s = loadJson(j);
    ASSERT_EQ(s.edits.size(), 4u);
    EXPECT_EQ(s.edits[0].atFrame, 0);
    EXPECT_EQ(s.edits[0].index, 1); // default
    EXPECT_EQ(s.edits[1].atFrame, 2);
    EXPECT_EQ(s.edits[1].model, 1);
    EXPECT_EQ(s.edits[1].op, ScriptedEdit::Op::Set);
    EXPECT_EQ(s.edits[1].box, (Box3i{{3, 2, 2}, {4, 3, 3}}));
    EXPECT_EQ(s.edits[1].index, 255);
    EXPECT_EQ(s.edits[2].op, ScriptedEdit::Op::Fill); // same frame: file order kept
    EXPECT_EQ(s.edits[2].box, (Box3i{{0, 0, 0}, {2, 3, 4}}));
    EXPECT_EQ(s.edits[2].index, 7);
    EXPECT_EQ(s.edits[3].op, ScriptedEdit::Op::Clear);
    EXPECT_EQ(s.edits[3].index, 0);
}

// ---------------------------------------------------------------------------------------------
// .vox scene graphs, flattened. Synthetic files first (no reader needed): they cover
// reflections, which none of the staged files contains.

using IMat3 = glm::mat<3, 3, int>;

/// Columns are the images of the voxel axes (glm is column-major).
IMat3 cols(glm::ivec3 cx, glm::ivec3 cy, glm::ivec3 cz) {
    return IMat3(cx, cy, cz);
}

VoxFile syntheticFile() {
    VoxFile f;
    f.source = "/somewhere/synthetic.vox";
    f.palette = proceduralPalette();
    f.models.push_back(makeArrow(9)->frame(0)); // odd x size: the pivot is not the centre
    auto shell = makeShell({3, 4, 5})->frame(0);
    shell.set({0, 0, 0}, 6); // make it asymmetric
    f.models.push_back(shell);
    return f;
}

/// World centre -> palette index of every solid voxel of an entity, as the renderer sees it.
std::map<std::array<long long, 3>, int> worldVoxels(const Scene& s, const Entity& e) {
    const VoxelModel& m = *s.models[std::size_t(e.model)];
    const VoxelGrid& g = m.frame(e.frame);
    const EntityPose pose = makeEntityPose(e, g.dims(), s.render.voxelSize);
    std::map<std::array<long long, 3>, int> out;
    for (int z = 0; z < g.dims().z; ++z)
        for (int y = 0; y < g.dims().y; ++y)
            for (int x = 0; x < g.dims().x; ++x)
                if (auto v = g.at({x, y, z})) {
                    // World positions in units of a quarter voxel, rounded: exact enough to
                    // distinguish neighbours, immune to 1e-16 rotation noise.
                    const glm::dvec3 w =
                        pose.relativeWorld(glm::dvec3(x, y, z) + 0.5, glm::dvec3(0.0));
                    const glm::dvec3 q = w / (s.render.voxelSize * e.scale) * 4.0;
                    out[{std::llround(q.x), std::llround(q.y), std::llround(q.z)}] = v;
                }
    return out;
}

/// The same, straight from the instance definition: vox-world = R (v + ½ - floor(size/2)) + t,
/// world = position + S (vox-world) * voxel_size * scale.
std::map<std::array<long long, 3>, int> instanceVoxels(const VoxFile& f, const VoxInstance& inst,
                                                       glm::dvec3 position, double k) {
    const VoxelGrid& g = f.models[std::size_t(inst.model)];
    const glm::dvec3 pivot(g.dims() / 2);
    const glm::dmat3 S = worldFromVoxelSwizzle();
    std::map<std::array<long long, 3>, int> out;
    for (int z = 0; z < g.dims().z; ++z)
        for (int y = 0; y < g.dims().y; ++y)
            for (int x = 0; x < g.dims().x; ++x)
                if (auto v = g.at({x, y, z})) {
                    const glm::dvec3 vw =
                        glm::dmat3(inst.rotation) * (glm::dvec3(x, y, z) + 0.5 - pivot) +
                        glm::dvec3(inst.translation);
                    const glm::dvec3 w = position + S * vw * k;
                    const glm::dvec3 q = w / k * 4.0;
                    out[{std::llround(q.x), std::llround(q.y), std::llround(q.z)}] = v;
                }
    return out;
}

std::vector<IMat3> allSignedPermutations() {
    std::vector<IMat3> out;
    const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (const auto& p : perms)
        for (int signs = 0; signs < 8; ++signs) {
            IMat3 m(0);
            for (int c = 0; c < 3; ++c) m[c][p[c]] = (signs >> c & 1) ? -1 : 1;
            out.push_back(m);
        }
    return out;
}

TEST(SceneLoader, FlattenedInstancesPlaceEveryVoxelWhereTheInstanceDoes) {
    // All 48 signed permutations (24 rotations, 24 reflections), both models, odd sizes.
    VoxFile f = syntheticFile();
    int i = 0;
    for (const IMat3& r : allSignedPermutations())
        for (int m = 0; m < 2; ++m) {
            VoxInstance inst;
            inst.model = m;
            inst.rotation = r;
            inst.translation = {3 * i - 40, 7 - i, 2 * i};
            f.instances.push_back(inst);
            ++i;
        }
    const glm::dvec3 position(100.0, -3.0, 42.0);
    const double scale = 1.5;
    Scene s;
    s.render.voxelSize = 0.1;
    FlattenedVoxScene flat = flattenVoxScene(f, position, scale, false, s.render.voxelSize);
    ASSERT_EQ(flat.entities.size(), f.instances.size());
    s.models = flat.models;
    for (std::size_t n = 0; n < f.instances.size(); ++n) {
        SCOPED_TRACE(n);
        const Entity& e = flat.entities[n];
        EXPECT_EQ(e.scale, scale);
        EXPECT_EQ(worldVoxels(s, e), instanceVoxels(f, f.instances[n], position, 0.1 * scale));
    }
    // One model per distinct (file model, mirror axis): 2 models x (none, x, y, z) at most.
    EXPECT_LE(flat.models.size(), 8u);
    std::set<std::pair<int, int>> keys(flat.modelKeys.begin(), flat.modelKeys.end());
    EXPECT_EQ(keys.size(), flat.modelKeys.size());
}

TEST(SceneLoader, MirroredInstanceGetsTheMirroredGrid) {
    VoxFile f = syntheticFile();
    VoxInstance plain, mirrorX, mirrorZ;
    plain.model = mirrorX.model = mirrorZ.model = 0;
    mirrorX.rotation = cols({-1, 0, 0}, {0, 1, 0}, {0, 0, 1});
    mirrorZ.rotation = cols({1, 0, 0}, {0, 1, 0}, {0, 0, -1});
    f.instances = {plain, mirrorX, mirrorZ, mirrorX};
    const FlattenedVoxScene flat = flattenVoxScene(f, glm::dvec3(0.0), 1.0, false, 0.1);
    ASSERT_EQ(flat.entities.size(), 4u);
    ASSERT_EQ(flat.models.size(), 3u); // the second mirrorX instance shares its model
    EXPECT_EQ(flat.entities[3].model, flat.entities[1].model);

    const VoxelGrid& src = f.models[0];
    const glm::ivec3 d = src.dims();
    const VoxelGrid& gx = flat.models[std::size_t(flat.entities[1].model)]->frame(0);
    const VoxelGrid& gz = flat.models[std::size_t(flat.entities[2].model)]->frame(0);
    ASSERT_EQ(gx.dims(), d);
    for (int z = 0; z < d.z; ++z)
        for (int y = 0; y < d.y; ++y)
            for (int x = 0; x < d.x; ++x) {
                ASSERT_EQ(gx.at({x, y, z}), src.at({d.x - 1 - x, y, z}));
                ASSERT_EQ(gz.at({x, y, z}), src.at({x, y, d.z - 1 - z}));
            }
    EXPECT_EQ(gx.data(), mirrorGrid(src, 0).data());
    // A pure mirror needs no rotation; the pivot moves to size - floor(size/2) on that axis.
    EXPECT_EQ(flat.entities[1].rotation, glm::dquat(1, 0, 0, 0));
    EXPECT_EQ(flat.entities[2].rotation, glm::dquat(1, 0, 0, 0));
    EXPECT_EQ(*flat.entities[1].anchor, glm::dvec3(9 - 4, 2, 2));
    EXPECT_EQ(*flat.entities[0].anchor, glm::dvec3(4, 2, 2));
    EXPECT_EQ(flat.models[std::size_t(flat.entities[1].model)]->name(), "synthetic#0~mirror-x");
    EXPECT_EQ(flat.models[std::size_t(flat.entities[2].model)]->name(), "synthetic#0~mirror-z");
}

TEST(SceneLoader, MirrorGridTwiceIsTheIdentity) {
    const auto m = makeArrow(11);
    for (int a = 0; a < 3; ++a)
        EXPECT_EQ(mirrorGrid(mirrorGrid(m->frame(0), a), a).data(), m->frame(0).data()) << a;
}

TEST(SceneLoader, FlattenSkipsHiddenInstancesUnlessAsked) {
    VoxFile f = syntheticFile();
    VoxInstance a, b;
    a.model = 0;
    a.name = "shown";
    b.model = 1;
    b.hidden = true;
    b.translation = {1, 2, 3};
    f.instances = {a, b};
    const auto visible = flattenVoxScene(f, glm::dvec3(0.0), 1.0, false, 0.1);
    ASSERT_EQ(visible.entities.size(), 1u);
    EXPECT_EQ(visible.entities[0].name, "shown");
    EXPECT_EQ(visible.models.size(), 1u);
    const auto all = flattenVoxScene(f, glm::dvec3(0.0), 1.0, true, 0.1);
    ASSERT_EQ(all.entities.size(), 2u);
    EXPECT_EQ(all.entities[1].name, "synthetic[1]");
    // Position = S t voxel_size: voxel (1, 2, 3) -> world (1, 3, -2).
    expectNear(all.entities[1].position, glm::dvec3(0.1, 0.3, -0.2));
}

TEST(SceneLoader, FileWithoutSceneGraphGivesOneEntityPerModel) {
    const VoxFile f = syntheticFile();
    const auto flat = flattenVoxScene(f, {1, 2, 3}, 2.0, false, 0.1);
    ASSERT_EQ(flat.entities.size(), 2u);
    for (const Entity& e : flat.entities) {
        EXPECT_EQ(e.position, glm::dvec3(1, 2, 3));
        EXPECT_EQ(e.scale, 2.0);
        EXPECT_FALSE(e.anchor.has_value());
    }
}

TEST(SceneLoader, FlattenRejectsABadInstance) {
    VoxFile f = syntheticFile();
    VoxInstance bad;
    bad.rotation = cols({1, 1, 0}, {0, 1, 0}, {0, 0, 1});
    f.instances = {bad};
    EXPECT_THROW(flattenVoxScene(f, glm::dvec3(0.0), 1.0, false, 0.1), InputError);
    f.instances[0] = VoxInstance{};
    f.instances[0].model = 2;
    EXPECT_THROW(flattenVoxScene(f, glm::dvec3(0.0), 1.0, false, 0.1), InputError);
}

// Real files (need the .vox reader). Instance counts from scenes/vox/MANIFEST.md, which were
// cross-checked against ogt_vox.

std::size_t voxSceneEntities(const std::string& vox, bool includeHidden) {
    json j = {{"models", {{{"name", "v"}, {"generator", "voxel"}}}},
              {"vox_scenes", {{{"vox", "vox/" + vox}, {"include_hidden", includeHidden}}}}};
    return loadJson(j).entities.size();
}

TEST(SceneLoader, VoxScenesFlattenToTheManifestInstanceCounts) {
    EXPECT_EQ(voxSceneEntities("opengametools/test_multiple_model_scene.vox", false), 104u);
    EXPECT_EQ(voxSceneEntities("opengametools/test_multiple_model_scene.vox", true), 104u);
    EXPECT_EQ(voxSceneEntities("bevy_vox_scene/test.vox", true), 11u);
    EXPECT_EQ(voxSceneEntities("bevy_vox_scene/test.vox", false), 9u); // 2 of 11 hidden
    EXPECT_EQ(voxSceneEntities("dot_vox/axes.vox", false), 10u);
    EXPECT_EQ(voxSceneEntities("blender_magicavoxel/hierarchy.vox", false), 4u);
    EXPECT_EQ(voxSceneEntities("vox-reader.js/tree.vox", false), 3u);
    EXPECT_EQ(voxSceneEntities("mmmm/chr_cop1.vox", false), 1u);
}

TEST(SceneLoader, VoxScenePlacesInstancesLikeTheFileSays) {
    const fs::path p = kScenes / "vox/opengametools/test_multiple_model_scene.vox";
    const VoxFile f = readVoxFile(p);
    json j = {{"voxel_size", 0.05},
              {"models", {{{"name", "v"}, {"generator", "voxel"}}}},
              {"entities", {{{"model", "v"}}}},
              {"vox_scenes", {{{"vox", p.string()}, {"position", {1, 2, 3}}, {"scale", 2}}}}};
    const Scene s = loadJson(j);
    ASSERT_EQ(s.entities.size(), 1 + f.instances.size());
    std::size_t n = 1;
    for (const VoxInstance& inst : f.instances) {
        if (inst.hidden) continue;
        SCOPED_TRACE(n);
        const Entity& e = s.entities[n++];
        EXPECT_EQ(worldVoxels(s, e), instanceVoxels(f, inst, {1, 2, 3}, 0.05 * 2));
    }
    // Models are shared by instances: at most one per (file model, mirror).
    EXPECT_LE(s.models.size(), 1 + f.models.size() * 4);
}

TEST(SceneLoader, TwoVoxScenesOfOneFileShareModels) {
    json j = {{"models", {{{"name", "v"}, {"generator", "voxel"}}}},
              {"vox_scenes",
               {{{"vox", "vox/dot_vox/axes.vox"}},
                {{"vox", "vox/dot_vox/axes.vox"}, {"position", {5, 0, 0}}}}}};
    const Scene s = loadJson(j);
    ASSERT_EQ(s.entities.size(), 20u);
    for (std::size_t i = 0; i < 10; ++i) {
        EXPECT_EQ(s.entities[i].model, s.entities[10 + i].model);
        expectNear(s.entities[10 + i].position - s.entities[i].position, {5, 0, 0});
    }
}

TEST(SceneLoader, VoxModelsLoadOneModelOrAllFrames) {
    json j = {{"models",
               {{{"name", "cop"}, {"vox", "vox/mmmm/chr_cop1.vox"}},
                {{"name", "axes"}, {"vox", "vox/dot_vox/axes.vox"}, {"frames", "all"}},
                {{"name", "axis3"}, {"vox", "vox/dot_vox/axes.vox"}, {"model", 3}},
                {{"name", "pick"}, {"vox", "vox/dot_vox/axes.vox"}, {"frames", {3, 0}}}}},
              {"entities", {{{"model", "axes"}, {"frame", 3}, {"fps", 4}}}}};
    const Scene s = loadJson(j);
    ASSERT_EQ(s.models.size(), 4u);
    EXPECT_EQ(s.models[0]->frame(0).dims(), glm::ivec3(8, 6, 11));
    EXPECT_EQ(s.models[0]->frame(0).solidCount(), 267u);
    ASSERT_EQ(s.models[1]->frameCount(), 4);
    EXPECT_EQ(s.models[1]->frame(0).dims(), glm::ivec3(40));
    EXPECT_EQ(s.models[1]->frame(3).dims(), glm::ivec3(32)); // frames may differ in size
    EXPECT_EQ(s.models[2]->frame(0).dims(), glm::ivec3(32));
    ASSERT_EQ(s.models[3]->frameCount(), 2);
    EXPECT_EQ(s.models[3]->frame(0).dims(), glm::ivec3(32));
    EXPECT_EQ(s.entities[0].frame, 3);
}

TEST(SceneLoader, VoxModelErrorsNameTheJsonPath) {
    auto expectError = [](const json& j, const std::string& field, const std::string& reason) {
        try {
            loadJson(j);
            ADD_FAILURE() << "no error for " << j.dump();
        } catch (const InputError& e) {
            EXPECT_EQ(e.field(), field) << e.what();
            EXPECT_NE(e.reason().find(reason), std::string::npos) << e.what();
            EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
        }
    };
    expectError({{"models", {{{"name", "c"}, {"vox", "vox/mmmm/chr_cop1.vox"}, {"model", 1}}}}},
                "models[0].model", "the file has 1 model(s)");
    expectError(
        {{"models", {{{"name", "c"}, {"vox", "vox/dot_vox/axes.vox"}, {"frames", {0, 4}}}}}},
        "models[0].frames[1]", "out of range");
    expectError(
        {{"models", {{{"name", "c"}, {"vox", "vox/dot_vox/axes.vox"}, {"frames", "some"}}}}},
        "models[0].frames", "\"all\"");
    // The reader's own error (bad magic) is kept, prefixed by the scene path.
    expectError({{"models", {{{"name", "c"}, {"vox", "vox/dot_vox/not_a.vox"}}}}}, "models[0].vox",
                "not_a.vox");
    expectError({{"models", {{{"name", "c"}, {"vox", "vox"}}}}}, "models[0].vox", "directory");
}

} // namespace
} // namespace voxtier
