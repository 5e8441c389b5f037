#pragma once
// Images in tests: a frame through the CPU reference tracer, the count of drawn pixels, and a
// readable description of where two images first differ.
#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "volumetric/reference_renderer.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

namespace voxtier::test {

/// "" when the images are identical (colour, depth bits, id); otherwise the number of differing
/// pixels and the first one with both values and the entity each image has there.
inline std::string describeDifference(const Image& a, const Image& b, const char* nameA = "vulkan",
                                      const char* nameB = "reference") {
    if (a.width != b.width || a.height != b.height)
        return "image sizes differ: " + std::to_string(a.width) + "x" + std::to_string(a.height) +
               " vs " + std::to_string(b.width) + "x" + std::to_string(b.height);
    const ImageDiff d = diffImages(a, b);
    if (d.identical()) return "";
    const std::size_t p = a.index(int(d.firstX), int(d.firstY));
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "%zu colour, %zu depth, %zu id pixels differ; first at (%zu,%zu): %s colour %08x "
                  "depth %.9g "
                  "entity %d, %s colour %08x depth %.9g entity %d",
                  d.colorDiffs, d.depthDiffs, d.idDiffs, d.firstX, d.firstY, nameA, a.color[p],
                  double(a.depth[p]), int(a.id[p]), nameB, b.color[p], double(b.depth[p]),
                  int(b.id[p]));
    return buf;
}

/// A frame of `s` at time t through the CPU reference tracer (the executable spec).
inline Image renderReferenceImage(const Scene& s, std::vector<SpriteSetup>* setups = nullptr,
                                  double time = 0.0) {
    const CameraFrame cam = makeCameraFrame(s.cameraAt(time));
    auto sprites = setupSprites(s, cam, time);
    Image img(cam.width, cam.height, s.render.background);
    renderReference(s.models, sprites, img);
    if (setups) *setups = std::move(sprites);
    return img;
}

/// The pixels some entity was drawn on (their id is not VT_NO_ENTITY).
inline std::size_t drawnPixels(const Image& img) {
    return std::size_t(std::count_if(img.id.begin(), img.id.end(),
                                     [](std::uint32_t v) { return v != kernel::VT_NO_ENTITY; }));
}

} // namespace voxtier::test
