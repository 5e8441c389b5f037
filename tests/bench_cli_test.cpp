// `voxtier bench` end to end, at the smallest size (--smoke: tiny images and entity counts, one
// timed pass, one sweep point): the outputs exist and agree with each other and with what can be
// worked out without the bench. No timings are asserted (the machine is shared).
#include "cli_support.hpp"
#include "compose/frame_figures.hpp"
#include "core/scene_loader.hpp"
#include "core/sprite.hpp"
#include "core/view_set.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
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

const json* row(const json& rows, const std::string& group, const std::string& scene,
                const std::string& mode) {
    for (const json& r : rows)
        if (r["group"] == group && r["scene"] == scene && r["mode"] == mode) return &r;
    return nullptr;
}

TEST(BenchCommand, SmokeRunWritesConsistentCsvJsonPlotsAndReport) {
    ScratchDir dir;
    const fs::path exact = dir.path / "exact.json", out = dir.path / "out";
    writeExactScene(exact);
    const CliRun r =
        runCli("bench --smoke --motion-frames 4 --motion-warmup 2 --budget 1 --snapshot-scales "
               "1,2 --out '" +
               out.string() + "' scenes/bench/tank_army.json '" + exact.string() + "'");
    ASSERT_EQ(r.status, 0) << r.out << r.err;
    for (const char* f : {"report.md", "results.csv", "results.json"})
        ASSERT_TRUE(fs::exists(out / f)) << f;

    // results.json: the five modes for each scene, the sweep point, both scaling curves.
    const json j = json::parse(slurp(out / "results.json"));
    EXPECT_EQ(j["plan"]["motion_frames"], 4);
    EXPECT_EQ(j["plan"]["motion_warmup"], 2);
    EXPECT_EQ(j["plan"]["budget_vpx"], 1.0);
    const std::vector<std::string> modes = {
        "near_vulkan", "near_vulkan_fragment", "near_reference", "far", "hybrid", "hybrid_gpu_far"};
    EXPECT_EQ(j["modes"], json(modes));
    const json& rows = j["rows"];
    for (const std::string scene : {"tank_army", "exact"})
        for (const std::string& mode : modes) {
            const json* m = row(rows, "modes", scene, mode);
            ASSERT_NE(m, nullptr) << scene << " " << mode;
            EXPECT_FALSE((*m)["frames"].empty());
            EXPECT_GT((*m)["frame_ms"].get<double>(), 0.0);
            EXPECT_GT((*m)["visible"].get<double>(), 0.0) << scene;
            // In motion (the scene with a path), 2 timed frames: median = mean, p90 = worst =
            // the slower one.
            if (scene == "tank_army") {
                const auto motion = [&](const char* k) { return (*m)[k].get<double>(); };
                EXPECT_GT(motion("in_motion_ms"), 0.0) << mode;
                EXPECT_DOUBLE_EQ(motion("in_motion_mean_ms"), motion("in_motion_ms"));
                EXPECT_GE(motion("in_motion_p90_ms"), motion("in_motion_ms"));
                EXPECT_EQ(motion("in_motion_worst_ms"), motion("in_motion_p90_ms"));
                // Both exact baselines in motion: all-near on Vulkan and on the CPU reference.
                EXPECT_NEAR(motion("in_motion_speedup_vs_all_near_reference") *
                                motion("in_motion_ms"),
                            motion("in_motion_all_near_reference_ms"),
                            1e-6 * motion("in_motion_all_near_reference_ms"))
                    << mode;
            }
            // --budget 1: every configuration but the sweeps measures the error budget.
            EXPECT_NE((*m)["selector"].get<std::string>().find("error_budget"), std::string::npos)
                << (*m)["selector"];
            // Who drew the near tier; the hybrid's is --near-backend auto's choice, and its
            // frames say the same where they drew near sprites.
            const std::string backend = (*m)["near_backend"].get<std::string>();
            if (mode == "near_vulkan" || mode == "near_vulkan_fragment")
                EXPECT_EQ(backend, "vulkan");
            if (mode == "near_reference") EXPECT_EQ(backend, "reference");
            // Who drew the far tier: the CPU blit (--far-backend cpu, the bench's default) beside
            // the Vulkan far pass.
            const std::string farBackend = (*m)["far_backend"].get<std::string>();
            if (mode == "far" || mode == "hybrid") EXPECT_EQ(farBackend, "cpu") << mode;
            if (mode == "hybrid_gpu_far") {
                EXPECT_EQ(farBackend, "vulkan");
                if ((*m)["far_entities"].get<double>() > 0)
                    EXPECT_GT((*m)["far_on_vulkan"].get<double>(), 0.0);
            }
            if (mode == "hybrid" || mode == "hybrid_gpu_far") {
                EXPECT_TRUE(backend == "vulkan" || backend == "reference") << backend;
                if ((*m)["near_entities"].get<double>() > 0)
                    EXPECT_EQ((*m)["near_on_vulkan"].get<double>() > 0, backend == "vulkan");
            }
            if (mode == "near_vulkan") {
                EXPECT_TRUE((*m)["error"].is_null()); // the truth itself
                EXPECT_EQ((*m)["far_entities"].get<double>(), 0.0);
            } else {
                ASSERT_TRUE((*m)["error"].is_object()) << scene << " " << mode;
            }
            if (mode == "far") {
                EXPECT_EQ((*m)["near_entities"].get<double>(), 0.0);
            }
            // Per-pixel and cell-rate near sprites draw the same image, and every mode has its
            // speed-up against the per-pixel near tier of the same run.
            if (mode == "near_vulkan_fragment") {
                EXPECT_EQ((*m)["error"]["mismatch_mean"].get<double>(), 0.0) << scene;
                EXPECT_EQ((*m)["near_cells_traced"].get<double>(), 0.0) << scene;
            }
            EXPECT_NEAR((*m)["speedup_vs_near_vulkan_fragment"].get<double>() *
                            (*m)["frame_ms"].get<double>(),
                        (*m)["near_vulkan_fragment_ms"].get<double>(),
                        1e-6 * (*m)["near_vulkan_fragment_ms"].get<double>())
                << scene << " " << mode;
        }
    // The CPU reference draws the Vulkan image exactly (the near tier's contract).
    for (const std::string scene : {"tank_army", "exact"}) {
        const json& e = (*row(rows, "modes", scene, "near_reference"))["error"];
        EXPECT_EQ(e["differing_pixels"].get<double>(), 0.0) << scene;
        EXPECT_EQ(e["mismatch_mean"].get<double>(), 0.0) << scene;
        EXPECT_TRUE(e["psnr_min"].is_null()) << scene; // equal images: infinite PSNR
    }
    // Exact scene: every view is canonical, so far and hybrid equal the truth pixel for pixel.
    for (const std::string mode : {"far", "hybrid", "hybrid_gpu_far"}) {
        const json& e = (*row(rows, "modes", "exact", mode))["error"];
        EXPECT_EQ(e["differing_pixels"].get<double>(), 0.0) << mode;
        EXPECT_EQ(e["mismatch_mean"].get<double>(), 0.0) << mode;
        EXPECT_EQ(e["far_displacement_worst_px"].get<double>(), 0.0) << mode;
    }
    // Tank army: worked out here, some visible tank is seen well away from every snapshot view,
    // so the all-far image must differ from the truth.
    {
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
        const json& e = (*row(rows, "modes", "tank_army", "far"))["error"];
        EXPECT_GT(e["mismatch_mean"].get<double>(), 0.0);
        EXPECT_GT(e["differing_pixels"].get<double>(), 0.0);
    }
    // Errors are fractions and distances; speed-ups are the ratio of the reported times.
    for (const json& m : rows) {
        if (!m["error"].is_null()) {
            EXPECT_GE(m["error"]["mismatch_mean"].get<double>(), 0.0);
            EXPECT_LE(m["error"]["mismatch_worst"].get<double>(), 1.0);
            EXPECT_GE(m["error"]["mismatch_worst"].get<double>(),
                      m["error"]["mismatch_mean"].get<double>());
        }
        EXPECT_NEAR(m["speedup_vs_all_near_vulkan"].get<double>() * m["frame_ms"].get<double>(),
                    m["all_near_vulkan_ms"].get<double>(),
                    1e-6 * m["all_near_vulkan_ms"].get<double>());
    }
    int sweeps = 0;
    std::set<double> counts, sides;
    for (const json& m : rows) {
        sweeps += m["group"] == "sweep";
        if (m["group"] == "scaling_entities") counts.insert(m["entities"].get<double>());
        if (m["group"] == "scaling_size") sides.insert(m["param"].get<double>());
    }
    // error_px far_at 1, and error_budget 1 vpx with each of the two snapshot scales.
    EXPECT_EQ(sweeps, 3);
    EXPECT_EQ(j["plan"]["sweeps"]["snapshot_scales"], json({"x1", "x2"}));
    // Each budget point is its own configuration, drawn with its own scale (a shared one would
    // report one snapshot scale twice); its speed-up against the fastest exact path is the
    // faster of near_reference and near_vulkan in motion over its own in-motion ms.
    std::map<std::string, int> budgetScales;
    for (const json& m : rows) {
        if (m["family"] != "budget (error_budget)") continue;
        budgetScales[m["setting"].get<std::string>()] = m["snapshot_scale"].get<int>();
        const double ref = m["in_motion_all_near_reference_ms"].get<double>(),
                     vk = m["in_motion_all_near_vulkan_ms"].get<double>();
        EXPECT_DOUBLE_EQ(m["in_motion_fastest_exact_ms"].get<double>(), std::min(ref, vk));
        EXPECT_NEAR(m["in_motion_speedup_vs_fastest_exact"].get<double>() *
                        m["in_motion_ms"].get<double>(),
                    std::min(ref, vk), 1e-6 * std::min(ref, vk));
        EXPECT_GT(m["in_motion_cache_bytes"].get<double>(), 0.0);
    }
    EXPECT_EQ(budgetScales, (std::map<std::string, int>{{"error_budget 1 vpx, x1", 1},
                                                        {"error_budget 1 vpx, x2", 2}}));
    // The modes keep the scene's own snapshot scale under --budget; those with no far tier name
    // none.
    const Scene army = loadScene("scenes/bench/tank_army.json");
    EXPECT_EQ((*row(rows, "modes", "tank_army", "hybrid"))["snapshot_scale"],
              army.selector.snapshotScale);
    EXPECT_EQ((*row(rows, "modes", "tank_army", "near_vulkan"))["snapshot_scale"], 0);
    EXPECT_EQ(counts, (std::set<double>{4, 12}));
    EXPECT_EQ(sides, (std::set<double>{16, 32}));

    // results.csv: a header and one row per JSON row, every row as wide as the header.
    std::istringstream csv(slurp(out / "results.csv"));
    std::string line;
    ASSERT_TRUE(std::getline(csv, line));
    const auto header = csvFields(line);
    std::map<std::string, std::size_t> col;
    for (std::size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
    for (const char* c : {"group",
                          "scene",
                          "mode",
                          "frame_ms",
                          "speedup_vs_all_near_vulkan",
                          "mismatch_mean",
                          "far_displacement_worst_vpx",
                          "rays_per_s",
                          "voxel_steps_per_s",
                          "blit_pixels_per_s",
                          "memcpy_pixels_per_s",
                          "cache_bytes",
                          "near_entities",
                          "far_entities",
                          "cold_bake_ms",
                          "in_motion_near_ms",
                          "in_motion_near_entities",
                          "in_motion_far_entities",
                          "snapshot_scale",
                          "in_motion_speedup_vs_fastest_exact",
                          "in_motion_cache_bytes"})
        ASSERT_TRUE(col.count(c)) << c;
    for (const FrameFigure& f : kFrameFigures) EXPECT_TRUE(col.count(f.name)) << f.name;
    std::size_t n = 0;
    while (std::getline(csv, line)) {
        const auto f = csvFields(line);
        ASSERT_EQ(f.size(), header.size()) << line;
        EXPECT_GT(std::stod(f[col["frame_ms"]]), 0.0) << line;
        const json& m = rows[n];
        EXPECT_EQ(f[col["mode"]], m["mode"].get<std::string>());
        EXPECT_EQ(std::stoi(f[col["snapshot_scale"]]), m["snapshot_scale"].get<int>());
        EXPECT_NEAR(std::stod(f[col["frame_ms"]]), m["frame_ms"].get<double>(),
                    1e-5 * m["frame_ms"].get<double>());
        ++n;
    }
    EXPECT_EQ(n, rows.size());

    // The frame figures (compose/frame_figures.hpp) in every row and every frame of the JSON: a
    // row's figure is the mean of its frames' (one sampled frame here: equal), and the visible
    // entities are those drawn near, far, or both while cross-fading.
    ASSERT_EQ(j["frame_figures"].size(), kFrameFigureCount);
    for (std::size_t i = 0; i < kFrameFigureCount; ++i)
        EXPECT_EQ(j["frame_figures"][i]["name"], kFrameFigures[i].name);
    for (const json& m : rows) {
        ASSERT_EQ(m["frames"].size(), 1u);
        for (const FrameFigure& f : kFrameFigures) {
            ASSERT_TRUE(m.contains(f.name)) << f.name;
            ASSERT_TRUE(m["frames"][0].contains(f.name)) << f.name;
            EXPECT_NEAR(m[f.name].get<double>(), m["frames"][0][f.name].get<double>(),
                        1e-9 * std::abs(m[f.name].get<double>()))
                << f.name;
        }
        EXPECT_EQ(m["visible"].get<double>(), m["near_entities"].get<double>() +
                                                  m["far_entities"].get<double>() -
                                                  m["fading_entities"].get<double>())
            << m["mode"] << " " << m["setting"];
    }

    // report.md: names every scene, and every plot it embeds exists; the JSON lists the same plots.
    const std::string report = slurp(out / "report.md");
    // The time split of the hybrid frame has a column per time step of the figure table.
    std::string steps = "| scene |";
    for (const FrameFigure& f : kFrameFigures)
        if (f.timeStep) steps += " " + f.words() + " |";
    EXPECT_NE(report.find(steps + " other | total |"), std::string::npos) << steps;
    // Every goal of the goal table is marked met or not in each measured column.
    for (const char* goal :
         {"| speed-up ≥ 10× |", "| mean footprint mismatch ≤ 2 % (coverage only) |",
          "| no far entity displaced > 1 virtual px |"}) {
        const auto at = report.find(goal);
        ASSERT_NE(at, std::string::npos) << goal;
        const std::string line = report.substr(at, report.find('\n', at) - at);
        std::size_t marks = 0;
        for (const char* mark : {"✓", "✗"})
            for (auto p = line.find(mark); p != std::string::npos; p = line.find(mark, p + 1))
                ++marks;
        EXPECT_EQ(marks + (line.find("none measured") != std::string::npos), 3u) << line;
    }
    EXPECT_NE(report.find("tank_army"), std::string::npos);
    EXPECT_NE(report.find("exact"), std::string::npos);
    // The error budget in motion (the smoke plan sweeps 1 vpx on the first scene): the near
    // tier's share of the in-motion frame is part of the frame, so the ceiling (per-pixel mean
    // over the near ms) is at least the measured mean speed-up; the report states the target
    // with a verdict and the ceiling for the scene.
    const json* budget = nullptr;
    for (const json& m : rows)
        if (m["family"] == "budget (error_budget)" && m["scene"] == "tank_army") budget = &m;
    ASSERT_NE(budget, nullptr);
    const double nearMs = (*budget)["in_motion_near_ms"].get<double>();
    EXPECT_GT(nearMs, 0.0);
    EXPECT_LE(nearMs, (*budget)["in_motion_mean_ms"].get<double>());
    EXPECT_GE((*budget)["in_motion_near_entities"].get<double>() +
                  (*budget)["in_motion_far_entities"].get<double>(),
              1.0);
    EXPECT_NE(report.find("## The error budget in motion: target and bound"), std::string::npos);
    const auto verdictAt = report.find("- **tank_army**: at 1 vpx, ");
    ASSERT_NE(verdictAt, std::string::npos) << report;
    const std::string verdictLine =
        report.substr(verdictAt, report.find('\n', verdictAt) - verdictAt);
    EXPECT_NE(verdictLine.find("would give at most"), std::string::npos) << verdictLine;
    EXPECT_NE(verdictLine.find("PSNR ≥ 40 dB"), std::string::npos) << verdictLine;
    // The measured displacement stands beside the prediction wherever far entities were
    // measured alone on the sampled frames.
    const json& err = (*budget)["error"];
    if (err.is_object() && err["far_alone_entities"].is_number() &&
        err["far_alone_entities"].get<double>() > 0.0)
        EXPECT_NE(verdictLine.find("(measured worst "), std::string::npos) << verdictLine;
    // Below 40 dB the verdict says how many differing pixels 40 dB would allow, from the worst
    // frame's own figures.
    const json& psnrMin = (*budget)["in_motion_psnr_min"]; // null where +inf (equal frames)
    if (psnrMin.is_number() && psnrMin.get<double>() < 40.0) {
        EXPECT_GT((*budget)["in_motion_psnr_min_differing_pixels"].get<double>(), 0.0);
        EXPECT_NE(verdictLine.find("40 dB asks for a "), std::string::npos) << verdictLine;
    }
    // The speed–error frontier: a row per snapshot scale at the one smoke budget; on the Pareto
    // frontier only points faster than the fastest exact path, and one of them if any is.
    const auto frontierAt = report.find("## Speed–error frontier");
    ASSERT_NE(frontierAt, std::string::npos) << report;
    const std::string frontier =
        report.substr(frontierAt, report.find("\n## ", frontierAt + 1) - frontierAt);
    std::size_t frontierRows = 0, onFrontier = 0;
    for (const char* variant : {"| x1 | 1.00 vpx |", "| x2 | 1.00 vpx |"}) {
        const auto at = frontier.find(variant);
        ASSERT_NE(at, std::string::npos) << variant << "\n" << frontier;
        const std::string line = frontier.substr(at, frontier.find('\n', at) - at);
        ++frontierRows;
        onFrontier += line.ends_with("| P |");
    }
    EXPECT_EQ(frontierRows, 2u);
    std::size_t faster = 0;
    for (const json& m : rows)
        faster += m["family"] == "budget (error_budget)" &&
                  m["in_motion_speedup_vs_fastest_exact"].get<double>() > 1.0;
    EXPECT_LE(onFrontier, faster) << frontier;
    EXPECT_EQ(onFrontier > 0, faster > 0) << frontier;
    std::set<std::string> embedded;
    const std::regex image(R"(!\[[^\]]*\]\(([^)]+)\))");
    for (auto it = std::sregex_iterator(report.begin(), report.end(), image);
         it != std::sregex_iterator(); ++it)
        embedded.insert((*it)[1]);
    for (const std::string& png : embedded) EXPECT_TRUE(fs::exists(out / png)) << png;
    std::set<std::string> listed;
    for (const json& p : j["plots"]) listed.insert(p.get<std::string>());
    EXPECT_EQ(embedded, listed);
    if (std::system("command -v gnuplot >/dev/null 2>&1") == 0) {
        EXPECT_EQ(listed,
                  (std::set<std::string>{"speed_error.png", "motion_error.png", "frontier.png",
                                         "scaling_entities.png", "scaling_size.png"}))
            << j["plot_note"];
    } else {
        EXPECT_NE(report.find("gnuplot"),
                  std::string::npos); // the report says why there are no plots
    }
}

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

// `bench near --out`: header and rows come from one column table (apps/bench/harness.hpp
// CsvWriter), so the header keeps its 15 names in order and every row is as wide as it.
TEST(BenchCommand, NearSubcommandStillRunsBesideTheSceneBench) {
    ScratchDir dir;
    const fs::path csvFile = dir.path / "sub" / "near.csv";
    const CliRun r = runCli("bench near --entities 3 --repeat 1 --warmup 0 --no-alternatives "
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
    ASSERT_TRUE(std::getline(csv, row));
    EXPECT_EQ(std::count(row.begin(), row.end(), ','), 14) << row;
    EXPECT_EQ(row.rfind("3,", 0), 0u) << row;
    EXPECT_NE(row.find(",hull-instanced,"), std::string::npos) << row;
    EXPECT_FALSE(std::getline(csv, extra)) << extra;
}

} // namespace
} // namespace voxtier
