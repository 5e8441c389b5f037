// flattenVoxScene and mirrorGrid (core/scene_loader.hpp): a .vox scene graph as entities.
#include "core/error.hpp"
#include "core/scene_loader.hpp"
#include "core/sprite.hpp"

#include <glm/gtc/quaternion.hpp>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>

namespace voxtier {

namespace {

/// Signed permutation test: every row and column has exactly one non-zero entry, ±1.
bool isSignedPermutation(const glm::mat<3, 3, int>& r) {
    for (int a = 0; a < 3; ++a) {
        int col = 0, row = 0;
        for (int b = 0; b < 3; ++b) {
            if (r[a][b] != 0 && r[a][b] != 1 && r[a][b] != -1) return false;
            col += r[a][b] != 0;
            row += r[b][a] != 0;
        }
        if (col != 1 || row != 1) return false;
    }
    return true;
}

int determinant(const glm::mat<3, 3, int>& m) {
    return m[0][0] * (m[1][1] * m[2][2] - m[2][1] * m[1][2]) -
           m[1][0] * (m[0][1] * m[2][2] - m[2][1] * m[0][2]) +
           m[2][0] * (m[0][1] * m[1][2] - m[1][1] * m[0][2]);
}

/// quat_cast of a signed permutation rotation, with components snapped to the exact values they
/// stand for (0, ±½, ±√½, ±1), so identical rotations give bit-identical quaternions.
glm::dquat exactQuat(const glm::dmat3& m) {
    glm::dquat q = glm::normalize(glm::quat_cast(m));
    const double exact[] = {0.0, 0.5, std::sqrt(0.5), 1.0};
    for (int i = 0; i < 4; ++i)
        for (double e : exact)
            if (std::abs(std::abs(q[i]) - e) < 1e-12) q[i] = std::copysign(e, q[i]);
    // q and -q are the same rotation; prefer w >= 0 (and a positive first non-zero) for stability.
    for (int i : {3, 0, 1, 2}) { // glm stores x, y, z, w; check w first
        if (q[i] > 0.0) break;
        if (q[i] < 0.0) {
            q = -q;
            break;
        }
    }
    return q;
}

} // namespace

VoxelGrid mirrorGrid(const VoxelGrid& grid, int axis) {
    VoxelGrid out(grid.dims());
    const glm::ivec3 d = grid.dims();
    for (int z = 0; z < d.z; ++z)
        for (int y = 0; y < d.y; ++y)
            for (int x = 0; x < d.x; ++x) {
                glm::ivec3 q{x, y, z};
                q[axis] = d[axis] - 1 - q[axis];
                out.set(q, grid.at({x, y, z}));
            }
    return out;
}

FlattenedVoxScene flattenVoxScene(const VoxFile& file, glm::dvec3 position, double scale,
                                  bool includeHidden, double voxelSize) {
    FlattenedVoxScene out;
    const std::string stem = std::filesystem::path(file.source).stem().string();
    std::map<std::pair<int, int>, int> local;
    auto modelFor = [&](int m, int axis) {
        const auto [it, inserted] = local.emplace(std::pair{m, axis}, int(out.models.size()));
        if (inserted) {
            const VoxelGrid& src = file.models[std::size_t(m)];
            std::string name = stem + "#" + std::to_string(m);
            if (axis >= 0) name += std::string("~mirror-") + "xyz"[axis];
            std::vector<VoxelGrid> frames{axis >= 0 ? mirrorGrid(src, axis) : src};
            out.models.push_back(
                std::make_shared<VoxelModel>(name, file.palette, std::move(frames)));
            out.modelKeys.emplace_back(m, axis);
        }
        return it->second;
    };

    if (file.instances.empty()) {
        for (int m = 0; m < int(file.models.size()); ++m) {
            Entity e;
            e.model = modelFor(m, -1);
            e.position = position;
            e.scale = scale;
            e.name = stem + "#" + std::to_string(m);
            out.entities.push_back(std::move(e));
        }
        return out;
    }

    const glm::dmat3 S = worldFromVoxelSwizzle();
    const double k = voxelSize * scale;
    for (std::size_t i = 0; i < file.instances.size(); ++i) {
        const VoxInstance& inst = file.instances[i];
        if (inst.hidden && !includeHidden) continue;
        const std::string field = "instances[" + std::to_string(i) + "]";
        if (inst.model < 0 || inst.model >= int(file.models.size()))
            throw InputError(file.source, field,
                             "model index " + std::to_string(inst.model) + " out of range");
        glm::mat<3, 3, int> R = inst.rotation;
        if (!isSignedPermutation(R))
            throw InputError(file.source, field, "rotation is not a signed permutation");
        const glm::ivec3 dims = file.models[std::size_t(inst.model)].dims();
        glm::dvec3 anchor = glm::dvec3(dims / 2); // the pivot floor(size/2)
        int axis = -1;
        if (determinant(R) < 0) {
            // R = R' M_a with M_a the flip of voxel axis a: mirror the data along a, keep R'.
            axis = 0;
            for (int a = 1; a < 3; ++a)
                if (R[a][a] < R[axis][axis]) axis = a;
            R[axis] = -R[axis]; // R' = R M_a negates column a
            // Mirroring p.a -> size.a - p.a moves the pivot to size.a - floor(size.a / 2).
            anchor[axis] = double(dims[axis] - dims[axis] / 2);
        }
        Entity e;
        e.model = modelFor(inst.model, axis);
        e.rotation = exactQuat(S * glm::dmat3(R) * glm::transpose(S));
        e.anchor = anchor;
        e.position = position + (S * glm::dvec3(inst.translation)) * k;
        e.scale = scale;
        e.name = inst.name.empty() ? stem + "[" + std::to_string(i) + "]" : inst.name;
        out.entities.push_back(std::move(e));
    }
    return out;
}

} // namespace voxtier
