// The far blit's SIMD kernel writes the scalar reference kernel's bits (issue 24): colour, depth
// and id, and the same pixel counts, on every SIMD target this CPU runs (AVX-512, AVX2, SSE4,
// SSSE3 ... each forced in turn), on every bundled model, at the 26 canonical and 20 seeded
// random views, with rolls (quarter turns and others), cross-fades on both sides, sprites partly
// off-screen, snapshots from other views than the nearest, sigma 0.5-3, 10^6 m from the origin,
// and a target already holding pixels at exactly the sprites' depths (the id rule).
#include "far_test_support.hpp"
#include "image_checks.hpp"
#include "source_tree.hpp"
#include "view_sweeps.hpp"

#include <glm/gtc/quaternion.hpp>
#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace voxtier {
namespace {

/// Restores the CPU's own SIMD targets when a test that forced one ends, even on failure.
struct ForcedTargetReset {
    ~ForcedTargetReset() { hwy::SetSupportedTargetsForTest(0); }
};

/// Every SIMD target this build compiled and this CPU runs, best first.
std::vector<std::int64_t> simdTargets() {
    return hwy::SupportedAndGeneratedTargets();
}

/// Five entities of `model`: one centred and seen exactly along `towardViewer` (voxel space; a
/// canonical direction stays exact), the others turned at random, two of them cut by the image
/// edges, one behind and one in front of the centre, on a camera rolled by `rollDeg` about its
/// forward axis.
Scene crowdAlong(std::shared_ptr<VoxelModel> model, glm::dvec3 towardViewer, double sigma,
                 double rollDeg, glm::dvec3 offset, std::mt19937_64& rng) {
    test::ViewSetup v = test::viewAlong(std::move(model), towardViewer, sigma, 1, 0, offset);
    Scene& s = v.scene;
    // A small, wide image: sprites of 256-voxel models are then minified (many cells a pixel),
    // small ones magnified, and the side entities leave it.
    s.camera.width = 96 + int(rng() % 64);
    s.camera.height = 64 + int(rng() % 48);
    const double r = 0.5 * glm::length(glm::dvec3(s.models[0]->frame(0).dims())) * 0.1;
    const glm::dvec3 fwd = glm::normalize(s.camera.target - s.camera.position);
    const glm::dvec3 up0 = s.camera.up;
    const double a = glm::radians(rollDeg);
    const glm::dvec3 side = glm::cross(fwd, up0);
    s.camera.up = std::cos(a) * up0 + std::sin(a) * side;
    // Far enough that the centred model is about 40 pixels tall.
    const double pixelScale = 2.0 * std::tan(glm::radians(s.camera.fovYDeg) * 0.5);
    const double dist = 2.0 * r * double(s.camera.height) / (40.0 * pixelScale);
    s.camera.position = s.entities[0].position - fwd * dist;
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const glm::dvec3 camUp = s.camera.up, camRight = glm::cross(fwd, camUp);
    const double halfW = dist * pixelScale * 0.5 * double(s.camera.width) / s.camera.height;
    const double halfH = dist * pixelScale * 0.5;
    const glm::dvec3 places[4] = {
        s.entities[0].position - camRight * halfW + camUp * (0.3 * halfH), // cut by the left edge
        s.entities[0].position + camRight * halfW + camUp * halfH,         // cut at a corner
        s.entities[0].position + fwd * (3.0 * r) + camRight * (0.4 * r),   // behind
        s.entities[0].position - fwd * (1.5 * r) + camUp * (0.5 * r)};     // in front
    for (const glm::dvec3& p : places) {
        Entity e = s.entities[0];
        e.position = p;
        e.rotation =
            glm::angleAxis(3.14159 * u(rng), glm::normalize(glm::dvec3(u(rng), u(rng), u(rng)) +
                                                            glm::dvec3(0.0, 0.0, 1e-3)));
        s.entities.push_back(e);
    }
    return std::move(s);
}

/// The target as a frame may hold it when the far tier draws: here and there a pixel already
/// drawn at exactly some sprite's depth, by a lower or higher entity id, or nearer or farther.
Image prefilledTarget(const Scene& s, const std::vector<SpriteSetup>& sprites,
                      std::mt19937_64& rng) {
    Image img(s.camera.width, s.camera.height, s.render.background);
    for (std::size_t p = 0; p < img.pixelCount(); ++p) {
        if (rng() % 3 != 0 || sprites.empty()) continue;
        const SpriteSetup& sp = sprites[rng() % sprites.size()];
        const std::uint32_t k = std::uint32_t(rng() % 4);
        img.depth[p] = k == 3   ? sp.gpu.depth * 1.001f
                       : k == 2 ? sp.gpu.depth * 0.999f
                                : sp.gpu.depth;
        img.id[p] = k == 0   ? sp.entityId + 1
                    : k == 1 ? (sp.entityId > 0 ? sp.entityId - 1 : 100)
                             : 50;
        img.color[p] = packRgba(unsigned(rng() % 256), 7, 9);
    }
    return img;
}

struct Compared {
    int scenes = 0, targets = 0;
    std::uint64_t written = 0;
};

/// Draws `scene`'s visible sprites through both kernels on every SIMD target and expects the
/// same image and counters. Odd sprites take a snapshot of another view than the nearest (an
/// oblique cell map), every third cross-fades.
void compareKernels(const Scene& scene, SnapshotCache& cache, std::mt19937_64& rng,
                    const std::string& what, Compared& totals) {
    const CameraFrame cam = makeCameraFrame(scene.camera);
    std::vector<SpriteSetup> sprites = setupSprites(scene, cam, 0.0);
    std::vector<FarSprite> far;
    const std::vector<ViewId> views98 = cubeSurfaceViews(2);
    for (std::size_t i = 0; i < sprites.size(); ++i) {
        SpriteSetup& sp = sprites[i];
        if (!sp.visible()) continue;
        if (i % 3 == 1) sp.gpu.fade = i % 2 ? 0.3f : 0.7f, sp.gpu.fadeSide = i % 4 ? 1.0f : -1.0f;
        const VoxelModel& m = *scene.models[std::size_t(sp.model)];
        const ViewId view = i % 2 ? views98[rng() % views98.size()]
                                  : viewIdOf(ViewSet::Cube26, chooseFarView(sp, ViewSet::Cube26));
        far.push_back({&sp, cache.get(m, sp.frame, view, sp.lattice.sigma).get(), &m.palette()});
    }
    const Image before = prefilledTarget(scene, sprites, rng);
    Image reference = before;
    FarBlitStats refStats;
    blitFar(far, reference, &refStats, {FarBlitKernel::Scalar});
    ForcedTargetReset reset;
    for (std::int64_t target : simdTargets()) {
        hwy::SetSupportedTargetsForTest(target);
        Image simd = before;
        FarBlitStats st;
        blitFar(far, simd, &st, {FarBlitKernel::Simd});
        EXPECT_EQ(test::describeDifference(reference, simd, "scalar", "simd"), "")
            << what << " on " << hwy::TargetName(target);
        EXPECT_EQ(st.pixelsTested, refStats.pixelsTested) << what;
        EXPECT_EQ(st.pixelsWritten, refStats.pixelsWritten) << what;
        EXPECT_STREQ(farBlitSimdTarget(), hwy::TargetName(target));
        ++totals.targets;
    }
    ++totals.scenes;
    totals.written += refStats.pixelsWritten;
}

TEST(FarBlitSimd, CoversTheSimdTargetsOfThisCpu) {
    const auto targets = simdTargets();
    ASSERT_FALSE(targets.empty());
    // The default dispatch picks the best of them.
    EXPECT_STREQ(farBlitSimdTarget(), hwy::TargetName(targets.front()));
#if defined(__x86_64__)
    // Every x86-64 CPU this project runs on has SSSE3 at least: more than the baseline target.
    EXPECT_GE(targets.size(), 2u);
#endif
}

TEST(FarBlitSimd, WritesTheScalarKernelsBitsOnEveryBundledModel) {
    const std::vector<glm::dvec3> dirs = test::sweepDirections();
    const double sigmas[] = {0.5, 1.0, 1.37, 2.0, 2.5, 3.0};
    const auto models = test::bundledVoxModels();
    ASSERT_GT(models.size(), 10u);
    std::mt19937_64 rng(24);
    Compared totals;
    for (std::size_t mi = 0; mi < models.size(); ++mi) {
        const auto& bm = models[mi];
        const glm::ivec3 dims = bm.model->frame(0).dims();
        const int maxDim = std::max({dims.x, dims.y, dims.z});
        SnapshotCache cache;
        for (std::size_t k = 0; k < dirs.size(); ++k) {
            // Each model sees a third of the directions (every direction is seen by many
            // models); the 256-voxel trees a sixth, at sigma <= 1, since their snapshots are big.
            if ((k + mi) % (maxDim > 64 ? 8 : 3) != 0) continue;
            double sigma = sigmas[(k / 3 + mi) % 6];
            if (maxDim > 64) sigma = std::min(sigma, 1.0);
            const double roll = 90.0 * double(k % 4) + (k % 3 == 2 ? 17.0 : 0.0);
            // Dyadic, so camera-relative doubles are exact: the far-from-origin hard case.
            const glm::dvec3 offset =
                k % 5 == 4 ? glm::dvec3(1048576.0, -524288.0, 1048576.0) : glm::dvec3(0.0);
            const Scene s = crowdAlong(bm.model, dirs[k], sigma, roll, offset, rng);
            compareKernels(s, cache, rng,
                           bm.file + " model " + std::to_string(bm.index) + " direction " +
                               std::to_string(k) + " sigma " + std::to_string(sigma),
                           totals);
        }
    }
    EXPECT_GT(totals.scenes, 300);
    EXPECT_GT(totals.written, 100000u);
}

// The band height changes only which task draws a row and in which order sprites meet there:
// the image is the same for every band, on both kernels.
TEST(FarBlitSimd, EveryBandHeightWritesTheSameImage) {
    std::mt19937_64 rng(7);
    const Scene s =
        crowdAlong(makeTank(3, 1), glm::dvec3(0.3, -1.0, 0.5), 1.37, 17.0, glm::dvec3(0.0), rng);
    const CameraFrame cam = makeCameraFrame(s.camera);
    const std::vector<SpriteSetup> sprites = setupSprites(s, cam, 0.0);
    SnapshotCache cache;
    std::vector<FarSprite> far;
    for (const SpriteSetup& sp : sprites)
        if (sp.visible())
            far.push_back({&sp,
                           cache
                               .get(*s.models[0], 0, ViewSet::Cube26,
                                    chooseFarView(sp, ViewSet::Cube26), sp.lattice.sigma)
                               .get(),
                           &s.models[0]->palette()});
    const Image before = prefilledTarget(s, sprites, rng);
    Image first = before;
    blitFar(far, first, nullptr, {FarBlitKernel::Scalar, 1});
    EXPECT_GT(diffImages(before, first).pixelDiffs, 200u);
    for (FarBlitKernel kernel : {FarBlitKernel::Scalar, FarBlitKernel::Simd})
        for (int band : {1, 2, 3, 16, 64, 1000}) {
            Image img = before;
            blitFar(far, img, nullptr, {kernel, band});
            EXPECT_EQ(test::describeDifference(first, img, "rows", "bands"), "")
                << (kernel == FarBlitKernel::Simd ? "simd" : "scalar") << " band " << band;
        }
}

} // namespace
} // namespace voxtier
