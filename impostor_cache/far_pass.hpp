#pragma once
// The far tier on Vulkan (CONTRACT.md §6, the far pass): the far blit of far_blit.hpp as a compute
// pass over a GpuFrame's planes (device/gpu_frame.hpp), after the near tier's passes, by the
// same exact rule (Image::writeIfNearer: nearer, or as near with the lower entity id), so the
// image equals the CPU blit into the near image bit for bit. Its snapshots stay on the device
// between frames (far_residency.hpp). Needs shaderFloat64 (the snapshot cell map is evaluated in
// double, as on the CPU).
#include "core/sprite_store.hpp"
#include "device/gpu_frame.hpp"
#include "impostor_cache/far_batch.hpp"
#include "impostor_cache/far_stats.hpp"

#include <cstdint>
#include <memory>

namespace voxtier {

class FarPass {
  public:
    /// Throws VulkanError when the device lacks shaderFloat64 (supported() says so first).
    explicit FarPass(GpuFrames& frames, FarTiles tiles = FarTiles::Auto);
    ~FarPass();
    FarPass(const FarPass&) = delete;
    FarPass& operator=(const FarPass&) = delete;

    static bool supported(const VulkanDevice& device) { return device.hasFloat64(); }

    /// Records the far sprites of `batch` into `frame`, after whatever drew its planes: their new
    /// snapshots uploaded, then the pass (timed as "far_upload" and "far_blit"). The planes must
    /// hold all three planes (colour, id, depth). With the sprite store's `history` of the
    /// batch's sprites, what the frame's slot holds of an earlier frame of the same store and is
    /// still current is not written again: an instance's record, and the draw order with the
    /// tile lists (FarPassStats::recordsKept, orderKept).
    void record(GpuFrame& frame, const FarBatch& batch, FarPassStats& stats,
                const SpriteHistory* history = nullptr);

    /// The tiles this pass runs (never Auto).
    FarTiles tiles() const;

    /// Bytes of snapshot cells resident on the device, and how many snapshots.
    std::uint64_t residentBytes() const;
    std::size_t residentSnapshots() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

} // namespace voxtier
