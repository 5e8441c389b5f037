// `voxtier bench [SCENES...] [--quick] [--out DIR]`: every render mode side by side on the bench
// scenes, the selector sweeps and the scaling curves, written as results.csv and results.json
// (apps/bench/results.hpp), then PNG plots and report.md (apps/bench/report.hpp);
// apps/bench/suite.hpp says how it measures, apps/bench/presets.hpp how much. The bench subcommands
// (`bench near`, ...) are registered here too, in one list.
#include "apps/bench/presets.hpp"
#include "apps/bench/report.hpp"
#include "apps/bench/results.hpp"
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
    // The results files first, whole, apart from the report (which reads results.csv).
    std::vector<std::string> files = bench::writeResults(results, options.out);
    for (const std::string& f : bench::writeReport(results, options.out)) files.push_back(f);

    // On stdout, the report's lead, then every mode of every scene against all-near on Vulkan.
    std::printf("voxtier bench (%s): %.0f s, Vulkan device: %s\n", results.plan.name.c_str(),
                results.wallSeconds, results.vulkanDevice.c_str());
    for (const std::string& line : bench::leadLines(results, /*markdown=*/false))
        std::printf("  %s\n", line.c_str());
    for (const bench::Measurement& m : results.rows) {
        if (m.group != "modes" || bench::info(m.mode).isTruth) continue;
        std::printf("  %-14s %-15s %8.2f ms  (all-near Vulkan %8.2f ms, %5.1fx)", m.scene.c_str(),
                    bench::toString(m.mode), m.frameMs(), m.allNearVulkanMs,
                    m.speedupVsAllNearVulkan);
        if (m.hasError)
            std::printf(
                "  mismatch mean %.2f%% worst %.2f%%, far displacement %.1f px (%.2f virtual px)",
                100 * m.error.mismatchMean, 100 * m.error.mismatchWorst,
                m.error.farDisplacementWorstPx, m.error.farDisplacementWorstVpx);
        if (m.motion.ms > 0) std::printf("  in motion %.2f ms", m.motion.ms);
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
    bench->add_flag_callback(
        "--quick", [o] { o->preset = o->preset == "smoke" ? "smoke" : "quick"; },
        "Fewer repeats, path frames and sweep points (under 2 minutes)");
    // Test-only: tiny images and entity counts, one repeat, one sweep point (tests/bench_cli_test).
    bench
        ->add_flag_callback(
            "--smoke", [o] { o->preset = "smoke"; }, "")
        ->group("");
    bench
        ->add_option("-o,--out", o->out,
                     "Output directory (report.md, results.csv, results.json, plots)")
        ->capture_default_str();
    // The preset's figures a flag overrides, and their bounds: one table with makePlan's.
    for (const bench::CountOverride& c : bench::countOverrides())
        bench
            ->add_option(c.flag, o.get()->*c.given,
                         std::string(c.help) + " " + bench::presetDefaults(c.field))
            ->check(atLeast(c.least, c.why));
    for (const bench::ListOverride& l : bench::listOverrides())
        bench
            ->add_option(l.flag, o.get()->*l.given,
                         std::string(l.help) + " " + bench::presetDefaults(l.field))
            ->check(intList(l.lo, l.hi));
    bench->add_option("--size", o->size, "Image size of every scene (default: each scene's)")
        ->type_name("WxH")
        ->check(imageSize());
    bench->add_flag("!--no-sweeps", o->sweeps,
                    "Skip the selector / view set / sigma / cross-fade sweeps");
    bench->add_flag("!--no-scaling", o->scaling, "Skip the scaling curves");
    addFrameFlags(
        *bench, o->frame,
        {.farBackend = "Who draws the far tier of the hybrid and far rows and the sweeps: cpu "
                       "(default: the CPU blit, beside the hybrid_gpu_far row's Vulkan far pass), "
                       "vulkan, or auto (Vulkan on a GPU, the CPU blit on a CPU device); same "
                       "image",
         .costBound = "The error budget's planner keeps every entity its budget sends far, "
                      "whatever its bakes and blit cost (default: it draws near what would not "
                      "pay): every snapshot scale's error on the same plan"});
    bench
        ->add_option("--budget", o->budgetVpx,
                     "Measure every scene with the error_budget selector at this many virtual "
                     "pixels (default: each scene's own selector)")
        ->type_name("VPX")
        ->check(numberIn(0.01, 64.0, "vpx"));
    auto cacheDir = std::make_shared<CacheDirArgs>();
    addCacheDirOptions(*bench, *cacheDir, "every configuration reads its snapshots from it");
    bench->callback([bench, o, cacheDir] {
        o->frame.cacheDir = cacheDir->dir;
        o->frame.cacheDirBytes = cacheDir->limitBytes();
        if (bench->get_subcommands().empty()) runBench(*o);
    });

    // The bench subcommands, one line each.
    addBenchNearCommand(*bench);
    addBenchEditsCommand(*bench);
}

} // namespace voxtier::cli
