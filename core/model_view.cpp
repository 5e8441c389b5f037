#include "core/model_view.hpp"

#include "core/error.hpp"

#include <cmath>

namespace voxtier {

Scene sceneForModel(std::shared_ptr<VoxelModel> model, const ModelView& v) {
    Limits::checkedSigma(v.sigma, "", "--sigma");
    if (!std::isfinite(v.azimuthDeg) || !std::isfinite(v.elevationDeg) ||
        !(v.elevationDeg >= -90.0 && v.elevationDeg <= 90.0))
        throw InputError("", "--view",
                         "azimuth must be finite and elevation within -90..90 degrees");
    if (!(v.distance >= 0.0) || !std::isfinite(v.distance))
        throw InputError("", "--distance", "must be a non-negative number");
    Scene s;
    s.source = model->name();
    s.render.sigma = v.sigma;
    s.render.voxelSize = v.voxelSize;
    const glm::ivec3 dims = model->frame(model->wrapFrame(v.frame)).dims();
    s.models.push_back(std::move(model));
    Entity e;
    e.anchor = glm::dvec3(dims) * 0.5;
    e.frame = v.frame;
    s.entities.push_back(e);
    const double az = glm::radians(v.azimuthDeg), el = glm::radians(v.elevationDeg);
    const glm::dvec3 toward{std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el)};
    double dist = v.distance;
    if (dist == 0.0) {
        const double radius = 0.5 * glm::length(glm::dvec3(dims)) * v.voxelSize;
        const double halfFov =
            glm::radians(v.fovYDeg) * 0.5 * std::min(1.0, double(v.width) / v.height);
        dist = 1.15 * radius / std::sin(halfFov);
    }
    s.camera.position = toward * dist;
    s.camera.target = glm::dvec3(0.0);
    s.camera.up = std::abs(v.elevationDeg) > 89.9 ? glm::dvec3(-std::sin(az), 0.0, -std::cos(az)) *
                                                        (v.elevationDeg > 0 ? 1.0 : -1.0)
                                                  : glm::dvec3(0.0, 1.0, 0.0);
    s.camera.fovYDeg = v.fovYDeg;
    s.camera.width = v.width;
    s.camera.height = v.height;
    s.camera.zNear = std::min(0.05, dist * 0.01);
    return s;
}

} // namespace voxtier
