// The bad-input policy (issue 8), end to end through the CLI: every malformed file, scene,
// argument or exceeded limit gives a non-zero exit (never a crash or a hang) and exactly one
// line on stderr naming the file (when there is one), the field or chunk, and the reason.
// Each case prints "[ input    ] <class> | <what the user sees>" so the table in the issue note
// is this test's output.
#include "cli_support.hpp"
#include "image_files/image_files.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace voxtier {
namespace {

namespace fs = std::filesystem;

fs::path scratch() {
    return test::scratchDir("voxtier_bad_input");
}

std::string write(const std::string& name, const std::string& text) {
    return test::writeText(scratch(), name, text);
}

std::string repo(const std::string& rel) {
    return (fs::path(VOXTIER_SOURCE_DIR) / rel).string();
}

/// The exit status says whose the error is (apps/main.cpp): the command line itself (the line
/// then points to --help, which lists what each option allows), or an input file / the run.
constexpr int kCommandLineError = 2, kInputError = 1;

struct Case {
    std::string what;   ///< class of bad input, for the table
    std::string args;   ///< CLI arguments
    std::string expect; ///< substring the one line must contain (file, field or reason)
    int status = kInputError;
    std::string env = "";
};

void expectOneLineError(const Case& c) {
    const test::CliRun r = test::runCli(c.args, c.env);
    std::string line = r.err;
    if (!line.empty() && line.back() == '\n') line.pop_back();
    std::printf("[ input    ] %s | %s\n", c.what.c_str(), line.c_str());
    EXPECT_NE(r.status, -1) << c.what << ": the process died from a signal";
    EXPECT_NE(r.status, 0) << c.what << ": accepted bad input";
    EXPECT_EQ(r.status, c.status) << c.what << ": " << r.err;
    EXPECT_EQ(r.err.find("(see --help)") != std::string::npos, c.status == kCommandLineError)
        << c.what << ": " << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << c.what << ":\n" << r.err;
    EXPECT_EQ(r.err.rfind("voxtier: error: ", 0), 0u) << c.what << ": " << r.err;
    EXPECT_NE(r.err.find(c.expect), std::string::npos)
        << c.what << ": expected '" << c.expect << "' in: " << r.err;
}

const char* kScene =
    R"({"camera": {"size": [64, 48]}, "models": [{"name": "b", "generator": "box"}],
 "entities": [{"model": "b", "position": [0, 0, -5]}]})";

TEST(BadInput, MalformedVoxFilesAreOneLineErrorsInEveryCommand) {
    std::vector<Case> cases = {
        {"not a .vox (bad magic)", "info " + repo("scenes/vox/dot_vox/not_a.vox"), "not_a.vox"}};
    for (const auto& f : fs::directory_iterator(repo("fuzz/corpus/vox"))) {
        const std::string name = f.path().filename().string();
        if (name.rfind("ok_", 0) == 0 || name.rfind("graph_ok", 0) == 0 ||
            name.rfind("version_999", 0) == 0)
            continue;
        cases.push_back(
            {"vox: " + f.path().stem().string(), "info '" + f.path().string() + "'", name});
        cases.push_back({"vox via render: " + f.path().stem().string(),
                         "render '" + f.path().string() + "' --mode reference -o " +
                             (scratch() / "x.png").string(),
                         name});
    }
    cases.push_back(
        {"vox via bake", "bake " + repo("fuzz/corpus/vox/voxel_outside_size.vox"), "XYZI"});
    cases.push_back({"missing file", "info /nonexistent/model.vox", "/nonexistent/model.vox",
                     kCommandLineError});
    cases.push_back({"directory instead of a file", "info " + scratch().string(),
                     "is actually a directory: " + scratch().string(), kCommandLineError});
    for (const Case& c : cases) expectOneLineError(c);
}

