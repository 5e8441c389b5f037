#include "impostor_cache/voxel_scene.hpp"

#include "core/error.hpp"
#include "core/stopwatch.hpp"
#include "impostor_cache/detail/bake_context.hpp"
#include "impostor_cache/detail/embree_device.hpp"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <chrono>
#include <limits>
#include <mutex>

namespace voxtier {

namespace {

/// Box-callback invocations that found FTZ/DAZ off (HARD_CASES 21); tests expect 0.
std::atomic<std::uint64_t> gCallsWithoutFtz{0};

struct BoxUserData {
    const VoxelRun* boxes;
    float pad;
};

void boxBounds(const RTCBoundsFunctionArguments* args) {
    const auto* d = static_cast<const BoxUserData*>(args->geometryUserPtr);
    const VoxelRun& r = d->boxes[args->primID];
    RTCBounds* b = args->bounds_o;
    b->lower_x = float(r.min.x) - d->pad, b->lower_y = float(r.min.y) - d->pad,
    b->lower_z = float(r.min.z) - d->pad;
    b->upper_x = float(r.max.x) + d->pad, b->upper_y = float(r.max.y) + d->pad,
    b->upper_z = float(r.max.z) + d->pad;
}

/// Robust ray / padded-box slab test (zero direction components take their own branch, no
/// 0 * inf). It reports where the ray enters the padded box, and the entered face as the
/// geometric normal. That parameter is a lower bound of where the kernel's traversal can
/// enter the voxels; the hit that counts (index, entered face, tie order) is decided
/// afterwards by the kernel-order traversal, because no float box test can reproduce the
/// kernel's own rounding and tie rules bit for bit.
void boxIntersect(const RTCIntersectFunctionNArguments* args) {
    if ((_mm_getcsr() & 0x8040u) != 0x8040u)
        gCallsWithoutFtz.fetch_add(1, std::memory_order_relaxed);
    const auto* d = static_cast<const BoxUserData*>(args->geometryUserPtr);
    const auto* ctx = reinterpret_cast<const detail::BakeIntersectContext*>(args->context);
    const VoxelRun& run = d->boxes[args->primID];
    const glm::vec3 lo = glm::vec3(run.min) - d->pad;
    const glm::vec3 hi = glm::vec3(run.max) + d->pad;
    RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, args->N);
    RTCHitN* hit = RTCRayHitN_HitN(args->rayhit, args->N);
    const unsigned N = args->N;
    for (unsigned i = 0; i < N; ++i) {
        if (!args->valid[i]) continue;
        const glm::vec3 o{RTCRayN_org_x(ray, N, i), RTCRayN_org_y(ray, N, i),
                          RTCRayN_org_z(ray, N, i)};
        float t0 = RTCRayN_tnear(ray, N, i);
        float t1 = RTCRayN_tfar(ray, N, i);
        const float tfar = t1;
        int axis = -1;
        bool miss = false;
        for (int k = 0; k < 3 && !miss; ++k) {
            if (ctx->dir[k] == 0.0f) {
                miss = o[k] < lo[k] || o[k] > hi[k];
            } else {
                const float a = (lo[k] - o[k]) * ctx->invDir[k];
                const float b = (hi[k] - o[k]) * ctx->invDir[k];
                const float tn = std::min(a, b);
                if (tn > t0) t0 = tn, axis = k;
                t1 = std::min(t1, std::max(a, b));
            }
        }
        // Strictly nearer than the current candidate: among equal bounds the first one found
        // stays, which is harmless because only the bound's value is used.
        if (miss || !(t0 <= t1) || !(t0 < tfar)) continue;
        glm::vec3 ng(0.0f);
        if (axis >= 0) ng[axis] = ctx->dir[axis] > 0.0f ? -1.0f : 1.0f;
        RTCRayN_tfar(ray, N, i) = t0;
        RTCHitN_Ng_x(hit, N, i) = ng.x;
        RTCHitN_Ng_y(hit, N, i) = ng.y;
        RTCHitN_Ng_z(hit, N, i) = ng.z;
        RTCHitN_u(hit, N, i) = 0.0f;
        RTCHitN_v(hit, N, i) = 0.0f;
        RTCHitN_primID(hit, N, i) = args->primID;
        RTCHitN_geomID(hit, N, i) = args->geomID;
        RTCHitN_instID(hit, N, i, 0) = args->context->instID[0];
    }
}

void boxOccluded(const RTCOccludedFunctionNArguments* args) {
    // Not used by the baker; a conservative answer (any padded box overlap occludes).
    const auto* d = static_cast<const BoxUserData*>(args->geometryUserPtr);
    const VoxelRun& run = d->boxes[args->primID];
    const glm::vec3 lo = glm::vec3(run.min) - d->pad;
    const glm::vec3 hi = glm::vec3(run.max) + d->pad;
    const unsigned N = args->N;
    for (unsigned i = 0; i < N; ++i) {
        if (!args->valid[i]) continue;
        const glm::vec3 o{RTCRayN_org_x(args->ray, N, i), RTCRayN_org_y(args->ray, N, i),
                          RTCRayN_org_z(args->ray, N, i)};
        const glm::vec3 dir{RTCRayN_dir_x(args->ray, N, i), RTCRayN_dir_y(args->ray, N, i),
                            RTCRayN_dir_z(args->ray, N, i)};
        float t0 = RTCRayN_tnear(args->ray, N, i), t1 = RTCRayN_tfar(args->ray, N, i);
        bool miss = false;
        for (int k = 0; k < 3 && !miss; ++k) {
            if (dir[k] == 0.0f) {
                miss = o[k] < lo[k] || o[k] > hi[k];
            } else {
                const float a = (lo[k] - o[k]) / dir[k], b = (hi[k] - o[k]) / dir[k];
                t0 = std::max(t0, std::min(a, b));
                t1 = std::min(t1, std::max(a, b));
            }
        }
        if (!miss && t0 <= t1)
            RTCRayN_tfar(args->ray, N, i) = -std::numeric_limits<float>::infinity();
    }
}

/// Scene builds are serialised: Embree reports memory per device, not per scene, so this is
/// what lets bytes() attribute the build's allocations to this scene. Builds are rare (once
/// per model frame and version) and each is parallel inside Embree.
std::mutex gBuildMutex;

} // namespace

