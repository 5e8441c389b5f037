#pragma once
// Shared helpers for the test suites: small scenes built in code and an independent,
// closed-form model of what a sprite must look like (double precision, no kernel code).
#include "core/image.hpp"
#include "core/model_view.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "core/vox_reader.hpp"
#include "volumetric/near_renderer.hpp"
#include "volumetric/reference_renderer.hpp"

#include <glm/glm.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace voxtier::test {

inline std::shared_ptr<VoxelModel> solidBox(glm::ivec3 dims, std::uint8_t index = 1) {
    VoxelGrid g(dims);
    for (auto& v : g.data()) v = index;
    Palette p;
    for (int i = 1; i < 256; ++i)
        p.colors[std::size_t(i)] =
            packRgba(unsigned(i * 37 % 256), unsigned(i * 91 % 256), unsigned(i * 53 % 256));
    p.colors[1] = packRgba(200, 120, 40);
    return std::make_shared<VoxelModel>("box", p, std::vector<VoxelGrid>{g});
}

/// The 26 canonical directions (voxel space, from the model centre towards the viewer).
inline std::vector<glm::ivec3> canonicalDirections() {
    std::vector<glm::ivec3> out;
    for (int z = -1; z <= 1; ++z)
        for (int y = -1; y <= 1; ++y)
            for (int x = -1; x <= 1; ++x)
                if (x || y || z) out.push_back({x, y, z});
    return out;
}

/// A one-entity scene looking at the model centre from voxel-space direction `towardViewer`,
/// at the distance where one virtual pixel is exactly `magnification` screen pixels (the
/// sprite plane is then parallel to the image plane and the screen mapping is affine).
/// `rollQuarterTurns` rotates the camera about its forward axis by multiples of 90 degrees.
/// A file of the source tree (scenes, models) by its path relative to the repository root.
inline std::string sourcePath(const std::string& rel) {
    return std::string(VOXTIER_SOURCE_DIR) + "/" + rel;
}

/// The identity sweeps' directions (voxel space, towards the viewer): the 26 canonical ones,
/// then 20 seeded random ones.
inline std::vector<glm::dvec3> sweepDirections() {
    std::vector<glm::dvec3> dirs;
    for (glm::ivec3 w : canonicalDirections()) dirs.push_back(glm::dvec3(w));
    std::mt19937_64 rng(20240601);
    std::normal_distribution<double> n(0.0, 1.0);
    while (dirs.size() < 26 + 20) {
        const glm::dvec3 d{n(rng), n(rng), n(rng)};
        if (glm::length(d) > 1e-3) dirs.push_back(glm::normalize(d));
    }
    return dirs;
}

/// A model view (the model fitted to a width x height image) looking along the voxel-space
/// direction `voxelDir` (towards the viewer). Canonical directions become azimuth/elevation
/// round trips with rounding zeros; the 1e-6 direction snap of core/sprite.cpp must restore them.
inline ModelView viewToward(glm::dvec3 voxelDir, double sigma, int width, int height) {
    const glm::dvec3 w = glm::normalize(worldFromVoxelSwizzle() * voxelDir);
    ModelView v;
    v.elevationDeg = glm::degrees(std::asin(std::clamp(w.y, -1.0, 1.0)));
    v.azimuthDeg = std::abs(w.y) > 0.999999 ? 0.0 : glm::degrees(std::atan2(w.x, w.z));
    v.sigma = sigma;
    v.width = width;
    v.height = height;
    return v;
}

struct BundledModel {
    std::string file; ///< path of the .vox file
    std::size_t index = 0;
    std::shared_ptr<VoxelModel> model; ///< one frame: the file's model `index`
};

/// Every non-empty model of every .vox file shipped in scenes/vox/ (not_a.vox is the bad-input
/// sample, not a model).
inline std::vector<BundledModel> bundledVoxModels() {
    std::vector<BundledModel> out;
    for (const auto& e : std::filesystem::recursive_directory_iterator(sourcePath("scenes/vox"))) {
        if (e.path().extension() != ".vox" || e.path().filename() == "not_a.vox") continue;
        const VoxFile vox = readVoxFile(e.path().string());
        for (std::size_t m = 0; m < vox.models.size(); ++m) {
            auto model = std::make_shared<VoxelModel>("m", vox.palette,
                                                      std::vector<VoxelGrid>{vox.models[m]});
            if (model->frame(0).solidCount() > 0) out.push_back({e.path().string(), m, model});
        }
    }
    return out;
}

