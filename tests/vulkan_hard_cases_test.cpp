// The numerically hard cases of CONTRACT.md §7 / HARD_CASES.md on the Vulkan near tier: each image
// must equal the CPU reference exactly, and where a closed form exists (solid boxes along the 26
// canonical directions), equal that too, independently of the kernel code.
#include "closed_form.hpp"
#include "core/procedural.hpp"
#include "hard_case_scenes.hpp"
#include "image_checks.hpp"
#include "image_files/image_files.hpp"
#include "test_models.hpp"
#include "view_sweeps.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <unistd.h>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

using test::VulkanTest;
/// Each hard case both ways of tracing per-pixel sprites: in compute (the default) and rasterised.
class NearHardCases : public VulkanTest, public ::testing::WithParamInterface<NearPixels> {
  protected:
    NearOptions options() const {
        NearOptions o;
        o.pixels = GetParam();
        return o;
    }
    test::NearAndReference renderBoth(const Scene& s) {
        return test::renderBoth(nearRenderer(), s, 0.0, options());
    }
};

std::string str(glm::ivec3 v) {
    return "(" + std::to_string(v.x) + "," + std::to_string(v.y) + "," + std::to_string(v.z) + ")";
}

struct CubeCase {
    int size;
    double sigma;
};
void PrintTo(const CubeCase& c, std::ostream* os) {
    *os << c.size << "^3 at sigma " << c.sigma;
}

class CanonicalBoxViewsOnVulkan : public VulkanTest,
                                  public ::testing::WithParamInterface<CubeCase> {};

// Direction components of exactly 0 (face views: two, edge views: one), even and odd sizes,
// integer and non-integer sigma: the GPU image is the closed-form silhouette with outline,
// lighting, billboard depth and id, and equals the reference: traced in compute, and rasterised
// with the hull and the quad proxy.
TEST_P(CanonicalBoxViewsOnVulkan, MatchClosedFormAndReferenceAlongAll26Directions) {
    const CubeCase cc = GetParam();
    const auto model = test::solidBox(glm::ivec3(cc.size));
    for (glm::ivec3 w : test::canonicalDirections())
        for (const test::NearWay& way : test::kNearWays) {
            const auto v = test::viewAlong(model, glm::dvec3(w), cc.sigma, 4);
            const auto r = test::renderBoth(nearRenderer(), v.scene, 0.0, way.options());
            const std::string name = std::string(" (") + way.name + ")";
            int zeros = 0;
            for (int k = 0; k < 3; ++k) zeros += r.sprites[0].gpu.dir[k] == 0.0f;
            EXPECT_EQ(zeros, (w.x == 0) + (w.y == 0) + (w.z == 0))
                << "view " << str(w) << ": direction not snapped";
            std::string first;
            EXPECT_EQ(test::countClosedFormMismatches(v, glm::dvec3(w), r.near, &first), 0)
                << "view " << str(w) << name << ": " << first;
            EXPECT_EQ(test::describeDifference(r.near, r.reference), "")
                << "view " << str(w) << name;
        }
}

INSTANTIATE_TEST_SUITE_P(EvenOddIntegerAndFractionalSigma, CanonicalBoxViewsOnVulkan,
                         ::testing::Values(CubeCase{4, 1.0}, CubeCase{5, 1.0}, CubeCase{4, 2.0},
                                           CubeCase{5, 2.0}, CubeCase{6, 3.0}, CubeCase{3, 3.0},
                                           CubeCase{4, 1.5}, CubeCase{5, 1.5}),
                         [](const auto& info) {
                             return "size" + std::to_string(info.param.size) + "_sigma" +
                                    std::to_string(int(info.param.sigma * 10));
                         });

