// `voxtier bench edits`: what a voxel edit costs the far tier (CONTRACT.md §4 invalidation), side
// by side in one run, medians over repeats.
//  1. Scenes: the Embree scene as one flat BVH against bricks instanced into a top-level scene,
//     for each brick size: full build, the update after a single-voxel edit (flat: a rebuild),
//     and the trace speed of a full bake of every view. This is the measurement behind
//     kDefaultBrickSize (impostor_cache/voxel_scene.hpp).
//  2. Single-voxel edits on a 64^3 ball (or --size / a .vox file), through the snapshot cache as
//     the frame uses it: every view warm, one surface voxel removed or put back, every view asked
//     for again. Incremental refresh (re-trace only the cells whose rays reach the edit) against
//     a fresh cache after the same edit (scene built from scratch, every view baked whole: what
//     an edit cost before incremental refresh). Cells re-traced / cells of a full bake, ms, and a
//     byte comparison of the two results.
#include "apps/bench/harness.hpp"
#include "apps/cli_options.hpp"
#include "apps/commands.hpp"
#include "core/error.hpp"
#include "core/procedural.hpp"
#include "core/view_set.hpp"
#include "core/vox_reader.hpp"
#include "impostor_cache/snapshot_baker.hpp"
#include "impostor_cache/snapshot_cache.hpp"
#include "impostor_cache/surface_voxels.hpp"
#include "impostor_cache/voxel_scene.hpp"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace voxtier::cli {

namespace {

struct BenchEditsArgs {
    std::vector<std::string> inputs; ///< extra .vox models for the scene comparison
    int size = 64;                   ///< edge of the ball of part 2 (and of part 1's balls)
    std::string edited;              ///< a .vox file edited in part 2 instead of the ball
    double sigma = 1.0;
    ViewSet views = ViewSet::Cube26;
    int repeats = 7;
    std::vector<int> bricks = {0, 16, 32};
    int threads = 0;
    bool scenes = true;
};

/// The edge of a voxelised ball: even (it is a diameter), 2..Limits::kMaxModelDim.
CLI::Validator ballEdge() {
    const std::string range = "[2, " + std::to_string(Limits::kMaxModelDim) + "]";
    const CLI::Validator inRange = intIn(2, Limits::kMaxModelDim);
    return CLI::Validator(
        [range, inRange](std::string& text) {
            return inRange(text).empty() && std::stoi(text) % 2 == 0
                       ? std::string()
                       : "expected an even integer in " + range + ", got '" + text + "'";
        },
        "even, in " + range);
}

std::string dimsText(glm::ivec3 d) {
    return std::to_string(d.x) + "x" + std::to_string(d.y) + "x" + std::to_string(d.z);
}

struct NamedModel {
    std::string name;
    std::shared_ptr<VoxelModel> model;
};

std::shared_ptr<VoxelModel> loadModel(const std::string& file) {
    const VoxFile vox = readVoxFile(file);
    if (vox.models.empty()) throw InputError(file, "models", "file has no model");
    return std::make_shared<VoxelModel>(std::filesystem::path(file).stem().string(), vox.palette,
                                        std::vector<VoxelGrid>{vox.models[0]});
}

/// A single-voxel edit that changes what can be seen: a surface voxel removed, or (every other
/// repeat) put back. Seeded, so every run edits the same voxels.
struct SurfaceToggler {
    std::vector<glm::ivec3> surface;
    std::mt19937 rng{20240611u};
    std::optional<std::pair<glm::ivec3, std::uint8_t>> removed;