struct ViewSetup {
    Scene scene;
    double distance = 0.0;
};
inline ViewSetup viewAlong(std::shared_ptr<VoxelModel> model, glm::dvec3 towardViewer, double sigma,
                           int magnification, int rollQuarterTurns = 0,
                           glm::dvec3 worldOffset = glm::dvec3(0.0)) {
    ViewSetup v;
    Scene& s = v.scene;
    s.render.sigma = sigma;
    s.render.voxelSize = 0.1;
    const glm::ivec3 dims = model->frame(0).dims();
    s.models.push_back(model);
    Entity e;
    e.model = 0;
    e.anchor = glm::dvec3(dims) * 0.5; // anchor at the centre: entity position = model centre
    e.position = worldOffset + glm::dvec3(0.25, 1.5, -2.0);
    s.entities.push_back(e);
    const glm::dvec3 wWorld = glm::normalize(worldFromVoxelSwizzle() * towardViewer);
    Camera& c = s.camera;
    c.fovYDeg = 40.0;
    // Image large enough for the sprite at this magnification (plus margin), even sizes.
    const double extent =
        glm::length(glm::dvec3(dims)) * sigma * magnification + 8.0 * magnification;
    c.width = c.height = 2 * int(std::ceil(extent * 0.5 + 4));
    const double pixelScale = 2.0 * std::tan(glm::radians(c.fovYDeg) * 0.5) / c.height;
    v.distance = s.render.voxelSize / (sigma * pixelScale * magnification);
    c.position = e.position + wWorld * v.distance;
    c.target = e.position;
    glm::dvec3 up = std::abs(wWorld.y) > 0.99 ? glm::dvec3(0, 0, -1) : glm::dvec3(0, 1, 0);
    const glm::dvec3 fwd = -wWorld;
    for (int r = 0; r < ((rollQuarterTurns % 4) + 4) % 4; ++r)
        up = glm::cross(fwd, up); // 90° about fwd
    c.up = up;
    c.zNear = 0.01;
    return v;
}

/// Independent closed-form silhouette of a solid box: for each lattice cell (§3.5, computed
/// here from the definition), does the parallel ray through its centre cross the box, and
/// through which face does it enter (axis priority x < y < z on ties)?
struct ExpectedCells {
    glm::ivec4 range;
    std::vector<int> kind; // 0 empty, 1 solid, 2 outline
    std::vector<int> face; // entered-face code for solid cells
    int w() const { return range.y - range.x + 1; }
    int h() const { return range.w - range.z + 1; }
    std::size_t at(int i, int j) const {
        return std::size_t(j - range.z) * std::size_t(w()) + std::size_t(i - range.x);
    }
    int count(int k) const {
        int n = 0;
        for (int v : kind) n += v == k;
        return n;
    }
};

