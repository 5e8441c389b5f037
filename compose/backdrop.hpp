#pragma once
// What a frame shows where no sprite is drawn: the scene's optional ground plane with its grid
// (Scene::ground), else the background colour, with its alpha. Drawn after the tiers, into the
// pixels no sprite wrote, so every sprite is over it in every render mode and both near
// backends and the far tier see the same ground; depth and id stay empty there (the EXR Z and id
// channels describe sprites only).
#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/scene.hpp"

namespace voxtier {

/// Fills the pixels of `image` that no sprite drew (id kernel::VT_NO_ENTITY). Does nothing
/// when the scene has no ground and an opaque background (the tiers already cleared to it).
void drawBackdrop(const Scene& scene, const CameraFrame& camera, Image& image);

/// The colour of the ground seen through pixel centre (x + 0.5, y + 0.5), blended into the
/// background by distance; the background itself above the horizon.
Rgba8 groundPixel(const GroundPlane& ground, const CameraFrame& camera, Rgba8 background, int x,
                  int y);

} // namespace voxtier