// Quarter-turn camera rolls keep the closed form (the lattice follows the camera up).
TEST_P(NearHardCases, RolledCameraMatchesClosedForm) {
    const auto model = test::solidBox({4, 6, 3});
    for (int roll = 1; roll < 4; ++roll)
        for (glm::ivec3 w : {glm::ivec3(1, 0, 0), glm::ivec3(0, 0, 1), glm::ivec3(1, -1, 0)}) {
            const auto v = test::viewAlong(model, glm::dvec3(w), 2.0, 4, roll);
            const auto r = renderBoth(v.scene);
            std::string first;
            EXPECT_EQ(test::countClosedFormMismatches(v, glm::dvec3(w), r.near, &first), 0)
                << "roll " << roll << " view " << str(w) << ": " << first;
            EXPECT_EQ(test::describeDifference(r.near, r.reference), "");
        }
}

// Camera-relative double precision: the world moved 2^20 m renders the same GPU image.
TEST_P(NearHardCases, WorldAtTwoToTheTwentyMetresEqualsWorldAtOrigin) {
    const auto origin = renderBoth(test::hardCaseWorld(glm::dvec3(0.0)));
    ASSERT_GT(test::drawnPixels(origin.near), 1000u);
    EXPECT_EQ(test::describeDifference(origin.near, origin.reference), "");
    for (glm::dvec3 offset :
         {glm::dvec3(1048576.0, 0.0, -1048576.0), glm::dvec3(-131072.0, 65536.0, 131072.0)}) {
        const auto far = renderBoth(test::hardCaseWorld(offset));
        EXPECT_EQ(test::describeDifference(far.near, origin.near), "") << "offset " << offset.x;
        EXPECT_EQ(test::describeDifference(far.near, far.reference), "");
    }
}

// RTS camera straight down (up = world -Z), slightly off-centre: equals the reference, and the
// bar's marker is right of and above its centre (no mirror, no flip on the GPU either).
TEST_P(NearHardCases, CameraStraightDownIsUprightUnmirroredAndExact) {
    const Scene s = test::topDownMarkedBar();
    const auto r = renderBoth(s);
    EXPECT_EQ(test::describeDifference(r.near, r.reference), "");
    const test::MarkerAndBar c = test::markerAndBarCentres(s, r.near);
    ASSERT_GT(c.markerPixels, 0);
    ASSERT_GT(c.barPixels, 0);
    EXPECT_GT(c.markerX, c.barX + 1.0);
    EXPECT_LT(c.markerY, c.barY);
}

// Eye inside and exactly on entity 0's proxy box: it is culled (the GPU draws none of it), the
// others still draw, and the image equals the reference.
TEST_P(NearHardCases, CameraInsideOrOnProxyBoxCullsOnlyThatEntity) {
    for (const Scene& t : test::eyeInsideAndOnProxyBox()) {
        const auto r = renderBoth(t);
        EXPECT_EQ(r.sprites[0].cull, CullReason::CameraInside);
        EXPECT_EQ(r.near.countEntity(0), 0u);
        EXPECT_GT(test::drawnPixels(r.near), 0u);
        EXPECT_EQ(test::describeDifference(r.near, r.reference), "");
    }
}

// Eye just outside the proxy box, looking past the entity at a wide angle: part of its quad lies
// behind the near plane and Vulkan clips it. The kernel's own "nearer than 2 zNear" rule decides
// those pixels, so the image still equals the reference.
TEST_P(NearHardCases, QuadCrossingTheNearPlaneIsClippedWithoutChangingPixels) {
    Scene s;
    s.render.sigma = 2.0;
    s.models = {test::solidBox({8, 8, 8}, 3)};
    Entity e;
    e.anchor = glm::dvec3(4.0); // entity position = model centre; proxy box = +-0.45 m
    s.entities.push_back(e);
    s.camera.width = 256;
    s.camera.height = 160;
    s.camera.fovYDeg = 90.0;
    s.camera.zNear = 0.01;
    int crossingAndDrawn = 0;
    for (double off : {0.55, 0.7})
        for (double angleDeg : {50.0, 60.0, 65.0}) {
            const double a = glm::radians(angleDeg);
            s.camera.position = {0.0, 0.05, off};
            s.camera.target = s.camera.position + glm::dvec3(std::sin(a), 0.0, -std::cos(a));
            const auto r = renderBoth(s);
            if (!r.sprites[0].visible()) continue;
            bool behind = false;
            for (const auto& q : r.sprites[0].quad) behind |= !(q.w > float(s.camera.zNear));
            crossingAndDrawn += behind && r.near.countEntity(0) > 0;
            EXPECT_EQ(test::describeDifference(r.near, r.reference), "")
                << "camera z " << off << " angle " << angleDeg;
        }
    EXPECT_GT(crossingAndDrawn, 0) << "no camera placement made a drawn quad cross the near plane";
}