inline ExpectedCells expectedBoxCells(glm::ivec3 dims, glm::dvec3 dir, glm::dvec3 up,
                                      double sigma) {
    dir = glm::normalize(dir);
    up = glm::normalize(up - glm::dot(up, dir) * dir);
    const glm::dvec3 right = glm::cross(dir, up);
    const glm::dvec3 c = glm::dvec3(dims) * 0.5;
    const glm::dvec3 g = glm::floor(c) - c;
    const double gu = glm::dot(g, right), gv = glm::dot(g, up);
    const double eu = glm::dot(glm::abs(right), c), ev = glm::dot(glm::abs(up), c);
    ExpectedCells e;
    e.range = {int(std::floor(sigma * (-eu - gu))) - 3, int(std::floor(sigma * (eu - gu))) + 3,
               int(std::floor(sigma * (-ev - gv))) - 3, int(std::floor(sigma * (ev - gv))) + 3};
    e.kind.assign(std::size_t(e.w() * e.h()), 0);
    e.face.assign(e.kind.size(), -1);
    for (int j = e.range.z; j <= e.range.w; ++j)
        for (int i = e.range.x; i <= e.range.y; ++i) {
            const glm::dvec3 p =
                c + (gu + (i + 0.5) / sigma) * right + (gv + (j + 0.5) / sigma) * up;
            double tIn = -1e300, tOut = 1e300;
            int axis = -1;
            bool miss = false;
            for (int k = 0; k < 3; ++k) {
                if (std::abs(dir[k]) < 1e-12) {
                    if (p[k] < 0.0 || p[k] >= dims[k]) miss = true;
                    continue;
                }
                const double t0 = (0.0 - p[k]) / dir[k], t1 = (dims[k] - p[k]) / dir[k];
                if (std::min(t0, t1) > tIn) {
                    tIn = std::min(t0, t1);
                    axis = k;
                }
                tOut = std::min(tOut, std::max(t0, t1));
            }
            if (!miss && tIn < tOut) {
                e.kind[e.at(i, j)] = 1;
                e.face[e.at(i, j)] = 2 * axis + (dir[axis] > 0 ? 0 : 1);
            }
        }
    // Cardinal dilation of the coverage: the outline.
    std::vector<int> k2 = e.kind;
    for (int j = e.range.z; j <= e.range.w; ++j)
        for (int i = e.range.x; i <= e.range.y; ++i) {
            if (e.kind[e.at(i, j)] == 1) continue;
            auto solid = [&](int a, int b) {
                return a >= e.range.x && a <= e.range.y && b >= e.range.z && b <= e.range.w &&
                       e.kind[e.at(a, b)] == 1;
            };
            if (solid(i - 1, j) || solid(i + 1, j) || solid(i, j - 1) || solid(i, j + 1))
                k2[e.at(i, j)] = 2;
        }
    e.kind = k2;
    return e;
}

/// The lighting formula of §3.7, written independently: channel * factor, rounded.
inline Rgba8 expectedLit(Rgba8 base, const Light& light, glm::dvec3 normalVoxel,
                         glm::dvec3 lightVoxel) {
    const double k = std::clamp(
        light.ambient + light.diffuse * std::max(0.0, glm::dot(normalVoxel, lightVoxel)), 0.0, 4.0);
    const long long f = std::llround(k * 65536.0);
    unsigned ch[3];
    for (int i = 0; i < 3; ++i)
        ch[i] = unsigned(std::min<long long>(255, (channel(base, i) * f + 32768) >> 16));
    return packRgba(ch[0], ch[1], ch[2], 255);
}

// ---------------------------------------------------------------------------------------------
// The Vulkan near tier in tests.

/// One NearRenderer per test process, shared by every Vulkan test in it: lavapipe JIT-compiles a
/// pipeline on first use, which would otherwise dominate the suite. Validation (with
/// synchronization validation) is always on; messages are recorded, not printed. There is no
/// "skip when no device": on a machine without Vulkan these tests fail, loudly.
/// Register it in each Vulkan test file with
///   const auto* kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);
/// Its TearDown destroys the renderer and device and asserts that the layer reported nothing,
/// leaked objects included (those are reported while the device and instance are destroyed).
class NearRendererEnvironment : public ::testing::Environment {
  public:
    static NearRenderer& renderer() {
        if (!instance()) {
            VulkanDeviceOptions options;
            options.validation = true;
            options.echoMessages = false;
            instance() = std::make_unique<NearRenderer>(options, log());
        }
        return *instance();
    }
    static const std::shared_ptr<VulkanMessageLog>& log() {
        static const auto l = std::make_shared<VulkanMessageLog>();
        return l;
    }
    void TearDown() override {
        instance().reset();
        EXPECT_EQ(log()->count(), 0u) << "Vulkan validation / loader messages:\n"
                                      << log()->joined();
    }

  private:
    static std::unique_ptr<NearRenderer>& instance() {
        static std::unique_ptr<NearRenderer> r;
        return r;
    }
};

/// Fixture for Vulkan tests: every test ends with zero validation messages.
class VulkanTest : public ::testing::Test {
  protected:
    static NearRenderer& nearRenderer() { return NearRendererEnvironment::renderer(); }
    void TearDown() override {
        const auto& log = NearRendererEnvironment::log();
        EXPECT_EQ(log->count(), 0u) << "Vulkan validation messages:\n" << log->joined();
    }
};