std::uint64_t embreeCallsWithoutFlushDenormals() {
    return gCallsWithoutFtz.load(std::memory_order_relaxed);
}

const char* toString(BakeGeometry g) {
    return g == BakeGeometry::Boxes ? "boxes" : "quads";
}

BakeGeometry parseBakeGeometry(const std::string& name) {
    if (name == "boxes") return BakeGeometry::Boxes;
    if (name == "quads") return BakeGeometry::Quads;
    throw InputError("", "--geometry", "expected 'quads' or 'boxes', got '" + name + "'");
}

struct VoxelScene::Brick {
    Box3i region;
    std::vector<VoxelRun> boxes; ///< Boxes: the voxel box of each primitive
    BoxUserData data{};          ///< Boxes: the callbacks' data (points into `boxes`)
    RTCScene scene = nullptr;    ///< bricked: this brick's own scene, instanced by the top level
    std::size_t primitives = 0;
    std::size_t embreeBytes = 0; ///< share of what Embree allocated for the build that made it
    ~Brick() {
        if (scene) rtcReleaseScene(scene);
    }
};

namespace {

/// The committed Embree geometry of the primitives inside `region`, or nullptr when there are
/// none. Boxes keep their primitive array in `brick` (the callbacks read it at trace time).
RTCGeometry makeGeometry(RTCDevice device, const VoxelGrid& grid, const VoxelSceneOptions& options,
                         float pad, Box3i region, std::vector<VoxelRun>& boxes, BoxUserData& data,
                         std::size_t& primitives) {
    if (options.geometry == BakeGeometry::Boxes) {
        boxes = surfaceBoxes(grid, options.surfaceOnly, options.mergePrimitives, region);
        boxes.shrink_to_fit();
        primitives = boxes.size();
        if (primitives == 0) return nullptr;
        RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
        rtcSetGeometryUserPrimitiveCount(geom, unsigned(primitives));
        // The user data must outlive every scene using the geometry: it lives in the brick, which
        // the scenes that instance it hold.
        data = BoxUserData{boxes.data(), pad};
        rtcSetGeometryUserData(geom, &data);
        rtcSetGeometryBoundsFunction(geom, boxBounds, &data);
        rtcSetGeometryIntersectFunction(geom, boxIntersect);
        rtcSetGeometryOccludedFunction(geom, boxOccluded);
        rtcCommitGeometry(geom);
        return geom;
    }
    const std::vector<FaceRect> faces =
        exposedFaces(grid, options.surfaceOnly, options.mergePrimitives, region);
    primitives = faces.size();
    if (primitives == 0) return nullptr;
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_QUAD);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 4 * primitives));
    auto* q = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT4, 4 * sizeof(unsigned), primitives));
    for (std::size_t f = 0; f < primitives; ++f) {
        const FaceRect& r = faces[f];
        const int a = r.face / 2, b = (a + 1) % 3, c = (a + 2) % 3;
        // The faces' own plane, grown by `pad` within the plane only: a ray the kernel sends
        // through one of these faces crosses the plane inside the quad.
        const float b0 = float(r.lo.x) - pad, b1 = float(r.hi.x) + pad;
        const float c0 = float(r.lo.y) - pad, c1 = float(r.hi.y) + pad;
        const float corners[4][2] = {{b0, c0}, {b1, c0}, {b1, c1}, {b0, c1}};
        for (int k = 0; k < 4; ++k) {
            float* out = v + 3 * (4 * f + std::size_t(k));
            out[a] = float(r.plane);
            out[b] = corners[k][0];
            out[c] = corners[k][1];
            q[4 * f + std::size_t(k)] = unsigned(4 * f + std::size_t(k));
        }
    }
    rtcCommitGeometry(geom);
    return geom;
}

