#include "core/model_view.hpp"

#include "core/error.hpp"
#include "core/scene_loader.hpp"
#include "core/sprite.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

namespace voxtier {

namespace {

void checkView(const ModelView& v) {
    Limits::checkedSigma(v.sigma, "", "--sigma");
    if (!std::isfinite(v.azimuthDeg) || !std::isfinite(v.elevationDeg) ||
        !(v.elevationDeg >= -90.0 && v.elevationDeg <= 90.0))
        throw InputError("", "--view",
                         "azimuth must be finite and elevation within -90..90 degrees");
    if (!(v.distance >= 0.0) || !std::isfinite(v.distance))
        throw InputError("", "--distance", "must be a non-negative number");
}

} // namespace

void frameEntities(Scene& s, const ModelView& v) {
    checkView(v);
    s.render.sigma = v.sigma;
    s.render.voxelSize = v.voxelSize;
    // The bounding sphere of the entities' bounding spheres (centre: the middle of their box).
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi = -lo;
    std::vector<std::pair<glm::dvec3, double>> spheres;
    for (const Entity& e : s.entities) {
        const VoxelModel& m = *s.models[std::size_t(e.model)];
        const glm::ivec3 dims = m.frame(m.wrapFrame(e.frame)).dims();
        const EntityPose pose = makeEntityPose(e, dims, v.voxelSize);
        const glm::dvec3 c = pose.relativeWorld(glm::dvec3(dims) * 0.5, glm::dvec3(0.0));
        const double r = 0.5 * glm::length(glm::dvec3(dims)) * pose.metresPerVoxel;
        spheres.emplace_back(c, r);
        lo = glm::min(lo, c - r);
        hi = glm::max(hi, c + r);
    }
    const glm::dvec3 centre = spheres.empty() ? glm::dvec3(0.0) : (lo + hi) * 0.5;
    double radius = 0.0;
    for (const auto& [c, r] : spheres) radius = std::max(radius, glm::length(c - centre) + r);

    const double az = glm::radians(v.azimuthDeg), el = glm::radians(v.elevationDeg);
    const glm::dvec3 toward{std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el)};
    double dist = v.distance;
    if (dist == 0.0) {
        const double halfFov =
            glm::radians(v.fovYDeg) * 0.5 * std::min(1.0, double(v.width) / v.height);
        dist = 1.15 * radius / std::sin(halfFov);
    }
    s.camera.position = centre + toward * dist;
    s.camera.target = centre;
    s.camera.up = std::abs(v.elevationDeg) > 89.9 ? glm::dvec3(-std::sin(az), 0.0, -std::cos(az)) *
                                                        (v.elevationDeg > 0 ? 1.0 : -1.0)
                                                  : glm::dvec3(0.0, 1.0, 0.0);
    s.camera.fovYDeg = v.fovYDeg;
    s.camera.width = v.width;
    s.camera.height = v.height;
    s.camera.zNear = std::min(0.05, dist * 0.01);
    s.cameraPositioned = true;
}

Scene sceneForModel(std::shared_ptr<VoxelModel> model, const ModelView& v) {
    checkView(v);
    Scene s;
    s.source = model->name();
    const glm::ivec3 dims = model->frame(model->wrapFrame(v.frame)).dims();
    s.models.push_back(std::move(model));
    Entity e;
    e.anchor = glm::dvec3(dims) * 0.5;
    e.frame = v.frame;
    s.entities.push_back(e);
    frameEntities(s, v);
    return s;
}

Scene sceneForVoxFile(const VoxFile& file, const ModelView& v) {
    checkView(v);
    FlattenedVoxScene flat = flattenVoxScene(file, glm::dvec3(0.0), 1.0, false, v.voxelSize);
    Scene s;
    s.source = file.source;
    s.models = std::move(flat.models);
    s.entities = std::move(flat.entities);
    frameEntities(s, v);
    return s;
}

} // namespace voxtier
