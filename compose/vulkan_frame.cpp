#include "compose/vulkan_frame.hpp"

#include "core/stopwatch.hpp"

#include <chrono>
#include <stdexcept>

namespace voxtier {

VulkanFrameInFlight submitVulkanFrame(NearRenderer& near, FarPass* farPass,
                                      const VulkanFrameRequest& request) {
    if ((request.far || request.farAfterNear) && !farPass)
        throw std::logic_error("submitVulkanFrame: far sprites need a FarPass");
    if (request.far && request.farAfterNear)
        throw std::logic_error("submitVulkanFrame: far sprites given two ways");
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    VulkanFrameInFlight out;
    out.near = &near;
    const CameraFrame& cam = *request.camera;
    GpuFrame& frame = near.frames().begin(cam.width, cam.height);
    out.frame = &frame;
    out.nearOptions = request.near;
    // The far pass composes by depth and id: the near planes need all three.
    out.nearOptions.readDepthAndIds =
        request.depthAndIds || request.far || bool(request.farAfterNear);
    out.depthAndIds = request.depthAndIds;
    near.passes().record(frame, cam, *request.models, request.nearSprites, request.clear,
                         out.nearOptions, out.result.near, request.history);
    const FarBatch* far = request.far;
    double aside = 0.0; // the host's time in farAfterNear: not the frame's recording
    if (request.farAfterNear) {
        frame.submitSoFar();
        const auto tAside = Clock::now();
        far = request.farAfterNear();
        aside = msSince(tAside);
    }
    if (far) {
        const auto tFar = Clock::now();
        farPass->record(frame, *far, out.result.far, request.history);
        out.result.farRecordMs = msSince(tFar);
    }
    if (request.readBack) frame.recordReadback(request.depthAndIds);
    frame.submit();
    out.recordMs = msSince(t0) - aside;
    return out;
}

VulkanFrameResult finishVulkanFrame(VulkanFrameInFlight&& f) {
    VulkanFrameResult out = std::move(f.result);
    f.near->passes().collect(*f.frame, f.nearOptions, out.near);
    out.image = f.frame->read(f.depthAndIds);
    out.report = reportOf(*f.frame, f.recordMs);
    return out;
}

VulkanFrameResult drawVulkanFrame(NearRenderer& near, FarPass* farPass,
                                  const VulkanFrameRequest& request) {
    return finishVulkanFrame(submitVulkanFrame(near, farPass, request));
}

} // namespace voxtier
