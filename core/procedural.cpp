#include "core/procedural.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

namespace voxtier {

namespace {

// Parameters are checked here too (not only by the scene loader) so a bad call is an error
// with a reason rather than a silently wrong layout; sizes are checked again by VoxelGrid.
void require(bool ok, const char* field, const std::string& reason) {
    if (!ok) throw InputError("procedural", field, reason);
}

std::shared_ptr<VoxelModel> single(const char* name, VoxelGrid grid) {
    std::vector<VoxelGrid> frames;
    frames.push_back(std::move(grid));
    return std::make_shared<VoxelModel>(name, proceduralPalette(), std::move(frames));
}

void fill(VoxelGrid& g, glm::ivec3 min, glm::ivec3 max, std::uint8_t index) {
    for (int z = min.z; z < max.z; ++z)
        for (int y = min.y; y < max.y; ++y)
            for (int x = min.x; x < max.x; ++x) g.set({x, y, z}, index);
}

} // namespace

const Palette& proceduralPalette() {
    static const Palette palette = [] {
        Palette p;
        p.colors[0] = packRgba(0, 0, 0, 0);
        p.colors[1] = packRgba(230, 40, 40);
        p.colors[2] = packRgba(40, 200, 60);
        p.colors[3] = packRgba(50, 90, 230);
        p.colors[4] = packRgba(240, 210, 40);
        p.colors[5] = packRgba(220, 50, 200);
        p.colors[6] = packRgba(40, 200, 220);
        p.colors[7] = packRgba(245, 130, 30);
        p.colors[8] = packRgba(140, 60, 230);
        // Red rises while green falls, so every entry differs from every other one in two
        // channels; blue 128 keeps them away from the black outline and from 1..8.
        for (unsigned i = 9; i < 256; ++i) p.colors[i] = packRgba(i, 255 - i, 128);
        return p;
    }();
    return palette;
}

std::shared_ptr<VoxelModel> makeBox(glm::ivec3 size, std::uint8_t index) {
    VoxelGrid g(size, "procedural box");
    std::fill(g.data().begin(), g.data().end(), index);
    return single("box", std::move(g));
}

std::shared_ptr<VoxelModel> makeSphere(int radius, std::uint8_t index) {
    require(radius >= 1 && 2 * radius <= Limits::kMaxModelDim, "sphere.radius",
            "radius must be 1.." + std::to_string(Limits::kMaxModelDim / 2));
    const int n = 2 * radius;
    VoxelGrid g(glm::ivec3(n), "procedural sphere");
    // Doubled coordinates keep the test exact: centre (x+½) - r becomes (2x+1) - 2r.
    const long long r2x4 = 4LL * radius * radius;
    for (int z = 0; z < n; ++z)
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x) {
                const long long dx = 2 * x + 1 - n, dy = 2 * y + 1 - n, dz = 2 * z + 1 - n;
                if (dx * dx + dy * dy + dz * dz <= r2x4) g.set({x, y, z}, index);
            }
    return single("sphere", std::move(g));
}

std::shared_ptr<VoxelModel> makeArrow(int length) {
    require(length >= 8 && length <= Limits::kMaxModelDim, "arrow.length",
            "length must be 8.." + std::to_string(Limits::kMaxModelDim));
    const int L = length;
    VoxelGrid g({L, 5, 5}, "procedural arrow");
    fill(g, {0, 2, 2}, {L - 3, 3, 3}, proc_index::kRed);            // shaft
    fill(g, {L - 3, 0, 0}, {L - 2, 5, 5}, proc_index::kGreen);      // head base 5x5
    fill(g, {L - 2, 1, 1}, {L - 1, 4, 4}, proc_index::kGreen);      // head middle 3x3
    fill(g, {L - 1, 2, 2}, {L, 3, 3}, proc_index::kGreen);          // head tip
    fill(g, {0, 2, 3}, {3, 3, 5}, proc_index::kBlue);               // fin, +Z at the tail
    fill(g, {L / 2, 3, 2}, {L / 2 + 1, 5, 3}, proc_index::kYellow); // stub, +Y
    return single("arrow", std::move(g));
}

std::shared_ptr<VoxelModel> makeShell(glm::ivec3 size, int thickness, std::uint8_t index) {
    require(thickness >= 1, "shell.thickness", "thickness must be at least 1");
    VoxelGrid g(size, "procedural shell");
    const int t = thickness;
    for (int z = 0; z < size.z; ++z)
        for (int y = 0; y < size.y; ++y)
            for (int x = 0; x < size.x; ++x) {
                const bool onFace = x < t || y < t || z < t || x >= size.x - t || y >= size.y - t ||
                                    z >= size.z - t;
                if (onFace) g.set({x, y, z}, index);
            }
    return single("shell", std::move(g));
}

std::shared_ptr<VoxelModel> makeSingleVoxel(std::uint8_t index) {
    VoxelGrid g(glm::ivec3(1), "procedural voxel");
    g.set({0, 0, 0}, index);
    return single("voxel", std::move(g));
}

} // namespace voxtier
