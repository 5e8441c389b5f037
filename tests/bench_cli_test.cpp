// `voxtier bench` end to end, at the smallest size (--smoke: tiny images and entity counts, one
// timed pass, one sweep point): the outputs exist and agree with each other and with what can be
// worked out without the bench. No timings are asserted (the machine is shared).
//
// The smoke run is made once (BenchSmoke below), and every test asserts one claim about it.
// CTest runs each test case as its own process, so the run is shared through a folder in the
// build tree, made under a lock by the first process and reused by the others while neither the
// CLI nor this test has been rebuilt.
#include "cli_support.hpp"
#include "compose/frame_figures.hpp"
#include "core/scene_loader.hpp"
#include "core/sprite.hpp"
#include "core/view_set.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/file.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace voxtier {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::CliRun;
using test::runCli;

struct ScratchDir {
    fs::path path;
    ScratchDir() {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        path = fs::temp_directory_path() /
               ("voxtier_bench_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(path);
        fs::create_directories(path);
    }
    ~ScratchDir() {
        std::error_code ec;
        fs::remove_all(path, ec);
    }
};

std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

std::string fixed(double v, int decimals) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

/// A scene where the far tier must equal the near tier exactly (CONTRACT.md §4): parallel view
/// rays straight down, entities turned by multiples of 90 degrees, so every sprite's view is the
/// canonical +Z snapshot with a quarter-turn roll.
void writeExactScene(const fs::path& file) {
    json models =
        json::array({{{"name", "tank"}, {"generator", "tank"}, {"seed", 3}, {"frames", 2}},
                     {{"name", "arrow"}, {"generator", "arrow"}},
                     {{"name", "box"}, {"generator", "box"}, {"size", {6, 4, 3}}, {"index", 5}}});
    json entities = json::array();
    const char* names[] = {"tank", "arrow", "box"};
    for (int k = 0; k < 9; ++k)
        entities.push_back({{"model", names[k % 3]},
                            {"position", {-4.0 + 4.0 * (k % 3), 0.0, -4.0 + 4.0 * (k / 3)}},
                            {"rotation_deg", {0, 90 * (k % 4), 0}},
                            {"frame", k % 6 == 3 ? 1 : 0}}); // the tank (k % 3 == 0) has two frames
    const json scene = {{"view_mode", "parallel"},
                        {"camera",
                         {{"position", {0, 16, 0}},
                          {"target", {0, 0, 0}},
                          {"up", {0, 0, -1}},
                          {"fov_y", 50},
                          {"size", {240, 136}}}},
                        {"models", models},
                        {"entities", entities}};
    std::ofstream(file) << scene.dump(1);
}

/// Splits one CSV line (RFC 4180 quoting).
std::vector<std::string> csvFields(const std::string& line) {
    std::vector<std::string> out(1);
    bool quoted = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
        const char c = line[i];
        if (quoted) {
            if (c == '"' && i + 1 < line.size() && line[i + 1] == '"')
                out.back() += '"', ++i;
            else if (c == '"')
                quoted = false;
            else
                out.back() += c;
        } else if (c == '"') {
            quoted = true;
        } else if (c == ',') {
            out.emplace_back();
        } else {
            out.back() += c;
        }
    }
    return out;
}

/// The first `n` lines of `text` ("" for those it lacks).
std::vector<std::string> linesOf(const std::string& text, std::size_t n) {
    std::vector<std::string> lines(n);
    std::istringstream in(text);
    for (std::string& line : lines) std::getline(in, line);
    return lines;
}

/// The cells of a markdown table row, trimmed.
std::vector<std::string> tableCells(const std::string& line) {
    std::vector<std::string> cells;
    std::istringstream in(line);
    std::string cell;
    std::getline(in, cell, '|'); // before the first bar
    while (std::getline(in, cell, '|')) {
        const auto a = cell.find_first_not_of(' '), b = cell.find_last_not_of(' ');
        cells.push_back(a == std::string::npos ? "" : cell.substr(a, b - a + 1));
    }
    if (!cells.empty() && cells.back().empty()) cells.pop_back(); // after the last bar
    return cells;
}

/// The line of `text` that contains `needle` ("" when none does).
std::string lineWith(const std::string& text, const std::string& needle) {
    const auto at = text.find(needle);
    if (at == std::string::npos) return "";
    const auto start = text.rfind('\n', at) == std::string::npos ? 0 : text.rfind('\n', at) + 1;
    return text.substr(start, text.find('\n', at) - start);
}

/// The first line of `text` that starts with `prefix` ("" when none does).
std::string lineStarting(const std::string& text, const std::string& prefix) {
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);)
        if (line.starts_with(prefix)) return line;
    return "";
}

const std::vector<std::string> kModes = {
    "near_vulkan", "near_vulkan_fragment", "near_reference", "far", "hybrid", "hybrid_gpu_far"};
const std::vector<std::string> kScenes = {"tank_army", "exact"};

// ---------------------------------------------------------------------------------------------
// The smoke run, made once.

struct SmokeRun {
    int status = -1;
    std::string out, err; ///< the command's stdout and stderr
    fs::path dir;         ///< its output folder
    json results;         ///< results.json
    std::string csv, report;
};

/// Seconds since the epoch of a file's last change, to name the shared run after the binaries.
long long changedAt(const fs::path& p) {
    return std::chrono::duration_cast<std::chrono::seconds>(
               fs::last_write_time(p).time_since_epoch())
        .count();
}

const SmokeRun& smokeRun() {
    static const SmokeRun run = [] {
        const fs::path root = fs::path(VOXTIER_CLI).parent_path() / "test_fixtures";
        fs::create_directories(root);
        const std::string key = std::to_string(changedAt(VOXTIER_CLI)) + "_" +
                                std::to_string(changedAt(fs::read_symlink("/proc/self/exe")));
        const fs::path shared = root / ("bench_smoke_" + key);
        // One process makes the run; the others wait for it on the lock, then read it.
        const int lock = ::open((root / "bench_smoke.lock").c_str(), O_CREAT | O_RDWR, 0644);
        ::flock(lock, LOCK_EX);
        if (!fs::exists(shared / "done")) {
            for (const auto& old : fs::directory_iterator(root))
                if (old.path().filename().string().starts_with("bench_smoke_"))
                    fs::remove_all(old.path());
            fs::create_directories(shared);
            writeExactScene(shared / "exact.json");
            const CliRun r = runCli(
                "bench --smoke --motion-frames 4 --motion-warmup 2 --budget 1 --snapshot-scales "
                "1,2 --out '" +
                (shared / "out").string() + "' scenes/bench/tank_army.json '" +
                (shared / "exact.json").string() + "'");
            std::ofstream(shared / "stdout") << r.out;
            std::ofstream(shared / "stderr") << r.err;
            std::ofstream(shared / "done") << r.status;
        }
        ::flock(lock, LOCK_UN);
        ::close(lock);
        SmokeRun s;
        std::istringstream(slurp(shared / "done")) >> s.status;
        s.out = slurp(shared / "stdout");
        s.err = slurp(shared / "stderr");
        s.dir = shared / "out";
        if (fs::exists(s.dir / "results.json"))
            s.results = json::parse(slurp(s.dir / "results.json"));
        s.csv = slurp(s.dir / "results.csv");
        s.report = slurp(s.dir / "report.md");
        return s;
    }();
    return run;
}

