// `voxtier bake MODEL.vox`: bake every far-tier snapshot of one model with Embree, print the
// cost, optionally write a contact sheet of the views. `voxtier bake --bench [MODEL.vox...]`:
// the Embree bake against the near kernel's scalar DDA over the same rays, side by side in one
// run (medians over repeats), plus the memory one cached model costs.
#include "apps/bench_util.hpp"
#include "apps/cli_options.hpp"
#include "apps/commands.hpp"
#include "core/error.hpp"
#include "core/image_io.hpp"
#include "core/procedural.hpp"
#include "core/vox_reader.hpp"
#include "impostor_cache/contact_sheet.hpp"
#include "impostor_cache/snapshot_baker.hpp"
#include "impostor_cache/view_set.hpp"
#include "impostor_cache/voxel_scene.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace voxtier::cli {

namespace {

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
};

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

void runBake(const BakeArgs& a) {
    if (a.inputs.size() != 1)
        throw CLI::ValidationError("model", "bake takes one .vox file (or --bench)");
    std::string name;
    const auto model = loadModel(a.inputs[0], a.model, &name);
    if (a.frame >= model->frameCount())
        throw InputError(a.inputs[0], "--frame",
                         "out of range: the model has " + std::to_string(model->frameCount()) +
                             " frames");
    const ViewSet set = a.views;
    VoxelSceneOptions so;
    so.geometry = a.geometry;
    BakeOptions bo;
    bo.api = a.api;

    const VoxelGrid& grid = model->frame(a.frame);
    const VoxelScene scene(grid, so);
    std::printf("%s: %s, %zu voxels, %s scene: %zu primitives, built in %.1f ms, %.2f MB\n",
                name.c_str(), dimsText(grid.dims()).c_str(), grid.solidCount(),
                toString(so.geometry), scene.primitiveCount(), scene.buildMs(),
                scene.bytes() / 1048576.0);
    std::vector<std::shared_ptr<const Snapshot>> snaps;
    BakeStats stats;
    std::size_t bytes = 0;
    const auto t0 = BenchClock::now();
    for (int v = 0; v < viewCount(set); ++v) {
        snaps.push_back(
            std::make_shared<const Snapshot>(bakeSnapshot(scene, set, v, a.sigma, bo, &stats)));
        bytes += snaps.back()->bytes();
    }
    const double ms = msSince(t0);
    std::printf("baked %d views at sigma %g with %s: %.1f ms, %llu rays, %.2f Mrays/s, %zu bytes "
                "of snapshots "
                "(%.1f KB per view)\n",
                viewCount(set), a.sigma, toString(bo.api), ms,
                static_cast<unsigned long long>(stats.rays), stats.rays / ms / 1e3, bytes,
                bytes / 1024.0 / viewCount(set));
    if (!a.sheet.empty()) {
        writeImage(a.sheet, makeContactSheet(snaps, model->palette()));
        std::printf("contact sheet -> %s\n", a.sheet.c_str());
    }
}

