// `voxtier bake SCENE --cache-dir DIR` bakes what the scene's renders ask for (issue 38): the
// views its still and camera path use, with a margin, not the whole ladder. On a short path of
// the default scene under the error-budget selector (ladder_cap 16, the issue's case, made
// small): the bake holds what the path bakes lazily within 2x, the next render of the path bakes
// nothing and draws the lazy render's images byte for byte; every size printed is in MiB.
#include "cli_support.hpp"
#include "impostor_cache/snapshot_store.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace voxtier {
namespace {

namespace fs = std::filesystem;

/// The renders' image size, small for CI (the bake takes it too: it changes the views).
const std::string kSize = " --size 240x136";
/// Path frames of the test scene: the default path's camera moves, 10x faster.
constexpr int kFrames = 16;

fs::path scratch() {
    return test::scratchDir("voxtier_path_bake", /*perTest=*/true);
}

std::string quoted(const fs::path& p) {
    return "'" + p.string() + "'";
}

std::string readText(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

/// scenes/default.json under the error-budget selector with its defaults (ladder_cap 16), its
/// camera path 10x faster (kFrames frames), model files by absolute path; `edits` added.
fs::path testScene(const fs::path& dir, const nlohmann::json& edits = nlohmann::json::array()) {
    const std::string scenes = std::string(VOXTIER_SOURCE_DIR) + "/scenes/";
    nlohmann::json s = nlohmann::json::parse(std::ifstream(scenes + "default.json"));
    s["selector"] = {{"metric", "error_budget"}};
    for (auto& key : s["camera_path"]["keys"]) key["time"] = key["time"].get<double>() / 10.0;
    for (auto* list : {&s["models"], &s["vox_scenes"]})
        for (auto& m : *list)
            if (m.contains("vox")) m["vox"] = scenes + m["vox"].get<std::string>();
    if (!edits.empty()) s["edits"] = edits;
    const fs::path file = dir / "scene.json";
    std::ofstream(file) << s.dump();
    return file;
}

/// The sum of a --csv column over its frames.
long long csvSum(const fs::path& csv, const std::string& column) {
    std::istringstream in(readText(csv));
    std::string header, line;
    std::getline(in, header);
    std::vector<std::string> names;
    std::stringstream hs(header);
    for (std::string n; std::getline(hs, n, ',');) names.push_back(n);
    const auto at = std::find(names.begin(), names.end(), column);
    EXPECT_NE(at, names.end()) << column << " not in " << header;
    long long sum = 0;
    while (std::getline(in, line)) {
        std::stringstream ls(line);
        std::string cell;
        for (std::ptrdiff_t k = 0; k <= at - names.begin(); ++k) std::getline(ls, cell, ',');
        sum += std::stoll(cell);
    }
    return sum;
}

/// The snapshots a directory's packs hold, read back through the pack decoder.
std::size_t snapshotsIn(const fs::path& dir) {
    std::size_t n = 0;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file() && e.path().extension() == ".pack") {
            const std::string bytes = readText(e.path());
            n += decodeSnapshotPack(std::vector<std::uint8_t>(bytes.begin(), bytes.end()))
                     .entries.size();
        }
    return n;
}

/// The bytes of a directory's packs.
std::uint64_t packBytes(const fs::path& dir) {
    std::uint64_t n = 0;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file() && e.path().extension() == ".pack") n += e.file_size();
    return n;
}

/// The first number after `prefix` in `text` (-1 if the prefix is not there).
double numberAfter(const std::string& text, const std::string& prefix) {
    const auto at = text.find(prefix);
    return at == std::string::npos ? -1.0 : std::strtod(text.c_str() + at + prefix.size(), nullptr);
}

/// "render SCENE --path" with the flags every render here takes: the image depends only on the
/// arguments (the cost bound learns from timings; the CPU reference on any machine).
std::string pathRender(const fs::path& scene, const fs::path& out) {
    return "render " + quoted(scene) + kSize +
           " --no-cost-bound --near-backend reference --far-backend cpu --path -o " +
           quoted(out / "f.png") + " --csv " + quoted(out / "frames.csv");
}

