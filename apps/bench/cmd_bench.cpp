// `voxtier bench [SCENES...] [--quick] [--out DIR]`: every render mode side by side on the bench
// scenes, the selector sweeps and the scaling curves, written as results.csv, results.json, PNG
// plots and report.md (apps/bench/suite.hpp says how it measures, apps/bench/report.hpp what it
// writes). The bench subcommands (`bench near`, ...) are registered here too, in one list.
#include "apps/bench/report.hpp"
#include "apps/bench/suite.hpp"
#include "apps/cache_dir_options.hpp"
#include "apps/cli_options.hpp"
#include "apps/commands.hpp"
#include "core/error.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

namespace voxtier::cli {

namespace {

namespace fs = std::filesystem;

const char* const kDefaultScenes[] = {"scenes/bench/tank_army.json", "scenes/bench/vox_crowd.json",
                                      "scenes/bench/rts_topdown.json", "scenes/bench/rts_pan.json"};

void prepareOutput(const std::string& out) {
    if (out.empty()) throw InputError("", "--out", "expected a directory");
    std::error_code ec;
    if (fs::exists(out, ec) && !fs::is_directory(out, ec))
        throw InputError(out, "--out", "exists and is not a directory");
    fs::create_directories(out, ec);
    if (ec) throw InputError(out, "--out", "cannot create the directory: " + ec.message());
    const fs::path probe = fs::path(out) / ".voxtier_bench_write_test";
    {
        std::ofstream f(probe);
        if (!f) throw InputError(out, "--out", "cannot write into the directory");
    }
    fs::remove(probe, ec);
}

void runBench(bench::SuiteOptions options) {
    if (options.scenes.empty()) {
        for (const char* s : kDefaultScenes) {
            if (!fs::exists(s))
                throw InputError(
                    s, "SCENES",
                    "bench scene not found (run from the repository root, or name the scenes)");
            options.scenes.push_back(s);
        }
    }
    bench::makePlan(options); // option errors before any work
    prepareOutput(options.out);
    const bench::SuiteResults results = bench::runSuite(options);
    const auto files = bench::writeReport(results, options.out);

    // A short summary on stdout: each scene's hybrid against all-near, with the error it costs.
    std::printf("voxtier bench (%s): %.0f s, Vulkan device: %s\n", results.plan.preset.c_str(),
                results.wallSeconds, results.vulkanDevice.c_str());
    for (const bench::Measurement& m : results.rows) {
        if (m.group != "modes" || bench::info(m.mode).isTruth) continue;
        std::printf("  %-14s %-15s %8.2f ms  (all-near Vulkan %8.2f ms, %5.1fx)", m.scene.c_str(),
                    bench::toString(m.mode), m.frameMs(), m.baselineMs, m.speedup);
        if (m.hasError)
            std::printf(
                "  mismatch mean %.2f%% worst %.2f%%, far displacement %.1f px (%.2f virtual px)",
                100 * m.mismatchMean, 100 * m.mismatchWorst, m.displacementWorstPx,
                m.displacementWorstCells);
        if (m.motionMs > 0) std::printf("  in motion %.2f ms", m.motionMs);
        if (!m.farBackend.empty()) std::printf(" (far tier: %s)", m.farBackend.c_str());
        std::printf("\n");
    }
    for (const std::string& n : results.notes) std::printf("  note: %s\n", n.c_str());
    for (const std::string& f : files) std::printf("-> %s\n", f.c_str());
}

} // namespace

void addBenchCommand(CLI::App& app) {
    CLI::App* bench = app.add_subcommand(
        "bench",
        "Speed against error: every mode side by side, selector sweeps, scaling curves, a report");
    bench->require_subcommand(0, 1);
    auto o = std::make_shared<bench::SuiteOptions>();
    bench
        ->add_option("scenes", o->scenes,
                     "Scene files (default: the four in scenes/bench); the first also gets the "
                     "sweeps and scaling curves")
        ->check(CLI::ExistingFile);
    bench->add_flag("--quick", o->quick,
                    "Fewer repeats, path frames and sweep points (under 2 minutes)");
    bench
        ->add_option("-o,--out", o->out,
                     "Output directory (report.md, results.csv, results.json, plots)")
        ->capture_default_str();
    bench
        ->add_option("--repeats", o->repeats, "Timed passes per path frame (default: 7, --quick 3)")
        ->check(atLeast(1));
    bench
        ->add_option("--warmup", o->warmup,
                     "Untimed passes first (default 1; cold bakes are measured in the first)")
        ->check(atLeast(1, "the cold bakes are measured in the first warm-up pass"));
    bench
        ->add_option("--frames", o->pathFrames,
                     "Path frames sampled per scene (default: 6, --quick 2)")
        ->check(atLeast(1));
    bench
        ->add_option("--motion-frames", o->motionFrames,
                     "Consecutive path frames of the in-motion run, cold start included "
                     "(default: 48, --quick 16); an animated crowd fills its snapshot cache "
                     "over one animation cycle")
        ->check(atLeast(2));
    bench
        ->add_option("--motion-warmup", o->motionWarmup,
                     "Of those, the first frames reported as the cold start, not timed in motion "
                     "(default: 6, --quick 4)")
        ->check(atLeast(1));
    bench->add_option("--size", o->size, "Image size of every scene (default: each scene's)")
        ->type_name("WxH")
        ->check(imageSize());
    bench->add_flag("!--no-sweeps", o->sweeps,
                    "Skip the selector / view set / sigma / cross-fade sweeps");
    bench->add_flag("!--no-scaling", o->scaling, "Skip the scaling curves");
    addNearRateOption(*bench, o->nearRate);
    addFarBlitOption(*bench, o->farBlit);
    addChoiceOption(*bench, "--far-backend", o->farBackend, kFarBackendNames, "far backend",
                    "Who draws the far tier of the hybrid and far rows and the sweeps: cpu "
                    "(default: the CPU blit, beside the hybrid_gpu_far row's Vulkan far pass), "
                    "vulkan, or auto (Vulkan on a GPU, the CPU blit on a CPU device); same image");
    auto cull = std::make_shared<CullSwitches>();
    addCullFlags(*bench, *cull);
    bench->add_flag("!--no-cost-bound", o->costBound,
                    "The error budget's planner keeps every entity its budget sends far, whatever "
                    "its bakes and blit cost (default: it draws near what would not pay): every "
                    "snapshot scale's error on the same plan");
    bench
        ->add_option("--budget", o->budgetVpx,
                     "Measure every scene with the error_budget selector at this many virtual "
                     "pixels (default: each scene's own selector)")
        ->type_name("VPX")
        ->check(numberIn(0.01, 64.0, "vpx"));
    // The same bounds as bench::makePlan's, which checks them again for callers other than
    // the command line.
    bench->add_option("--entity-counts", o->entityCounts, "Entity counts of the scaling curve")
        ->check(intList(1, 100000));
    bench->add_option("--model-sides", o->modelSides, "Tank sides (voxels) of the model-size curve")
        ->check(intList(8, Limits::kMaxModelDim));
    bench
        ->add_option("--snapshot-scales", o->snapshotScales,
                     "Snapshot scales of the error_budget sweep, each run at every budget: the far "
                     "tier's snapshots at that multiple of the sprite's sigma, 1..4 (default: "
                     "1,2,3,4; --quick 1,3)")
        ->check(intList(1, kMaxSnapshotScale));
    // Test-only: tiny images and entity counts, one repeat, one sweep point (tests/bench_cli_test).
    bench->add_flag("--smoke", o->smoke, "")->group("");
    auto cacheDir = std::make_shared<CacheDirArgs>();
    addCacheDirOptions(*bench, *cacheDir, "every configuration reads its snapshots from it");
    bench->callback([bench, o, cacheDir, cull] {
        o->occlusionCull = cull->occlusionCull;
        o->earlyDepthTest = cull->earlyDepthTest;
        o->cacheDir = cacheDir->dir;
        o->cacheDirBytes = cacheDir->limitBytes();
        if (bench->get_subcommands().empty()) runBench(*o);
    });

    // The bench subcommands, one line each.
    addBenchNearCommand(*bench);
    addBenchEditsCommand(*bench);
}

} // namespace voxtier::cli
