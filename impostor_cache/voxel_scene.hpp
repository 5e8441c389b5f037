#pragma once
// The per-(model, frame, version) half of the far tier: one Embree scene over the voxels a ray
// can hit first, built once and shared by every view baked from it (and, later, by incremental
// re-bakes). Snapshots are the per-view half (snapshot_baker.hpp).
#include "core/voxel_model.hpp"
#include "impostor_cache/surface_voxels.hpp"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

struct RTCSceneTy; // Embree's scene handle, kept opaque so this header stays Embree-free

namespace voxtier {

/// How the voxels are handed to Embree; both give identical snapshots (the exact hit is
/// decided by the kernel-order traversal, see snapshot_baker.cpp), they differ in speed and
/// memory.
enum class BakeGeometry {
    Boxes, ///< user geometry: one padded AABB per surface voxel, a robust slab test in a callback
    Quads, ///< built-in quads: the exposed faces, grown in-plane, Embree's robust mode
};
const char* toString(BakeGeometry g);
BakeGeometry parseBakeGeometry(const std::string& name); ///< "boxes" | "quads", else InputError
/// Boxes by default: as fast as quads or faster where Embree pays, and faster to build and
/// smaller on noisy models (`voxtier bake --bench`; docs/decisions/embree-bake-geometry.md).
inline constexpr BakeGeometry kDefaultBakeGeometry = BakeGeometry::Boxes;

/// How many times an Embree callback of this module ran in a thread without FTZ/DAZ set
/// (HARD_CASES 21: every worker that calls Embree must set them). Tests expect 0.
std::uint64_t embreeCallsWithoutFlushDenormals();

/// Edge (voxels) of the bricks a scene is split into once its model is edited; see
/// VoxelSceneOptions. An edit rebuilds only the bricks it reaches, at a small price in trace
/// speed (figures: docs/decisions/incremental-refresh.md). Most models are never edited, so a
/// scene built from scratch stays flat (flatUntilEdited) and the first edit pays one bricked
/// build.
inline constexpr int kDefaultBrickSize = 16;
inline constexpr bool kDefaultFlatUntilEdited = true;

struct VoxelSceneOptions {
    BakeGeometry geometry = kDefaultBakeGeometry;
    /// Only voxels with an empty or out-of-bounds 6-neighbour (HARD_CASES 19). false puts every
    /// solid voxel in (tests prove both give the same snapshots).
    bool surfaceOnly = true;
    /// Runs of surface voxels along x as one box, rectangles of coplanar exposed faces as one
    /// quad (surface_voxels.hpp). Same snapshots, fewer primitives.
    bool mergePrimitives = true;
    /// > 0: the grid is cut into bricks of this edge, each its own Embree scene, instanced
    /// (identity transform) into a top-level scene, so the scene of an edited model rebuilds only
    /// the bricks the edit reaches (CONTRACT.md §4 invalidation). 0: one flat scene, rebuilt whole
    /// after every edit. Same snapshots either way (the exact hit never comes from Embree).
    int brickSize = kDefaultBrickSize;
    /// With bricks: a scene built from scratch is still one flat BVH (it traces faster), and the
    /// first scene derived after an edit builds every brick; from then on only the bricks an edit
    /// reaches are rebuilt. So models that are never edited never pay for the bricks.
    bool flatUntilEdited = kDefaultFlatUntilEdited;
};

/// What building a scene cost: for a derived scene (after an edit) only the bricks it rebuilt.
struct SceneBuildStats {
    std::size_t bricksBuilt = 0;  ///< bricks (or the one flat scene) built by this constructor
    std::size_t bricksReused = 0; ///< bricks shared with the previous version
    std::size_t primitivesBuilt = 0;
    double ms = 0.0;
};

class VoxelScene {
  public:
    /// Copies the grid (the scene must describe one fixed version even if the model is edited
    /// later) and builds the Embree BVH. Throws EmbreeError (impostor_cache/embree_error.hpp) on an
    /// Embree error.
    VoxelScene(const VoxelGrid& grid, VoxelSceneOptions options);
    /// The scene of `grid`, a later version of `previous.grid()` that differs from it only inside
    /// `dirty` (VoxelModel::dirtySince). A voxel's surface status depends on its 6 neighbours, so
    /// the primitives can change only inside `dirty` grown by one voxel: the bricks that box
    /// reaches are rebuilt, every other brick (its BVH and primitives) is shared with `previous`
    /// and only the top-level scene is committed again. A flat scene (brickSize 0) is rebuilt
    /// whole. Same options and dims as `previous`.
    VoxelScene(const VoxelScene& previous, const VoxelGrid& grid, Box3i dirty);
    ~VoxelScene();
    VoxelScene(const VoxelScene&) = delete;
    VoxelScene& operator=(const VoxelScene&) = delete;

    const VoxelGrid& grid() const { return grid_; }
    const VoxelSceneOptions& options() const { return options_; }
    std::size_t primitiveCount() const { return primitives_; }
    /// How far (voxels) every candidate primitive reaches beyond the voxel it stands for: the
    /// slack that makes Embree's answer a safe lower bound despite float rounding.
    float padding() const { return padding_; }
    /// Grid copy + primitive arrays + what Embree allocated while building (memory monitor).
    /// Bricks shared with other versions are counted in each scene that holds them.
    std::size_t bytes() const { return bytes_; }
    std::size_t embreeBytes() const { return embreeBytes_; }
    double buildMs() const { return build_.ms; }
    const SceneBuildStats& buildStats() const { return build_; }
    /// Bricks holding at least one primitive (1 for a flat scene that is not empty).
    std::size_t brickCount() const;
    /// Built as bricks under a top-level scene (else one flat BVH).
    bool bricked() const { return bricked_; }
    bool empty() const { return primitives_ == 0; }
    RTCSceneTy* handle() const { return scene_; }

  private:
    struct Brick;
    void build(const VoxelScene* previous, Box3i rebuild, bool derived);

    VoxelGrid grid_;
    VoxelSceneOptions options_;
    /// Per brick slot (x fastest), null where a brick holds no primitive; one slot when flat.
    std::vector<std::shared_ptr<const Brick>> bricks_;
    glm::ivec3 brickGrid_{1};
    bool bricked_ = false;
    std::size_t primitives_ = 0;
    float padding_ = 0.0f;
    std::size_t bytes_ = 0, embreeBytes_ = 0;
    SceneBuildStats build_;
    RTCSceneTy* scene_ = nullptr;
};

} // namespace voxtier