class BenchSmoke : public ::testing::Test {
  protected:
    void SetUp() override {
        ASSERT_EQ(run().status, 0) << run().out << run().err;
        ASSERT_TRUE(run().results.is_object()) << run().out << run().err;
    }
    static const SmokeRun& run() { return smokeRun(); }
    static const json& results() { return run().results; }
    static const json& rows() { return results()["rows"]; }
    static const json& row(const std::string& group, const std::string& scene,
                           const std::string& mode) {
        for (const json& r : rows())
            if (r["group"] == group && r["scene"] == scene && r["mode"] == mode) return r;
        static const json none;
        ADD_FAILURE() << "no row " << group << " " << scene << " " << mode;
        return none;
    }
    static const json& modeRow(const std::string& scene, const std::string& mode) {
        return row("modes", scene, mode);
    }
    static double num(const json& r, const char* key) { return r[key].get<double>(); }
    /// The rows of the error_budget sweep.
    static std::vector<const json*> budgetRows() {
        std::vector<const json*> out;
        for (const json& r : rows())
            if (r["family"] == "budget (error_budget)") out.push_back(&r);
        return out;
    }
};

// --- The files ---------------------------------------------------------------------------------

TEST_F(BenchSmoke, WritesTheResultsFilesAndTheReportWhole) {
    for (const char* f : {"report.md", "results.csv", "results.json"})
        EXPECT_TRUE(fs::exists(run().dir / f)) << f;
    // Every file is written under a temporary name and renamed (core/file_write.hpp).
    for (const auto& f : fs::directory_iterator(run().dir))
        EXPECT_EQ(f.path().filename().string().find(".tmp-"), std::string::npos) << f.path();
}

TEST_F(BenchSmoke, PlanRecordsThePresetAndTheOverrides) {
    const json& plan = results()["plan"];
    EXPECT_EQ(plan["preset"], "smoke");
    EXPECT_EQ(plan["motion_frames"], 4);
    EXPECT_EQ(plan["motion_warmup"], 2);
    EXPECT_EQ(plan["budget_vpx"], 1.0);
    EXPECT_EQ(plan["sweeps"]["snapshot_scales"], json({"x1", "x2"}));
    EXPECT_EQ(plan["far_backend"], "cpu"); // the bench's own default
}

TEST_F(BenchSmoke, ListsTheModesInTableOrder) {
    EXPECT_EQ(results()["modes"], json(kModes));
}

TEST_F(BenchSmoke, EverySceneHasEveryModeWithFramesAndTime) {
    for (const std::string& scene : kScenes)
        for (const std::string& mode : kModes) {
            const json& m = modeRow(scene, mode);
            EXPECT_FALSE(m["frames"].empty()) << scene << " " << mode;
            EXPECT_GT(num(m, "frame_ms"), 0.0) << scene << " " << mode;
            EXPECT_GT(num(m, "visible"), 0.0) << scene << " " << mode;
        }
}

// --- Measurements ------------------------------------------------------------------------------

TEST_F(BenchSmoke, InMotionTwoTimedFramesGiveMedianEqualMeanAndP90EqualWorst) {
    for (const std::string& mode : kModes) {
        const json& m = modeRow("tank_army", mode);
        EXPECT_GT(num(m, "in_motion_ms"), 0.0) << mode;
        EXPECT_DOUBLE_EQ(num(m, "in_motion_mean_ms"), num(m, "in_motion_ms")) << mode;
        EXPECT_GE(num(m, "in_motion_p90_ms"), num(m, "in_motion_ms")) << mode;
        EXPECT_EQ(num(m, "in_motion_worst_ms"), num(m, "in_motion_p90_ms")) << mode;
    }
}

TEST_F(BenchSmoke, SpeedupsAreTheRatiosOfTheReportedTimes) {
    const auto ratio = [](const json& m, const char* speedup, const char* baseline,
                          const char* ms) {
        EXPECT_NEAR(m[speedup].get<double>() * m[ms].get<double>(), m[baseline].get<double>(),
                    1e-6 * m[baseline].get<double>())
            << m["mode"] << " " << m["setting"] << " " << speedup;
    };
    for (const json& m : rows()) {
        ratio(m, "speedup_vs_all_near_vulkan", "all_near_vulkan_ms", "frame_ms");
        ratio(m, "speedup_vs_fastest_exact", "fastest_exact_ms", "frame_ms");
        if (m["group"] == "modes")
            ratio(m, "speedup_vs_near_vulkan_fragment", "near_vulkan_fragment_ms", "frame_ms");
        if (m["scene"] == "tank_army" && m["group"] == "modes")
            ratio(m, "in_motion_speedup_vs_all_near_reference", "in_motion_all_near_reference_ms",
                  "in_motion_ms");
    }
}

TEST_F(BenchSmoke, FastestExactIsTheFasterOfTheTwoAllNearRows) {
    for (const std::string& scene : kScenes) {
        const double vk = num(modeRow(scene, "near_vulkan"), "frame_ms");
        const double ref = num(modeRow(scene, "near_reference"), "frame_ms");
        for (const std::string& mode : kModes) {
            const json& m = modeRow(scene, mode);
            EXPECT_DOUBLE_EQ(num(m, "fastest_exact_ms"), std::min(vk, ref)) << scene << mode;
            EXPECT_EQ(m["fastest_exact"], ref < vk ? "near_reference" : "near_vulkan");
        }
    }
}

TEST_F(BenchSmoke, BudgetFlagGivesEveryConfigurationTheErrorBudget) {
    for (const std::string& scene : kScenes)
        for (const std::string& mode : kModes) {
            const std::string selector = modeRow(scene, mode)["selector"];
            EXPECT_NE(selector.find("error_budget"), std::string::npos) << selector;
        }
}

TEST_F(BenchSmoke, NearBackendNamesWhoDrewTheNearTier) {
    for (const std::string& scene : kScenes) {
        EXPECT_EQ(modeRow(scene, "near_vulkan")["near_backend"], "vulkan");
        EXPECT_EQ(modeRow(scene, "near_vulkan_fragment")["near_backend"], "vulkan");
        EXPECT_EQ(modeRow(scene, "near_reference")["near_backend"], "reference");
        // The hybrid's is --near-backend auto's choice, and its frames say the same where they
        // drew near sprites.
        for (const char* mode : {"hybrid", "hybrid_gpu_far"}) {
            const json& m = modeRow(scene, mode);
            const std::string backend = m["near_backend"];
            EXPECT_TRUE(backend == "vulkan" || backend == "reference") << backend;
            if (num(m, "near_entities") > 0) {
                EXPECT_EQ(num(m, "near_on_vulkan") > 0, backend == "vulkan") << scene << mode;
            }
        }
    }
}

