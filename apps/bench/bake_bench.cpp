// `voxtier bake --bench` (apps/bench/bake_bench.hpp): the measuring side of the option.
#include "apps/bench/bake_bench.hpp"

#include "apps/bench/harness.hpp"
#include "core/procedural.hpp"
#include "impostor_cache/snapshot_baker.hpp"
#include "impostor_cache/voxel_scene.hpp"

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace voxtier::cli {

namespace {

std::string dimsText(glm::ivec3 d) {
    return std::to_string(d.x) + "x" + std::to_string(d.y) + "x" + std::to_string(d.z);
}

} // namespace

void runBakeBench(const BakeBenchArgs& a) {
    std::vector<BakeBenchModel> models = a.models;
    if (models.empty()) {
        // Compact solid models of the sizes the far tier is for: voxelised balls, 16^3..128^3.
        for (int r : {8, 16, 32, 64})
            models.push_back({"ball " + dimsText(glm::ivec3(2 * r)), makeSphere(r)});
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
    for (const BakeBenchModel& nm : models) {
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

} // namespace voxtier::cli