    explicit SurfaceToggler(const VoxelGrid& g) {
        const glm::ivec3 n = g.dims();
        for (int z = 0; z < n.z; ++z)
            for (int y = 0; y < n.y; ++y)
                for (int x = 0; x < n.x; ++x)
                    if (isSurfaceVoxel(g, {x, y, z})) surface.push_back({x, y, z});
    }
    /// Applies the next edit; returns false when the model has no surface voxel.
    bool next(VoxelModel& m) {
        if (removed) {
            m.setVoxel(0, removed->first, removed->second);
            removed.reset();
            return true;
        }
        if (surface.empty()) return false;
        const glm::ivec3 p = surface[rng() % surface.size()];
        removed = std::make_pair(p, m.frame(0).at(p));
        m.setVoxel(0, p, 0);
        return true;
    }
};

void benchScenes(const BenchEditsArgs& a, const std::vector<NamedModel>& models, ViewSet set) {
    std::vector<int> bricks = a.bricks;
    // The flat scene first: every "vs flat" column divides by it.
    bricks.erase(std::remove(bricks.begin(), bricks.end(), 0), bricks.end());
    bricks.insert(bricks.begin(), 0);
    const int reps = a.repeats;
    std::printf(
        "1. Embree scene: one flat BVH vs bricks instanced in a top-level scene (%d views, sigma "
        "%g; medians of %d)\n"
        "   build = scene from scratch; bake = every view, full, from that scene; 1st edit / "
        "edit = the scene\n"
        "   after a first / a later single-voxel surface edit (flat: rebuilt whole; bricks: the "
        "bricks the\n"
        "   edit reaches + the top level); rebuilt = bricks built by a later edit; bake' = every "
        "view, full,\n"
        "   from the scene after the edits. 'flat, bricks N once edited' is the default "
        "(VoxelSceneOptions).\n\n",
        viewCount(set), a.sigma, reps);
    struct Variant {
        std::string label;
        VoxelSceneOptions options;
    };
    std::vector<Variant> variants;
    for (int edge : bricks) {
        VoxelSceneOptions so;
        so.brickSize = edge;
        so.flatUntilEdited = false;
        variants.push_back({edge == 0 ? "flat" : "bricks " + std::to_string(edge), so});
    }
    {
        VoxelSceneOptions so; // the default
        variants.push_back({"flat, bricks " + std::to_string(so.brickSize) + " once edited", so});
    }
    for (const NamedModel& nm : models) {
        const VoxelGrid& grid0 = nm.model->frame(0);
        std::printf("   %s: %s, %zu voxels\n", nm.name.c_str(), dimsText(grid0.dims()).c_str(),
                    grid0.solidCount());
        std::printf("   %-28s %7s %9s %9s %8s %7s %9s %8s %7s %9s %7s %s\n", "scene", "prims",
                    "build ms", "bake ms", "Mrays/s", "vs flat", "1st edit", "edit ms", "rebuilt",
                    "bake' ms", "vs flat", "same bytes");
        std::vector<Snapshot> reference;
        for (int v = 0; v < viewCount(set); ++v)
            reference.push_back(bakeSnapshotScalar(grid0, set, v, a.sigma));
        struct Result {
            std::vector<double> buildMs, bakeMs, firstEditMs, editMs, bakeAfterMs;
            std::uint64_t rays = 0;
            std::size_t prims = 0, rebuilt = 0;
            bool same = true;
        };
        std::vector<Result> results(variants.size());
        // A private copy of the model; every variant sees the same edits (a surface voxel
        // removed, then put back, so each repeat starts from the same model).
        VoxelModel m(nm.name, nm.model->palette(), {grid0});
        SurfaceToggler toggler(grid0);
        for (int r = 0; r < reps; ++r) {
            // One repeat = every variant once, interleaved, so load changes hit all alike.
            const std::mt19937 rngAtStart = toggler.rng;
            for (std::size_t k = 0; k < variants.size(); ++k) {
                Result& res = results[k];
                toggler.rng = rngAtStart; // the same voxel for every variant
                auto bakeAll = [&](const VoxelScene& scene, bool check) {
                    BakeStats st;
                    for (int v = 0; v < viewCount(set); ++v) {
                        const Snapshot s = bakeSnapshot(scene, set, v, a.sigma, {}, &st);
                        if (check && s.cells != reference[std::size_t(v)].cells) res.same = false;
                    }
                    res.rays = st.rays;
                    return st.ms;
                };
                auto edited = [&](const VoxelScene& previous) -> std::unique_ptr<VoxelScene> {
                    const std::uint64_t before = m.version();
                    if (!toggler.next(m)) return nullptr;
                    return std::make_unique<VoxelScene>(previous, m.frame(0),
                                                        m.dirtySince(before, 0).value_or(Box3i{}));
                };
                const VoxelScene scene(m.frame(0), variants[k].options);
                res.buildMs.push_back(scene.buildMs());
                res.prims = scene.primitiveCount();
                res.bakeMs.push_back(bakeAll(scene, r == 0));
                const auto first = edited(scene);
                if (!first) continue;
                res.firstEditMs.push_back(first->buildMs());
                const auto second = edited(*first);
                res.editMs.push_back(second->buildMs());
                res.rebuilt = second->buildStats().bricksBuilt;
                res.bakeAfterMs.push_back(bakeAll(*second, r == 0));
            }
        }
        const double flatBake = median(results[0].bakeMs);
        for (std::size_t k = 0; k < variants.size(); ++k) {
            const Result& res = results[k];
            const double bake = median(res.bakeMs), bakeAfter = median(res.bakeAfterMs);
            std::printf("   %-28s %7zu %9.2f %9.2f %8.2f %6.2fx %9.3f %8.3f %7zu %9.2f %6.2fx %s\n",
                        variants[k].label.c_str(), res.prims, median(res.buildMs), bake,
                        res.rays / bake / 1e3, flatBake / bake, median(res.firstEditMs),
                        median(res.editMs), res.rebuilt, bakeAfter,
                        bakeAfter > 0.0 ? flatBake / bakeAfter : 0.0, res.same ? "yes" : "NO");
        }
        std::printf("\n");
    }
}

void benchEdits(const BenchEditsArgs& a, const NamedModel& nm, ViewSet set) {
    const int reps = a.repeats;
    const int views = viewCount(set);
    const VoxelSceneOptions defaults;
    std::printf(
        "2. Single-voxel surface edits on %s (%s, %zu voxels): every one of the %d views asked "
        "for\n"
        "   again after each edit, as a frame asks (sigma %g, default scene options: bricks %d, "
        "flat until\n"
        "   edited). incremental = the cache refreshes each view from its stale snapshot; full = "
        "a fresh\n"
        "   cache after the same edit (scene from scratch, every view baked whole: the cost "
        "before\n"
        "   incremental refresh). The first edit of a model also builds its bricks, so it is "
        "shown apart;\n"
        "   medians over the %d edits after it.\n\n",
        nm.name.c_str(), dimsText(nm.model->frame(0).dims()).c_str(),
        nm.model->frame(0).solidCount(), views, a.sigma, defaults.brickSize, reps);
    VoxelModel m(nm.name, nm.model->palette(), {nm.model->frame(0)});
    SurfaceToggler toggler(m.frame(0));
    SnapshotCache incremental;
    auto askAll = [&](SnapshotCache& cache, std::vector<std::shared_ptr<const Snapshot>>* out) {
        std::vector<std::shared_ptr<const Snapshot>> got(static_cast<std::size_t>(views));
        // As the frame asks (impostor_cache/far_frame.cpp): distinct views in parallel.
        tbb::parallel_for(0, views,
                          [&](int v) { got[std::size_t(v)] = cache.get(m, 0, set, v, a.sigma); });
        if (out) *out = std::move(got);
    };
    askAll(incremental, nullptr); // warm: every view at the starting version
    struct Sample {
        double incMs = 0.0, fullMs = 0.0, share = 0.0;
        std::uint64_t retraced = 0, cells = 0, fullRefreshes = 0, bricks = 0;
        bool identical = true;
    };
    auto oneEdit = [&]() -> std::optional<Sample> {
        if (!toggler.next(m)) return std::nullopt;
        Sample s;
        const SnapshotCacheCounters c0 = incremental.counters();
        std::vector<std::shared_ptr<const Snapshot>> inc, full;
        s.incMs = timedMs([&] { askAll(incremental, &inc); });
        const SnapshotCacheCounters c1 = incremental.counters();
        SnapshotCache fresh;
        s.fullMs = timedMs([&] { askAll(fresh, &full); });
        for (int v = 0; v < views; ++v)
            if (inc[std::size_t(v)]->cells != full[std::size_t(v)]->cells) s.identical = false;
        s.retraced = c1.cellsRetraced - c0.cellsRetraced;
        s.cells = c1.cellsRefreshed - c0.cellsRefreshed;
        s.fullRefreshes = c1.fullRefreshes - c0.fullRefreshes;
        s.bricks = c1.bricksRebuilt - c0.bricksRebuilt;
        s.share = s.cells ? double(s.retraced) / double(s.cells) : 0.0;
        return s;
    };
    const std::optional<Sample> first = oneEdit();
    if (!first) {
        std::printf("   the model has no surface voxel: nothing to edit\n");
        return;
    }
    std::vector<Sample> later;
    for (int r = 0; r < reps; ++r) later.push_back(*oneEdit());
    auto med = [&](auto field) {
        std::vector<double> v;
        for (const Sample& s : later) v.push_back(double(field(s)));
        return median(v);
    };
    bool identical = first->identical;
    std::uint64_t fullRefreshes = first->fullRefreshes, retraced = 0, cells = 0;
    for (const Sample& s : later) {
        identical = identical && s.identical;
        fullRefreshes += s.fullRefreshes;
        retraced += s.retraced;
        cells += s.cells;
    }
    std::printf("   %-14s %10s %12s %11s %14s %12s %8s\n", "", "re-traced", "of cells", "share",
                "incremental ms", "full ms", "speed-up");
    std::printf("   %-14s %10llu %12llu %10.3f%% %14.3f %12.3f %7.1fx  (%llu bricks built)\n",
                "first edit", static_cast<unsigned long long>(first->retraced),
                static_cast<unsigned long long>(first->cells), 100.0 * first->share, first->incMs,
                first->fullMs, first->fullMs / first->incMs,
                static_cast<unsigned long long>(first->bricks));
    std::printf("   %-14s %10.0f %12.0f %10.3f%% %14.3f %12.3f %7.1fx  (%.0f bricks rebuilt)\n",
                "later (median)", med([](const Sample& s) { return s.retraced; }),
                med([](const Sample& s) { return s.cells; }),
                100.0 * med([](const Sample& s) { return s.share; }),
                med([](const Sample& s) { return s.incMs; }),
                med([](const Sample& s) { return s.fullMs; }),
                med([](const Sample& s) { return s.fullMs / s.incMs; }),
                med([](const Sample& s) { return s.bricks; }));
    std::printf(
        "   over all %d later edits: %llu of %llu cells re-traced (%.3f%%); views that fell "
        "back to a\n"
        "   full bake: %llu; incremental == full, byte for byte, after every edit: %s\n\n",
        reps, static_cast<unsigned long long>(retraced), static_cast<unsigned long long>(cells),
        cells ? 100.0 * double(retraced) / double(cells) : 0.0,
        static_cast<unsigned long long>(fullRefreshes), identical ? "yes" : "NO");
}

void run(const BenchEditsArgs& a) {
    const ViewSet set = a.views;
    std::optional<tbb::global_control> limit;
    if (a.threads > 0)
        limit.emplace(tbb::global_control::max_allowed_parallelism, std::size_t(a.threads));
    std::printf("bench edits: %u hardware threads, load average %s\n\n",
                std::thread::hardware_concurrency(), loadAverage().c_str());
    const NamedModel edited =
        a.edited.empty()
            ? NamedModel{"ball " + dimsText(glm::ivec3(a.size)), makeSphere(a.size / 2)}
            : NamedModel{std::filesystem::path(a.edited).stem().string(), loadModel(a.edited)};
    if (a.scenes) {
        std::vector<NamedModel> models = {edited};
        if (a.edited.empty() && a.size != 128)
            models.push_back({"ball 128x128x128", makeSphere(64)});
        for (const std::string& f : a.inputs)
            models.push_back({std::filesystem::path(f).stem().string(), loadModel(f)});
        benchScenes(a, models, set);
    }
    benchEdits(a, edited, set);
}

} // namespace