TEST(BadInput, MalformedScenesNameTheFileAndTheJsonPath) {
    const std::vector<std::pair<std::string, std::string>> scenes = {
        {"JSON syntax error", R"({"models": [ )"},
        {"unknown key (typo)", R"({"modles": []})"},
        {"number overflow (1e999)", R"({"models": [{"name": "b", "generator": "box"}],)"
                                    R"( "entities": [{"model": "b", "position": [0, 1e999, 0]}]})"},
        {"zero quaternion", R"({"models": [{"name": "b", "generator": "box"}],)"
                            R"( "entities": [{"model": "b", "quaternion": [0, 0, 0, 0]}]})"},
        {"unknown model",
         R"({"models": [{"name": "b", "generator": "box"}], "entities": [{"model": "tank"}]})"},
        {"model too large",
         R"({"models": [{"name": "b", "generator": "box", "size": [300, 4, 4]}]})"},
        {"too many entities", R"({"models": [{"name": "b", "generator": "box"}],)"
                              R"( "crowds": [{"models": ["b"], "count": 2000000}]})"},
        {"image too large",
         R"({"camera": {"size": [20000, 100]}, "models": [{"name": "b", "generator": "box"}]})"},
        {"degenerate camera", R"({"camera": {"position": [1, 2, 3], "target": [1, 2, 3]},)"
                              R"( "models": [{"name": "b", "generator": "box"}]})"},
        {"hysteresis band inverted", R"({"selector": {"near_at": 50, "far_at": 40},)"
                                     R"( "models": [{"name": "b", "generator": "box"}]})"},
        {"missing .vox referenced by a scene",
         R"({"models": [{"name": "v", "vox": "nope/missing.vox"}]})"},
        {"broken .vox referenced by a scene", R"({"models": [{"name": "v", "vox": ")" +
                                                  repo("scenes/vox/dot_vox/not_a.vox") + R"("}]})"},
        {"models over the scene's voxel budget", R"({"models": [{"name": "t", "generator": "tank",)"
                                                 R"( "size": [256, 256, 256], "frames": 4096}]})"},
        {"edit outside the model",
         R"({"models": [{"name": "b", "generator": "box", "size": [4, 4, 4]}],)"
         R"( "edits": [{"frame": 1, "model": "b", "op": "set", "at": [9, 0, 0]}]})"},
    };
    int n = 0;
    for (const auto& [what, text] : scenes) {
        const std::string file = write("scene" + std::to_string(n++) + ".json", text);
        expectOneLineError(
            {"scene: " + what,
             "render '" + file + "' --mode reference -o " + (scratch() / "x.png").string(),
             fs::path(file).filename().string()});
    }
}

TEST(BadInput, BadArgumentsAreOneLineErrors) {
    const std::string scene = write("ok.json", kScene);
    const std::string vox = repo("scenes/vox/mmmm/chr_cop1.vox");
    std::vector<Case> commandLine = {
        {"unknown mode", "render " + scene + " --mode bogus", "--mode"},
        {"unknown near backend", "render " + scene + " --near-backend metal", "--near-backend"},
        {"not a number", "render " + scene + " --frame abc", "--frame"},
        {"negative frame", "render " + scene + " --frame -2", "--frame"},
        {"non-finite time", "render " + scene + " --time nan", "--time"},
        {"bad image size", "render " + vox + " --size 0x0", "--size"},
        {"bad view", "render " + vox + " --view north,up", "--view"},
        {"elevation beyond the pole", "render " + vox + " --view 10,100", "[-90, 90]"},
        {"negative sigma", "render " + vox + " --sigma -1", "--sigma"},
        {"sigma over the limit", "render " + vox + " --sigma 1000", "--sigma"},
        {"sigma over the limit on a scene", "render " + scene + " --sigma 17", "--sigma"},
        {"zero cache budget", "render " + scene + " --cache-mb 0", "--cache-mb"},
        {"cache budget beyond the limit", "render " + scene + " --cache-mb 1e9", "--cache-mb"},
        {"non-finite cache budget", "render " + scene + " --cache-mb nan", "--cache-mb"},
        {"view on a scene", "render " + scene + " --view 10,10", "--view"},
        {"distance on a scene", "render " + scene + " --distance 5", "--distance"},
        {"model index on a scene", "render " + scene + " --model 1", "--model"},
        {"negative model index", "render " + vox + " --model -1", "--model"},
        {"unknown option", "render " + scene + " --no-such-option", "--no-such-option"},
        {"unknown view set", "bake " + vox + " --views 27", "(expected: 26, 98, 218)"},
        {"unknown bake geometry", "bake " + vox + " --geometry spheres", "--geometry"},
        {"bake of two models", "bake " + vox + " " + vox, "one .vox file"},
        {"bench near entity list", "bench near --entities 10,x", "--entities"},
        {"bench near model source", "bench near --models lego", "(expected: vox, procedural)"},
        {"bench edits odd ball", "bench edits --size 7", "--size"},
        {"bench edits brick list", "bench edits --bricks 0,300", "--bricks"},
        {"no subcommand", "", "subcommand"},
    };
    // These need the input file to tell.
    const std::vector<Case> inputFile = {
        {"path without a camera path", "render " + scene + " --path", "camera_path"},
        {"model index out of range", "render " + vox + " --model 7", "--model"},
    };
    for (Case& c : commandLine) {
        c.status = kCommandLineError;
        expectOneLineError(c);
    }
    for (const Case& c : inputFile) expectOneLineError(c);
}

