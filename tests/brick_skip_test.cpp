// Empty-space skipping (core/sprite_kernel.h vtSkipBrick over core/voxel_model.hpp's
// BrickOccupancy) is exact: the skipping traversal returns what the cell-by-cell traversal
// returns (hit, palette index, entered face) for every ray tried, and the reference images with
// and without it are the same pixels (colour, depth bits, entity id) at both rates. The oracle
// is the far baker's cell-by-cell loop (impostor_cache/kernel_order_dda.hpp traceKernelOrder with
// no bound), which never reads the occupancy. The occupancy itself is checked against its
// definition, brick by brick, on every bundled model and through random edits.
#include "core/model_view.hpp"
#include "core/scene_loader.hpp"
#include "core/view_set.hpp"
#include "impostor_cache/kernel_order_dda.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <random>

namespace voxtier {
namespace {

using test::sourcePath;

int maxSide(glm::ivec3 d) {
    return std::max({d.x, d.y, d.z});
}

/// Whether box `b` of side `side` of `g` holds a non-empty voxel, from the definition.
bool boxHasVoxel(const VoxelGrid& g, glm::ivec3 b, int side) {
    for (int z = b.z * side; z < std::min((b.z + 1) * side, g.dims().z); ++z)
        for (int y = b.y * side; y < std::min((b.y + 1) * side, g.dims().y); ++y)
            for (int x = b.x * side; x < std::min((b.x + 1) * side, g.dims().x); ++x)
                if (g.at({x, y, z}) != 0) return true;
    return false;
}

/// Number of bricks and regions whose occupancy differs from the definition (0: tight); the
/// first in `first`.
int untightBoxes(const VoxelGrid& g, const BrickOccupancy& o, std::string* first) {
    int bad = 0;
    for (int shift : {kernel::VT_BRICK_SHIFT, kernel::VT_REGION_SHIFT}) {
        const int side = 1 << shift;
        const glm::ivec3 n = (g.dims() + side - 1) / side;
        if (o.dims(shift) != n) {
            *first = "dims differ at side " + std::to_string(side);
            return 1;
        }
        for (int z = 0; z < n.z; ++z)
            for (int y = 0; y < n.y; ++y)
                for (int x = 0; x < n.x; ++x)
                    if (o.occupied(shift, {x, y, z}) != boxHasVoxel(g, {x, y, z}, side) &&
                        bad++ == 0)
                        *first = "box " + std::to_string(x) + "," + std::to_string(y) + "," +
                                 std::to_string(z) + " of side " + std::to_string(side);
    }
    return bad;
}

TEST(BrickOccupancy, TightOnEveryBundledModel) {
    int models = 0;
    for (const test::BundledModel& b : test::bundledVoxModels()) {
        std::string first;
        EXPECT_EQ(untightBoxes(b.model->frame(0), b.model->bricks(0), &first), 0)
            << b.file << " model " << b.index << ": " << first;
        ++models;
    }
    EXPECT_GT(models, 12);
}

// Fills, clears and single voxels at random, on sizes that are no multiple of the brick side:
// after every edit the edited frame's occupancy is exactly its definition, the other frame's
// unchanged.
TEST(BrickOccupancy, EditsKeepItTight) {
    std::mt19937 rng(35);
    int emptied = 0, occupied = 0; // edits that cleared a brick's bit, and that set one
    const auto bits = [](const BrickOccupancy& o) {
        int n = 0;
        for (std::uint32_t w : o.words()) n += std::popcount(w);
        return n;
    };
    for (glm::ivec3 dims :
         {glm::ivec3(13, 9, 18), glm::ivec3(1, 1, 1), glm::ivec3(4, 8, 5), glm::ivec3(31, 2, 7)}) {
        VoxelModel model("edits", Palette{}, {VoxelGrid(dims), VoxelGrid(dims)});
        const std::vector<std::uint32_t> otherWords(model.bricks(1).words().begin(),
                                                    model.bricks(1).words().end());
        auto coord = [&](int axis) {
            return std::uniform_int_distribution<int>(-2, dims[axis] + 1)(rng);
        };
        for (int edit = 0; edit < 300; ++edit) {
            const glm::ivec3 a(coord(0), coord(1), coord(2)), b(coord(0), coord(1), coord(2));
            const Box3i box{glm::min(a, b), glm::max(a, b) + 1};
            const int kind = edit % 4;
            const int before = bits(model.bricks(0));
            const std::uint8_t index = std::uint8_t(1 + rng() % 255);
            if (kind == 0) model.fillBox(0, box, index);
            if (kind == 1) model.clearBox(0, box);
            if (kind == 2) model.setVoxel(0, a, index);
            if (kind == 3) model.setVoxel(0, a, 0);
            std::string first;
            ASSERT_EQ(untightBoxes(model.frame(0), model.bricks(0), &first), 0)
                << "dims " << dims.x << "x" << dims.y << "x" << dims.z << " edit " << edit << ": "
                << first;
            emptied += bits(model.bricks(0)) < before;
            occupied += bits(model.bricks(0)) > before;
        }
        EXPECT_TRUE(
            std::equal(otherWords.begin(), otherWords.end(), model.bricks(1).words().begin()));
    }
    EXPECT_GT(emptied, 50);
    EXPECT_GT(occupied, 50);
}

// Which sprites march over the occupancy (SpriteGpu::skipEmpty, set by setupSprites): those
// whose empty bricks' share times the mean side reaches BrickOccupancy::kWorthSkippingCells,
// counted here from the definition; it follows edits.
TEST(BrickOccupancy, WorthSkippingFollowsTheEmptyBricks) {
    const auto expected = [](const VoxelGrid& g) {
        const glm::ivec3 n = (g.dims() + kernel::VT_BRICK - 1) / kernel::VT_BRICK;
        int empty = 0;
        for (int z = 0; z < n.z; ++z)
            for (int y = 0; y < n.y; ++y)
                for (int x = 0; x < n.x; ++x) empty += !boxHasVoxel(g, {x, y, z}, kernel::VT_BRICK);
        const double side = (g.dims().x + g.dims().y + g.dims().z) / 3.0;
        return double(empty) / double(n.x * n.y * n.z) * side >=
               double(BrickOccupancy::kWorthSkippingCells);
    };
    std::mt19937 rng(3);
    VoxelModel model("worth", Palette{}, {VoxelGrid({60, 40, 50})});
    int worth = 0, notWorth = 0;
    for (int edit = 0; edit < 80; ++edit) {
        // Fill while skipping pays, clear while it does not: the answer swings both ways.
        const glm::ivec3 a(int(rng() % 60), int(rng() % 40), int(rng() % 50));
        const glm::ivec3 size(int(rng() % 20), int(rng() % 20), int(rng() % 20));
        if (model.bricks(0).worthSkipping())
            model.fillBox(0, {a - size, a + size}, 9);
        else
            model.clearBox(0, {a - size, a + size});
        const bool want = expected(model.frame(0));
        ASSERT_EQ(model.bricks(0).worthSkipping(), want) << "edit " << edit;
        worth += want;
        notWorth += !want;
    }
    EXPECT_GT(worth, 5);
    EXPECT_GT(notWorth, 5);
    // setupSprites carries it to the kernel.
    auto sparse = std::make_shared<VoxelModel>("sparse", Palette{},
                                               std::vector<VoxelGrid>{VoxelGrid({80, 80, 80})});
    sparse->setVoxel(0, {40, 40, 40}, 3);
    for (const auto& [m, skip] :
         {std::pair{sparse, 1u}, std::pair{test::solidBox({80, 80, 80}), 0u}}) {
        const Scene scene = sceneForModel(m, test::viewToward({1, 2, 3}, 1.0, 64, 48));
        const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
        EXPECT_EQ(setupSprites(scene, cam, 0.0)[0].gpu.skipEmpty, skip);
    }
}

/// The cell-by-cell source (the oracle's) and the skipping one, counting reads.
struct PlainVoxels {
    const VoxelGrid& grid;
    mutable std::uint64_t reads = 0;
    unsigned fetch(glm::ivec3 c) const {
        ++reads;
        return grid.at(c);
    }
};
struct BrickedVoxels {
    const VoxelGrid& grid;
    const BrickOccupancy& bricks;
    mutable std::uint64_t reads = 0, brickReads = 0;
    kernel::uint fetch(glm::ivec3 c) const {
        ++reads;
        return grid.at(c);
    }
    kernel::uint fetchBrickWord(kernel::uint word) const {
        ++brickReads;
        return bricks.words()[word];
    }
};

struct Tally {
    std::uint64_t rays = 0, hits = 0, plainReads = 0, voxelReads = 0, brickReads = 0;
};

/// One ray of `sprite` (lattice cell `cell`) both ways, skipping whatever the sprite's
/// skipEmpty says; "" when they agree.
std::string compareRay(const kernel::SpriteGpu& sprite, glm::ivec2 cell, const VoxelGrid& grid,
                       const BrickOccupancy& bricks, Tally& tally) {
    kernel::SpriteGpu s = sprite;
    s.skipEmpty = 1u;
    const PlainVoxels plain{grid};
    const KernelOrderHit want =
        traceKernelOrder(s, kernel::vtCellRayOrigin(s, cell), plain, true, -kernel::VT_FAR);
    const BrickedVoxels bricked{grid, bricks};
    kernel::SpriteTracer<BrickedVoxels> tracer{bricked};
    kernel::uint index = 0, face = 0;
    const bool hit = tracer.vtTrace(s, cell, index, face);
    ++tally.rays;
    tally.hits += hit;
    tally.plainReads += plain.reads;
    tally.voxelReads += bricked.reads;
    tally.brickReads += bricked.brickReads;
    if (hit != want.hit || (hit && (index != want.index || face != want.face)))
        return "cell " + std::to_string(cell.x) + "," + std::to_string(cell.y) + ": skipping " +
               (hit ? "hits index " + std::to_string(index) + " face " + std::to_string(face)
                    : std::string("misses")) +
               ", cell by cell " +
               (want.hit ? "hits index " + std::to_string(want.index) + " face " +
                               std::to_string(want.face)
                         : std::string("misses"));
    // Skipping only leaves voxel reads out.
    if (bricked.reads > plain.reads)
        return "cell " + std::to_string(cell.x) + "," + std::to_string(cell.y) + ": " +
               std::to_string(bricked.reads) + " voxel reads against " +
               std::to_string(plain.reads) + " cell by cell";
    return "";
}

/// Directions (voxel space, towards the viewer) beyond the identity sweeps': components small
/// enough for the 1e-6 snap to zero them, and just large enough to stay (huge 1/d).
std::vector<glm::dvec3> awkwardDirections() {
    return {{1.0, 3e-7, 0.4}, {-2e-7, 1.0, -1e-7}, {0.3, -0.2, 4e-7},
            {1.0, 2e-6, 0.0}, {3e-6, -1.0, 1.0},   {0.0, 5e-6, -1.0}};
}

// Every bundled model (the two 256^3 trees too) through the near tier's own sprites: the 26
// canonical directions (exact zero components), 20 seeded random ones and the awkward ones, at
// integer and non-integer sigma (where face-view rays run exactly along voxel faces), every cell
// of the cell range and a ring around it. The 256^3 models take every second cell at sigma 0.5
// and every seventh at 1.5 (all of them would take minutes).
TEST(BrickSkip, EveryBundledModelEveryDirectionEqualsTheCellByCellTrace) {
    std::vector<glm::dvec3> dirs = test::sweepDirections();
    for (const glm::dvec3& d : awkwardDirections()) dirs.push_back(d);
    Tally tally;
    int sprites = 0;
    for (const test::BundledModel& b : test::bundledVoxModels()) {
        const VoxelGrid& grid = b.model->frame(0);
        const bool large = maxSide(grid.dims()) > 128;
        for (double sigma :
             large ? std::vector<double>{0.5, 1.5} : std::vector<double>{0.5, 1.0, 1.5, 2.5})
            for (std::size_t k = 0; k < dirs.size(); ++k) {
                const Scene scene =
                    sceneForModel(b.model, test::viewToward(dirs[k], sigma, 64, 48));
                const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
                const kernel::SpriteGpu s = setupSprites(scene, cam, 0.0)[0].gpu;
                const int stride = large ? (sigma > 1.0 ? 7 : 2) : 1;
                const glm::ivec4 r = s.cellRange;
                ++sprites;
                for (int j = r.z - 1; j <= r.w + 1; ++j)
                    for (int i = r.x - 1 + (j % stride + stride) % stride; i <= r.y + 1;
                         i += stride) {
                        const std::string diff =
                            compareRay(s, {i, j}, grid, b.model->bricks(0), tally);
                        ASSERT_EQ(diff, "") << b.file << " model " << b.index << " sigma " << sigma
                                            << " direction #" << k;
                    }
            }
    }
    EXPECT_GT(sprites, 12 * 2 * 52);
    EXPECT_GT(tally.hits, tally.rays / 20);
    // Skipping leaves out most reads on these models (a real outcome of the occupancy, not a
    // timing).
    EXPECT_LT(tally.voxelReads + tally.brickReads, tally.plainReads / 2);
    std::printf("%llu rays, %llu hits; reads per ray: %.2f cell by cell, %.2f voxel + %.2f brick "
                "skipping\n",
                (unsigned long long)tally.rays, (unsigned long long)tally.hits,
                double(tally.plainReads) / double(tally.rays),
                double(tally.voxelReads) / double(tally.rays),
                double(tally.brickReads) / double(tally.rays));
}

/// A ray frame of one ray (vtTrace's cell (0, 0)): origin `o` exactly, direction `w` normalised.
kernel::SpriteGpu singleRay(glm::ivec3 dims, glm::vec3 o, glm::dvec3 w) {
    kernel::SpriteGpu s{};
    s.skipEmpty = 1u;
    const glm::dvec3 d = glm::normalize(w);
    s.dir = glm::vec3(d);
    for (int k = 0; k < 3; ++k) s.invDir[k] = s.dir[k] != 0.0f ? float(1.0 / d[k]) : 0.0f;
    s.rayBase = o; // cellRight = cellUp = 0: the origin of cell (0, 0) is rayBase exactly
    s.dims = glm::uvec4(glm::uvec3(dims), 0u);
    return s;
}

/// A grid with voxels at `density`, and one voxel on each side of a region corner (a brick
/// corner in grids smaller than a region) near the centre.
VoxelGrid sparseGrid(glm::ivec3 dims, double density, std::mt19937& rng) {
    VoxelGrid g(dims);
    std::bernoulli_distribution solid(density);
    for (auto& v : g.data()) v = solid(rng) ? std::uint8_t(1 + rng() % 255) : 0;
    const int side = maxSide(dims) > kernel::VT_REGION ? kernel::VT_REGION : kernel::VT_BRICK;
    const glm::ivec3 c = (dims / 2 / side) * side;
    for (glm::ivec3 p : {c, c - 1})
        if (glm::all(glm::greaterThanEqual(p, glm::ivec3(0))) && glm::all(glm::lessThan(p, dims)))
            g.set(p, 7);
    return g;
}

// Exact ties, built in: origins q + f - L w with q every integer point around the grid and w an
// integer direction, so that (when |w_x| = |w_y|, say) the x and y planes are crossed at the very
// same float t, brick planes included, and with f = 0 the rays run along voxel edges and faces.
// Directions with zero components, and sizes that are no multiple of the brick side (partial
// bricks at the far faces), down to 1x1x1.
TEST(BrickSkip, ExactTiesZeroComponentsAndPartialBricks) {
    std::mt19937 rng(20261128);
    std::vector<glm::ivec3> dirs = test::canonicalDirections();
    for (glm::ivec3 w : {glm::ivec3(1, 2, 0), glm::ivec3(-2, 1, 1), glm::ivec3(1, 1, 3),
                         glm::ivec3(3, -3, 1), glm::ivec3(0, 4, -1)})
        dirs.push_back(w);
    Tally tally;
    for (glm::ivec3 dims :
         {glm::ivec3(1, 1, 1), glm::ivec3(3, 1, 7), glm::ivec3(5, 5, 5), glm::ivec3(8, 8, 8),
          glm::ivec3(9, 17, 4), glm::ivec3(13, 9, 18), glm::ivec3(37, 20, 33)})
        for (double density : {0.0, 0.003, 0.25}) {
            VoxelModel model("ties", Palette{}, {sparseGrid(dims, density, rng)});
            const VoxelGrid& grid = model.frame(0);
            const int L = maxSide(dims) + 3;
            for (glm::ivec3 w : dirs)
                for (float f : {0.0f, 0.25f})
                    for (int qz = -1; qz <= dims.z; ++qz)
                        for (int qy = -1; qy <= dims.y; ++qy)
                            for (int qx = -1; qx <= dims.x; ++qx) {
                                const glm::vec3 o =
                                    glm::vec3(glm::ivec3(qx, qy, qz) - L * w) + glm::vec3(f);
                                const std::string diff =
                                    compareRay(singleRay(dims, o, glm::dvec3(w)), {0, 0}, grid,
                                               model.bricks(0), tally);
                                ASSERT_EQ(diff, "")
                                    << "dims " << dims.x << "x" << dims.y << "x" << dims.z
                                    << " density " << density << " w (" << w.x << "," << w.y << ","
                                    << w.z << ") origin (" << o.x << "," << o.y << "," << o.z
                                    << ")";
                            }
        }
    EXPECT_GT(tally.hits, tally.rays / 10);
}

// Random origins and directions (no built-in structure), through the same grids.
TEST(BrickSkip, RandomRaysEqualTheCellByCellTrace) {
    std::mt19937 rng(7);
    std::normal_distribution<double> normal(0.0, 1.0);
    Tally tally;
    for (glm::ivec3 dims : {glm::ivec3(6, 11, 3), glm::ivec3(13, 9, 18), glm::ivec3(40, 33, 21)})
        for (double density : {0.005, 0.05, 0.3}) {
            VoxelModel model("random", Palette{}, {sparseGrid(dims, density, rng)});
            std::uniform_real_distribution<float> inside(-2.0f, float(maxSide(dims)) + 2.0f);
            for (int ray = 0; ray < 20000; ++ray) {
                const glm::dvec3 w(normal(rng), normal(rng), normal(rng));
                const glm::vec3 target(inside(rng), inside(rng), inside(rng));
                const glm::vec3 o = target - glm::vec3(glm::normalize(w)) * float(2 * 40 + 7);
                ASSERT_EQ(compareRay(singleRay(dims, o, w), {0, 0}, model.frame(0), model.bricks(0),
                                     tally),
                          "")
                    << "dims " << dims.x << "x" << dims.y << "x" << dims.z << " ray " << ray;
            }
        }
    EXPECT_GT(tally.hits, tally.rays / 10);
}

/// How the reference images of a test trace: cell by cell (no occupancy), as each sprite's
/// skipEmpty says (the product), or skipping on every sprite.
enum class Skip { Never, AsSet, Always };

/// The reference image of `scene` at `rate`.
Image referenceImage(const Scene& scene, NearRate rate, Skip skip, ReferenceStats* stats) {
    const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
    std::vector<SpriteSetup> sprites = setupSprites(scene, cam, 0.0);
    if (skip == Skip::Always)
        for (SpriteSetup& s : sprites) s.gpu.skipEmpty = 1u;
    Image img(cam.width, cam.height, scene.render.background);
    ReferenceOptions options;
    options.rate = rate;
    options.skipEmptyBricks = skip != Skip::Never;
    renderReference(scene.models, sprites, img, stats, options);
    return img;
}

void expectSameImagesAtBothRates(const Scene& scene, const std::string& what,
                                 std::uint64_t* readsPlain = nullptr,
                                 std::uint64_t* readsSkipping = nullptr) {
    for (NearRate rate : {NearRate::Fragment, NearRate::Cell}) {
        ReferenceStats plain, skipping, product;
        const Image a = referenceImage(scene, rate, Skip::Never, &plain);
        const Image b = referenceImage(scene, rate, Skip::Always, &skipping);
        const Image c = referenceImage(scene, rate, Skip::AsSet, &product);
        const char* name = rate == NearRate::Cell ? " at cell rate" : " per pixel";
        ASSERT_EQ(test::describeDifference(b, a, "skipping", "cell by cell"), "") << what << name;
        ASSERT_EQ(test::describeDifference(c, a, "as set", "cell by cell"), "") << what << name;
        EXPECT_EQ(plain.brickFetches, 0u) << what << name;
        // Per pixel only: cell-rate bands may trace a shared cell twice (reference_renderer.cpp
        // LazyCells), so its read counts vary from run to run.
        if (rate != NearRate::Fragment) continue;
        EXPECT_LE(skipping.voxelFetches - skipping.brickFetches, plain.voxelFetches) << what;
        if (readsPlain) *readsPlain += plain.voxelFetches;
        if (readsSkipping) *readsSkipping += skipping.voxelFetches;
    }
}

// Whole images (colour, depth bits, entity id), per pixel and cell-rate: every bundled model
// from the 26 canonical and 20 random directions at sigma 1 and 2.
TEST(BrickSkip, EveryBundledModelImagesEqualAtBothRates) {
    const std::vector<glm::dvec3> dirs = test::sweepDirections();
    std::uint64_t plain = 0, skipping = 0;
    for (const test::BundledModel& b : test::bundledVoxModels())
        for (double sigma : {1.0, 2.0})
            for (std::size_t k = 0; k < dirs.size(); ++k)
                expectSameImagesAtBothRates(
                    sceneForModel(b.model, test::viewToward(dirs[k], sigma, 64, 48)),
                    b.file + " model " + std::to_string(b.index) + " sigma " +
                        std::to_string(sigma) + " direction #" + std::to_string(k),
                    &plain, &skipping);
    EXPECT_LT(skipping, plain);
}

// The bench scenes' first frames and the golden scenes, whole.
TEST(BrickSkip, BenchAndGoldenScenesImagesEqualAtBothRates) {
    for (const char* file :
         {"scenes/bench/street.json", "scenes/bench/tank_army.json", "scenes/bench/rts_pan.json",
          "scenes/bench/rts_topdown.json", "scenes/bench/vox_crowd.json",
          "scenes/golden/crowd.json", "scenes/golden/far_origin.json", "scenes/default.json"}) {
        Scene scene = loadScene(sourcePath(file));
        // Half size: the same sprites, a quarter of the pixels.
        scene.camera.width = std::max(64, scene.camera.width / 2);
        scene.camera.height = std::max(48, scene.camera.height / 2);
        expectSameImagesAtBothRates(scene, file);
    }
}

} // namespace
} // namespace voxtier
