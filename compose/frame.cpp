#include "compose/frame.hpp"

#include "core/error.hpp"
#include "impostor_cache/far_frame.hpp"
#include "volumetric/near_renderer.hpp"
#include "volumetric/reference_renderer.hpp"

#include <algorithm>
#include <chrono>

namespace voxtier {

namespace {
double msSince(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
} // namespace

RenderMode parseRenderMode(const std::string& name) {
    if (name == "reference") return RenderMode::Reference;
    if (name == "near") return RenderMode::Near;
    if (name == "far") return RenderMode::Far;
    throw InputError("", "--mode", "unknown render mode '" + name + "' (expected: reference, near, far)");
}

const char* toString(RenderMode m) {
    switch (m) {
    case RenderMode::Reference: return "reference";
    case RenderMode::Far: return "far";
    case RenderMode::Near: return "near";
    }
    return "?";
}

FrameRenderer::FrameRenderer(Scene& scene) : scene_(scene), cache_(std::make_unique<SnapshotCache>()) {
    std::stable_sort(scene_.edits.begin(), scene_.edits.end(),
                     [](const ScriptedEdit& a, const ScriptedEdit& b) { return a.atFrame < b.atFrame; });
}

FrameRenderer::~FrameRenderer() = default;

std::string FrameRenderer::nearDeviceName() const { return near_ ? near_->deviceName() : std::string(); }

void FrameRenderer::applyEditsThrough(int frame) {
    while (editsApplied_ < int(scene_.edits.size()) && scene_.edits[std::size_t(editsApplied_)].atFrame <= frame) {
        const ScriptedEdit& e = scene_.edits[std::size_t(editsApplied_++)];
        VoxelModel& m = *scene_.models.at(std::size_t(e.model));
        switch (e.op) {
        case ScriptedEdit::Op::Set: m.setVoxel(e.modelFrame, e.box.min, e.index); break;
        case ScriptedEdit::Op::Fill: m.fillBox(e.modelFrame, e.box, e.index); break;
        case ScriptedEdit::Op::Clear: m.clearBox(e.modelFrame, e.box); break;
        }
    }
}

FrameResult FrameRenderer::render(double time, RenderMode mode) {
    const auto t0 = std::chrono::steady_clock::now();
    FrameResult out;
    const CameraFrame cam = makeCameraFrame(scene_.cameraAt(time));
    out.image = Image(cam.width, cam.height, scene_.render.background);

    // 1. Per-entity sprite set-up (DESIGN.md §3, double precision, camera-relative).
    out.sprites = setupSprites(scene_, cam, time);
    out.stats.entities = int(out.sprites.size());
    for (const auto& s : out.sprites) out.stats.culled += !s.visible();
    out.stats.setupMs = msSince(t0);

    // 2. Draw.
    switch (mode) {
    case RenderMode::Reference: {
        ReferenceStats rs;
        renderReference(scene_.models, out.sprites, out.image, &rs);
        out.stats.drawnReference = int(rs.sprites);
        out.stats.referenceMs = rs.milliseconds;
        out.stats.pixelsTested = rs.pixelsTested;
        out.stats.voxelFetches = rs.voxelFetches;
        break;
    }
    case RenderMode::Far: {
        std::vector<FarRequest> requests;
        requests.reserve(out.sprites.size());
        for (const auto& s : out.sprites) requests.push_back({&s, std::nullopt});
        FarFrameStats fs;
        drawFarSprites(scene_.models, requests, *cache_, viewSetFromSize(scene_.selector.viewSetSize), out.image, &fs);
        out.stats.drawnFar = int(fs.sprites);
        out.stats.farBakes = int(fs.bakes);
        out.stats.farMs = fs.ensureMs + fs.blit.milliseconds;
        out.stats.pixelsTested = fs.blit.pixelsTested;
        break;
    }
    case RenderMode::Near: {
        // Created on first use: reference-only runs never touch Vulkan.
        if (!near_) near_ = std::make_unique<NearRenderer>();
        NearStats ns;
        out.image = near_->render(cam, scene_.models, out.sprites, scene_.render.background, {}, &ns);
        out.stats.drawnNear = int(ns.sprites);
        out.stats.nearMs = ns.uploadMs + ns.drawMs + ns.readbackMs;
        break;
    }
    }
    out.stats.totalMs = msSince(t0);
    return out;
}

} // namespace voxtier