// Each option's allowed values and ranges are in its --help, where the errors above point.
TEST(BadInput, HelpListsTheAllowedValues) {
    const std::vector<std::pair<std::string, std::vector<std::string>>> expected = {
        {"render",
         {"{hybrid,near,far,reference}=hybrid", "{auto,vulkan,reference}=auto",
          "{simd,scalar}=simd", "--cache-mb FLOAT:in [1, 65536] MiB", "--sigma FLOAT:in (0, 16]",
          "--size WxH:W, H in [1, 16384]", "--frame INT:>= 0", "ELEVATION in [-90, 90]"}},
        {"bake",
         {"--views INT:{26,98,218}=26", "{quads,boxes}", "{packet8,packet16,stream}",
          "--repeats INT:>= 1=5", "model TEXT:FILE"}},
        {"bench",
         {"--warmup INT:>= 1", "--entity-counts TEXT:a,b,... each in [1, 100000]",
          "--budget VPX:in [0.01, 64] vpx", "{simd,scalar}=simd"}},
        {"bench near", {"--entities INT:in [1, 1000000]=[10,100,1000]", "{vox,procedural}=vox"}},
        {"bench edits", {"--size INT:even, in [2, 256]=64", "--bricks INT:in [0, 256]=[0,16,32]"}},
        {"info", {"file TEXT:FILE"}},
    };
    for (const auto& [command, lines] : expected) {
        const test::CliRun r = test::runCli(command + " --help");
        EXPECT_EQ(r.status, 0) << command << ": " << r.err;
        for (const std::string& line : lines)
            EXPECT_NE(r.out.find(line), std::string::npos) << command << " --help lacks " << line;
    }
}

// --size and --sigma override a scene's camera size and sigma (instead of being ignored).
TEST(BadInput, SizeAndSigmaOverrideTheScene) {
    const std::string scene = write("override.json", kScene);
    auto render = [&](const std::string& sigma) {
        const std::string out = (scratch() / ("override_" + sigma + ".png")).string();
        const test::CliRun r = test::runCli(
            "render " + scene + " --mode reference --size 320x240 --sigma " + sigma + " -o " + out);
        EXPECT_EQ(r.status, 0) << r.err;
        return readColorImage(out);
    };
    const Image one = render("1"), two = render("2");
    EXPECT_EQ(one.width, 320);
    EXPECT_EQ(one.height, 240);
    // The sprite keeps its screen size; twice the virtual pixels per voxel makes each virtual
    // pixel, and so the one-virtual-pixel outline, half as wide on screen.
    auto outline = [](const Image& im) {
        return std::count(im.color.begin(), im.color.end(), packRgba(0, 0, 0));
    };
    EXPECT_GT(outline(one), 0);
    EXPECT_LT(outline(two), outline(one));
}

// Without any Vulkan driver the GPU modes fail with one clear line; the CPU modes still work,
// and so does the default hybrid frame (--near-backend auto), which says in one line that the
// CPU reference draws its near tier and why.
TEST(BadInput, MissingVulkanDeviceFailsGpuModesOnlyOneLine) {
    const std::string scene = write("novk.json", kScene);
    const std::string noDriver =
        "VK_DRIVER_FILES=/nonexistent/none.json VK_ICD_FILENAMES=/nonexistent/none.json";
    for (const char* args : {"--mode near", "--mode hybrid --near-backend vulkan"})
        expectOneLineError(
            {std::string("no Vulkan device, ") + args,
             "render " + scene + " " + args + " -o " + (scratch() / "x.png").string(),
             "no Vulkan device", kInputError, noDriver});
    for (const char* mode : {"reference", "far", "hybrid"}) {
        const test::CliRun r = test::runCli("render " + scene + " --mode " + mode + " -o " +
                                                (scratch() / "y.png").string(),
                                            noDriver);
        EXPECT_EQ(r.status, 0) << mode << ": " << r.err;
        std::printf("[ input    ] no Vulkan device, --mode %s | works (exit 0)\n", mode);
        if (std::string(mode) == "hybrid") {
            // The scene has near entities: the CPU reference drew them, and the output says so.
            EXPECT_NE(r.out.find("near tier: CPU reference (--near-backend auto: no Vulkan device"),
                      std::string::npos)
                << r.out;
            EXPECT_NE(r.out.find("; near tier on the CPU reference)"), std::string::npos) << r.out;
        }
    }
}

} // namespace
} // namespace voxtier
