// Golden tests of the CPU reference tracer with closed-form answers: the expected image of a
// solid box seen along each of the 26 canonical directions is computed here, in double
// precision, from the definitions of CONTRACT.md §3 (lattice anchored at floor(c), parallel rays,
// cardinal outline, billboard depth, face lighting) — never recorded from the renderer.
#include "closed_form.hpp"
#include "image_checks.hpp"
#include "test_models.hpp"
#include "view_sweeps.hpp"
#include "volumetric/reference_renderer.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace voxtier {
namespace {

using test::ExpectedCells;

Image renderScene(const Scene& s) {
    return test::renderReferenceImage(s);
}

struct Mismatch {
    int count = 0;
    std::string what;
};

/// Compares a rendered single-box view with the closed-form image, pixel by pixel
/// (test::countClosedFormMismatches, shared with the Vulkan suite).
Mismatch compareWithClosedForm(const test::ViewSetup& v, glm::dvec3 towardViewer, const Image& img,
                               ExpectedCells* out = nullptr) {
    Mismatch mm;
    mm.count = test::countClosedFormMismatches(v, towardViewer, img, &mm.what, out);
    return mm;
}

struct CubeCase {
    int size;
    double sigma;
};
void PrintTo(const CubeCase& c, std::ostream* os) {
    *os << c.size << "^3 at sigma " << c.sigma;
}

class CanonicalBoxViews : public ::testing::TestWithParam<CubeCase> {};

// An even- and an odd-sized cube, every canonical direction: the whole image (colour, depth,
// id) equals the closed-form silhouette with its outline and face lighting.
TEST_P(CanonicalBoxViews, MatchesClosedFormImageAlongAll26Directions) {
    const CubeCase cc = GetParam();
    const auto model = test::solidBox(glm::ivec3(cc.size));
    for (glm::ivec3 w : test::canonicalDirections()) {
        const auto v = test::viewAlong(model, glm::dvec3(w), cc.sigma, 4);
        const Image img = renderScene(v.scene);
        ExpectedCells e;
        const Mismatch mm = compareWithClosedForm(v, glm::dvec3(w), img, &e);
        EXPECT_EQ(mm.count, 0) << "view (" << w.x << "," << w.y << "," << w.z << "): " << mm.what;
        // Each virtual pixel is a 4x4 block of screen pixels.
        EXPECT_EQ(img.countEntity(0), std::size_t(16 * (e.count(1) + e.count(2))));
    }
}

INSTANTIATE_TEST_SUITE_P(
    EvenAndOddSizes, CanonicalBoxViews,
    ::testing::Values(CubeCase{4, 1.0}, CubeCase{5, 1.0}, CubeCase{4, 2.0}, CubeCase{5, 2.0},
                      CubeCase{6, 3.0}, CubeCase{3, 3.0},
                      // non-integer sigma: some rays run exactly along voxel faces, and
                      // the half-open rule (a boundary belongs to the + side) decides
                      CubeCase{4, 1.5}, CubeCase{5, 1.5}),
    [](const auto& info) {
        return "size" + std::to_string(info.param.size) + "_sigma" +
               std::to_string(int(info.param.sigma * 10));
    });

// Hand-counted: a single voxel seen along a face is a sigma x sigma block with a 4*sigma-cell
// outline and nothing on the diagonals.
TEST(SingleVoxel, FaceViewIsSigmaSquareBlockWithFourSidedOutline) {
    const auto model = test::solidBox(glm::ivec3(1));
    for (double sigma : {1.0, 2.0, 3.0}) {
        for (glm::ivec3 w : {glm::ivec3(1, 0, 0), glm::ivec3(0, -1, 0), glm::ivec3(0, 0, 1)}) {
            const auto v = test::viewAlong(model, glm::dvec3(w), sigma, 4);
            const Image img = renderScene(v.scene);
            const int s = int(sigma);
            std::size_t black = 0, solid = 0;
            for (std::size_t p = 0; p < img.pixelCount(); ++p) {
                if (img.id[p] != 0u) continue;
                (img.color[p] == kernel::VT_OUTLINE_RGBA ? black : solid)++;
            }
            EXPECT_EQ(solid, std::size_t(16 * s * s)) << "sigma " << sigma;
            EXPECT_EQ(black, std::size_t(16 * 4 * s)) << "sigma " << sigma;
            // No diagonal outline: the drawn pixels' bounding box is (s+2)x(s+2) cells, but its
            // four corner cells are background.
            int x0 = img.width, y0 = img.height, x1 = -1, y1 = -1;
            for (int y = 0; y < img.height; ++y)
                for (int x = 0; x < img.width; ++x)
                    if (img.id[img.index(x, y)] == 0u) {
                        x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x),
                        y1 = std::max(y1, y);
                    }
            EXPECT_EQ(x1 - x0 + 1, 4 * (s + 2));
            EXPECT_EQ(y1 - y0 + 1, 4 * (s + 2));
            for (auto [cx, cy] : {std::pair{x0, y0}, {x1, y0}, {x0, y1}, {x1, y1}})
                EXPECT_EQ(img.id[img.index(cx, cy)], kernel::VT_NO_ENTITY);
        }
    }
}

// A non-cubic box seen exactly along each axis is a w x h rectangle of sigma-cells with a
// 2(w+h)*sigma outline (no corners).
TEST(BoxAlongAxes, RectangleOfModelSizeTimesSigma) {
    const glm::ivec3 dims{3, 5, 8};
    const auto model = test::solidBox(dims);
    for (double sigma : {1.0, 2.0}) {
        for (int axis = 0; axis < 3; ++axis)
            for (int sign : {-1, 1}) {
                glm::ivec3 w(0);
                w[axis] = sign;
                const auto v = test::viewAlong(model, glm::dvec3(w), sigma, 4);
                const Image img = renderScene(v.scene);
                const int a = dims[(axis + 1) % 3] * int(sigma),
                          b = dims[(axis + 2) % 3] * int(sigma);
                std::size_t black = 0, solid = 0;
                for (std::size_t p = 0; p < img.pixelCount(); ++p)
                    if (img.id[p] == 0u)
                        (img.color[p] == kernel::VT_OUTLINE_RGBA ? black : solid)++;
                EXPECT_EQ(solid, std::size_t(16 * a * b)) << "axis " << axis << " sign " << sign;
                EXPECT_EQ(black, std::size_t(16 * 2 * (a + b)))
                    << "axis " << axis << " sign " << sign;
                EXPECT_EQ(compareWithClosedForm(v, glm::dvec3(w), img).count, 0);
            }
    }
}

// Rolling the camera by quarter turns keeps the closed form (the lattice follows the camera up).
TEST(CanonicalViews, RolledCameraMatchesClosedForm) {
    const auto model = test::solidBox({4, 6, 3});
    for (int roll = 1; roll < 4; ++roll)
        for (glm::ivec3 w : {glm::ivec3(1, 0, 0), glm::ivec3(0, 0, 1), glm::ivec3(1, -1, 0)}) {
            const auto v = test::viewAlong(model, glm::dvec3(w), 2.0, 4, roll);
            const Image img = renderScene(v.scene);
            const Mismatch mm = compareWithClosedForm(v, glm::dvec3(w), img);
            EXPECT_EQ(mm.count, 0) << "roll " << roll << " view (" << w.x << "," << w.y << ","
                                   << w.z << "): " << mm.what;
        }
}

} // namespace
} // namespace voxtier