RTCScene newScene(RTCDevice device) {
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);
    return scene;
}

} // namespace

VoxelScene::VoxelScene(const VoxelGrid& grid, VoxelSceneOptions options)
    : grid_(grid), options_(options) {
    build(nullptr, Box3i{}, /*derived=*/false);
}

VoxelScene::VoxelScene(const VoxelScene& previous, const VoxelGrid& grid, Box3i dirty)
    : grid_(grid), options_(previous.options_) {
    // Another size is another model: nothing to share (API misuse, but a full build is correct).
    assert(previous.grid_.dims() == grid.dims());
    const bool sameShape = previous.grid_.dims() == grid.dims();
    build(sameShape ? &previous : nullptr, dirty.expanded(1), /*derived=*/true);
}

std::size_t VoxelScene::brickCount() const {
    return std::size_t(
        std::count_if(bricks_.begin(), bricks_.end(), [](const auto& b) { return b != nullptr; }));
}

void VoxelScene::build(const VoxelScene* previous, Box3i rebuild, bool derived) {
    const auto t0 = std::chrono::steady_clock::now();
    const glm::ivec3 n = grid_.dims();
    // Slack for float rounding (see snapshot_baker.cpp): the kernel's crossing parameters are
    // off by at most a few ulps of coordinates <= ~3.5 * maxDim, i.e. ~3e-4 voxel at 256.
    // 1/64 + maxDim/4096 is 20-50x that and costs only a rare extra traversal step.
    padding_ = 1.0f / 64.0f + float(std::max({n.x, n.y, n.z})) / 4096.0f;

    const int edge = options_.brickSize;
    const bool flat = edge <= 0 || (!derived && options_.flatUntilEdited);
    bricked_ = !flat;
    brickGrid_ = flat ? glm::ivec3(1) : (n + edge - 1) / edge;
    // Bricks are shared only between bricked scenes (the first one after a flat scene builds all).
    if (previous && !previous->bricked_) previous = nullptr;
    const std::size_t slots =
        std::size_t(brickGrid_.x) * std::size_t(brickGrid_.y) * std::size_t(brickGrid_.z);
    bricks_.assign(slots, nullptr);
    std::vector<std::size_t> todo;
    for (std::size_t slot = 0; slot < slots; ++slot) {
        Box3i region{{0, 0, 0}, n};
        if (!flat) {
            const glm::ivec3 b(int(slot % std::size_t(brickGrid_.x)),
                               int(slot / std::size_t(brickGrid_.x) % std::size_t(brickGrid_.y)),
                               int(slot / (std::size_t(brickGrid_.x) * std::size_t(brickGrid_.y))));
            region = Box3i{b * edge, glm::min(b * edge + edge, n)};
        }
        if (previous && !flat && region.intersected(rebuild).empty()) {
            bricks_[slot] = previous->bricks_[slot]; // untouched by the edit: shared
        } else {
            auto brick = std::make_shared<Brick>();
            brick->region = region;
            bricks_[slot] = std::move(brick);
            todo.push_back(slot);
        }
    }

    RTCDevice device = detail::embreeDevice();
    std::lock_guard lock(gBuildMutex);
    const std::int64_t before = detail::embreeBytesInUse();
    std::size_t topBytes = 0;
    RTCGeometry flatGeometry = nullptr;
    tbb::this_task_arena::isolate([&] {
        detail::FlushDenormalsScope ftz;
        // The bricks to build, in parallel (each brick's build is small; Embree's own parallel
        // build only pays on big ones). Bricks are built apart from one another, so one brick's
        // primitives never depend on which others are rebuilt: the same grid gives the same
        // bricks whether they were built fresh or after an edit.
        auto buildBrick = [&](std::size_t slot) {
            detail::FlushDenormalsScope workerFtz; // TBB workers do not inherit MXCSR
            auto* brick = const_cast<Brick*>(bricks_[slot].get());
            RTCGeometry geom = makeGeometry(device, grid_, options_, padding_, brick->region,
                                            brick->boxes, brick->data, brick->primitives);
            if (!geom) return;
            if (flat) {
                flatGeometry = geom; // attached to the top-level scene below
                return;
            }
            brick->scene = newScene(device);
            rtcAttachGeometry(brick->scene, geom);
            rtcReleaseGeometry(geom); // the scene holds its own reference
            rtcCommitScene(brick->scene);
        };
        if (todo.size() == 1)
            buildBrick(todo[0]);
        else
            tbb::parallel_for(std::size_t(0), todo.size(),
                              [&](std::size_t k) { buildBrick(todo[k]); });
        const std::int64_t afterBricks = detail::embreeBytesInUse();
        // Embree reports memory per device: the bricks built here share what it allocated,
        // in proportion to their primitives.
        std::size_t builtPrimitives = 0;
        for (std::size_t slot : todo) builtPrimitives += bricks_[slot]->primitives;
        const double brickBytes = double(std::max<std::int64_t>(0, afterBricks - before));
        for (std::size_t slot : todo) {
            auto* brick = const_cast<Brick*>(bricks_[slot].get());
            brick->embreeBytes =
                builtPrimitives
                    ? std::size_t(brickBytes * double(brick->primitives) / double(builtPrimitives))
                    : 0;
        }
        build_.bricksBuilt = todo.size();
        build_.primitivesBuilt = builtPrimitives;

        RTCScene scene = newScene(device);
        if (flat) {
            if (flatGeometry) {
                rtcAttachGeometry(scene, flatGeometry);
                rtcReleaseGeometry(flatGeometry);
            }
        } else {
            // Identity instances: the rays reach each brick unchanged (instancing only splits
            // the BVH into parts that can be rebuilt on their own).
            static constexpr float kIdentity[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
            for (std::size_t slot = 0; slot < slots; ++slot) {
                const Brick* brick = bricks_[slot].get();
                if (!brick || !brick->scene) continue;
                RTCGeometry inst = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
                rtcSetGeometryInstancedScene(inst, brick->scene);
                rtcSetGeometryTransform(inst, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, kIdentity);
                rtcCommitGeometry(inst);
                rtcAttachGeometryByID(scene, inst, unsigned(slot));
                rtcReleaseGeometry(inst);
            }
        }
        rtcCommitScene(scene);
        scene_ = scene;
        topBytes = std::size_t(std::max<std::int64_t>(0, detail::embreeBytesInUse() - afterBricks));
    });
    detail::throwOnEmbreeError("scene build");
    // Empty bricks are dropped, so brickCount() and sharing only see bricks with primitives.
    for (auto& b : bricks_)
        if (b && b->primitives == 0) b.reset();
    if (previous)
        for (std::size_t slot = 0; slot < slots; ++slot)
            build_.bricksReused +=
                bricks_[slot] && bricks_[slot] == previous->bricks_[slot] ? 1u : 0u;
    primitives_ = 0;
    embreeBytes_ = topBytes;
    bytes_ = sizeof(*this) + grid_.data().capacity() + bricks_.capacity() * sizeof(bricks_[0]);
    for (const auto& b : bricks_) {
        if (!b) continue;
        primitives_ += b->primitives;
        embreeBytes_ += b->embreeBytes;
        bytes_ += sizeof(Brick) + b->boxes.capacity() * sizeof(VoxelRun) + b->embreeBytes;
    }
    bytes_ += topBytes;
    build_.ms = msSince(t0);
}

VoxelScene::~VoxelScene() {
    if (scene_) rtcReleaseScene(scene_);
}

} // namespace voxtier