TEST(PathBake, BakesWhatThePathBakesLazilyAndTheNextRenderBakesNothing) {
    const fs::path d = scratch();
    const fs::path scene = testScene(d);
    fs::create_directories(d / "lazy");
    fs::create_directories(d / "warm");
    const test::CliRun lazy = test::runCli(pathRender(scene, d / "lazy"));
    ASSERT_EQ(lazy.status, 0) << lazy.err;
    const long long lazyBakes = csvSum(d / "lazy" / "frames.csv", "far_bakes");
    ASSERT_GT(lazyBakes, 50);

    const test::CliRun bake =
        test::runCli("bake " + quoted(scene) + kSize + " --cache-dir " + quoted(d / "cache"));
    ASSERT_EQ(bake.status, 0) << bake.err;
    EXPECT_NE(bake.out.find("the still camera and the camera path's " + std::to_string(kFrames) +
                            " frames, with a margin of 0 degrees"),
              std::string::npos)
        << bake.out;
    // What it wrote, counted in the packs: at least what the path bakes lazily (every frame's
    // views), at most twice that, and what its estimate said.
    const std::size_t baked = snapshotsIn(d / "cache");
    EXPECT_GE(baked, std::size_t(lazyBakes));
    EXPECT_LE(baked, std::size_t(2 * lazyBakes));
    EXPECT_EQ(numberAfter(bake.out, "estimate: "), double(baked)) << bake.out;

    // The path again, reading the directory: no frame bakes, every image is the lazy one.
    const test::CliRun warm =
        test::runCli(pathRender(scene, d / "warm") + " --cache-dir " + quoted(d / "cache"));
    ASSERT_EQ(warm.status, 0) << warm.err;
    EXPECT_EQ(csvSum(d / "warm" / "frames.csv", "far_bakes"), 0) << warm.out;
    EXPECT_NE(warm.out.find(" 0 written"), std::string::npos) << warm.out;
    for (int f = 0; f < kFrames; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "f_%04d.png", f);
        EXPECT_EQ(readText(d / "lazy" / name), readText(d / "warm" / name)) << name;
    }
    // The still (the static camera, not on the path's frames) and lone frames (a fresh
    // selector, the default margin) bake nothing either.
    for (const std::string frame : {"", " --frame 5", " --frame 11"}) {
        const test::CliRun lone =
            test::runCli("render " + quoted(scene) + kSize + frame + " -o " +
                         quoted(d / "lone.png") + " --cache-dir " + quoted(d / "cache"));
        ASSERT_EQ(lone.status, 0) << lone.err;
        EXPECT_NE(lone.out.find(", 0 bakes,"), std::string::npos) << frame << ": " << lone.out;
    }
}

// --margin none bakes the still and the path in order only; the default adds lone frames' views,
// a margin in degrees more again, and a lone frame the path alone does not cover bakes.
TEST(PathBake, TheMarginWidensWhatIsBaked) {
    const fs::path d = scratch();
    const fs::path scene = testScene(d);
    std::vector<double> counts;
    for (const std::string margin : {"none", "0", "2"}) {
        const test::CliRun bake = test::runCli("bake " + quoted(scene) + kSize + " --margin " +
                                               margin + " --cache-dir " + quoted(d / margin));
        ASSERT_EQ(bake.status, 0) << bake.err;
        counts.push_back(double(snapshotsIn(d / margin)));
    }
    EXPECT_LT(counts[0], counts[1]);
    EXPECT_LT(counts[1], counts[2]);
    int lonelyBakes = 0;
    for (const int f : {1, 8, 13}) {
        const test::CliRun lone =
            test::runCli("render " + quoted(scene) + kSize + " --frame " + std::to_string(f) +
                         " -o " + quoted(d / "l.png") + " --cache-dir " + quoted(d / "none"));
        ASSERT_EQ(lone.status, 0) << lone.err;
        lonelyBakes += int(numberAfter(lone.out, " switches, "));
    }
    EXPECT_GT(lonelyBakes, 0) << "the lone frames need no more than the path: a weak test scene";
}

// A scripted edit: the bake bakes the edited model frame's views after the edit, so the render
// bakes only the refreshes of the views it held from before the edit (which are never read from
// a directory: SnapshotCache refreshes them where the edit reaches).
TEST(PathBake, AfterAScriptedEditTheRenderOnlyRefreshes) {
    const fs::path d = scratch();
    const fs::path scene =
        testScene(d, nlohmann::json::parse(R"([{"frame": 8, "model": "crate", "op": "clear",
                                       "min": [0, 0, 5], "max": [10, 10, 10]}])"));
    const test::CliRun bake =
        test::runCli("bake " + quoted(scene) + kSize + " --cache-dir " + quoted(d / "cache"));
    ASSERT_EQ(bake.status, 0) << bake.err;
    EXPECT_NE(bake.out.find("crate frame 0 (edited by path frame 8)"), std::string::npos)
        << bake.out;
    fs::create_directories(d / "warm");
    const test::CliRun warm =
        test::runCli(pathRender(scene, d / "warm") + " --cache-dir " + quoted(d / "cache"));
    ASSERT_EQ(warm.status, 0) << warm.err;
    const fs::path csv = d / "warm" / "frames.csv";
    EXPECT_GT(csvSum(csv, "far_refreshes"), 0);
    EXPECT_EQ(csvSum(csv, "far_bakes"), csvSum(csv, "far_refreshes"));
}