// Equal depths: the lower entity id owns every shared pixel, whatever order the sprites are
// handed to the renderer in (it sorts them: one instanced draw in ascending id, depth GREATER).
TEST_P(NearHardCases, EqualDepthLowerIdWinsRegardlessOfSubmissionOrder) {
    const Scene s = test::equalDepthPair();
    const CameraFrame cam = makeCameraFrame(s.camera);
    const auto sprites = setupSprites(s, cam, 0.0);
    ASSERT_EQ(sprites[0].gpu.depth, sprites[1].gpu.depth);
    NearRenderer& nr = nearRenderer();
    const Image forward = nr.render(
        cam, s.models, std::vector<const SpriteSetup*>{&sprites[0], &sprites[1]}, 0, options());
    const Image backward = nr.render(
        cam, s.models, std::vector<const SpriteSetup*>{&sprites[1], &sprites[0]}, 0, options());
    const Image only1 =
        nr.render(cam, s.models, std::vector<const SpriteSetup*>{&sprites[1]}, 0, options());
    EXPECT_EQ(test::describeDifference(forward, backward), "");
    Image ref(cam.width, cam.height, 0);
    renderReference(s.models, sprites, ref);
    EXPECT_EQ(test::describeDifference(forward, ref), "");
    std::size_t overlap = 0;
    for (std::size_t p = 0; p < forward.pixelCount(); ++p)
        overlap += only1.id[p] == 1u && forward.id[p] == 0u;
    EXPECT_GT(overlap, 100u);
    EXPECT_GT(forward.countEntity(1), 0u);
}

TEST_P(NearHardCases, EntityBehindCameraDrawsNothing) {
    const Scene s = test::entityBehindCamera();
    const auto r = renderBoth(s);
    EXPECT_EQ(r.sprites[0].cull, CullReason::BehindCamera);
    EXPECT_EQ(test::drawnPixels(r.near), 0u);
    EXPECT_EQ(r.nearStats.sprites, 0u);
    EXPECT_EQ(test::describeDifference(r.near, r.reference), "");
}

TEST_P(NearHardCases, SubPixelEntityDrawsNothing) {
    const Scene s = test::subPixelEntity();
    const auto r = renderBoth(s);
    EXPECT_EQ(r.sprites[0].cull, CullReason::SubPixel);
    EXPECT_EQ(test::drawnPixels(r.near), 0u);
    EXPECT_EQ(test::describeDifference(r.near, r.reference), "");
}

/// A dense crowd over a 320x256 image with lavapipe's 64x64 tiles: many sprites straddle tile
/// edges in x, in y, and at tile corners.
Scene tileCrowd() {
    Scene s;
    s.render.sigma = 2.0;
    s.models = {makeArrow(), makeSphere(3, proc_index::kCyan),
                makeBox({5, 4, 6}, proc_index::kOrange), makeSingleVoxel(255)};
    int id = 0;
    for (int row = 0; row < 7; ++row)
        for (int col = 0; col < 9; ++col, ++id) {
            Entity e;
            e.model = id % int(s.models.size());
            e.position = {-3.2 + 0.8 * col + 0.05 * row, -1.9 + 0.62 * row,
                          -5.0 - 0.1 * ((id * 7) % 5)};
            e.rotation = glm::angleAxis(0.37 * id, glm::normalize(glm::dvec3(0.3, 1.0, 0.2)));
            e.scale = e.model == 3 ? 4.0 : 1.0;
            s.entities.push_back(e);
        }
    s.camera.position = {0.0, 0.0, 0.0};
    s.camera.target = {0.0, 0.0, -1.0};
    s.camera.width = 320;
    s.camera.height = 256;
    s.camera.fovYDeg = 45.0;
    return s;
}

