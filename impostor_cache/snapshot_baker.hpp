#pragma once
// Baking one snapshot (CONTRACT.md §4): orthographic rays through every cell of the view's §3.5
// lattice, traced against a VoxelScene with Embree's packet or stream API, TBB-parallel over
// rows. Each cell ends up exactly as the near kernel's vtShadeCell would shade it.
#include "core/view_set.hpp"
#include "core/voxel_model.hpp"
#include "impostor_cache/snapshot.hpp"
#include "impostor_cache/voxel_scene.hpp"

#include <cstdint>
#include <string>

namespace voxtier {

enum class TraceApi {
    Packet8,  ///< rtcIntersect8 over runs of 8 rays
    Packet16, ///< rtcIntersect16 over runs of 16 rays
    Stream,   ///< rtcIntersect1M over a block of rows
};
const char* toString(TraceApi api);
TraceApi parseTraceApi(const std::string& name); ///< packet8 | packet16 | stream, else InputError
/// Measured with voxtier bake --bench (2 shared cores, AVX-512 Embree 3.13): packets of 8 beat
/// packets of 16 and rtcIntersect1M streams on every model tried (tree.vox: 4.9 vs 2.7 vs 2.6
/// Mrays/s with boxes).
inline constexpr TraceApi kDefaultTraceApi = TraceApi::Packet8;

struct BakeOptions {
    TraceApi api = kDefaultTraceApi;
    bool withDepth = false; ///< also store Snapshot::depth
    int snapshotScale = 1;  ///< Snapshot::snapshotScale (1..kMaxSnapshotScale)
    /// Voxels the kernel-order traversal reads on its own before a ray is handed to Embree
    /// (0 = every ray that enters the box and starts in an empty voxel goes to Embree). Reads
    /// before Embree pay on compact models and are wasted on sparse ones; `voxtier bake --bench`
    /// prints both, and the default leaves the empty-space skipping to Embree
    /// (docs/decisions/embree-bake-geometry.md).
    int traverseFirst = 0;
    /// rebakeSnapshot: when the cells to re-trace cover more than this share of the snapshot,
    /// it bakes the snapshot whole instead (copying the rest would save little).
    double maxIncrementalShare = 0.5;
};

struct BakeStats {
    std::uint64_t rays = 0;  ///< primary rays traced: every cell of a full bake, the re-traced
                             ///< rectangle of an incremental one
    std::uint64_t cells = 0; ///< cells of the snapshots produced (rays / cells: share re-traced)
    std::uint64_t voxelReads =
        0; ///< grid reads of the exact traversal (before and after Embree's bound)
    std::uint64_t embreeRays = 0;  ///< rays handed to Embree
    std::uint64_t incremental = 0; ///< snapshots re-baked incrementally (rebakeSnapshot)
    double ms = 0.0;
    BakeStats& operator+=(const BakeStats& o) {
        rays += o.rays, cells += o.cells, voxelReads += o.voxelReads, embreeRays += o.embreeRays;
        incremental += o.incremental, ms += o.ms;
        return *this;
    }
};

/// Bakes `view` from `scene` at sigma. Thread-safe (the scene is read-only).
Snapshot bakeSnapshot(const VoxelScene& scene, ViewId view, double sigma,
                      const BakeOptions& options = {}, BakeStats* stats = nullptr);
/// View `index` of `set`.
inline Snapshot bakeSnapshot(const VoxelScene& scene, ViewSet set, int index, double sigma,
                             const BakeOptions& options = {}, BakeStats* stats = nullptr) {
    return bakeSnapshot(scene, viewIdOf(set, index), sigma, options, stats);
}

/// Cells of the snapshot lattice whose primary ray can visit a voxel of `box` (voxel
/// coordinates, half-open), as an inclusive lattice range (iMin, iMax, jMin, jMax) clamped to
/// lattice.cellRange, with one cell of margin on every side; iMin > iMax when `box` is empty.
/// Only these cells can change when the voxels of `box` change (snapshot_baker.cpp says why).
glm::ivec4 cellsReachingBox(const SpriteLattice& lattice, Box3i box);

/// `previous` (a snapshot of the same view, sigma and set, baked from an earlier version of
/// scene.grid() that differs from it only inside `dirty`) brought up to date: a copy in which
/// only cellsReachingBox(dirty) are traced again, with the same code as bakeSnapshot, and the
/// outline recomputed one cell around them. Equals bakeSnapshot(scene, ...) byte for byte. Falls
/// back to a full bake when the cells to re-trace exceed options.maxIncrementalShare, or when
/// `previous` does not fit (other lattice, depth wanted but not stored); stats->incremental says
/// which happened.
Snapshot rebakeSnapshot(const VoxelScene& scene, const Snapshot& previous, Box3i dirty,
                        const BakeOptions& options = {}, BakeStats* stats = nullptr);

/// The same snapshot with no Embree at all: the near kernel's own vtTrace for every cell over
/// the dense grid (TBB-parallel over rows). The baseline the Embree bake is measured against,
/// and an independent check of it.
Snapshot bakeSnapshotScalar(const VoxelGrid& grid, ViewId view, double sigma,
                            BakeStats* stats = nullptr);
inline Snapshot bakeSnapshotScalar(const VoxelGrid& grid, ViewSet set, int index, double sigma,
                                   BakeStats* stats = nullptr) {
    return bakeSnapshotScalar(grid, viewIdOf(set, index), sigma, stats);
}

} // namespace voxtier
