#pragma once
// The near tier on Vulkan (DESIGN.md §3, §6): every visible sprite is one instance of the frame's
// instanced draw of its proxy polygon (NearProxy), equal depths in ascending entity id (front to
// back under NearOptions::earlyDepthTest, else all in ascending id), into an R32_UINT colour
// target (the kernel's packed RGBA8), an R32_UINT entity-id target and a D32_SFLOAT reversed-Z
// depth target (test GREATER: at equal depth the first, lower-id fragment stays, exactly like
// Image::writeIfNearer). The fragment shader runs the shared kernel (core/sprite_kernel.h), so the
// image equals the CPU reference pixel for pixel. Voxels live in one 3D atlas
// (volumetric/voxel_residency.hpp).
//
// No Vulkan types here: compose/ and apps/ use this header (DESIGN.md §1).
#include "core/camera.hpp"
#include "core/far_batch.hpp"
#include "core/image.hpp"
#include "core/near_rate.hpp"
#include "core/sprite.hpp"
#include "core/voxel_model.hpp"
#include "device/vulkan_options.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace voxtier {

/// What the GPU rasterises per sprite (DESIGN.md §3.10). Quad and Hull cover every pixel whose
/// kernel outcome can be non-empty, with margin, so the image is exact with either; they differ
/// only in how many fragments run the kernel to find out it is empty.
enum class NearProxy {
    /// The camera-facing quad of SpriteGpu::quad: the bounding rectangle of the cells that can be
    /// non-empty plus one cell and two pixels.
    Quad,
    /// The proxy box (model bounds + 1/sigma), rasterised in perspective: loses outline pixels at
    /// close range, where eye rays diverge from the sprite's parallel rays. Measured only.
    Box,
    /// Default. The model box projected along the sprite's parallel rays onto the sprite plane (a
    /// hexagon), grown by the kernel's exact reach (outline ring + half a cell = 1.5 cells) and
    /// two pixels, drawn as a fan of at most 10 triangles. Exact like the quad with ~35% fewer
    /// fragments in `voxtier bench near` (the quad's rectangle corners and extra cells go).
    Hull,
};
/// How the sprites are submitted.
enum class NearDraws {
    Instanced, ///< one instanced draw for all sprites (default; the equal-depth rule needs the
               ///< order)
    PerEntity, ///< one draw per sprite, same order (for measuring draw-call overhead)
};

struct NearOptions {
    NearProxy proxy = NearProxy::Hull;
    NearDraws draws = NearDraws::Instanced;
    /// Use the shader variant compiled with -DVT_COUNT_STEPS (counts the fragment shader's voxel
    /// reads; the cell-rate compute pass is not counted; slower).
    bool countSteps = false;
    /// Count fragment-shader invocations with a pipeline-statistics query (when supported).
    bool pipelineStatistics = true;
    /// Per-pixel or cell-rate tracing per sprite (core/near_rate.hpp): cell-rate sprites are traced
    /// once per cell and shaded per pixel by compute passes; the draw skips them.
    NearRate rate = NearRate::Auto;
    /// The frame's cell store never grows past this; sprites that do not fit trace per pixel.
    std::uint64_t cellBudgetBytes = kDefaultCellBudgetBytes;
    /// Far sprites to draw in the same frame (DESIGN.md §6, the far pass on Vulkan), or null: a
    /// compute pass after the near sprites, into the same targets, by the far blit's exact rule
    /// (the image equals the CPU blit into the near image, bit for bit). Needs
    /// NearRenderer::farPassSupported().
    const FarBatch* far = nullptr;
    /// false: only the colour target is read back (one plane, not three); the image's depth
    /// and id planes are left empty. For frames whose depth and ids nobody reads (a PNG with
    /// no far sprite drawn on the CPU, no --ids, no error metrics).
    bool readDepthAndIds = true;
    /// The colour the targets are cleared to (the background), or, when set, this one instead.
    std::optional<Rgba8> clearColor;
    /// The early depth test (DESIGN.md §6 Occlusion), like ReferenceOptions::earlyDepthTest:
    /// the sprites are drawn front to back (nearer depth first, equal depths by ascending id, so
    /// the depth test keeps what it kept in id order), and each per-pixel hull sprite wholly in
    /// front of the near plane is rasterised flat at its own depth. The rasteriser's depth is
    /// then the sprite's depth bit for bit, the fragment shader writes none, and the depth test
    /// runs before the shader and rejects a fragment a nearer sprite already covers, untraced.
    /// The image is the same bit for bit. Cell-rate sprites are not culled (their compute passes
    /// run before the draw); the quad and box proxies are only reordered. false: ascending id,
    /// every sprite's depth written by its shader (the tests' and --no-cull's baseline).
    bool earlyDepthTest = true;
};