// Two shards of a scene's bake write the unsharded bake's packs between them, byte for byte.
TEST(PathBake, ShardsTogetherAreTheUnshardedBake) {
    const fs::path d = scratch();
    const fs::path scene = testScene(d);
    const std::string bake = "bake " + quoted(scene) + kSize + " --cache-dir ";
    ASSERT_EQ(test::runCli(bake + quoted(d / "whole")).status, 0);
    for (const char* shard : {"0/2", "1/2"})
        ASSERT_EQ(test::runCli(bake + quoted(d / "sharded") + " --shard " + shard).status, 0);
    std::size_t packs = 0;
    for (const auto& e : fs::recursive_directory_iterator(d / "whole")) {
        if (!e.is_regular_file() || e.path().extension() != ".pack") continue;
        ++packs;
        EXPECT_EQ(readText(e.path()), readText(d / "sharded" / fs::relative(e.path(), d / "whole")))
            << e.path();
    }
    EXPECT_GT(packs, 10u);
}

// Issue 38 item 6: every size the bake and the cache line print is binary megabytes, "MiB",
// and the figures agree with each other and with the bytes on disk.
TEST(PathBake, EverySizeIsPrintedInMiB) {
    const fs::path d = scratch();
    const fs::path scene = testScene(d);
    const test::CliRun bake =
        test::runCli("bake " + quoted(scene) + kSize + " --cache-dir " + quoted(d / "cache"));
    ASSERT_EQ(bake.status, 0) << bake.err;
    EXPECT_FALSE(std::regex_search(bake.out, std::regex("\\bMB\\b"))) << bake.out;
    const auto mib = [](double bytes) {
        char text[32];
        std::snprintf(text, sizeof text, "%.2f MiB", bytes / double(1 << 20));
        return std::string(text);
    };
    // The estimate's bytes are exact for an empty directory; the summary's bytes written are
    // the packs', each written once, and the cache line gives the same bytes.
    const double packs = double(packBytes(d / "cache"));
    EXPECT_NE(bake.out.find(" pack files, " + mib(packs) + ", "), std::string::npos) << bake.out;
    std::smatch written;
    ASSERT_TRUE(std::regex_search(bake.out, written, std::regex("([0-9]+) bytes written")));
    EXPECT_EQ(std::stod(written[1].str()), packs);
    EXPECT_NE(bake.out.find("written (" + mib(packs) + ", "), std::string::npos) << bake.out;

    // A refusal says the estimate's own figure: the whole ladder of the test scene at
    // ladder_cap 16 is over 256 MiB.
    const test::CliRun ladder = test::runCli(
        "bake " + quoted(scene) + " --ladder --frames all --cache-dir " + quoted(d / "ladder"));
    EXPECT_EQ(ladder.status, 1) << ladder.err;
    std::smatch onDisk;
    ASSERT_TRUE(std::regex_search(ladder.out, onDisk, std::regex(", ([0-9.]+ MiB) on disk")))
        << ladder.out;
    EXPECT_NE(ladder.err.find("snapshots, " + onDisk[1].str() + " on disk (over 256.00 MiB)"),
              std::string::npos)
        << ladder.err;
    EXPECT_EQ(test::lineCount(ladder.err), 1u) << ladder.err;
    EXPECT_FALSE(fs::exists(d / "ladder") && !fs::is_empty(d / "ladder"));
    // ... and the path bake's second estimate line is that ladder's figure.
    std::smatch whole;
    ASSERT_TRUE(std::regex_search(ladder.out, whole,
                                  std::regex("estimate: ([0-9]+ snapshots in [^\n]* on disk)")));
    EXPECT_NE(bake.out.find("(--ladder --frames all) would be " + whole[1].str()),
              std::string::npos)
        << bake.out << "\n"
        << ladder.out;
}

TEST(PathBake, OptionsOfOtherBakesAreOneLineErrors) {
    const fs::path d = scratch();
    const fs::path scene = testScene(d);
    const std::string vox = quoted(fs::path(VOXTIER_SOURCE_DIR) / "scenes/vox/mmmm/chr_cop1.vox");
    const std::string dir = " --cache-dir " + quoted(d / "cache");
    const struct {
        std::string args, expect;
    } cases[] = {
        {"bake " + quoted(scene) + dir + " --frames all", "--frames: applies to --ladder bakes"},
        {"bake " + quoted(scene) + dir + " --frame 1", "--frame: applies to --ladder bakes"},
        {"bake " + quoted(scene) + dir + " --mode near", "--mode: near renders draw no snapshot"},
        {"bake " + quoted(scene) + dir + " --margin 90", "--margin: expected degrees in [0, 45]"},
        {"bake " + vox + dir + " --margin 1", "--margin: applies to a scene's bake"},
        {"bake " + quoted(scene) + dir + " --ladder --size 10x10", "--size: applies to a scene's"},
        {"bake " + vox + " --ladder", "--ladder: applies with --cache-dir only"},
    };
    for (const auto& c : cases) {
        const test::CliRun r = test::runCli(c.args);
        EXPECT_NE(r.status, 0) << c.args;
        EXPECT_EQ(test::lineCount(r.err), 1u) << c.args << ": " << r.err;
        EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << ": " << r.err;
    }
    EXPECT_FALSE(fs::exists(d / "cache"));
}

} // namespace
} // namespace voxtier