/// A frame of a scene through the CPU reference and through the Vulkan near tier.
struct NearAndReference {
    Image near, reference;
    std::vector<SpriteSetup> sprites;
    NearStats nearStats;
    ReferenceStats referenceStats;
};
inline NearAndReference renderBoth(NearRenderer& renderer, const Scene& scene, double time = 0.0,
                                   const NearOptions& options = {},
                                   const ReferenceOptions& referenceOptions = {}) {
    NearAndReference r;
    const CameraFrame cam = makeCameraFrame(scene.cameraAt(time));
    r.sprites = setupSprites(scene, cam, time);
    r.reference = Image(cam.width, cam.height, scene.render.background);
    renderReference(scene.models, r.sprites, r.reference, &r.referenceStats, referenceOptions);
    r.near = renderer.render(cam, scene.models, r.sprites, scene.render.background, options,
                             &r.nearStats);
    return r;
}

/// "" when the images are identical (colour, depth bits, id); otherwise the number of differing
/// pixels and the first one with both values and the entity each image has there.
inline std::string describeDifference(const Image& a, const Image& b, const char* nameA = "vulkan",
                                      const char* nameB = "reference") {
    if (a.width != b.width || a.height != b.height)
        return "image sizes differ: " + std::to_string(a.width) + "x" + std::to_string(a.height) +
               " vs " + std::to_string(b.width) + "x" + std::to_string(b.height);
    const ImageDiff d = diffImages(a, b);
    if (d.identical()) return "";
    const std::size_t p = a.index(int(d.firstX), int(d.firstY));
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "%zu colour, %zu depth, %zu id pixels differ; first at (%zu,%zu): %s colour %08x "
                  "depth %.9g "
                  "entity %d, %s colour %08x depth %.9g entity %d",
                  d.colorDiffs, d.depthDiffs, d.idDiffs, d.firstX, d.firstY, nameA, a.color[p],
                  double(a.depth[p]), int(a.id[p]), nameB, b.color[p], double(b.depth[p]),
                  int(b.id[p]));
    return buf;
}

/// A frame of `s` at time t through the CPU reference tracer (the executable spec).
inline Image renderReferenceImage(const Scene& s, std::vector<SpriteSetup>* setups = nullptr,
                                  double time = 0.0) {
    const CameraFrame cam = makeCameraFrame(s.cameraAt(time));
    auto sprites = setupSprites(s, cam, time);
    Image img(cam.width, cam.height, s.render.background);
    renderReference(s.models, sprites, img);
    if (setups) *setups = std::move(sprites);
    return img;
}

inline std::size_t drawnPixels(const Image& img) {
    return std::size_t(std::count_if(img.id.begin(), img.id.end(),
                                     [](std::uint32_t v) { return v != kernel::VT_NO_ENTITY; }));
}