TEST_F(BenchSmoke, FarBackendIsTheCpuBlitBesideTheVulkanFarPass) {
    for (const std::string& scene : kScenes) {
        EXPECT_EQ(modeRow(scene, "far")["far_backend"], "cpu");
        EXPECT_EQ(modeRow(scene, "hybrid")["far_backend"], "cpu");
        const json& gpu = modeRow(scene, "hybrid_gpu_far");
        EXPECT_EQ(gpu["far_backend"], "vulkan");
        if (num(gpu, "far_entities") > 0) {
            EXPECT_GT(num(gpu, "far_on_vulkan"), 0.0) << scene;
            // Its recording is timed apart, within the frame's.
            EXPECT_GT(num(gpu, "host_record_far_ms"), 0.0) << scene;
            EXPECT_LE(num(gpu, "host_record_far_ms"), num(gpu, "host_record_ms")) << scene;
        }
        EXPECT_EQ(num(modeRow(scene, "hybrid"), "host_record_far_ms"), 0.0) << scene;
    }
}

TEST_F(BenchSmoke, DeviceFrameIsTimedWhereTheWholeFrameIsOnVulkan) {
    for (const std::string& scene : kScenes) {
        // All-near on Vulkan draws the whole frame there (on lavapipe too); the CPU reference
        // and the all-far CPU blit draw it on the host.
        for (const char* mode : {"near_vulkan", "near_vulkan_fragment"})
            EXPECT_GT(num(modeRow(scene, mode), "device_frame_ms"), 0.0) << scene << " " << mode;
        for (const char* mode : {"near_reference", "far"})
            EXPECT_EQ(num(modeRow(scene, mode), "device_frame_ms"), 0.0) << scene << " " << mode;
        // The hybrids: wholly on Vulkan where no tier of theirs drew a sprite on the CPU.
        const auto nearOnCpu = [&](const json& m) {
            return m["near_backend"] != "vulkan" && num(m, "near_entities") > 0;
        };
        const json& gpu = modeRow(scene, "hybrid_gpu_far");
        EXPECT_EQ(num(gpu, "device_frame_ms") > 0.0, !nearOnCpu(gpu)) << scene;
        const json& cpu = modeRow(scene, "hybrid");
        EXPECT_EQ(num(cpu, "device_frame_ms") > 0.0,
                  !nearOnCpu(cpu) && num(cpu, "far_entities") == 0.0)
            << scene;
    }
}

TEST_F(BenchSmoke, ModesTableShowsTheDeviceFrameBesideTheWarmFrame) {
    const auto headings = tableCells(lineWith(run().report, "| mode | near / far entities |"));
    const auto warm = std::find(headings.begin(), headings.end(), "warm re-render: frame ms");
    ASSERT_NE(warm, headings.end());
    ASSERT_NE(warm + 1, headings.end());
    EXPECT_EQ(*(warm + 1), "device frame ms (no readback)");
    const std::size_t at = std::size_t(warm + 1 - headings.begin());
    // The first scene's table comes first in the report.
    for (const std::string& mode : kModes) {
        const auto cells = tableCells(lineStarting(run().report, "| " + mode + " | "));
        ASSERT_GT(cells.size(), at) << mode;
        const double ms = num(modeRow(kScenes[0], mode), "device_frame_ms");
        EXPECT_EQ(cells[at], ms > 0 ? fixed(ms, 2) : "– (a CPU tier)") << mode;
    }
}

TEST_F(BenchSmoke, DeviceSplitHasTheHostPartAndEveryGpuPassOfEachModeOnVulkan) {
    std::vector<std::string> names;
    std::string header = "| scene | mode |";
    for (const FrameFigure& f : kFrameFigures) {
        const std::string name = f.name;
        if ((name.starts_with("host_") && !name.starts_with("host_select_") && !f.timeStep) ||
            name.starts_with("gpu_"))
            names.push_back(name), header += " " + name + " |";
    }
    // record (its two near halves, the near records' order and residency, the lists' arithmetic
    // and uploads, the far pass), wait, readback; the frame and seven passes (not the selection's
    // parts: a step before the frame)
    EXPECT_EQ(names.size(), 18u);
    const auto at = run().report.find(header + "\n");
    ASSERT_NE(at, std::string::npos) << header;
    const std::string table = run().report.substr(at, run().report.find("\n\n", at) - at);
    for (const std::string& scene : kScenes)
        for (const std::string& mode : kModes) {
            const json& m = modeRow(scene, mode);
            const std::string line = lineStarting(table, "| " + scene + " | " + mode + " | ");
            EXPECT_EQ(!line.empty(), num(m, "near_on_vulkan") > 0 || num(m, "far_on_vulkan") > 0)
                << scene << " " << mode;
            if (line.empty()) continue;
            const auto cells = tableCells(line);
            ASSERT_EQ(cells.size(), names.size() + 2) << line;
            for (std::size_t i = 0; i < names.size(); ++i)
                EXPECT_EQ(cells[i + 2], fixed(num(m, names[i].c_str()), 2)) << line;
        }
    // All-near on Vulkan waits for the device to draw its frame.
    const json& nearVulkan = modeRow(kScenes[0], "near_vulkan");
    EXPECT_GT(num(nearVulkan, "host_wait_ms"), 0.0);
    // The recording's two near halves are parts of it (a median of parts is at most the median
    // of the whole: every frame's part is at most its whole).
    for (const char* part : {"host_record_sprites_ms", "host_record_lists_ms"}) {
        EXPECT_GT(num(nearVulkan, part), 0.0) << part;
        EXPECT_LE(num(nearVulkan, part), num(nearVulkan, "host_record_ms")) << part;
    }
    // The lists' host arithmetic and uploads are parts of the lists.
    for (const char* part : {"host_record_lists_build_ms", "host_record_lists_upload_ms"}) {
        EXPECT_GT(num(nearVulkan, part), 0.0) << part;
        EXPECT_LE(num(nearVulkan, part), num(nearVulkan, "host_record_lists_ms")) << part;
    }
    // And the sprite records' draw order and residency are parts of those; all-near records no
    // far pass.
    for (const char* part : {"host_record_order_ms", "host_record_residency_ms"}) {
        EXPECT_GT(num(nearVulkan, part), 0.0) << part;
        EXPECT_LE(num(nearVulkan, part), num(nearVulkan, "host_record_sprites_ms")) << part;
    }
    EXPECT_EQ(num(nearVulkan, "host_record_far_ms"), 0.0);
}

