// `voxtier bake MODEL.vox`: bake every far-tier snapshot of one model with Embree, print the
// cost, optionally write a contact sheet of the views. `voxtier bake MODEL.vox|SCENE.json ...
// --cache-dir DIR`: pre-bake into the on-disk snapshot cache (impostor_cache/snapshot_store.hpp)
// a scene's snapshots its renders ask for (its still and camera path, with a margin;
// compose/scene_render.hpp), or with --ladder (or --level, --views, a .vox) every view of every
// model frame named; optionally one deterministic share of the work (`--shard I/N`, for N
// independent jobs of a cluster scheduler; docs/baking.md).
// `voxtier bake --bench [MODEL.vox...]`:
// the Embree bake against the near kernel's scalar DDA over the same rays, side by side in one
// run (medians over repeats), plus the memory one cached model costs (measured in
// apps/bench/bake_bench.cpp).
#include "apps/bench/bake_bench.hpp"
#include "apps/bench/harness.hpp"
#include "apps/cache_dir_options.hpp"
#include "apps/cli_options.hpp"
#include "apps/commands.hpp"
#include "apps/progress.hpp"
#include "compose/frame.hpp"
#include "compose/scene_render.hpp"
#include "core/error.hpp"
#include "core/procedural.hpp"
#include "core/scene_loader.hpp"
#include "core/stopwatch.hpp"
#include "core/view_set.hpp"
#include "core/vox_reader.hpp"
#include "image_files/image_files.hpp"
#include "impostor_cache/contact_sheet.hpp"
#include "impostor_cache/snapshot_baker.hpp"
#include "impostor_cache/snapshot_cache.hpp"
#include "impostor_cache/voxel_scene.hpp"

#include <sys/statvfs.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace voxtier::cli {

