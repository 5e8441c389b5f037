// ARCHITECTURE.md's module rules as a test: a module includes only modules to its left, Embree
// appears only in impostor_cache, Vulkan headers only in device and volumetric,
// OpenImageIO only in image_files/openimageio_module.cpp (no module of the renderer, core to
// compose, touches an image file format), and lod/ plans while compose/ draws. Reads the sources,
// so a forbidden include fails here before it becomes a habit.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

const std::map<std::string, std::set<std::string>> kAllowed = {
    {"core", {"core"}},
    {"device", {"core", "device"}},
    {"volumetric", {"core", "device", "volumetric"}},
    {"impostor_cache", {"core", "device", "impostor_cache"}},
    {"lod", {"core", "lod"}},
    {"compose", {"core", "device", "volumetric", "impostor_cache", "lod", "compose"}},
    {"image_files", {"core", "image_files"}},
    {"apps",
     {"core", "device", "volumetric", "impostor_cache", "lod", "compose", "image_files", "apps"}},
};

std::vector<fs::path> sourcesOf(const std::string& module) {
    std::vector<fs::path> out;
    const fs::path dir = fs::path(VOXTIER_SOURCE_DIR) / module;
    if (!fs::exists(dir)) return out;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        const auto ext = e.path().extension().string();
        if (ext == ".cpp" || ext == ".hpp" || ext == ".h" || ext == ".glsl" || ext == ".frag" ||
            ext == ".vert" || ext == ".comp")
            out.push_back(e.path());
    }
    return out;
}

TEST(Architecture, ModulesIncludeOnlyLeftwardModules) {
    const std::regex include(R"re(#\s*include\s*"([a-z_]+)/)re");
    for (const auto& [module, allowed] : kAllowed)
        for (const fs::path& file : sourcesOf(module)) {
            std::ifstream in(file);
            std::string line;
            int n = 0;
            while (std::getline(in, line)) {
                ++n;
                std::smatch m;
                if (std::regex_search(line, m, include) && kAllowed.count(m[1]) &&
                    !allowed.count(m[1]))
                    ADD_FAILURE() << file.string() << ":" << n << ": " << module
                                  << " must not include " << m[1];
            }
        }
}

TEST(Architecture, ThirdPartyLibrariesStayInTheirModules) {
    struct Rule {
        std::string pattern;
        std::set<std::string> modules; // where it may appear
    };
    const Rule rules[] = {
        {"<embree3/", {"impostor_cache"}},
        {"<vulkan/", {"device", "volumetric"}},
        {"<OpenImageIO/", {"image_files"}},
    };
    for (const auto& [module, allowed] : kAllowed)
        for (const fs::path& file : sourcesOf(module)) {
            std::ifstream in(file);
            std::string line;
            while (std::getline(in, line))
                for (const Rule& r : rules) {
                    if (line.find("#include") != std::string::npos &&
                        line.find(r.pattern) != std::string::npos) {
                        EXPECT_TRUE(r.modules.count(module))
                            << file.string() << " includes " << r.pattern;
                    }
                }
        }
    // OpenImageIO only in the one file that is its module (loaded on first use) and that a build
    // with VOXTIER_IMAGE_FILES=OFF leaves out.
    for (const fs::path& file : sourcesOf("image_files")) {
        std::ifstream in(file);
        const std::string text((std::istreambuf_iterator<char>(in)), {});
        if (text.find("#include <OpenImageIO/") != std::string::npos) {
            EXPECT_EQ(file.filename().string(), "openimageio_module.cpp") << file.string();
        }
    }
}

// Tier x backend in the folders (issue 36): volumetric/ is the near tier, impostor_cache/ the far
// tier with its own GPU pass; the device module knows neither tier; lod/ links core alone.
TEST(Architecture, NoFarTierSourceUnderVolumetric) {
    const std::vector<fs::path> files = sourcesOf("volumetric");
    ASSERT_FALSE(files.empty());
    for (const fs::path& file : files) {
        const std::string name = file.filename().string();
        EXPECT_EQ(name.find("far"), std::string::npos) << file.string() << " is the far tier's";
    }
}