TEST_F(BenchSmoke, TruthHasNoErrorAndEveryOtherModeHasOne) {
    for (const std::string& scene : kScenes)
        for (const std::string& mode : kModes) {
            const json& m = modeRow(scene, mode);
            EXPECT_EQ(m["error"].is_null(), mode == "near_vulkan") << scene << " " << mode;
        }
}

TEST_F(BenchSmoke, AllNearDrawsNoFarEntityAndAllFarNoNearOne) {
    for (const std::string& scene : kScenes) {
        EXPECT_EQ(num(modeRow(scene, "near_vulkan"), "far_entities"), 0.0);
        EXPECT_EQ(num(modeRow(scene, "far"), "near_entities"), 0.0);
    }
}

TEST_F(BenchSmoke, PerPixelNearSpritesDrawTheCellRateImage) {
    for (const std::string& scene : kScenes) {
        const json& m = modeRow(scene, "near_vulkan_fragment");
        EXPECT_EQ(m["error"]["mismatch_mean"].get<double>(), 0.0) << scene;
        EXPECT_EQ(num(m, "near_cells_traced"), 0.0) << scene;
    }
}

TEST_F(BenchSmoke, ReferenceDrawsTheVulkanImageExactly) {
    for (const std::string& scene : kScenes) {
        const json& e = modeRow(scene, "near_reference")["error"];
        EXPECT_EQ(e["differing_pixels"].get<double>(), 0.0) << scene;
        EXPECT_EQ(e["mismatch_mean"].get<double>(), 0.0) << scene;
        EXPECT_TRUE(e["psnr_min"].is_null()) << scene; // equal images: infinite PSNR
    }
}

TEST_F(BenchSmoke, ExactSceneFarAndHybridEqualTheTruth) {
    // Every view is canonical, so far and hybrid equal the truth pixel for pixel.
    for (const std::string mode : {"far", "hybrid", "hybrid_gpu_far"}) {
        const json& e = modeRow("exact", mode)["error"];
        EXPECT_EQ(e["differing_pixels"].get<double>(), 0.0) << mode;
        EXPECT_EQ(e["mismatch_mean"].get<double>(), 0.0) << mode;
        EXPECT_EQ(e["far_displacement_worst_px"].get<double>(), 0.0) << mode;
    }
}

TEST_F(BenchSmoke, TankArmyAllFarDiffersFromTheTruth) {
    // Worked out here: some visible tank is seen well away from every snapshot view.
    Scene s = loadScene("scenes/bench/tank_army.json");
    s.entities.resize(24); // --smoke keeps the first 24 entities at 240x136
    s.camera.width = 240, s.camera.height = 136;
    const auto sprites = setupSprites(s, makeCameraFrame(s.cameraAt(0.0)), 0.0);
    double worstAngle = 0.0;
    for (const SpriteSetup& sp : sprites) {
        if (!sp.visible()) continue;
        const glm::dvec3 w = -sp.lattice.dir;
        double best = -1.0;
        for (const glm::dvec3& v : viewDirections(ViewSet::Cube26))
            best = std::max(best, glm::dot(v, w));
        worstAngle = std::max(worstAngle, std::acos(std::min(1.0, best)) * 180.0 / M_PI);
    }
    ASSERT_GT(worstAngle, 5.0);
    const json& e = modeRow("tank_army", "far")["error"];
    EXPECT_GT(e["mismatch_mean"].get<double>(), 0.0);
    EXPECT_GT(e["differing_pixels"].get<double>(), 0.0);
}

TEST_F(BenchSmoke, MismatchesAreFractionsWithTheWorstAtLeastTheMean) {
    for (const json& m : rows()) {
        if (m["error"].is_null()) continue;
        const double mean = m["error"]["mismatch_mean"], worst = m["error"]["mismatch_worst"];
        EXPECT_GE(mean, 0.0);
        EXPECT_LE(worst, 1.0);
        EXPECT_GE(worst, mean);
    }
}

TEST_F(BenchSmoke, SweepAndScalingPointsAreThePlans) {
    int sweeps = 0;
    std::set<double> counts, sides;
    for (const json& m : rows()) {
        sweeps += m["group"] == "sweep";
        if (m["group"] == "scaling_entities") counts.insert(num(m, "entities"));
        if (m["group"] == "scaling_size") sides.insert(num(m, "param"));
    }
    // error_px far_at 1, and error_budget 1 vpx with each of the two snapshot scales.
    EXPECT_EQ(sweeps, 3);
    EXPECT_EQ(counts, (std::set<double>{4, 12}));
    EXPECT_EQ(sides, (std::set<double>{16, 32}));
}

TEST_F(BenchSmoke, EachBudgetPointDrawsWithItsOwnSnapshotScale) {
    // A shared configuration would report one snapshot scale twice.
    std::map<std::string, int> scales;
    for (const json* m : budgetRows())
        scales[(*m)["setting"].get<std::string>()] = (*m)["snapshot_scale"].get<int>();
    EXPECT_EQ(scales, (std::map<std::string, int>{{"error_budget 1 vpx, x1", 1},
                                                  {"error_budget 1 vpx, x2", 2}}));
}

TEST_F(BenchSmoke, BudgetPointsInMotionAreSetAgainstTheFasterExactPath) {
    for (const json* m : budgetRows()) {
        const double ref = num(*m, "in_motion_all_near_reference_ms"),
                     vk = num(*m, "in_motion_all_near_vulkan_ms");
        EXPECT_DOUBLE_EQ(num(*m, "in_motion_fastest_exact_ms"), std::min(ref, vk));
        EXPECT_NEAR(num(*m, "in_motion_speedup_vs_fastest_exact") * num(*m, "in_motion_ms"),
                    std::min(ref, vk), 1e-6 * std::min(ref, vk));
        EXPECT_GT(num(*m, "in_motion_cache_bytes"), 0.0);
    }
}

TEST_F(BenchSmoke, ModesKeepTheScenesSnapshotScaleAndAllNearNamesNone) {
    const Scene army = loadScene("scenes/bench/tank_army.json");
    EXPECT_EQ(modeRow("tank_army", "hybrid")["snapshot_scale"], army.selector.snapshotScale);
    EXPECT_EQ(modeRow("tank_army", "near_vulkan")["snapshot_scale"], 0);
}

TEST_F(BenchSmoke, NearShareIsAgainstAllNearDrawnTheSameWay) {
    // Near fragments count different things on each backend, so the share's baseline is the
    // all-near row of the row's own near backend and rate.
    for (const std::string& scene : kScenes)
        for (const std::string& mode : kModes) {
            const json& m = modeRow(scene, mode);
            const std::string same = m["near_backend"] == "reference" ? "near_reference"
                                     : mode == "near_vulkan_fragment" ? "near_vulkan_fragment"
                                                                      : "near_vulkan";
            EXPECT_EQ(num(m, "all_near_same_backend_fragments"),
                      num(modeRow(scene, same), "near_fragments"))
                << scene << " " << mode;
        }
}