void addBenchEditsCommand(CLI::App& bench) {
    auto args = std::make_shared<BenchEditsArgs>();
    CLI::App* cmd = bench.add_subcommand(
        "edits", "What a voxel edit costs the far tier: incremental refresh vs full re-bake, and "
                 "flat vs bricked Embree scenes");
    cmd->add_option("models", args->inputs,
                    "More .vox models for the scene comparison (first model of each file)")
        ->check(CLI::ExistingFile);
    cmd->add_option("--size", args->size, "Edge of the edited ball")
        ->check(ballEdge())
        ->capture_default_str();
    cmd->add_option("--edit", args->edited,
                    "Edit this .vox model (first model) instead of the ball")
        ->check(CLI::ExistingFile);
    cmd->add_option("--sigma", args->sigma, "Virtual pixels per voxel")
        ->check(sigmaRange())
        ->capture_default_str();
    cmd->add_option("--views", args->views, "View set: how many directions")
        ->type_name("INT")
        ->transform(oneOf(viewSetNames(), "view set"))
        ->default_str(nameOf(viewSetNames(), args->views));
    cmd->add_option("--repeats", args->repeats, "Repeats / edits (medians)")
        ->check(atLeast(1))
        ->capture_default_str();
    cmd->add_option("--bricks", args->bricks, "Brick edges to compare (0 = flat scene)")
        ->delimiter(',')
        ->check(intIn(0, Limits::kMaxModelDim))
        ->capture_default_str();
    cmd->add_option("--threads", args->threads, "Worker threads (0 = all)")
        ->check(atLeast(0))
        ->capture_default_str();
    cmd->add_flag("!--no-scenes", args->scenes, "Skip the scene comparison (part 1)");
    cmd->callback([args] { run(*args); });
}

} // namespace voxtier::cli