namespace {

/// The margin a scene's bake adds to what its renders ask for (SnapshotNeedOptions::marginDeg):
/// the views a fresh selector picks at every frame (lone `--frame N` renders); docs/baking.md
/// and docs/decisions/path-sized-bakes.md give what wider margins cost.
constexpr double kDefaultMarginDeg = 0.0;
/// A camera further off its path than this is another path (bake it as one).
constexpr double kMaxMarginDeg = 45.0;

/// "DEG" in [0, kMaxMarginDeg] -> DEG; nullopt for anything else ("none" included).
std::optional<double> readMargin(const std::string& text) {
    char* end = nullptr;
    const double deg = std::strtod(text.c_str(), &end);
    if (text.empty() || end != text.c_str() + text.size() || !(deg >= 0.0 && deg <= kMaxMarginDeg))
        return std::nullopt;
    return deg;
}

struct BakeArgs {
    std::vector<std::string> inputs;
    int model = 0;
    int frame = 0;
    ViewSet views = ViewSet::Cube26;
    double sigma = 1.0;
    std::string sheet;
    BakeGeometry geometry = kDefaultBakeGeometry;
    TraceApi api = kDefaultTraceApi;
    bool bench = false;
    int repeats = 5;
    int threads = 0;
    // Pre-baking into an on-disk cache.
    CacheDirArgs cacheDir;
    bool viewsGiven = false, sigmaGiven = false; ///< else a scene's own
    std::optional<int> level; ///< cube lattice n (1: 26, 2: 98, 3: 218 views ...)
    bool allFrames = false;   ///< --frames all
    bool frameGiven = false;  ///< --frame on the command line
    std::string shard;        ///< "I/N" (readShard), "" = all the work
    bool yes = false;         ///< go ahead past kConfirmDiskBytes
    /// Every view of the view set or ladder (else a scene's bake follows its renders).
    bool ladder = false;
    // A scene's bake that follows its renders (compose/scene_render.hpp, SnapshotNeedOptions).
    RenderMode mode = RenderMode::Hybrid;
    std::string margin;                                  ///< --margin: DEG or "none"
    std::optional<double> marginDeg = kDefaultMarginDeg; ///< nullopt: --margin none
    std::optional<std::string> size;                     ///< WxH, as render's --size
    /// --mode, --margin or --size, which only a scene following its renders reads.
    std::vector<std::string> renderOptionsGiven;
    /// Whether a scene is baked as its renders ask (else every view of the set or ladder).
    bool followsRenders(const std::string& file) const {
        return !ladder && !level && !viewsGiven && lowerExtension(file) != ".vox";
    }
};

/// A pre-bake that would take more than this on disk is refused unless the user says --yes or
/// caps the directory (--cache-dir-mb). 256 MiB is about 10x every frame of the bundled default
/// scene (19,686 snapshots in 51 packs, ~26 MB on disk) and 4x a 267-voxel character at
/// --level 64 (98,306 snapshots in a 64 MB pack; 402 MB on disk when each snapshot was a file of
/// its own); the same character at --level 64 --sigma 4 (487 MB) is refused.
constexpr std::uint64_t kConfirmDiskBytes = std::uint64_t(256) << 20;

/// "I/N" -> {I, N}; nullopt unless 1 <= N <= 1000000 and 0 <= I < N.
std::optional<std::pair<int, int>> readShard(const std::string& text) {
    int i = -1, n = 0;
    char tail = 0;
    if (std::sscanf(text.c_str(), "%d/%d%c", &i, &n, &tail) != 2 || n < 1 || n > 1000000 || i < 0 ||
        i >= n)
        return std::nullopt;
    return std::pair{i, n};
}

struct NamedModel {
    std::string name;
    std::shared_ptr<VoxelModel> model;
};

std::shared_ptr<VoxelModel> loadModel(const std::string& file, int index, std::string* name) {
    const VoxFile vox = readVoxFile(file);
    if (index < 0 || index >= int(vox.models.size()))
        throw InputError(file, "--model",
                         "file has " + std::to_string(vox.models.size()) + " models");
    *name = std::filesystem::path(file).stem().string() +
            (vox.models.size() > 1 ? "#" + std::to_string(index) : "");
    return std::make_shared<VoxelModel>(*name, vox.palette,
                                        std::vector<VoxelGrid>{vox.models[std::size_t(index)]});
}

std::string dimsText(glm::ivec3 d) {
    return std::to_string(d.x) + "x" + std::to_string(d.y) + "x" + std::to_string(d.z);
}

/// The views to bake: --level n is the cube lattice {-n..n}^3 (the error-budget selector's
/// ladder levels are n = 1, 2, 4, ... 64), --views one of the fixed sets (n = 1, 2, 3).
std::vector<ViewId> viewsToBake(ViewSet set, std::optional<int> level) {
    if (level) return cubeSurfaceViews(*level);
    std::vector<ViewId> views;
    for (int v = 0; v < viewCount(set); ++v) views.push_back(viewIdOf(set, v));
    return views;
}

bool isVox(const std::string& file) {
    return lowerExtension(file) == ".vox";
}

/// A scene (or any non-.vox file) given where a .vox model is read: say what to do instead of the
/// .vox reader's "not a MagicaVoxel file".
void requireVox(const std::string& file, const char* instead) {
    if (!isVox(file)) throw InputError(file, "", instead);
}

void runBake(const BakeArgs& a) {
    if (a.inputs.size() != 1)
        throw CLI::ValidationError("model", "bake takes one .vox file (or --bench)");
    requireVox(a.inputs[0], "bake without --cache-dir takes one .vox model; to pre-bake a "
                            "scene's models add --cache-dir DIR");
    std::string name;
    const auto model = loadModel(a.inputs[0], a.model, &name);
    if (a.frame >= model->frameCount())
        throw InputError(a.inputs[0], "--frame",
                         "out of range: the model has " + std::to_string(model->frameCount()) +
                             " frames");
    if (a.allFrames) throw CLI::ValidationError("--frames", "applies with --cache-dir only");
    if (!a.shard.empty()) throw CLI::ValidationError("--shard", "applies with --cache-dir only");
    if (a.ladder) throw CLI::ValidationError("--ladder", "applies with --cache-dir only");
    if (!a.renderOptionsGiven.empty())
        throw CLI::ValidationError(a.renderOptionsGiven.front(), "applies with --cache-dir only");
    const std::vector<ViewId> views = viewsToBake(a.views, a.level);
    VoxelSceneOptions so;
    so.geometry = a.geometry;
    BakeOptions bo;
    bo.api = a.api;

    const VoxelGrid& grid = model->frame(a.frame);
    const VoxelScene scene(grid, so);
    std::printf("%s: %s, %zu voxels, %s scene: %zu primitives, built in %.1f ms, %s\n",
                name.c_str(), dimsText(grid.dims()).c_str(), grid.solidCount(),
                toString(so.geometry), scene.primitiveCount(), scene.buildMs(),
                mebibytes(scene.bytes()).c_str());
    std::vector<std::shared_ptr<const Snapshot>> snaps;
    BakeStats stats;
    std::size_t bytes = 0;
    const auto t0 = BenchClock::now();
    {
        Progress progress("views", views.size());
        for (ViewId v : views) {
            snaps.push_back(
                std::make_shared<const Snapshot>(bakeSnapshot(scene, v, a.sigma, bo, &stats)));
            bytes += snaps.back()->bytes();
            progress.done(snaps.size());
        }
    }
    const double ms = msSince(t0);
    std::printf("baked %d views at sigma %g with %s: %.1f ms, %llu rays, %.2f Mrays/s, %zu bytes "
                "of snapshots "
                "(%.1f KiB per view)\n",
                int(views.size()), a.sigma, toString(bo.api), ms,
                static_cast<unsigned long long>(stats.rays), stats.rays / ms / 1e3, bytes,
                bytes / 1024.0 / double(views.size()));
    if (!a.sheet.empty()) {
        writeImage(a.sheet, makeContactSheet(snaps, model->palette()));
        std::printf("contact sheet -> %s\n", a.sheet.c_str());
    }
}

/// What one input asks to be baked: its models with the view set and sigma to bake them at, or
/// (a scene following its renders) the snapshots its renders ask for.
struct BakeSource {
    std::string file;
    std::vector<NamedModel> models;
    std::vector<ViewId> views; ///< every view of every model frame (the set or the ladder)
    double sigma = 1.0;        ///< of the snapshots: the sprites' sigma x outlineStride
    /// A scene's snapshot_scale: its renders ask for snapshots at that multiple of its sigma,
    /// with that outline stride.
    int outlineStride = 1;
    /// A scene baked as its renders ask (BakeArgs::followsRenders): the scene (its models are
    /// `models`), what its renders ask for, and, where it has scripted edits, a renderer that
    /// applies them (the bake bakes an edited model frame's snapshots after its edits).
    std::unique_ptr<Scene> scene;
    SnapshotNeeds needs;
    std::unique_ptr<FrameRenderer> editor;
};

/// The views of a scene's view set, or under the error-budget selector of its ladder_cap level
/// (which holds every coarser level's views): every view its renders may ask for.
std::vector<ViewId> ladderViews(const Scene& scene) {
    return scene.selector.metric == SelectorMetric::ErrorBudget
               ? cubeSurfaceViews(scene.selector.ladderCap)
               : viewsToBake(viewSetFromSize(scene.selector.viewSetSize), std::nullopt);
}

/// A .vox gives the --model model (every model of the file with --frames all: a multi-model
/// file is often an animation); a scene gives its models at its own sigma, and either the
/// snapshots its renders ask for or (--ladder) every view of its view set or ladder. The
/// command line's --views / --level / --sigma override both.
BakeSource loadSource(const std::string& file, const BakeArgs& a) {
    BakeSource src{file, {}, viewsToBake(ViewSet::Cube26, std::nullopt), 1.0};
    if (isVox(file)) {
        const VoxFile vox = readVoxFile(file);
        const std::string stem = std::filesystem::path(file).stem().string();
        if (a.allFrames) {
            src.models.push_back(
                {stem, std::make_shared<VoxelModel>(stem, vox.palette, vox.models)});
        } else {
            std::string name;
            src.models.push_back({"", loadModel(file, a.model, &name)});
            src.models.back().name = name;
        }
    } else {
        src.scene = std::make_unique<Scene>(loadScene(file));
        Scene& scene = *src.scene;
        // A render's --size and --sigma change its sprites, so its views: the bake takes them too.
        if (a.size) {
            const glm::ivec2 wh = *readImageSize(*a.size);
            scene.camera.width = wh.x;
            scene.camera.height = wh.y;
        }
        if (a.sigmaGiven) scene.render.sigma = a.sigma;
        for (const auto& m : scene.models) src.models.push_back({m->name(), m});
        src.views = ladderViews(scene);
        src.outlineStride = scene.selector.snapshotScale;
        src.sigma = scene.render.sigma;
        if (a.followsRenders(file)) {
            src.needs = snapshotsRendersAskFor(scene, {.mode = a.mode, .marginDeg = a.marginDeg});
            if (!scene.edits.empty()) src.editor = std::make_unique<FrameRenderer>(scene);
        }
    }
    if (a.level || a.viewsGiven) src.views = viewsToBake(a.views, a.level);
    if (a.sigmaGiven) src.sigma = a.sigma;
    src.sigma *= src.outlineStride;
    return src;
}

/// One unit of work, one pack: views of one frame of one model.
struct BakeItem {
    const BakeSource* source;
    const NamedModel* model;
    int frame;
    const std::vector<ViewId>* views;
    double sigma; ///< of the snapshots
    /// Of a scene following its renders: the path frame whose scripted edits are applied before
    /// baking (-1: none; SnapshotNeed::editedAt).
    int editedAt = -1;
};

/// Every view (source.views) of model frames: --frame's, or with `allFrames` every one.
void addLadderItems(const BakeSource& src, const BakeArgs& a, bool allFrames,
                    std::vector<BakeItem>& items) {
    for (const NamedModel& m : src.models) {
        const int frames = m.model->frameCount();
        if (!allFrames && a.frame >= frames)
            throw InputError(src.file, "--frame",
                             m.name + " has " + std::to_string(frames) + " frames");
        for (int f = allFrames ? 0 : a.frame; f < (allFrames ? frames : a.frame + 1); ++f)
            items.push_back({&src, &m, f, &src.views, src.sigma});
    }
}

/// The work list in a fixed order (inputs as given; a scene following its renders in
/// SnapshotNeeds' order, else models in file order, frames ascending), so that shard I of N is
/// the same items in every job.
std::vector<BakeItem> workList(const std::vector<BakeSource>& sources, const BakeArgs& a) {
    std::vector<BakeItem> items;
    for (const BakeSource& src : sources) {
        if (!a.followsRenders(src.file)) {
            addLadderItems(src, a, a.allFrames, items);
            continue;
        }
        for (const SnapshotNeed& n : src.needs.needs)
            items.push_back({&src, &src.models[std::size_t(n.model)], n.frame, &n.views,
                             n.sigma * src.outlineStride, n.editedAt});
    }
    return items;
}

/// What a pre-bake will write at most (snapshots already in the directory are not written
/// again): the snapshots, the pack files holding them (one per model frame), their bytes, and the
/// disk they take, each pack rounded up to the filesystem's block and the subdirectories the
/// pack names spread over counted as a block each (their empty ".lock" files take none).
struct BakeEstimate {
    std::uint64_t snapshots = 0, files = 0, bytes = 0, diskBytes = 0, blockBytes = 4096;
    /// "19686 snapshots in 51 pack files, 24.64 MiB, 24.85 MiB on disk"
    std::string text() const {
        return std::to_string(snapshots) + " snapshots in " + std::to_string(files) + " pack file" +
               (files == 1 ? "" : "s") + ", " + mebibytes(bytes) + ", " + mebibytes(diskBytes) +
               " on disk";
    }
};

BakeEstimate estimateBake(const std::vector<BakeItem>& items, const std::string& dir) {
    BakeEstimate e;
    // The filesystem the directory will be on: its nearest existing ancestor's.
    std::filesystem::path p = std::filesystem::absolute(dir);
    while (!p.empty() && !std::filesystem::exists(p) && p != p.parent_path()) p = p.parent_path();
    struct statvfs fs {};
    if (statvfs(p.c_str(), &fs) == 0 && fs.f_frsize > 0) e.blockBytes = fs.f_frsize;
    const auto rounded = [&](std::uint64_t b) {
        return (b + e.blockBytes - 1) / e.blockBytes * e.blockBytes;
    };
    for (const BakeItem& it : items) {
        const glm::ivec3 dims = it.model->model->frame(it.frame).dims();
        std::uint64_t pack = snapshotPackOverhead(it.views->size());
        for (ViewId v : *it.views) pack += snapshotFileBytes(dims, v, it.sigma);
        e.snapshots += it.views->size();
        ++e.files;
        e.bytes += pack;
        e.diskBytes += rounded(pack);
    }
    // Packs go to 256 subdirectories by the first byte of their hash: the expected number used.
    const double dirs = 256.0 * (1.0 - std::pow(1.0 - 1.0 / 256.0, double(e.files)));
    e.diskBytes += std::uint64_t(std::ceil(dirs)) * e.blockBytes;
    return e;
}

/// "the still camera and the camera path's 73 frames, with a margin of 0.5 degrees" (what a
/// scene's bake follows).
std::string followedText(const BakeSource& src, const BakeArgs& a) {
    std::string text = src.needs.still ? "the still camera" : "";
    if (src.needs.frames > 0) {
        if (!text.empty()) text += " and ";
        text += src.scene->path
                    ? "the camera path's " + std::to_string(src.needs.frames) + " frames"
                    : "the static camera over " + std::to_string(src.needs.frames) +
                          " frames of animation";
    }
    char margin[96];
    if (!a.marginDeg)
        std::snprintf(margin, sizeof margin, ", in order only (--margin none)");
    else
        std::snprintf(margin, sizeof margin, ", with a margin of %g degree%s", *a.marginDeg,
                      *a.marginDeg == 1.0 ? "" : "s");
    return text + (a.mode == RenderMode::Far ? " in far mode" : "") + margin;
}

void runPrebake(const BakeArgs& a) {
    if (a.inputs.empty()) throw CLI::ValidationError("model", "name at least one .vox or scene");
    // A scene's bake follows its renders, which decide the views and model frames themselves;
    // the renders' options mean nothing to any other bake.
    const bool anyFollows = std::any_of(a.inputs.begin(), a.inputs.end(),
                                        [&](const std::string& f) { return a.followsRenders(f); });
    if (!anyFollows && !a.renderOptionsGiven.empty())
        throw CLI::ValidationError(a.renderOptionsGiven.front(),
                                   "applies to a scene's bake that follows its renders (not with "
                                   "--ladder, --level, --views or a .vox)");
    if (a.mode != RenderMode::Hybrid && a.mode != RenderMode::Far)
        throw CLI::ValidationError("--mode", std::string(toString(a.mode)) +
                                                 " renders draw no snapshot: hybrid or far");
    for (const std::string& f : a.inputs)
        if (a.followsRenders(f)) {
            const char* why = "applies to --ladder bakes (a scene's bake takes the animation "
                              "frames its renders show)";
            if (a.allFrames) throw CLI::ValidationError("--frames", why);
            if (a.frameGiven) throw CLI::ValidationError("--frame", why);
        }
    std::vector<BakeSource> sources;
    for (const std::string& f : a.inputs) sources.push_back(loadSource(f, a));
    std::vector<BakeItem> items = workList(sources, a);
    for (const BakeSource& src : sources)
        if (a.followsRenders(src.file))
            std::printf("%s: %zu snapshots of %zu model frames its renders ask for: %s\n",
                        src.file.c_str(), src.needs.snapshots(), src.needs.needs.size(),
                        followedText(src, a).c_str());
    if (const auto shard = readShard(a.shard)) {
        // Round robin over the fixed work list: every job computes the same list and keeps
        // every N-th item from its own index, so N jobs cover it exactly once, with no
        // coordination and balanced when models are listed in no particular order of size.
        const std::size_t all = items.size();
        std::vector<BakeItem> mine;
        for (std::size_t k = std::size_t(shard->first); k < all; k += std::size_t(shard->second))
            mine.push_back(items[k]);
        items = std::move(mine);
        std::printf("shard %d/%d: %zu of %zu model frames\n", shard->first, shard->second,
                    items.size(), all);
    }

    const BakeEstimate est = estimateBake(items, a.cacheDir.dir);
    std::printf("estimate: %s (%llu-byte blocks; snapshots already there are not written again)\n",
                est.text().c_str(), static_cast<unsigned long long>(est.blockBytes));
    // What --ladder --frames all would write instead, for the scenes that follow their renders.
    std::vector<BakeItem> ladder;
    for (const BakeSource& src : sources)
        if (a.followsRenders(src.file)) addLadderItems(src, a, /*allFrames=*/true, ladder);
    if (!ladder.empty())
        std::printf("estimate: the whole ladder of every model frame (--ladder --frames all) "
                    "would be %s\n",
                    estimateBake(ladder, a.cacheDir.dir).text().c_str());
    std::fflush(stdout);
    if (est.diskBytes > kConfirmDiskBytes && !a.yes && !a.cacheDir.limitMb)
        throw InputError(a.cacheDir.dir, "--cache-dir",
                         "this bake would write " + std::to_string(est.snapshots) + " snapshots, " +
                             mebibytes(est.diskBytes) + " on disk (over " +
                             mebibytes(kConfirmDiskBytes) +
                             "); add --yes to go ahead, or --cache-dir-mb MIB to cap the "
                             "directory");

    SnapshotCacheConfig config;
    config.budgetBytes = 0; // every snapshot goes to disk; nothing needs to stay in memory
    // Each pack written once, after its model frame (the bytes written are the packs'); a lock
    // another bake holds is waited for longer than a render would, since failing is the cost.
    config.store =
        std::make_shared<SnapshotStore>(SnapshotStoreOptions{.dir = a.cacheDir.dir,
                                                             .limitBytes = a.cacheDir.limitBytes(),
                                                             .writeOnlyOnFlush = true,
                                                             .lockWait = std::chrono::seconds(60)});
    // One cache per outline stride the sources ask for, one store.
    std::map<int, std::unique_ptr<SnapshotCache>> caches;
    const auto cacheFor = [&](const BakeSource& src) -> SnapshotCache& {
        auto& c = caches[src.outlineStride];
        if (!c) {
            SnapshotCacheConfig kind = config;
            kind.bake.outlineStride = src.outlineStride;
            c = std::make_unique<SnapshotCache>(kind);
        }
        return *c;
    };
    const auto t0 = std::chrono::steady_clock::now();
    std::uint64_t views = 0;
    std::optional<Progress> progress(std::in_place, "model frames", items.size());
    for (std::size_t i = 0; i < items.size(); ++i) {
        const BakeItem& it = items[i];
        SnapshotCache& cache = cacheFor(*it.source);
        // The edited voxels of a model frame's later snapshots: the work list is in the order
        // the edits are due, so applying them as it goes gives each item its own voxels.
        if (it.editedAt >= 0) it.source->editor->applyEditsThrough(it.editedAt);
        const SnapshotCacheCounters before = cache.counters();
        const auto t1 = std::chrono::steady_clock::now();
        const std::vector<ViewId>& viewList = *it.views;
        const int n = int(viewList.size());
        tbb::parallel_for(0, n, [&](int v) {
            cache.get(*it.model->model, it.frame, viewList[std::size_t(v)], it.sigma);
        });
        config.store->flush(); // the model frame's pack, written once
        views += std::uint64_t(n);
        const SnapshotCacheCounters after = cache.counters();
        progress->clear();
        std::printf("[%zu/%zu] %s %s frame %d%s: %d views at sigma %g, %llu baked, %llu already "
                    "there, %.1f ms\n",
                    i + 1, items.size(), it.source->file.c_str(), it.model->name.c_str(), it.frame,
                    it.editedAt >= 0
                        ? (" (edited by path frame " + std::to_string(it.editedAt) + ")").c_str()
                        : "",
                    n, it.sigma, static_cast<unsigned long long>(after.bakes - before.bakes),
                    static_cast<unsigned long long>(after.diskLoads - before.diskLoads),
                    msSince(t1));
        std::fflush(stdout);
        progress->done(i + 1);
    }
    progress.reset();
    const double ms = msSince(t0);
    SnapshotCacheCounters c;
    for (const auto& [kind, cache] : caches) {
        const SnapshotCacheCounters k = cache->counters();
        c.bakes += k.bakes;
        c.diskLoads += k.diskLoads;
        c.raysTraced += k.raysTraced;
    }
    const SnapshotStoreCounters sc = config.store->counters();
    // Throughput over the wall time: scene builds, file reads and writes included.
    std::printf("baked %llu of %llu snapshots (%llu already in the directory) for %zu model "
                "frames in %.1f ms: %llu bytes written, %llu rays, %.2f Mrays/s, %.0f "
                "snapshots/s\n",
                static_cast<unsigned long long>(c.bakes), static_cast<unsigned long long>(views),
                static_cast<unsigned long long>(c.diskLoads), items.size(), ms,
                static_cast<unsigned long long>(sc.bytesWritten),
                static_cast<unsigned long long>(c.raysTraced), c.raysTraced / ms / 1e3,
                double(views) * 1e3 / ms);
    std::printf("%s\n", cacheDirSummary(config.store->options(), sc).c_str());
    // A pre-bake exists to fill the directory: a snapshot not written fails the run (exit 1),
    // so that a user or a scheduler (--shard) does not take a partial library for a full one.
    if (sc.writeFailures > 0)
        throw InputError(a.cacheDir.dir, "--cache-dir",
                         std::to_string(sc.writeFailures) + " of " + std::to_string(views) +
                             " snapshots could not be written (" + sc.writeFailureReason + "); " +
                             std::to_string(sc.writes) + " written, " +
                             std::to_string(c.diskLoads) + " already there");
}

void runBench(const BakeArgs& a) {
    BakeBenchArgs b;
    for (const std::string& f : a.inputs) {
        requireVox(f, "bake --bench takes .vox models");
        std::string name;
        auto m = loadModel(f, a.model, &name);
        b.models.push_back({name, m});
    }
    b.views = a.views;
    b.sigma = a.sigma;
    b.repeats = a.repeats;
    runBakeBench(b);
}

} // namespace