TEST_P(NearHardCases, SpritesStraddlingRasterizerTileEdgesMatchReference) {
    const auto r = renderBoth(tileCrowd());
    int straddleX = 0, straddleY = 0, corners = 0;
    for (const auto& sp : r.sprites) {
        if (!sp.visible()) continue;
        const bool x = sp.screenRect.x / 64 != (sp.screenRect.z - 1) / 64;
        const bool y = sp.screenRect.y / 64 != (sp.screenRect.w - 1) / 64;
        straddleX += x;
        straddleY += y;
        corners += x && y;
    }
    EXPECT_GE(straddleX, 10);
    EXPECT_GE(straddleY, 10);
    EXPECT_GE(corners, 3);
    EXPECT_GT(test::drawnPixels(r.near), 5000u);
    EXPECT_EQ(test::describeDifference(r.near, r.reference), "");
}

// HARD_CASES 7: the ray crosses a whole 256^3 grid along its diagonal (766 cells) before it
// hits the one voxel in the far corner: the step bound never truncates it, on the GPU either.
TEST_P(NearHardCases, LongestDiagonalIn256CubedGridReachesFarCornerVoxel) {
    VoxelGrid g({256, 256, 256});
    g.set({255, 255, 255}, 5);
    auto model =
        std::make_shared<VoxelModel>("diag", proceduralPalette(), std::vector<VoxelGrid>{g});
    const glm::ivec3 w(-1, -1, -1); // viewer on the (0,0,0) side: the voxel is at the far end
    auto v = test::viewAlong(model, glm::dvec3(w), 1.0, 1);
    // Only the middle of the sprite is needed (the voxel sits on the diagonal through the centre):
    // a narrow view from outside the proxy box (half-diagonal 22 m), about 2 pixels per voxel.
    v.scene.camera.width = v.scene.camera.height = 96;
    v.scene.camera.fovYDeg = 8.0;
    const glm::dvec3 dirW = glm::normalize(worldFromVoxelSwizzle() * glm::dvec3(w));
    v.scene.camera.position = v.scene.entities[0].position + dirW * 35.0;
    const auto r = renderBoth(v.scene);
    EXPECT_GT(r.near.countEntity(0), 0u);
    EXPECT_EQ(test::describeDifference(r.near, r.reference), "");
}

// ---------------------------------------------------------------------------------------------
// Thread-count independence (HARD_CASES 14), through the CLI as separate processes because
// LP_NUM_THREADS is read when lavapipe starts.

std::string readFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

/// OIIO stamps an EXR header with the write time (OpenEXR's "capDate" string attribute); blank
/// its value so that two files compare equal exactly when everything else, pixels included, is.
std::string withoutDateTime(std::string exr) {
    const std::string key("capDate\0string\0", 15);
    const auto at = exr.find(key);
    if (at == std::string::npos || at + key.size() + 4 > exr.size()) return exr;
    std::uint32_t len = 0;
    std::memcpy(&len, exr.data() + at + key.size(), 4); // little-endian int32, as in the EXR file
    const std::size_t value = at + key.size() + 4;
    if (value + len <= exr.size())
        std::fill(exr.begin() + std::ptrdiff_t(value), exr.begin() + std::ptrdiff_t(value + len),
                  '\0');
    return exr;
}

