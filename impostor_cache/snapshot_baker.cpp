#include "impostor_cache/snapshot_baker.hpp"

#include "impostor_cache/detail/bake_context.hpp"
#include "impostor_cache/detail/embree_device.hpp"
#include "impostor_cache/kernel_order_dda.hpp"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

// Why the Embree answer can be trusted to the last bit. Embree does not decide any cell: for
// each ray it returns the parameter t_e where the ray first meets a *padded* candidate (a
// surface voxel's box grown by `padding`, or an exposed face grown in its plane). The first
// solid voxel the kernel visits is a surface voxel, entered through an exposed face, and at the
// kernel's (float) entry parameter the exact ray is within ~1e-4 voxel of it, hence inside its
// padded candidate: so t_e, less a margin for float rounding, is a lower bound of the kernel's
// first-hit parameter. kernel_order_dda.hpp then resumes the kernel's own traversal at that
// bound, which reproduces vtTrace exactly (index, entered face, tie order). When Embree finds
// nothing the kernel cannot hit anything past its entry cell, which is read directly.

namespace voxtier {

namespace {

struct GridVoxels {
    const std::uint8_t* data;
    std::size_t sx, sxy;
    unsigned fetch(glm::ivec3 c) const { return data[std::size_t(c.x) + sx * std::size_t(c.y) + sxy * std::size_t(c.z)]; }
};
GridVoxels voxelsOf(const VoxelGrid& g) {
    return {g.data().data(), std::size_t(g.dims().x), std::size_t(g.dims().x) * std::size_t(g.dims().y)};
}

Snapshot emptySnapshot(const VoxelGrid& grid, ViewSet set, int view, double sigma) {
    Snapshot s;
    s.set = set;
    s.view = view;
    s.w = viewDirections(set).at(std::size_t(view));
    s.lattice = snapshotLattice(s.w, grid.dims(), sigma);
    s.cells.assign(std::size_t(s.width()) * std::size_t(s.height()), SnapshotCell{});
    return s;
}

/// Quads: the grown face is only guaranteed to catch the kernel's ray when no direction
/// component is tiny (the lateral drift between the kernel's crossing and the exact one grows
/// like 1/|d_k|). Every view of the 26/98/218 sets has components 0 or >= 1/sqrt(19); other
/// directions below this fall back to the exact traversal from the entry cell.
constexpr float kMinQuadComponent = 0.05f;

/// Lower bound of the kernel's first-hit parameter from Embree's candidate parameter.
struct BoundMargin {
    float absolute = 0.0f;
    float relative = 1e-5f; // float rounding of t itself (a few ulps, with 100x room)
    float apply(float te) const { return te - absolute - relative * (std::abs(te) + 1.0f); }
};

double msSince(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace

const char* toString(TraceApi api) { return api == TraceApi::Packet8 ? "packet8" : "stream"; }

Snapshot bakeSnapshot(const VoxelScene& scene, ViewSet set, int view, double sigma, const BakeOptions& options,
                      BakeStats* stats) {
    const auto t0 = std::chrono::steady_clock::now();
    const VoxelGrid& grid = scene.grid();
    Snapshot snap = emptySnapshot(grid, set, view, sigma);
    if (options.withDepth) snap.depth.assign(snap.cells.size(), 0.0f);
    const kernel::SpriteGpu frame = snapshotRayFrame(snap.lattice);
    const GridVoxels voxels = voxelsOf(grid);
    const int W = snap.width(), H = snap.height();
    const glm::ivec4 range = snap.lattice.cellRange;

    float dMin = 1.0f;
    for (int k = 0; k < 3; ++k)
        if (frame.dir[k] != 0.0f) dMin = std::min(dMin, std::abs(frame.dir[k]));
    const bool quads = scene.options().geometry == BakeGeometry::Quads;
    // No usable bound: resume at -infinity, i.e. the plain kernel traversal.
    const bool exactOnly = quads && dMin < kMinQuadComponent;
    BoundMargin margin;
    margin.absolute = quads ? 2.0f * scene.padding() / dMin : scene.padding();
    const float maxDim2 = float(2.0 * snap.lattice.maxDim);

    detail::BakeIntersectContext ctx;
    rtcInitIntersectContext(&ctx.base);
    ctx.base.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT; // parallel rays in lattice order
    ctx.dir = frame.dir;
    ctx.invDir = frame.invDir;
    RTCScene handle = scene.handle();
    const bool useEmbree = !scene.empty() && !exactOnly;

    tbb::combinable<std::uint64_t> reads;
    tbb::parallel_for(tbb::blocked_range<int>(0, H, 2), [&](const tbb::blocked_range<int>& rows) {
        std::vector<RTCRayHit> stream;
        std::vector<float> bound(std::size_t(W), -kernel::VT_FAR);
        std::vector<unsigned char> have(std::size_t(W), exactOnly ? 1 : 0);
        std::vector<glm::vec3> origin(static_cast<std::size_t>(W));
        std::uint64_t localReads = 0;
        for (int y = rows.begin(); y < rows.end(); ++y) {
            const int j = range.z + y;
            for (int x = 0; x < W; ++x) origin[std::size_t(x)] = kernelRayOrigin(frame, {range.x + x, j});
            if (useEmbree) {
                detail::FlushDenormalsScope ftz; // restored before the exact traversal below
                auto initRay = [&](RTCRay& r, glm::vec3 o) {
                    r.org_x = o.x, r.org_y = o.y, r.org_z = o.z;
                    r.dir_x = frame.dir.x, r.dir_y = frame.dir.y, r.dir_z = frame.dir.z;
                    r.tnear = 0.0f;
                    r.tfar = std::numeric_limits<float>::infinity();
                    r.time = 0.0f;
                    r.mask = 0xFFFFFFFFu;
                    r.id = 0;
                    r.flags = 0;
                };
                if (options.api == TraceApi::Stream) {
                    stream.resize(std::size_t(W));
                    for (int x = 0; x < W; ++x) {
                        initRay(stream[std::size_t(x)].ray, origin[std::size_t(x)]);
                        stream[std::size_t(x)].hit.geomID = RTC_INVALID_GEOMETRY_ID;
                        stream[std::size_t(x)].hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
                    }
                    rtcIntersect1M(handle, &ctx.base, stream.data(), unsigned(W), sizeof(RTCRayHit));
                    for (int x = 0; x < W; ++x) {
                        const RTCRayHit& rh = stream[std::size_t(x)];
                        have[std::size_t(x)] = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
                        bound[std::size_t(x)] = rh.ray.tfar;
                    }
                } else {
                    for (int x0 = 0; x0 < W; x0 += 8) {
                        alignas(32) RTCRayHit8 p;
                        alignas(32) int valid[8];
                        for (int l = 0; l < 8; ++l) {
                            const int x = std::min(x0 + l, W - 1);
                            valid[l] = x0 + l < W ? -1 : 0;
                            const glm::vec3 o = origin[std::size_t(x)];
                            p.ray.org_x[l] = o.x, p.ray.org_y[l] = o.y, p.ray.org_z[l] = o.z;
                            p.ray.dir_x[l] = frame.dir.x, p.ray.dir_y[l] = frame.dir.y, p.ray.dir_z[l] = frame.dir.z;
                            p.ray.tnear[l] = 0.0f;
                            p.ray.tfar[l] = std::numeric_limits<float>::infinity();
                            p.ray.time[l] = 0.0f;
                            p.ray.mask[l] = 0xFFFFFFFFu;
                            p.ray.id[l] = 0;
                            p.ray.flags[l] = 0;
                            p.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
                            p.hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
                        }
                        rtcIntersect8(valid, handle, &ctx.base, &p);
                        for (int l = 0; l < 8 && x0 + l < W; ++l) {
                            have[std::size_t(x0 + l)] = p.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
                            bound[std::size_t(x0 + l)] = p.ray.tfar[l];
                        }
                    }
                }
            }
            for (int x = 0; x < W; ++x) {
                const float tLow = exactOnly ? -kernel::VT_FAR : margin.apply(bound[std::size_t(x)]);
                const KernelOrderHit h = traceKernelOrder(frame, origin[std::size_t(x)], voxels, have[std::size_t(x)] != 0, tLow);
                localReads += std::uint64_t(h.steps);
                if (!h.hit) continue;
                const std::size_t k = std::size_t(y) * std::size_t(W) + std::size_t(x);
                snap.cells[k] = {h.index, std::uint8_t(snapshot_code::kSolid0 + h.face)};
                if (options.withDepth) snap.depth[k] = h.t - maxDim2;
            }
        }
        reads.local() += localReads;
    });
    applyCardinalOutline(snap);
    if (stats) {
        stats->rays += std::uint64_t(W) * std::uint64_t(H);
        stats->voxelReads += reads.combine([](std::uint64_t a, std::uint64_t b) { return a + b; });
        stats->ms += msSince(t0);
    }
    return snap;
}

Snapshot bakeSnapshotScalar(const VoxelGrid& grid, ViewSet set, int view, double sigma, BakeStats* stats) {
    const auto t0 = std::chrono::steady_clock::now();
    Snapshot snap = emptySnapshot(grid, set, view, sigma);
    const kernel::SpriteGpu frame = snapshotRayFrame(snap.lattice);
    const GridVoxels voxels = voxelsOf(grid);
    kernel::SpriteTracer<GridVoxels> tracer{voxels};
    const int W = snap.width(), H = snap.height();
    const glm::ivec4 range = snap.lattice.cellRange;
    tbb::parallel_for(tbb::blocked_range<int>(0, H, 2), [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y < rows.end(); ++y)
            for (int x = 0; x < W; ++x) {
                kernel::uint index, face;
                if (!tracer.vtTrace(frame, {range.x + x, range.z + y}, index, face)) continue;
                snap.cells[std::size_t(y) * std::size_t(W) + std::size_t(x)] = {std::uint8_t(index),
                                                                               std::uint8_t(snapshot_code::kSolid0 + face)};
            }
    });
    applyCardinalOutline(snap);
    if (stats) {
        stats->rays += std::uint64_t(W) * std::uint64_t(H);
        stats->ms += msSince(t0);
    }
    return snap;
}

} // namespace voxtier