TEST_F(BenchSmoke, VisibleEntitiesAreThoseDrawnNearFarOrBoth) {
    for (const json& m : rows())
        EXPECT_EQ(num(m, "visible"),
                  num(m, "near_entities") + num(m, "far_entities") - num(m, "fading_entities"))
            << m["mode"] << " " << m["setting"];
}

TEST_F(BenchSmoke, InMotionNearTimeIsPartOfTheFrameAndSomeoneDrawsEachEntity) {
    const json* budget = nullptr;
    for (const json* m : budgetRows())
        if ((*m)["scene"] == "tank_army") budget = m;
    ASSERT_NE(budget, nullptr);
    EXPECT_GT(num(*budget, "in_motion_near_ms"), 0.0);
    EXPECT_LE(num(*budget, "in_motion_near_ms"), num(*budget, "in_motion_mean_ms"));
    EXPECT_GE(num(*budget, "in_motion_near_entities") + num(*budget, "in_motion_far_entities"),
              1.0);
}

// --- results.csv and results.json ---------------------------------------------------------------

TEST_F(BenchSmoke, CsvKeepsEveryColumnItHad) {
    // The columns scripts read (tools/gpu_check.sh among them) keep their names.
    const std::vector<std::string> header = csvFields(run().csv.substr(0, run().csv.find('\n')));
    const std::set<std::string> has(header.begin(), header.end());
    for (const char* c : {"group",
                          "scene",
                          "mode",
                          "family",
                          "setting",
                          "param",
                          "selector",
                          "truth",
                          "frames",
                          "visible",
                          "worst_frame_ms",
                          "device_frame_ms",
                          "all_near_vulkan_ms",
                          "speedup_vs_all_near_vulkan",
                          "near_vulkan_fragment_ms",
                          "speedup_vs_near_vulkan_fragment",
                          "all_near_vulkan_fragments",
                          "voxel_steps_per_s",
                          "blit_pixels_per_s",
                          "memcpy_pixels_per_s",
                          "in_motion_ms",
                          "in_motion_mean_ms",
                          "in_motion_p90_ms",
                          "in_motion_worst_ms",
                          "in_motion_cold_ms",
                          "in_motion_all_near_vulkan_ms",
                          "in_motion_speedup_vs_all_near_vulkan",
                          "in_motion_all_near_reference_ms",
                          "in_motion_speedup_vs_all_near_reference",
                          "in_motion_fastest_exact_ms",
                          "in_motion_speedup_vs_fastest_exact",
                          "near_backend",
                          "far_backend",
                          "snapshot_scale",
                          "in_motion_bakes_per_frame",
                          "in_motion_bake_ms_per_frame",
                          "in_motion_cache_bytes",
                          "in_motion_near_ms",
                          "in_motion_near_entities",
                          "in_motion_far_entities",
                          "in_motion_psnr_min",
                          "in_motion_differing_share",
                          "in_motion_psnr_min_differing_pixels",
                          "in_motion_psnr_min_far_entities",
                          "in_motion_predicted_worst_vpx",
                          "cold_first_frame_ms",
                          "cold_bake_ms",
                          "cold_bakes",
                          "cold_rays",
                          "rays_per_s",
                          "has_error",
                          "mismatch_mean",
                          "mismatch_worst",
                          "coverage_mismatch_mean",
                          "far_mismatch_mean",
                          "far_alone_mismatch_mean",
                          "far_displacement_worst_px",
                          "far_displacement_worst_vpx",
                          "far_visible_displacement_worst_px",
                          "far_alone_entities",
                          "far_displaced_over_1_vpx",
                          "rmse_mean",
                          "psnr_min",
                          "differing_pixels",
                          "missing_entities"})
        EXPECT_TRUE(has.count(c)) << c;
}

TEST_F(BenchSmoke, CsvNamesEachColumnOnce) {
    // One name per figure: a frame figure's column is its kFrameFigures name, a bench figure's
    // its line in results.cpp, and no two share one.
    const std::vector<std::string> header = csvFields(run().csv.substr(0, run().csv.find('\n')));
    std::set<std::string> seen;
    for (const std::string& name : header) EXPECT_TRUE(seen.insert(name).second) << name;
    EXPECT_GT(header.size(), kFrameFigureCount);
}

TEST_F(BenchSmoke, CsvHasAColumnPerFrameFigure) {
    const std::vector<std::string> header = csvFields(run().csv.substr(0, run().csv.find('\n')));
    for (const FrameFigure& f : kFrameFigures)
        EXPECT_EQ(std::count(header.begin(), header.end(), f.name), 1) << f.name;
}

