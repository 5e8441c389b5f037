#include "volumetric/near_renderer.hpp"

#include "core/stopwatch.hpp"
#include "volumetric/voxel_residency.hpp"

#include <chrono>

namespace voxtier {

std::optional<double> GpuFrameReport::ms(std::string_view name) const {
    std::optional<double> sum;
    for (const PassTime& p : passes)
        if (p.name == name) sum = sum.value_or(0.0) + p.ms;
    return sum;
}

GpuFrameReport reportOf(GpuFrame& frame, double recordMs) {
    frame.wait();
    GpuFrameReport r;
    r.passes = frame.timer().results();
    r.host = frame.hostTimes();
    r.recordMs = recordMs;
    return r;
}

NearRenderer::NearRenderer(const VulkanDeviceOptions& options,
                           std::shared_ptr<VulkanMessageLog> log)
    : device_(options, std::move(log)), frames_(device_), passes_(frames_) {}

NearRenderer::~NearRenderer() {
    frames_.waitAll();
}

const std::string& NearRenderer::deviceName() const {
    return device_.name();
}
bool NearRenderer::deviceIsCpu() const {
    return device_.isCpu();
}
bool NearRenderer::validationEnabled() const {
    return device_.validationEnabled();
}
const std::shared_ptr<VulkanMessageLog>& NearRenderer::messageLog() const {
    return device_.messageLog();
}
std::uint64_t NearRenderer::totalBytesUploaded() const {
    return passes_.residency().totals().bytesUploaded;
}

Image NearRenderer::render(const CameraFrame& camera,
                           const std::vector<std::shared_ptr<VoxelModel>>& models,
                           std::span<const SpriteSetup* const> sprites, Rgba8 background,
                           const NearOptions& options, NearStats* statsOut,
                           GpuFrameReport* report) {
    const auto t0 = std::chrono::steady_clock::now();
    NearStats stats;
    GpuFrame& frame = frames_.begin(camera.width, camera.height);
    passes_.record(frame, camera, models, sprites, options.clearColor.value_or(background), options,
                   stats);
    frame.recordReadback(options.readDepthAndIds);
    frame.submit();
    const double recordMs = msSince(t0);
    passes_.collect(frame, options, stats);
    Image image = frame.read(options.readDepthAndIds);
    if (report) *report = reportOf(frame, recordMs);
    if (statsOut) *statsOut = stats;
    return image;
}

Image NearRenderer::render(const CameraFrame& camera,
                           const std::vector<std::shared_ptr<VoxelModel>>& models,
                           const std::vector<SpriteSetup>& sprites, Rgba8 background,
                           const NearOptions& options, NearStats* stats, GpuFrameReport* report) {
    std::vector<const SpriteSetup*> ptrs;
    ptrs.reserve(sprites.size());
    for (const auto& s : sprites) ptrs.push_back(&s);
    return render(camera, models, ptrs, background, options, stats, report);
}

} // namespace voxtier
