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
/// Measured with voxtier bake --bench: boxes are as fast as quads or faster on the models where
/// Embree pays (tree.vox 256^3: 9.7x vs 4.6x the scalar DDA; 128^3 ball 1.85x vs 1.64x), quads
/// win slightly on small models and flat-walled ones (house 126x126x64: 3.7x vs 3.5x). Boxes
/// also build 4x faster and take 4.5x less memory on noisy models (tree: 47 MB vs 214 MB).
inline constexpr BakeGeometry kDefaultBakeGeometry = BakeGeometry::Boxes;

/// How many times an Embree callback of this module ran in a thread without FTZ/DAZ set
/// (HARD_CASES 21: every worker that calls Embree must set them). Tests expect 0.
std::uint64_t embreeCallsWithoutFlushDenormals();

struct VoxelSceneOptions {
    BakeGeometry geometry = kDefaultBakeGeometry;
    /// Only voxels with an empty or out-of-bounds 6-neighbour (HARD_CASES 19). false puts every
    /// solid voxel in (tests prove both give the same snapshots).
    bool surfaceOnly = true;
    /// Runs of surface voxels along x as one box, rectangles of coplanar exposed faces as one
    /// quad (surface_voxels.hpp). Same snapshots, fewer primitives.
    bool mergePrimitives = true;
};

class VoxelScene {
  public:
    /// Copies the grid (the scene must describe one fixed version even if the model is edited
    /// later) and builds the Embree BVH. Throws std::runtime_error on an Embree error.
    VoxelScene(const VoxelGrid& grid, VoxelSceneOptions options);
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
    std::size_t bytes() const { return bytes_; }
    std::size_t embreeBytes() const { return embreeBytes_; }
    double buildMs() const { return buildMs_; }
    bool empty() const { return primitives_ == 0; }
    RTCSceneTy* handle() const { return scene_; }

  private:
    VoxelGrid grid_;
    VoxelSceneOptions options_;
    std::vector<VoxelRun> boxes_; ///< Boxes: the voxel box of each primitive
    std::size_t primitives_ = 0;
    float padding_ = 0.0f;
    std::size_t bytes_ = 0, embreeBytes_ = 0;
    double buildMs_ = 0.0;
    RTCSceneTy* scene_ = nullptr;
    void* userData_ = nullptr; ///< Boxes: the callbacks' data (owned)
};

} // namespace voxtier