int runCli(const std::string& env, const std::string& args, const std::string& errFile) {
    const std::string cmd = env + " " + VOXTIER_CLI + " " + args + " >/dev/null 2>" + errFile;
    const int status = std::system(cmd.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

INSTANTIATE_TEST_SUITE_P(ComputeAndRaster, NearHardCases,
                         ::testing::Values(NearPixels::Compute, NearPixels::Raster),
                         [](const auto& info) {
                             return std::string(info.param == NearPixels::Compute ? "compute"
                                                                                  : "raster");
                         });

TEST(VulkanThreads, ImageIdenticalForLpNumThreads0And1And2) {
    const std::string dir =
        ::testing::TempDir() + "voxtier_lp_threads_" + std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    const std::string scene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/default.json";
    std::string first;
    for (int threads : {0, 1, 2}) {
        const std::string out = dir + "/near_" + std::to_string(threads) + ".exr";
        const std::string err = dir + "/err_" + std::to_string(threads) + ".txt";
        ASSERT_EQ(runCli("LP_NUM_THREADS=" + std::to_string(threads) + " VOXTIER_VALIDATION=1",
                         "render " + scene + " --mode near --out " + out, err),
                  0)
            << readFile(err);
        EXPECT_EQ(readFile(err), "") << "validation messages with LP_NUM_THREADS=" << threads;
        const std::string bytes = withoutDateTime(readFile(out));
        ASSERT_GT(bytes.size(), 1000u);
        if (first.empty())
            first = bytes;
        else
            EXPECT_TRUE(bytes == first)
                << "EXR (colour, Z, id) differs with LP_NUM_THREADS=" << threads;
    }
    // And the same file as the reference mode writes.
    const std::string ref = dir + "/reference.exr";
    ASSERT_EQ(
        runCli("", "render " + scene + " --mode reference --out " + ref, dir + "/err_ref.txt"), 0);
    EXPECT_TRUE(withoutDateTime(readFile(ref)) == first) << "near EXR differs from reference EXR";
    std::filesystem::remove_all(dir);
}

// The trace's workgroup shape a GPU takes (8x8 blocks, a pixel per invocation) and another,
// forced on lavapipe through the measuring variables: the same EXR (colour, Z, id) as the
// reference, per-pixel sprites only, traced in compute (so that every sprite goes through the
// trace; lavapipe would rasterise them by default). A bad value is a one-line error naming the
// variable.
TEST(VulkanTraceShape, EveryShapeWritesTheReferenceImage) {
    const std::string dir =
        ::testing::TempDir() + "voxtier_trace_shape_" + std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    const std::string scene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/default.json";
    const std::string ref = dir + "/reference.exr";
    ASSERT_EQ(runCli("", "render " + scene + " --mode reference --out " + ref, dir + "/e.txt"), 0)
        << readFile(dir + "/e.txt");
    for (const char* shape : {"VOXTIER_NEAR_TRACE_BLOCK=8 VOXTIER_NEAR_TRACE_ROWS=8",
                              "VOXTIER_NEAR_TRACE_BLOCK=16 VOXTIER_NEAR_TRACE_ROWS=1"}) {
        const std::string out = dir + "/near.exr";
        ASSERT_EQ(runCli(shape,
                         "render " + scene +
                             " --mode near --near-backend vulkan --near-rate fragment "
                             "--near-pixels compute --out " +
                             out,
                         dir + "/e.txt"),
                  0)
            << shape << ": " << readFile(dir + "/e.txt");
        EXPECT_TRUE(withoutDateTime(readFile(out)) == withoutDateTime(readFile(ref))) << shape;
    }
    EXPECT_EQ(
        runCli("VOXTIER_NEAR_TRACE_BLOCK=12",
               "render " + scene + " --mode near --near-backend vulkan --out " + dir + "/x.exr",
               dir + "/e.txt"),
        1);
    const std::string err = readFile(dir + "/e.txt");
    EXPECT_NE(err.find("VOXTIER_NEAR_TRACE_BLOCK"), std::string::npos) << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    std::filesystem::remove_all(dir);
}

} // namespace
} // namespace voxtier