TEST(Architecture, DeviceIncludesNeitherTier) {
    const std::regex include(R"re(#\s*include\s*"(volumetric|impostor_cache|lod|compose)/)re");
    const std::vector<fs::path> files = sourcesOf("device");
    ASSERT_FALSE(files.empty());
    for (const fs::path& file : files) {
        std::ifstream in(file);
        const std::string text((std::istreambuf_iterator<char>(in)), {});
        EXPECT_FALSE(std::regex_search(text, include)) << file.string() << " includes a tier";
    }
}

TEST(Architecture, LodLinksCoreAlone) {
    std::ifstream in(fs::path(VOXTIER_SOURCE_DIR) / "lod" / "CMakeLists.txt");
    const std::string text((std::istreambuf_iterator<char>(in)), {});
    std::smatch m;
    ASSERT_TRUE(std::regex_search(text, m, std::regex(R"re(voxtier_module\(lod([^)]*)\))re")));
    const std::string args = m[1];
    std::smatch deps;
    ASSERT_TRUE(std::regex_search(args, deps, std::regex(R"re(PUBLIC_DEPS\s+([^\n]*))re")));
    EXPECT_EQ(std::string(deps[1]), "voxtier_core") << "lod/ links " << deps[1];
    EXPECT_EQ(args.find("PRIVATE_DEPS"), std::string::npos) << "lod/ links privately: " << args;
}

/// A source file's text with its comments blanked out (a comment may name anything).
std::string codeOf(const fs::path& file) {
    std::ifstream in(file);
    const std::string text((std::istreambuf_iterator<char>(in)), {});
    static const std::regex comment(R"re(//[^\n]*|/\*[\s\S]*?\*/)re");
    return std::regex_replace(text, comment, " ");
}

// ARCHITECTURE.md: lod/ plans, compose/ draws. The selection, the error budget, the planner and its
// cost model are defined in lod/ alone; compose/ asks FramePlanner for a plan and hands back
// what drawing it cost, and neither defines nor calls a step of the policy itself.
TEST(Architecture, LodPlansComposeDraws) {
    // The policy's steps (and, for compose, the names they had there before issue 29).
    const std::vector<std::string> steps = {"planBudgetView",       "keepAffordableBakes",
                                            "predictedBudgetUnits", "bestBudgetUnits",
                                            "budgetUnitsPerVpx",    "farSavingMs"};
    const std::vector<std::string> oldComposeSteps = {"planFrame", "measureCosts"};
    const std::vector<std::string> types = {"BakeCosts", "ErrorBudgetViews", "FramePlanner",
                                            "CostModel", "EntityPlan"};
    const auto call = [](const std::string& name) { return std::regex("\\b" + name + "\\s*\\("); };
    const auto definition = [](const std::string& name) {
        return std::regex("\\b(struct|class)\\s+" + name + "\\b");
    };
    std::string lod;
    for (const fs::path& file : sourcesOf("lod")) lod += codeOf(file);
    // The names are real: a rename in lod/ must rename them here too, or the check below
    // would pass on names nothing uses.
    for (const std::string& name : steps)
        EXPECT_TRUE(std::regex_search(lod, call(name))) << "lod/ defines no " << name;
    for (const std::string& name : types)
        EXPECT_TRUE(std::regex_search(lod, definition(name))) << "lod/ defines no " << name;

    const std::vector<fs::path> compose = sourcesOf("compose");
    ASSERT_FALSE(compose.empty());
    for (const fs::path& file : compose) {
        const std::string stem = file.stem().string();
        EXPECT_NE(stem.rfind("error_budget", 0), 0u) << file.string() << ": the budget is lod/'s";
        EXPECT_NE(stem.rfind("frame_planner", 0), 0u) << file.string() << ": the plan is lod/'s";
        const std::string code = codeOf(file);
        for (const auto* names : {&steps, &oldComposeSteps})
            for (const std::string& name : *names)
                EXPECT_FALSE(std::regex_search(code, call(name)))
                    << file.string() << ": " << name << " is a step of the LOD policy (lod/)";
        for (const std::string& name : types)
            EXPECT_FALSE(std::regex_search(code, definition(name)))
                << file.string() << " defines " << name << ", which belongs to lod/";
    }
}

} // namespace
