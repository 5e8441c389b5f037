#pragma once
// A one-entity scene for looking at a single model: what `voxtier render MODEL.vox` and many
// tests use instead of a scene file.
#include "core/scene.hpp"
#include "core/vox_reader.hpp"

#include <memory>

namespace voxtier {

struct ModelView {
    double azimuthDeg = 30.0; ///< around world Y; 0 = camera on +Z (sees the model's voxel -Y side)
    double elevationDeg = 20.0; ///< above the horizon; +-90 = straight down / up
    double distance = 0.0;      ///< metres from the model centre; 0 = fit the model in view
    double sigma = 1.0;
    double voxelSize = 0.1;
    int width = 640, height = 480;
    double fovYDeg = 40.0;
    int frame = 0;
};

/// Aims the camera of `view` at all of the scene's entities: at the centre of their bounding
/// sphere, from (azimuth, elevation), at `distance` (0: the sphere fits the view); also sets the
/// image size, sigma and voxel size. sceneForModel and sceneForVoxFile use it.
void frameEntities(Scene& scene, const ModelView& view);

/// The whole scene graph of a .vox file as entities (its visible instances, as a scene's
/// "vox_scenes" entry at the origin flattens them, see flattenVoxScene), framed by `view`.
Scene sceneForVoxFile(const VoxFile& file, const ModelView& view);

/// The model's centre sits at the world origin; the camera looks at it from (azimuth,
/// elevation) with world up Y (world -Z when looking straight down or up).
Scene sceneForModel(std::shared_ptr<VoxelModel> model, const ModelView& view);

} // namespace voxtier
