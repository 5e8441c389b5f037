#include "compose/vulkan_frame.hpp"

#include "core/stopwatch.hpp"

#include <chrono>
#include <stdexcept>

namespace voxtier {

VulkanFrameResult drawVulkanFrame(NearRenderer& near, FarPass* farPass,
                                  const VulkanFrameRequest& request) {
    if (request.far && !farPass)
        throw std::logic_error("drawVulkanFrame: far sprites need a FarPass");
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    VulkanFrameResult out;
    const CameraFrame& cam = *request.camera;
    GpuFrame& frame = near.frames().begin(cam.width, cam.height);
    NearOptions nearOptions = request.near;
    // The far pass composes by depth and id: the near planes need all three.
    nearOptions.readDepthAndIds = request.depthAndIds || request.far;
    near.passes().record(frame, cam, *request.models, request.nearSprites, request.clear,
                         nearOptions, out.near);
    if (request.far) {
        const auto tFar = Clock::now();
        farPass->record(frame, *request.far, out.far);
        out.farRecordMs = msSince(tFar);
    }
    if (request.readBack) frame.recordReadback(request.depthAndIds);
    frame.submit();
    const double recordMs = msSince(t0);
    near.passes().collect(frame, nearOptions, out.near);
    out.image = frame.read(request.depthAndIds);
    out.report = reportOf(frame, recordMs);
    return out;
}

} // namespace voxtier