TEST_F(BenchSmoke, CsvHasOneRowPerJsonRowSayingTheSame) {
    std::istringstream csv(run().csv);
    std::string line;
    ASSERT_TRUE(std::getline(csv, line));
    const auto header = csvFields(line);
    std::map<std::string, std::size_t> col;
    for (std::size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
    std::size_t n = 0;
    while (std::getline(csv, line)) {
        const auto f = csvFields(line);
        ASSERT_EQ(f.size(), header.size()) << line;
        ASSERT_LT(n, rows().size());
        const json& m = rows()[n];
        EXPECT_EQ(f[col["mode"]], m["mode"].get<std::string>());
        EXPECT_EQ(std::stoi(f[col["snapshot_scale"]]), m["snapshot_scale"].get<int>());
        EXPECT_NEAR(std::stod(f[col["frame_ms"]]), num(m, "frame_ms"), 1e-5 * num(m, "frame_ms"));
        ++n;
    }
    EXPECT_EQ(n, rows().size());
}

TEST_F(BenchSmoke, JsonNamesTheFrameFiguresInTableOrder) {
    const json& figures = results()["frame_figures"];
    ASSERT_EQ(figures.size(), kFrameFigureCount);
    for (std::size_t i = 0; i < kFrameFigureCount; ++i)
        EXPECT_EQ(figures[i]["name"], kFrameFigures[i].name);
}

TEST_F(BenchSmoke, JsonRowFiguresAreTheirFramesCombined) {
    // One sampled frame here: a row's figure is its frame's.
    for (const json& m : rows()) {
        ASSERT_EQ(m["frames"].size(), 1u);
        for (const FrameFigure& f : kFrameFigures) {
            ASSERT_TRUE(m.contains(f.name)) << f.name;
            ASSERT_TRUE(m["frames"][0].contains(f.name)) << f.name;
            EXPECT_NEAR(m[f.name].get<double>(), m["frames"][0][f.name].get<double>(),
                        1e-9 * std::abs(m[f.name].get<double>()))
                << f.name;
        }
    }
}

// --- report.md and stdout ----------------------------------------------------------------------

/// The report's lead for a scene, worked out from results.json.
std::string expectedLead(const json& h, const std::string& scene, bool markdown) {
    const std::string b = markdown ? "**" : "";
    const bool moving = h["in_motion_ms"].get<double>() > 0;
    const double ms = moving ? h["in_motion_ms"].get<double>() : h["frame_ms"].get<double>();
    const double fastestMs = moving ? h["in_motion_fastest_exact_ms"].get<double>()
                                    : h["fastest_exact_ms"].get<double>();
    const std::string fastest =
        moving ? (h["in_motion_all_near_reference_ms"].get<double>() == fastestMs ? "near_reference"
                                                                                  : "near_vulkan")
               : h["fastest_exact"].get<std::string>();
    return b + scene + b + ": the hybrid is " + b + fixed(fastestMs / ms, 2) + "×" + b +
           " the fastest exact path on this machine: " + fixed(ms, 2) + " ms a frame " +
           (moving ? "in motion" : "(warm re-render; the scene has no camera path)") + " against " +
           fixed(fastestMs, 2) + " ms for " + fastest + " (";
}

TEST_F(BenchSmoke, ReportLeadsWithTheHybridAgainstTheFastestExactPath) {
    const std::vector<std::string> report = linesOf(run().report, 3);
    EXPECT_EQ(report[0], "# voxtier bench (smoke)");
    const std::string& first = report[2];
    const json& h = modeRow("tank_army", "hybrid");
    EXPECT_EQ(first.rfind("- " + expectedLead(h, "tank_army", true), 0), 0u) << first;
    // Its error: min frame PSNR and differing share in motion, worst far displacement.
    const json& psnr = h["in_motion_psnr_min"];
    if (psnr.is_number()) {
        EXPECT_NE(first.find("min frame PSNR " + fixed(psnr.get<double>(), 1) + " dB"),
                  std::string::npos)
            << first;
    }
    EXPECT_NE(first.find(fixed(100 * num(h, "in_motion_differing_share"), 2) +
                         " % of pixels differing (mean)"),
              std::string::npos)
        << first;
    const json& e = h["error"];
    if (e["far_alone_entities"].get<double>() > 0) {
        EXPECT_NE(first.find("worst far displacement " +
                             fixed(e["far_displacement_worst_vpx"].get<double>(), 2) + " vpx"),
                  std::string::npos)
            << first;
    }
}

TEST_F(BenchSmoke, LeadOfASceneWithoutPathIsTheWarmFrameWithEqualImages) {
    const std::string line = lineWith(run().report, "- **exact**: ");
    EXPECT_EQ(line.rfind("- " + expectedLead(modeRow("exact", "hybrid"), "exact", true), 0), 0u)
        << line;
    EXPECT_NE(line.find("min frame PSNR ∞ dB (equal frames), 0.00 % of pixels differing"),
              std::string::npos)
        << line;
}

TEST_F(BenchSmoke, StdoutLeadsWithTheSameLines) {
    const std::vector<std::string> out = linesOf(run().out, 3);
    const std::string &first = out[1], &second = out[2];
    EXPECT_EQ(
        first.rfind("  " + expectedLead(modeRow("tank_army", "hybrid"), "tank_army", false), 0), 0u)
        << first;
    EXPECT_EQ(second.rfind("  " + expectedLead(modeRow("exact", "hybrid"), "exact", false), 0), 0u)
        << second;
}

TEST_F(BenchSmoke, TimeSplitHasEveryTierAndItsPartsFromTheFigureTable) {
    // The headings, worked out from the table: the top-level time steps, then each tier's whole
    // time followed by the time steps named after it.
    std::string steps, near, far;
    for (const FrameFigure& f : kFrameFigures) {
        const std::string name = f.name;
        if (!f.timeStep || name == "near_ms" || name == "far_ms") continue; // the tiers
        (name.starts_with("near_")  ? near
         : name.starts_with("far_") ? far
                                    : steps) += " " + f.words() + " |";
    }
    const std::string header = "| scene | mode |" + steps + " near tier |" + near + " far tier |" +
                               far + " other | total |";
    EXPECT_NE(run().report.find(header + "\n"), std::string::npos) << header;
}

TEST_F(BenchSmoke, TimeSplitHasARowPerModeWhoseNearTierIsItsNearTime) {
    // The CPU reference's trace is in the near tier: nothing of a mode's frame is left out.
    const std::string header = lineWith(run().report, "| scene | mode | ");
    const auto headings = tableCells(header);
    const auto nearAt = std::find(headings.begin(), headings.end(), "near tier");
    ASSERT_NE(nearAt, headings.end()) << header;
    for (const std::string& scene : kScenes)
        for (const std::string& mode : kModes) {
            const std::string line = lineWith(run().report, "| " + scene + " | " + mode + " | ");
            ASSERT_FALSE(line.empty()) << scene << " " << mode;
            const auto cells = tableCells(line);
            ASSERT_EQ(cells.size(), headings.size()) << line;
            EXPECT_EQ(cells[std::size_t(nearAt - headings.begin())],
                      fixed(num(modeRow(scene, mode), "near_ms"), 2))
                << line;
        }
}

TEST_F(BenchSmoke, InMotionSplitAddsUpToTheMeanFrameInMotionAndIsInTheReport) {
    // The split of the frames timed in motion: each time figure's mean over them, so the frame's
    // own column is in_motion_mean_ms, and the tiers and the steps before them (each frame's
    // parts of that frame) add up to at most the frame.
    const auto at = run().report.find("## Where the time goes in motion");
    ASSERT_NE(at, std::string::npos);
    const auto end = run().report.find("\n## ", at + 1);
    const std::string section = run().report.substr(at, end == std::string::npos ? end : end - at);
    const auto headings = tableCells(lineWith(section, "| scene | mode | "));
    ASSERT_FALSE(headings.empty());
    ASSERT_EQ(headings.back(), "total");
    std::size_t timedModes = 0;
    for (const std::string& scene : kScenes)
        for (const std::string& mode : kModes) {
            const json& m = modeRow(scene, mode);
            const std::string line = lineStarting(section, "| " + scene + " | " + mode + " | ");
            if (num(m, "in_motion_ms") <= 0) { // a scene without a camera path
                EXPECT_TRUE(line.empty()) << line;
                continue;
            }
            ++timedModes;
            const double frame = num(m, "in_motion_mean_frame_ms");
            EXPECT_NEAR(frame, num(m, "in_motion_mean_ms"), 1e-9 * frame) << scene << " " << mode;
            double steps = 0.0;
            for (const char* step : {"host_setup_ms", "host_select_ms", "near_ms", "far_ms"})
                steps += num(m, ("in_motion_mean_" + std::string(step)).c_str());
            EXPECT_GT(steps, 0.0) << scene << " " << mode;
            EXPECT_LE(steps, frame * (1.0 + 1e-9)) << scene << " " << mode;
            EXPECT_LE(num(m, "in_motion_mean_far_lookup_bake_ms") +
                          num(m, "in_motion_mean_far_blit_ms"),
                      num(m, "in_motion_mean_far_ms") * (1.0 + 1e-9) + 1e-9)
                << scene << " " << mode;
            // The near tier's mean in motion was a column before this split: the same figure.
            EXPECT_NEAR(num(m, "in_motion_mean_near_ms"), num(m, "in_motion_near_ms"),
                        1e-9 * (1.0 + num(m, "in_motion_near_ms")))
                << scene << " " << mode;
            ASSERT_FALSE(line.empty()) << scene << " " << mode;
            const auto cells = tableCells(line);
            ASSERT_EQ(cells.size(), headings.size()) << line;
            EXPECT_EQ(cells.back(), fixed(num(m, "in_motion_mean_ms"), 2)) << line;
        }
    EXPECT_EQ(timedModes, kModes.size()); // the tank army's every mode
    // All-near on Vulkan in motion: the device's frame, under the wait for it.
    const json& nearVulkan = modeRow("tank_army", "near_vulkan");
    EXPECT_GT(num(nearVulkan, "in_motion_mean_host_wait_ms"), 0.0);
    EXPECT_NE(lineStarting(section.substr(section.find("| scene | mode | host_record_ms")),
                           "| tank_army | near_vulkan | "),
              "");
}

TEST_F(BenchSmoke, GoalTableMarksEveryGoalOrSaysWhyASettingIsMissing) {
    for (const char* goal : {"| speed-up vs the fastest exact path ≥ 10× |",
                             "| mean footprint mismatch ≤ 2 % (coverage only) |",
                             "| no far entity displaced > 1 virtual px |"}) {
        const std::string line = lineWith(run().report, goal);
        ASSERT_FALSE(line.empty()) << goal;
        std::size_t marks = 0;
        for (const char* mark : {"✓", "✗"})
            for (auto p = line.find(mark); p != std::string::npos; p = line.find(mark, p + 1))
                ++marks;
        const bool noBest =
            lineWith(run().report, "| setting |").find("| none ") != std::string::npos;
        EXPECT_EQ(marks, noBest ? 2u : 3u) << line;
    }
}

TEST_F(BenchSmoke, NoCellReadsOfZeroOrNoneMeasured) {
    EXPECT_EQ(run().report.find("none measured"), std::string::npos);
    const std::regex ofZero(R"((^|[^0-9.])[0-9.]+ of 0([^0-9.]|$))");
    std::istringstream lines(run().report);
    for (std::string line; std::getline(lines, line);)
        EXPECT_FALSE(std::regex_search(line, ofZero)) << line;
}

TEST_F(BenchSmoke, BudgetTargetStatesItsVerdictAndCeiling) {
    EXPECT_NE(run().report.find("## The error budget in motion: target and bound"),
              std::string::npos);
    const std::string verdict = lineWith(run().report, "- **tank_army**: at 1 vpx, ");
    ASSERT_FALSE(verdict.empty()) << run().report;
    EXPECT_NE(verdict.find("would give at most"), std::string::npos) << verdict;
    EXPECT_NE(verdict.find("PSNR ≥ 40 dB"), std::string::npos) << verdict;
    const json* budget = nullptr;
    for (const json* m : budgetRows())
        if ((*m)["scene"] == "tank_army") budget = m;
    ASSERT_NE(budget, nullptr);
    // The measured displacement stands beside the prediction wherever far entities were
    // measured alone on the sampled frames.
    const json& err = (*budget)["error"];
    if (err.is_object() && err["far_alone_entities"].get<double>() > 0.0) {
        EXPECT_NE(verdict.find("(measured worst "), std::string::npos) << verdict;
    }
    // Below 40 dB the verdict says how many differing pixels 40 dB would allow.
    const json& psnrMin = (*budget)["in_motion_psnr_min"]; // null where +inf (equal frames)
    if (psnrMin.is_number() && psnrMin.get<double>() < 40.0) {
        EXPECT_NE(verdict.find("40 dB asks for a "), std::string::npos) << verdict;
    }
}

TEST_F(BenchSmoke, FrontierHasARowPerScaleAndMarksOnlyFasterPoints) {
    const auto at = run().report.find("## Speed–error frontier");
    ASSERT_NE(at, std::string::npos) << run().report;
    const std::string frontier = run().report.substr(at, run().report.find("\n## ", at + 1) - at);
    std::size_t onFrontier = 0;
    for (const char* variant : {"| x1 | 1.00 vpx |", "| x2 | 1.00 vpx |"}) {
        const std::string line = lineWith(frontier, variant);
        ASSERT_FALSE(line.empty()) << variant << "\n" << frontier;
        onFrontier += line.ends_with("| P |");
    }
    std::size_t faster = 0;
    for (const json* m : budgetRows())
        faster += num(*m, "in_motion_speedup_vs_fastest_exact") > 1.0;
    EXPECT_LE(onFrontier, faster) << frontier;
    EXPECT_EQ(onFrontier > 0, faster > 0) << frontier;
}

TEST_F(BenchSmoke, EveryEmbeddedPlotExists) {
    std::set<std::string> embedded;
    const std::regex image(R"(!\[[^\]]*\]\(([^)]+)\))");
    for (auto it = std::sregex_iterator(run().report.begin(), run().report.end(), image);
         it != std::sregex_iterator(); ++it)
        embedded.insert((*it)[1]);
    for (const std::string& png : embedded) EXPECT_TRUE(fs::exists(run().dir / png)) << png;
    if (std::system("command -v gnuplot >/dev/null 2>&1") == 0)
        EXPECT_EQ(embedded,
                  (std::set<std::string>{"speed_error.png", "motion_error.png", "frontier.png",
                                         "scaling_entities.png", "scaling_size.png"}));
    else
        EXPECT_NE(run().report.find("gnuplot"), std::string::npos); // says why there are none
}

// ---------------------------------------------------------------------------------------------

// `render --csv`: one column per frame figure (the same table as the bench's), one row per path
// frame, every row as wide as the header.
TEST(RenderCsv, HasEveryFrameFigureForEveryPathFrame) {
    ScratchDir dir;
    const fs::path scene = dir.path / "path.json", csvFile = dir.path / "frames.csv";
    writeExactScene(scene);
    json doc = json::parse(slurp(scene));
    doc["camera_path"] = {{"fps", 4},
                          {"keys",
                           {{{"time", 0}, {"position", {0, 40, 0}}, {"target", {0, 0, 0}}},
                            {{"time", 1}, {"position", {0, 12, 0}}, {"target", {0, 0, 0}}}}}};
    std::ofstream(scene) << doc.dump(1);
    const CliRun r =
        runCli("render '" + scene.string() + "' --path --near-backend reference --csv '" +
               csvFile.string() + "' -o '" + (dir.path / "f.png").string() + "'");
    ASSERT_EQ(r.status, 0) << r.out << r.err;
    std::istringstream csv(slurp(csvFile));
    std::string line;
    ASSERT_TRUE(std::getline(csv, line));
    EXPECT_EQ(line, "frame,time," + figureCsvHeader());
    const auto header = csvFields(line);
    std::map<std::string, std::size_t> col;
    for (std::size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
    int frame = 0;
    while (std::getline(csv, line)) {
        const auto f = csvFields(line);
        ASSERT_EQ(f.size(), header.size()) << line;
        EXPECT_EQ(std::stoi(f[col["frame"]]), frame) << line;
        auto at = [&](const char* name) { return std::stod(f[col[name]]); };
        EXPECT_EQ(at("entities"), 9.0) << line;
        EXPECT_EQ(at("entities") - at("culled"),
                  at("near_entities") + at("far_entities") - at("fading_entities"))
            << line;
        EXPECT_GT(at("frame_ms"), 0.0) << line;
        ++frame;
    }
    EXPECT_EQ(frame, 5); // 1 s at 4 frames per second, both ends
}

TEST(BenchCommand, BadInputIsOneLineNamingTheFileOrFlag) {
    ScratchDir dir;
    const std::string out = " --out '" + (dir.path / "out").string() + "'";
    auto expectOneLine = [](const CliRun& r, const std::string& what) {
        EXPECT_NE(r.status, 0) << r.out;
        EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
        EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
    };
    expectOneLine(runCli("bench --smoke no/such/scene.json" + out), "no/such/scene.json");
    const fs::path file = dir.path / "a_file";
    std::ofstream(file) << "x";
    expectOneLine(runCli("bench --smoke scenes/bench/tank_army.json --out '" + file.string() + "'"),
                  "--out");
    expectOneLine(runCli("bench --smoke scenes/bench/tank_army.json --size 0x5" + out), "--size");
    expectOneLine(runCli("bench --smoke scenes/bench/tank_army.json --repeats 0" + out),
                  "--repeats");
    expectOneLine(runCli("bench --smoke scenes/bench/tank_army.json --entity-counts 10,x" + out),
                  "--entity-counts");
    expectOneLine(runCli("bench --smoke scenes/bench/tank_army.json --motion-frames 1" + out),
                  "--motion-frames");
    for (const char* scales : {"5", "0", "x", "1:2"})
        expectOneLine(runCli("bench --smoke scenes/bench/tank_army.json --snapshot-scales '" +
                             std::string(scales) + "'" + out),
                      "--snapshot-scales");
    // The smoke preset's in-motion run is 3 frames: a cold start of 3 would leave none timed.
    expectOneLine(runCli("bench --smoke scenes/bench/tank_army.json --motion-warmup 3" + out),
                  "--motion-warmup");
    EXPECT_FALSE(fs::exists(dir.path / "out" / "results.csv"));
}

// The presets are a table: --help gives each overridable figure's value in every preset.
TEST(BenchCommand, HelpGivesEachPresetsFigures) {
    const CliRun r = runCli("bench --help");
    ASSERT_EQ(r.status, 0) << r.err;
    for (const char* text : {"Timed passes per path frame (default: 7, --quick 3)",
                             "Path frames sampled per scene (default: 6, --quick 2)",
                             "(default: 1,2,3,4; --quick 1,3)"})
        EXPECT_NE(r.out.find(text), std::string::npos) << text << "\n" << r.out;
    EXPECT_EQ(r.out.find("smoke"), std::string::npos) << r.out; // test-only
}

// --entity-counts and --far-backend vulkan, which the smoke fixture above does not pass: the
// entity curve has a row per mode at the asked count, and every mode with far sprites names the
// Vulkan far pass (the GPU check's profile runs them at scale; this keeps them under the
// sanitizers at the smallest size).
TEST(BenchCommand, EntityCountsAndTheVulkanFarPassGiveTheirRows) {
    ScratchDir dir;
    const CliRun r = runCli("bench --smoke --no-sweeps --far-backend vulkan --entity-counts 20 "
                            "scenes/bench/tank_army.json --out '" +
                            (dir.path / "out").string() + "'");
    ASSERT_EQ(r.status, 0) << r.out << r.err;
    const json results = json::parse(slurp(dir.path / "out" / "results.json"));
    std::set<std::string> curve, farOnVulkan;
    for (const json& row : results["rows"]) {
        if (row["group"] == "scaling_entities" && row["param"].get<double>() == 20.0)
            curve.insert(row["mode"].get<std::string>());
        if (row["group"] == "modes" && row["far_backend"] == "vulkan")
            farOnVulkan.insert(row["mode"].get<std::string>());
    }
    EXPECT_EQ(curve, (std::set<std::string>{"near_vulkan", "near_vulkan_fragment", "near_reference",
                                            "far", "hybrid", "hybrid_gpu_far"}));
    EXPECT_EQ(farOnVulkan, (std::set<std::string>{"far", "hybrid", "hybrid_gpu_far"}));
}

// `bench near --out`: header and rows come from one column table (apps/bench/harness.hpp
// CsvWriter), so the header keeps its 15 names in order and every row is as wide as it. Its
// repeats are --repeats, as everywhere else in the bench.
TEST(BenchCommand, NearSubcommandStillRunsBesideTheSceneBench) {
    ScratchDir dir;
    const fs::path csvFile = dir.path / "sub" / "near.csv";
    const CliRun r = runCli("bench near --entities 3 --repeats 1 --warmup 0 --no-alternatives "
                            "--models procedural --size 160x90 --out '" +
                            csvFile.string() + "'");
    ASSERT_EQ(r.status, 0) << r.out << r.err;
    EXPECT_NE(r.out.find("hull-instanced"), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("quad-instanced"), std::string::npos) << r.out;
    std::istringstream csv(slurp(csvFile));
    std::string header, row, extra;
    ASSERT_TRUE(std::getline(csv, header));
    EXPECT_EQ(header, "entities,visible,variant,vk_draw_ms,vk_readback_ms,vk_frame_ms,reference_ms,"
                      "reference_over_vk,vk_cpu_ms,reference_cpu_ms,fragments_shaded,"
                      "kernel_fragments,dda_steps_per_fragment,differing_pixels,drawn_pixels");
    // Without alternatives: the default (per-pixel sprites traced in compute), then the draw.
    for (const char* variant : {",compute,", ",hull-instanced,"}) {
        ASSERT_TRUE(std::getline(csv, row)) << variant;
        EXPECT_EQ(std::count(row.begin(), row.end(), ','), 14) << row;
        EXPECT_EQ(row.rfind("3,", 0), 0u) << row;
        EXPECT_NE(row.find(variant), std::string::npos) << row;
    }
    EXPECT_FALSE(std::getline(csv, extra)) << extra;
}

} // namespace
} // namespace voxtier