/// The closed-form check of tests/reference_golden_test.cpp (compareWithClosedForm), shared
/// here so the Vulkan tests hold the GPU image to the same independent answer: a solid box from
/// viewAlong(towardViewer) must be exactly the double-precision silhouette, outline, lighting,
/// depth and id. Returns the number of wrong pixels and describes the first.
inline int countClosedFormMismatches(const ViewSetup& v, glm::dvec3 towardViewer, const Image& img,
                                     std::string* first = nullptr,
                                     ExpectedCells* expected = nullptr) {
    const Scene& s = v.scene;
    const CameraFrame cam = makeCameraFrame(s.camera);
    const glm::dmat3 voxelFromWorld = glm::transpose(worldFromVoxelSwizzle());
    const glm::dvec3 dir = -glm::normalize(towardViewer);
    const glm::dvec3 upVoxel = voxelFromWorld * cam.up;
    const double sigma = s.render.sigma;
    const glm::ivec3 dims = s.models[0]->frame(0).dims();
    const ExpectedCells e = expectedBoxCells(dims, dir, upVoxel, sigma);
    if (expected) *expected = e;
    const glm::dvec3 up = glm::normalize(upVoxel - glm::dot(upVoxel, dir) * dir);
    const glm::dvec3 right = glm::cross(dir, up);
    const glm::dvec3 c = glm::dvec3(dims) * 0.5;
    const glm::dvec3 g = glm::floor(c) - c;
    const double gu = glm::dot(g, right), gv = glm::dot(g, up);
    const double m =
        double(std::lround(s.render.voxelSize / (sigma * cam.pixelScale() * v.distance)));
    const glm::dvec3 lightVoxel = voxelFromWorld * glm::normalize(s.light.direction);
    const float depth = float(cam.zNear / v.distance);
    int count = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const double su = (x + 0.5 - img.width * 0.5) / m;
            const double sv = -(y + 0.5 - img.height * 0.5) / m;
            const int i = int(std::floor(su - sigma * gu)), j = int(std::floor(sv - sigma * gv));
            int kind = 0, face = -1;
            if (i >= e.range.x && i <= e.range.y && j >= e.range.z && j <= e.range.w) {
                kind = e.kind[e.at(i, j)];
                face = e.face[e.at(i, j)];
            }
            const std::size_t p = img.index(x, y);
            Rgba8 want = s.render.background;
            if (kind == 1)
                want = expectedLit(s.models[0]->palette().colors[1], s.light,
                                   faceNormal(unsigned(face)), lightVoxel);
            if (kind == 2) want = packRgba(0, 0, 0, 255);
            const bool idOk = kind == 0 ? img.id[p] == kernel::VT_NO_ENTITY : img.id[p] == 0u;
            const bool depthOk =
                kind == 0 ? img.depth[p] == 0.0f : std::abs(img.depth[p] - depth) <= 1e-6f * depth;
            if (img.color[p] != want || !idOk || !depthOk) {
                if (count++ == 0 && first) {
                    char buf[200];
                    std::snprintf(buf, sizeof buf,
                                  "pixel (%d,%d) cell (%d,%d): expected kind %d colour %08x, got "
                                  "colour %08x id %u",
                                  x, y, i, j, kind, want, img.color[p], img.id[p]);
                    *first = buf;
                }
            }
        }
    return count;
}

/// A bar along voxel +X (index 1) with a marker voxel (index 2) at the +X end on the +Y side:
/// asymmetric under every mirror, so a flipped axis anywhere shows.
inline std::shared_ptr<VoxelModel> markedBar() {
    auto m = solidBox({6, 2, 1}, 1);
    VoxelGrid g = m->frame(0);
    g.set({5, 1, 0}, 2);
    Palette p = m->palette();
    p.colors[2] = packRgba(20, 220, 60);
    return std::make_shared<VoxelModel>("bar", p, std::vector<VoxelGrid>{g});
}

/// Four rotated entities of three models in front of a camera, the whole thing moved by
/// `offset`. Positions are dyadic so that, with a power-of-two offset, every camera-relative
/// double is bit-identical to the unshifted world (the far-from-origin hard case).
inline Scene hardCaseWorld(glm::dvec3 offset) {
    Scene s;
    s.render.sigma = 2.0;
    s.models = {solidBox({8, 6, 5}), solidBox({3, 3, 9}, 7), markedBar()};
    const glm::dvec3 spots[] = {
        {0.25, 0.0, -3.5}, {1.5, 0.5, -6.0}, {-2.0, 0.25, -9.5}, {0.75, -0.5, -4.25}};
    for (int i = 0; i < 4; ++i) {
        Entity e;
        e.model = i % 3;
        e.position = offset + spots[i];
        e.rotation = glm::angleAxis(0.3 * i + 0.1, glm::normalize(glm::dvec3(0.2, 1.0, 0.1 * i)));
        s.entities.push_back(e);
    }
    s.camera.position = offset + glm::dvec3(0.5, 1.25, 2.0);
    s.camera.target = offset + glm::dvec3(0.0, 0.0, -5.0);
    s.camera.width = 320;
    s.camera.height = 200;
    return s;
}