void runBench(const BakeArgs& a) {
    std::vector<NamedModel> models;
    if (a.inputs.empty()) {
        // Compact solid models of the sizes the far tier is for: voxelised balls, 16^3..128^3.
        for (int r : {8, 16, 32, 64})
            models.push_back({"ball " + dimsText(glm::ivec3(2 * r)), makeSphere(r)});
    }
    for (const std::string& f : a.inputs) {
        std::string name;
        auto m = loadModel(f, a.model, &name);
        models.push_back({name, m});
    }
    const ViewSet set = a.views;
    const int reps = a.repeats;
    std::printf(
        "bench: %d views, sigma %g, %d repeats (medians), %u hardware threads, load average %s\n",
        viewCount(set), a.sigma, reps, std::thread::hardware_concurrency(), loadAverage().c_str());
    std::printf("rays/s: every cell of every snapshot is one ray; the scalar DDA is the near "
                "kernel's vtTrace over\n"
                "the dense grid, the Embree bake = Embree lower bound + the kernel-order "
                "traversal; both give\n"
                "identical snapshots (checked below).\n\n");
    struct Config {
        BakeGeometry geometry;
        TraceApi api;
        int traverseFirst = 0;
    };
    const std::vector<Config> configs = {
        {BakeGeometry::Boxes, TraceApi::Packet8},    {BakeGeometry::Boxes, TraceApi::Packet16},
        {BakeGeometry::Boxes, TraceApi::Stream},     {BakeGeometry::Quads, TraceApi::Packet8},
        {BakeGeometry::Quads, TraceApi::Packet16},   {BakeGeometry::Quads, TraceApi::Stream},
        {kDefaultBakeGeometry, kDefaultTraceApi, 16}};
    for (const NamedModel& nm : models) {
        const VoxelGrid& grid = nm.model->frame(0);
        std::unique_ptr<VoxelScene> scenes[2];
        std::vector<double> buildMs[2];
        std::vector<double> scalarMs;
        std::vector<std::vector<double>> configMs(configs.size());
        std::uint64_t rays = 0;
        std::size_t snapshotBytes = 0;
        bool identical = true;
        for (int r = 0; r < reps; ++r) {
            // One repeat = every variant once, interleaved, so load changes hit all alike.
            std::vector<Snapshot> reference;
            BakeStats s;
            for (int v = 0; v < viewCount(set); ++v)
                reference.push_back(bakeSnapshotScalar(grid, set, v, a.sigma, &s));
            scalarMs.push_back(s.ms);
            rays = s.rays;
            if (r == 0)
                for (const Snapshot& snap : reference) snapshotBytes += snap.bytes();
            for (int g = 0; g < 2; ++g) {
                VoxelSceneOptions so;
                so.geometry = g == 0 ? BakeGeometry::Boxes : BakeGeometry::Quads;
                scenes[g].reset();
                scenes[g] = std::make_unique<VoxelScene>(grid, so);
                buildMs[g].push_back(scenes[g]->buildMs());
            }
            for (std::size_t c = 0; c < configs.size(); ++c) {
                const VoxelScene& sc = *scenes[configs[c].geometry == BakeGeometry::Boxes ? 0 : 1];
                BakeStats es;
                BakeOptions bo;
                bo.api = configs[c].api;
                bo.traverseFirst = configs[c].traverseFirst;
                for (int v = 0; v < viewCount(set); ++v) {
                    const Snapshot snap = bakeSnapshot(sc, set, v, a.sigma, bo, &es);
                    if (r == 0 && snap.cells != reference[std::size_t(v)].cells) identical = false;
                }
                configMs[c].push_back(es.ms);
            }
        }
        const double scalar = median(scalarMs);
        std::printf("%-22s %s, %zu voxels, %llu rays; snapshots identical to the scalar DDA: %s\n",
                    nm.name.c_str(), dimsText(grid.dims()).c_str(), grid.solidCount(),
                    static_cast<unsigned long long>(rays), identical ? "yes" : "NO");
        std::printf("  %-36s %9.2f ms  %7.2f Mrays/s\n", "scalar DDA (near kernel vtTrace)", scalar,
                    rays / scalar / 1e3);
        for (std::size_t c = 0; c < configs.size(); ++c) {
            const double ms = median(configMs[c]);
            std::string label = std::string("embree ") + toString(configs[c].geometry) + " " +
                                toString(configs[c].api);
            if (configs[c].traverseFirst > 0)
                label += " +" + std::to_string(configs[c].traverseFirst) + " reads first";
            std::printf("  %-36s %9.2f ms  %7.2f Mrays/s  %5.2fx scalar\n", label.c_str(), ms,
                        rays / ms / 1e3, scalar / ms);
        }
        std::printf("  memory per cached model (%d views, sigma %g): snapshots %.1f KB; + Embree "
                    "scene: boxes %.1f KB "
                    "(%zu prims, build %.1f ms), quads %.1f KB (%zu prims, build %.1f ms)\n\n",
                    viewCount(set), a.sigma, snapshotBytes / 1024.0, scenes[0]->bytes() / 1024.0,
                    scenes[0]->primitiveCount(), median(buildMs[0]), scenes[1]->bytes() / 1024.0,
                    scenes[1]->primitiveCount(), median(buildMs[1]));
    }
}

} // namespace

void addBakeCommand(CLI::App& app) {
    auto args = std::make_shared<BakeArgs>();
    CLI::App* cmd = app.add_subcommand(
        "bake",
        "Bake the far-tier snapshots of a model (Embree); --bench compares with the scalar DDA");
    cmd->add_option(
           "model", args->inputs,
           "MagicaVoxel model (.vox); with --bench any number (default: balls 16^3..128^3)")
        ->check(CLI::ExistingFile);
    cmd->add_option("--model", args->model, "Which model of a multi-model file")
        ->check(atLeast(0))
        ->capture_default_str();
    cmd->add_option("--frame", args->frame, "Animation frame")
        ->check(atLeast(0))
        ->capture_default_str();
    cmd->add_option("--views", args->views, "View set: how many directions")
        ->type_name("INT")
        ->transform(oneOf(viewSetNames(), "view set"))
        ->default_str(nameOf(viewSetNames(), args->views));
    cmd->add_option("--sigma", args->sigma, "Virtual pixels per voxel")
        ->check(sigmaRange())
        ->capture_default_str();
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
    cmd->callback([args] {
        std::optional<tbb::global_control> limit;
        if (args->threads > 0)
            limit.emplace(tbb::global_control::max_allowed_parallelism, std::size_t(args->threads));
        if (args->bench)
            runBench(*args);
        else
            runBake(*args);
    });
}

} // namespace voxtier::cli
