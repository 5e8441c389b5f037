#pragma once
// The frame recipe of DESIGN.md §6 (select -> near -> far -> compose). A FrameRenderer keeps
// what persists between frames of one scene: selector state, the snapshot cache, GPU residency.
#include "core/image.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"

#include <memory>
#include <string>
#include <vector>

namespace voxtier {

class NearRenderer;

enum class RenderMode {
    Reference, ///< every entity through the CPU reference tracer (the executable spec)
    Far,       ///< every entity through the far tier's snapshot cache (DESIGN.md §4)
    Near,      ///< every entity through the Vulkan near tier (volumetric/near_renderer.hpp)
};
RenderMode parseRenderMode(const std::string& name); ///< throws InputError(field "--mode")
const char* toString(RenderMode m);

struct FrameStats {
    int entities = 0;
    int culled = 0;
    int drawnReference = 0;
    int drawnFar = 0;
    double farMs = 0.0;    ///< snapshot lookups and bakes + blit
    int farBakes = 0;      ///< snapshots baked during this frame
    int drawnNear = 0;
    double setupMs = 0.0;
    double referenceMs = 0.0;
    double nearMs = 0.0; ///< near tier: upload + draw + readback
    double totalMs = 0.0;
    std::uint64_t pixelsTested = 0, voxelFetches = 0;
};

struct FrameResult {
    Image image;
    std::vector<SpriteSetup> sprites; ///< per entity id
    FrameStats stats;
};

class SnapshotCache;

class FrameRenderer {
public:
    explicit FrameRenderer(Scene& scene);
    ~FrameRenderer();
    FrameRenderer(const FrameRenderer&) = delete;
    FrameRenderer& operator=(const FrameRenderer&) = delete;

    /// Applies the scene's scripted edits due up to path frame `frame` (each once).
    void applyEditsThrough(int frame);
    /// One frame at time t.
    FrameResult render(double time, RenderMode mode);
    /// The far tier's snapshot cache; it persists across frames of this renderer.
    SnapshotCache& snapshotCache() { return *cache_; }
    /// The Vulkan device of the near tier ("" until a Near frame created it).
    std::string nearDeviceName() const;

private:
    Scene& scene_;
    std::unique_ptr<NearRenderer> near_; ///< created by the first Near frame (owns the Vulkan device)
    int editsApplied_ = 0; ///< scene.edits are applied in order of atFrame
    std::unique_ptr<SnapshotCache> cache_;
};

} // namespace voxtier