struct NearStats : CellRateCounts {
    std::uint64_t sprites = 0; ///< instances drawn
    std::uint64_t drawCalls = 0;
    /// FRAGMENT_SHADER_INVOCATIONS of the draw (0 when the device has no statistics queries).
    std::uint64_t fragmentInvocations = 0;
    /// With countSteps: fragments that ran the kernel, and their vtFetchVoxel calls (DDA steps,
    /// the four outline neighbour rays included).
    std::uint64_t kernelFragments = 0, voxelFetches = 0;
    std::uint64_t bytesUploaded = 0; ///< voxel bytes copied to the atlas for this frame
    std::uint64_t uploadRegions = 0;
    std::uint64_t atlasGrowths = 0; ///< the atlas was re-created larger this frame
    double uploadMs = 0.0;          ///< residency: pack + copy + wait
    /// GPU time of the cell-rate compute passes: trace, outline, splat and resolve (timestamp
    /// queries; 0 without cell-rate sprites or where the device has no timestamps).
    double computeMs = 0.0;
    /// Record + submit + wait of the frame's one submission, less the compute, copy and far
    /// pass GPU times (all of it where the device has no timestamps).
    double drawMs = 0.0;
    /// GPU time of the copy of the targets to host memory (one plane or three) + unpack into
    /// Image.
    double readbackMs = 0.0;
    /// The far pass: sprites drawn, image tiles it walked, snapshots (and their bytes) uploaded
    /// to the device this frame, and its time (host preparation + GPU time of its uploads and
    /// compute pass; host preparation alone where the device has no timestamps).
    std::uint64_t farSprites = 0, farTiles = 0, farSnapshotsUploaded = 0, farBytesUploaded = 0;
    double farMs = 0.0;
    /// Sprites rasterised flat at their depth, with the early depth test (earlyDepthTest).
    std::uint64_t earlyDepthSprites = 0;
};

class NearRenderer {
  public:
    /// Creates the Vulkan device (throws VulkanError, e.g. with kNoVulkanDeviceMessage).
    explicit NearRenderer(const VulkanDeviceOptions& options = {},
                          std::shared_ptr<VulkanMessageLog> log = nullptr);
    ~NearRenderer();
    NearRenderer(const NearRenderer&) = delete;
    NearRenderer& operator=(const NearRenderer&) = delete;

    /// Name of the Vulkan device in use (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)").
    const std::string& deviceName() const;
    bool deviceIsCpu() const;
    /// Whether this device can run the far pass (NearOptions::far): it needs shaderFloat64.
    bool farPassSupported() const;
    /// Bytes of snapshot cells resident on the device for the far pass, and how many snapshots.
    std::uint64_t farResidentBytes() const;
    std::size_t farResidentSnapshots() const;
    bool validationEnabled() const;
    const std::shared_ptr<VulkanMessageLog>& messageLog() const;

    /// Draws every visible sprite of `sprites` into a fresh camera-sized image cleared to
    /// `background` (depth 0, no entity). Sprite order does not matter: they are drawn in
    /// ascending entity id at equal depths. Models are indexed by SpriteSetup::model.
    Image render(const CameraFrame& camera, const std::vector<std::shared_ptr<VoxelModel>>& models,
                 std::span<const SpriteSetup* const> sprites, Rgba8 background,
                 const NearOptions& options = {}, NearStats* stats = nullptr);
    Image render(const CameraFrame& camera, const std::vector<std::shared_ptr<VoxelModel>>& models,
                 const std::vector<SpriteSetup>& sprites, Rgba8 background,
                 const NearOptions& options = {}, NearStats* stats = nullptr);

    /// Voxel bytes uploaded to the atlas since construction.
    std::uint64_t totalBytesUploaded() const;

    /// The clip-space corners of a sprite's proxy box (model bounds grown by 1/sigma voxel),
    /// corner k = (k & 1, k >> 1 & 1, k >> 2), computed in double, camera-relative.
    /// The clip-space corners of a sprite's hull proxy (NearProxy::Hull), a convex polygon in fan
    /// order with at most 12 corners, computed in double, camera-relative.
    static std::vector<glm::dvec4> proxyHullClipCorners(const CameraFrame& camera,
                                                        const SpriteSetup& sprite);
    static std::array<glm::dvec4, 8> proxyBoxClipCorners(const CameraFrame& camera,
                                                         const SpriteSetup& sprite);

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

} // namespace voxtier
