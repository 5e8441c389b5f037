#include "core/procedural.hpp"

#include "core/error.hpp"
#include "core/splitmix64.hpp"

#include <algorithm>
#include <cmath>
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

namespace tank_index {
constexpr std::uint8_t kHullFirst = 32; ///< 32..39: hull tones
constexpr std::uint8_t kTrackDark = 40, kTrackLight = 41, kWheel = 42, kBarrel = 43, kHatch = 44,
                       kGrille = 45, kAntenna = 46, kTrim = 47;
} // namespace tank_index

} // namespace

const Palette& tankPalette() {
    static const Palette palette = [] {
        Palette p = proceduralPalette();
        const Rgba8 tones[16] = {
            packRgba(95, 110, 50),   packRgba(190, 165, 110),
            packRgba(60, 85, 50),    packRgba(120, 125, 118),
            packRgba(150, 110, 70),  packRgba(80, 95, 110),
            packRgba(215, 215, 205), packRgba(140, 75, 45), // hull tones
            packRgba(45, 45, 42),    packRgba(88, 86, 80),
            packRgba(150, 150, 140), // tracks, wheel
            packRgba(62, 64, 58),    packRgba(34, 38, 36),
            packRgba(52, 58, 46),                              // barrel, hatch, grille
            packRgba(205, 45, 40),   packRgba(176, 170, 150)}; // antenna tip, turret trim
        for (int i = 0; i < 16; ++i) p.colors[std::size_t(32 + i)] = tones[i];
        return p;
    }();
    return palette;
}

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

