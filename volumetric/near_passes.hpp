#pragma once
// The near tier's passes on Vulkan (CONTRACT.md §3, §6), recorded into a GpuFrame
// (device/gpu_frame.hpp) in this order:
//   near_upload   the frame's sprite data into device-local buffers (and new voxels into the
//                 atlas, volumetric/voxel_residency.hpp);
//   near_cells    cell-rate sprites (core/near_rate.hpp): every cell's primary ray, then its
//                 outline from the neighbours' primaries;
//   near_splat    every pixel of a cell-rate sprite's rectangle leaves its nearest cell in a
//                 per-pixel word;
//   near_trace    the per-pixel sprites in compute (NearPixels::Compute; Auto on a GPU): every
//                 pixel of their rectangles runs the shared kernel (core/sprite_kernel.h) and
//                 leaves its word as the splat does;
//   near_draw     or else the per-pixel sprites drawn: one instanced draw of their proxies
//                 (near_proxy.hpp), front to back under the early depth test, whose fragment
//                 shader runs the kernel into the frame's colour, id and depth attachments, then
//                 copied into the frame's planes (with nothing to rasterise, the planes cleared);
//   near_resolve  the words' pixels composed into the planes by the depth/id rule.
// The image equals the CPU reference pixel for pixel. No Vulkan types in this header beyond the
// device module's: compose/ records a frame's far pass after these.
#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/near_rate.hpp"
#include "core/sprite.hpp"
#include "core/sprite_store.hpp"
#include "core/voxel_model.hpp"
#include "device/gpu_frame.hpp"
#include "volumetric/near_proxy.hpp"
#include "volumetric/near_stats.hpp"

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace voxtier {

/// How the sprites are submitted.
enum class NearDraws {
    Instanced, ///< one instanced draw for all sprites (default; the equal-depth rule needs the
               ///< order)
    PerEntity, ///< one draw per sprite, same order (for measuring draw-call overhead)
};

struct NearOptions {
    NearPixels pixels = NearPixels::Auto;
    NearProxy proxy = NearProxy::Hull;
    NearDraws draws = NearDraws::Instanced;
    /// Use the shader variant compiled with -DVT_COUNT_STEPS (counts the per-pixel sprites' voxel
    /// reads, in the fragment shader or the trace pass; the cell-rate compute pass is not counted;
    /// slower).
    bool countSteps = false;
    /// Count fragment-shader invocations with a pipeline-statistics query (when supported).
    bool pipelineStatistics = true;
    /// Per-pixel or cell-rate tracing per sprite (core/near_rate.hpp): cell-rate sprites are
    /// traced once per cell and shaded per pixel by compute passes; the draw skips them.
    NearRate rate = NearRate::Auto;
    /// The frame's cell store never grows past this; sprites that do not fit trace per pixel.
    std::uint64_t cellBudgetBytes = kDefaultCellBudgetBytes;
    /// false: only the colour plane is read back (one of three); the image's depth and id planes
    /// are left empty. For frames whose depth and ids nobody reads.
    bool readDepthAndIds = true;
    /// The colour the targets are cleared to (the background), or, when set, this one instead.
    std::optional<Rgba8> clearColor;
    /// The early depth test (CONTRACT.md §6 Occlusion), like ReferenceOptions::earlyDepthTest:
    /// the sprites are drawn front to back (nearer depth first, equal depths by ascending id, so
    /// the depth test keeps what it kept in id order), and each per-pixel hull sprite wholly in
    /// front of the near plane is rasterised flat at its own depth. The rasteriser's depth is
    /// then the sprite's depth bit for bit, the fragment shader writes none, and the depth test
    /// runs before the shader and rejects a fragment a nearer sprite already covers, untraced.
    /// The image is the same bit for bit. Cell-rate sprites are not culled (their compute passes
    /// run before the draw); the quad and box proxies are only reordered. false: ascending id,
    /// every sprite's depth written by its shader (the tests' and --no-cull's baseline).
    bool earlyDepthTest = true;
    /// Empty-space skipping (core/sprite_kernel.h vtMarchBoxes) for the sprites whose model frame
    /// qualifies (SpriteGpu::skipEmpty): the same image either way. Off by default on Vulkan: on
    /// llvmpipe the shaders that hold the box march ran the near tier 1.3-2x slower, skipping
    /// or not (docs/decisions/empty-space-skipping.md); a GPU's figure decides.
    bool skipEmpty = false;
    /// Where the records lie (NearRecords).
    NearRecords records = NearRecords::Drawn;
};

class VoxelResidency;

class NearPasses {
  public:
    /// Pipelines and per-slot buffers for the frames of `frames` (one set per slot in flight).
    explicit NearPasses(GpuFrames& frames);
    ~NearPasses();
    NearPasses(const NearPasses&) = delete;
    NearPasses& operator=(const NearPasses&) = delete;

    /// Records the near tier's passes for `sprites` into `frame` (see the file comment); the
    /// frame's planes hold the near image afterwards. `clear` is the colour the planes start as.
    /// Sprite order does not matter: equal depths keep the lower entity id.
    /// `history` (optional): where the sprites are a SpriteStore's, what changed when. A slot's
    /// sprite record that holds the same entity's unchanged sprite is then not written again, or
    /// only its animation frame's fields after a step (where the host writes the slot's buffer
    /// directly), and the draw order is last frame's while no sprite was set up anew: a still
    /// camera's frame writes what changed.
    void record(GpuFrame& frame, const CameraFrame& camera,
                const std::vector<std::shared_ptr<VoxelModel>>& models,
                std::span<const SpriteSetup* const> sprites, Rgba8 clear,
                const NearOptions& options, NearStats& stats,
                const SpriteHistory* history = nullptr);
    /// After the frame's fence: what the device counted (fragment invocations, voxel reads).
    void collect(GpuFrame& frame, const NearOptions& options, NearStats& stats);

    const VoxelResidency& residency() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

} // namespace voxtier