/// The RTS camera hard case: the marked bar seen straight down (up = world -Z), slightly
/// off-centre so the view direction is not exactly the camera forward.
inline Scene topDownMarkedBar() {
    Scene s;
    s.models = {markedBar()};
    s.render.sigma = 2.0;
    s.entities.push_back(Entity{});
    s.camera.position = {0.3, 6.0, 0.0};
    s.camera.target = {0.3, 0.0, 0.0};
    s.camera.up = {0.0, 0.0, -1.0};
    s.camera.width = s.camera.height = 200;
    return s;
}

/// Mean pixel positions of topDownMarkedBar's marker voxel (its lit top face, from the closed
/// form) and of the rest of the bar, outline excluded. Counts are 0 where nothing was seen.
struct MarkerAndBar {
    double markerX = 0, markerY = 0, barX = 0, barY = 0;
    int markerPixels = 0, barPixels = 0;
};
inline MarkerAndBar markerAndBarCentres(const Scene& s, const Image& img) {
    const Rgba8 marker =
        expectedLit(packRgba(20, 220, 60), s.light, {0, 0, 1},
                    glm::transpose(worldFromVoxelSwizzle()) * glm::normalize(s.light.direction));
    MarkerAndBar r;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const std::size_t p = img.index(x, y);
            if (img.id[p] != 0u || img.color[p] == kernel::VT_OUTLINE_RGBA) continue;
            if (img.color[p] == marker)
                r.markerX += x, r.markerY += y, ++r.markerPixels;
            else
                r.barX += x, r.barY += y, ++r.barPixels;
        }
    if (r.markerPixels) r.markerX /= r.markerPixels, r.markerY /= r.markerPixels;
    if (r.barPixels) r.barX /= r.barPixels, r.barY /= r.barPixels;
    return r;
}

/// Two overlapping boxes (palette indices 1 and 7) at exactly the same depth, parallel view
/// mode: the equal-depth hard case, where the lower entity id must own every shared pixel.
inline Scene equalDepthPair() {
    Scene s;
    s.models = {solidBox({6, 6, 6}, 1), solidBox({6, 6, 6}, 7)};
    for (int i = 0; i < 2; ++i) {
        Entity e;
        e.model = i;
        e.position = {0.25 * i, 0.0, -4.0}; // same depth along the camera forward (-Z)
        s.entities.push_back(e);
    }
    s.render.viewMode = ViewMode::Parallel;
    s.camera.position = {0.0, 0.3, 0.0};
    s.camera.target = {0.0, 0.3, -1.0};
    s.camera.width = s.camera.height = 160;
    return s;
}

/// hardCaseWorld's first entity alone, 3 m behind the camera (which looks along -Z).
inline Scene entityBehindCamera() {
    Scene s = hardCaseWorld(glm::dvec3(0.0));
    s.entities.resize(1);
    s.entities[0].position = s.camera.position + glm::dvec3(0.0, 0.0, 3.0);
    return s;
}

/// hardCaseWorld's first entity alone, 5 km ahead of the camera: under half a pixel.
inline Scene subPixelEntity() {
    Scene s = hardCaseWorld(glm::dvec3(0.0));
    s.entities.resize(1);
    s.entities[0].position = s.camera.position + glm::dvec3(0.0, 0.0, -5000.0);
    s.camera.target = s.entities[0].position;
    return s;
}

/// hardCaseWorld with the eye at entity 0's model centre, then exactly on its proxy box face
/// (voxel z = 5 + 1/sigma), looking the same way: entity 0 must be culled, the others drawn.
inline std::vector<Scene> eyeInsideAndOnProxyBox() {
    const Scene s = hardCaseWorld(glm::dvec3(0.0));
    const EntityPose pose =
        makeEntityPose(s.entities[0], s.models[0]->frame(0).dims(), s.render.voxelSize);
    std::vector<Scene> out;
    for (glm::dvec3 eyeVoxel :
         {glm::dvec3(4.0, 3.0, 2.5), glm::dvec3(4.0, 3.0, 5.0 + 1.0 / s.render.sigma)}) {
        Scene t = s;
        t.camera.position = pose.relativeWorld(eyeVoxel, glm::dvec3(0.0));
        t.camera.target = t.camera.position + (s.camera.target - s.camera.position);
        out.push_back(t);
    }
    return out;
}

} // namespace voxtier::test