std::shared_ptr<VoxelModel> makeTank(std::uint64_t seed, int frames, glm::ivec3 size) {
    require(frames >= 1 && frames <= Limits::kMaxFramesPerModel, "tank.frames",
            "frames must be 1.." + std::to_string(Limits::kMaxFramesPerModel));
    for (int a = 0; a < 3; ++a)
        require(size[a] >= 8 && size[a] <= Limits::kMaxModelDim, "tank.size",
                "each side must be 8.." + std::to_string(Limits::kMaxModelDim));
    const int L = size.x, W = size.y, H = size.z;
    // The type: every proportion is drawn from the seed, relative to the grid, so a 64x64x32
    // tank of a seed is the 32x32x16 one at twice the resolution.
    SplitMix64 rng{seed};
    const auto hull = std::uint8_t(tank_index::kHullFirst + rng.next() % 8);
    const std::uint8_t turretColor = rng.next() % 2 ? hull : tank_index::kTrim;
    const int margin = int(std::lround(W * rng.uniform(0.03, 0.12))); // tracks to grid side
    const int trackW = std::max(2, int(std::lround(W * rng.uniform(0.17, 0.23))));
    const int trackH = std::max(3, int(std::lround(H * rng.uniform(0.28, 0.36))));
    const int hullTop =
        std::min(H - 3, trackH + 1 + std::max(1, int(std::lround(H * rng.uniform(0.12, 0.20)))));
    const int turretTop =
        std::min(H - 1, hullTop + std::max(2, int(std::lround(H * rng.uniform(0.22, 0.30)))));
    const double turretR = W * rng.uniform(0.17, 0.24);
    const double tx = L * rng.uniform(0.38, 0.50), ty = W * 0.5;
    const double barrelLen = L * rng.uniform(0.28, 0.45);
    const double yaw0 = rng.uniform(0.0, 6.283185307179586);
    const int slope = std::max(1, L / 8); // glacis run
    const int treadPeriod = std::max(2, L / 16);
    const int y0 = margin, y1 = W - margin; // outer faces of the tracks

    std::vector<VoxelGrid> grids;
    grids.reserve(std::size_t(frames));
    for (int f = 0; f < frames; ++f) {
        VoxelGrid g(size, "procedural tank");
        auto put = [&](int x, int y, int z, std::uint8_t v) {
            if (x >= 0 && y >= 0 && z >= 0 && x < L && y < W && z < H) g.set({x, y, z}, v);
        };
        // Tracks: rounded ends, treads that roll by one voxel per frame (top and bottom run
        // opposite ways, as on a real track), a row of wheel hubs on the outer faces.
        for (int side = 0; side < 2; ++side)
            for (int y = side ? y1 - trackW : y0; y < (side ? y1 : y0 + trackW); ++y)
                for (int z = 0; z < trackH; ++z)
                    for (int x = 0; x < L; ++x) {
                        if ((x == 0 || x == L - 1) && (z == 0 || z == trackH - 1)) continue;
                        const int phase = z >= trackH / 2 ? x + f : x - f;
                        const int p =
                            ((phase % (2 * treadPeriod)) + 2 * treadPeriod) % (2 * treadPeriod);
                        std::uint8_t v =
                            p < treadPeriod ? tank_index::kTrackDark : tank_index::kTrackLight;
                        const bool outer = y == y0 || y == y1 - 1;
                        if (outer && z == trackH / 2 && x % std::max(2, L / 6) == L / 12)
                            v = tank_index::kWheel;
                        put(x, y, z, v);
                    }
        // Hull: a lower hull between the tracks, a fender over them, a narrower superstructure
        // with a sloped front (glacis) and an engine grille at the rear.
        for (int z = 1; z <= trackH; ++z)
            for (int y = y0 + trackW; y < y1 - trackW; ++y)
                for (int x = 2; x < L - 2; ++x) put(x, y, z, hull);
        for (int x = 1; x < L - 1; ++x)
            for (int y = y0; y < y1; ++y) put(x, y, trackH, hull);
        for (int x = 2; x < L - 2; ++x) {
            const int drop = std::max(0, x - (L - 2 - slope));
            for (int z = trackH + 1; z < hullTop - drop; ++z)
                for (int y = y0 + trackW - 1; y < y1 - trackW + 1; ++y) {
                    const bool grille = z == hullTop - 1 && x < L / 5 && y % 2 == 0;
                    put(x, y, z, grille ? tank_index::kGrille : hull);
                }
        }
        // Turret: a disc of radius R, one voxel narrower on its top layer, turned by the frame.
        const double yaw = yaw0 + 6.283185307179586 * f / frames;
        const double cy = std::cos(yaw), sy = std::sin(yaw);
        for (int z = hullTop; z < turretTop; ++z) {
            const double r = z == turretTop - 1 ? turretR - 1.0 : turretR;
            for (int y = 0; y < W; ++y)
                for (int x = 0; x < L; ++x) {
                    const double dx = x + 0.5 - tx, dy = y + 0.5 - ty;
                    if (dx * dx + dy * dy <= r * r) put(x, y, z, turretColor);
                }
        }
        // Hatch on the turret top, off the turret's axis (it turns with the turret).
        const double hx = tx + (-0.4 * cy - 0.35 * sy) * turretR,
                     hy = ty + (-0.4 * sy + 0.35 * cy) * turretR;
        for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx)
                put(int(std::floor(hx)) + dx, int(std::floor(hy)) + dy, turretTop,
                    tank_index::kHatch);
        // Barrel: two voxels wide and high, from inside the turret outwards along the yaw.
        const int barrelZ = hullTop + (turretTop - hullTop - 2) / 2;
        for (double t = turretR * 0.5; t < turretR + barrelLen; t += 0.25)
            for (double w : {-0.5, 0.5}) {
                const int bx = int(std::floor(tx + cy * t - sy * w * 0.9));
                const int by = int(std::floor(ty + sy * t + cy * w * 0.9));
                put(bx, by, barrelZ, tank_index::kBarrel);
                put(bx, by, barrelZ + 1, tank_index::kBarrel);
            }
        // Antenna at the high-Y rear corner of the superstructure, up to the top of the grid.
        for (int z = hullTop; z < H; ++z)
            put(3, y1 - trackW - 1, z, z == H - 1 ? tank_index::kAntenna : tank_index::kBarrel);
        grids.push_back(std::move(g));
    }
    return std::make_shared<VoxelModel>("tank", tankPalette(), std::move(grids));
}

} // namespace voxtier