void addBakeCommand(CLI::App& app) {
    auto args = std::make_shared<BakeArgs>();
    CLI::App* cmd = app.add_subcommand(
        "bake",
        "Bake the far-tier snapshots of a model (Embree); --cache-dir pre-bakes models and scenes "
        "into an on-disk cache; --bench compares with the scalar DDA");
    cmd->add_option(
           "model", args->inputs,
           "MagicaVoxel model (.vox); with --cache-dir any number of models and scenes (.json), "
           "with --bench any number of models (default: balls 16^3..128^3)")
        ->check(CLI::ExistingFile);
    cmd->add_option("--model", args->model, "Which model of a multi-model file")
        ->check(atLeast(0))
        ->capture_default_str();
    CLI::Option* frame = cmd->add_option("--frame", args->frame,
                                         "Animation frame (with --cache-dir: of a --ladder bake)")
                             ->check(atLeast(0))
                             ->capture_default_str();
    CLI::Option* views =
        cmd->add_option("--views", args->views,
                        "View set: how many directions (a scene's own with --cache-dir)")
            ->type_name("INT")
            ->transform(oneOf(viewSetNames(), "view set"))
            ->default_str(nameOf(viewSetNames(), args->views));
    cmd->add_option("--level", args->level,
                    "View set as the cube lattice {-n..n}^3 of level n (1: 26, 2: 98, 3: 218, 4: "
                    "386 ... 64: 98,306 views; the error-budget ladder is 1, 2, 4, ... 64)")
        ->check(intIn(1, 64))
        ->excludes(views);
    CLI::Option* sigma =
        cmd->add_option("--sigma", args->sigma,
                        "Virtual pixels per voxel (a scene's own with --cache-dir)")
            ->check(sigmaRange())
            ->capture_default_str();
    cmd->add_option("--frames", args->allFrames,
                    "With --cache-dir, of a .vox or a --ladder bake: 'all' bakes every animation "
                    "frame (default: --frame)")
        ->type_name("all")
        ->transform(CLI::Validator(
            [](std::string& text) {
                if (text != "all") return "unknown --frames value '" + text + "' (expected: all)";
                text = "1";
                return std::string();
            },
            "{all}"));
    cmd->add_option("--shard", args->shard,
                    "With --cache-dir: bake only share I of N of the (model, frame) work list "
                    "(I in 0..N-1; for N independent jobs, docs/baking.md)")
        ->type_name("I/N")
        ->check(CLI::Validator(
            [](std::string& text) {
                return readShard(text)
                           ? std::string()
                           : "expected I/N with 0 <= I < N <= 1000000, got '" + text + "'";
            },
            "I/N"));
    addCacheDirOptions(*cmd, args->cacheDir,
                       "pre-bake into it a scene's snapshots its renders ask for (its still and "
                       "camera path), or with --ladder every view of every model frame named");
    cmd->add_flag("--ladder", args->ladder,
                  "With --cache-dir: bake every view of a scene's view set or error-budget ladder "
                  "(up to ladder_cap) for --frame's or (--frames all) every model frame, not only "
                  "what its renders ask for (implied by --level, --views and a .vox)");
    CLI::Option* mode =
        addChoiceOption(*cmd, "--mode", args->mode, kRenderModeNames, "render mode",
                        "With --cache-dir, a scene's bake: the mode of the renders it prepares, "
                        "hybrid (default) or far (near and reference draw no snapshot)");
    CLI::Option* margin =
        cmd->add_option(
               "--margin", args->margin,
               "With --cache-dir, a scene's bake: beyond what its still and camera path ask "
               "for, the view a fresh selector picks for each far entity at every frame (a "
               "lone --frame N render) and, at DEG > 0, seen DEG degrees off its direction "
               "(a camera off the path); 'none': the path in order only (default 0)")
            ->type_name("DEG|none")
            ->check(CLI::Validator(
                [](std::string& text) {
                    return text == "none" || readMargin(text)
                               ? std::string()
                               : "expected degrees in [0, " + std::to_string(int(kMaxMarginDeg)) +
                                     "] or 'none', got '" + text + "'";
                },
                "DEG|none"));
    CLI::Option* size =
        cmd->add_option("--size", args->size,
                        "With --cache-dir, a scene's bake: the image size its renders use, as "
                        "render's --size (default: the scene's camera)")
            ->type_name("WxH")
            ->check(imageSize());
    cmd->add_flag(
        "--yes", args->yes,
        "With --cache-dir: go ahead with a bake estimated at over 256 MiB on disk (without "
        "it, or a --cache-dir-mb cap, such a bake is refused before writing)");
    cmd->add_option("--sheet", args->sheet, "Write a contact sheet of the views (PNG)");
    cmd->add_option("--geometry", args->geometry, "Embree geometry")
        ->type_name("TEXT")
        ->transform(oneOf(namesOf({BakeGeometry::Quads, BakeGeometry::Boxes}), "Embree geometry"))
        ->default_str(toString(args->geometry));
    cmd->add_option("--api", args->api, "Embree API")
        ->type_name("TEXT")
        ->transform(
            oneOf(namesOf({TraceApi::Packet8, TraceApi::Packet16, TraceApi::Stream}), "Embree API"))
        ->default_str(toString(args->api));
    cmd->add_flag("--bench", args->bench,
                  "Embree vs scalar DDA rays/s and memory per cached model");
    cmd->add_option("--repeats", args->repeats, "Bench repeats (medians)")
        ->check(atLeast(1))
        ->capture_default_str();
    cmd->add_option("--threads", args->threads, "Worker threads (0 = all)")
        ->check(atLeast(0))
        ->capture_default_str();
    cmd->callback([args, views, sigma, frame, mode, margin, size] {
        args->viewsGiven = views->count() > 0;
        args->sigmaGiven = sigma->count() > 0;
        args->frameGiven = frame->count() > 0;
        for (const CLI::Option* o : {mode, margin, size})
            if (o->count() > 0) args->renderOptionsGiven.push_back(o->get_name());
        if (margin->count() > 0) args->marginDeg = readMargin(args->margin);
        std::optional<tbb::global_control> limit;
        if (args->threads > 0)
            limit.emplace(tbb::global_control::max_allowed_parallelism, std::size_t(args->threads));
        if (args->bench)
            runBench(*args);
        else if (!args->cacheDir.dir.empty())
            runPrebake(*args);
        else
            runBake(*args);
    });
}

} // namespace voxtier::cli
