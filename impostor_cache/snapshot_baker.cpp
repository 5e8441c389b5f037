#include "impostor_cache/snapshot_baker.hpp"

#include "core/error.hpp"
#include "core/stopwatch.hpp"
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
    unsigned fetch(glm::ivec3 c) const {
        return data[std::size_t(c.x) + sx * std::size_t(c.y) + sxy * std::size_t(c.z)];
    }
};
GridVoxels voxelsOf(const VoxelGrid& g) {
    return {g.data().data(), std::size_t(g.dims().x),
            std::size_t(g.dims().x) * std::size_t(g.dims().y)};
}

Snapshot emptySnapshot(const VoxelGrid& grid, ViewId view, double sigma, int snapshotScale = 1) {
    Snapshot s;
    s.view = view;
    s.w = viewDirection(view);
    s.lattice = snapshotLattice(s.w, grid.dims(), sigma, snapshotScale);
    s.snapshotScale = snapshotScale;
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

} // namespace

namespace {

/// Embree's packet types by width.
template <int N> struct Packet;
template <> struct Packet<8> {
    using RayHit = RTCRayHit8;
    static void intersect(const int* valid, RTCScene scene, RTCIntersectContext* ctx, RayHit* rh) {
        rtcIntersect8(valid, scene, ctx, rh);
    }
};
template <> struct Packet<16> {
    using RayHit = RTCRayHit16;
    static void intersect(const int* valid, RTCScene scene, RTCIntersectContext* ctx, RayHit* rh) {
        rtcIntersect16(valid, scene, ctx, rh);
    }
};

/// Traces rays `origin[0..count)` (direction `dir`) and returns, per ray, whether Embree found
/// a candidate and its parameter. Runs with FTZ/DAZ set (restored on return).
struct EmbreeBatch {
    RTCScene scene;
    detail::BakeIntersectContext* ctx;
    glm::vec3 dir;
    std::vector<RTCRayHit> stream; // scratch for the stream API

    template <int N>
    void packets(const glm::vec3* origin, std::size_t count, unsigned char* have, float* tHit) {
        using P = Packet<N>;
        for (std::size_t b = 0; b < count; b += N) {
            alignas(64) typename P::RayHit p;
            alignas(64) int valid[N];
            for (int l = 0; l < N; ++l) {
                const std::size_t r = std::min(b + std::size_t(l), count - 1);
                valid[l] = b + std::size_t(l) < count ? -1 : 0;
                p.ray.org_x[l] = origin[r].x, p.ray.org_y[l] = origin[r].y,
                p.ray.org_z[l] = origin[r].z;
                p.ray.dir_x[l] = dir.x, p.ray.dir_y[l] = dir.y, p.ray.dir_z[l] = dir.z;
                p.ray.tnear[l] = 0.0f;
                p.ray.tfar[l] = std::numeric_limits<float>::infinity();
                p.ray.time[l] = 0.0f;
                p.ray.mask[l] = 0xFFFFFFFFu;
                p.ray.id[l] = 0;
                p.ray.flags[l] = 0;
                p.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
                p.hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
            }
            P::intersect(valid, scene, &ctx->base, &p);
            for (int l = 0; l < N && b + std::size_t(l) < count; ++l) {
                have[b + std::size_t(l)] = p.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
                tHit[b + std::size_t(l)] = p.ray.tfar[l];
            }
        }
    }

    void streamed(const glm::vec3* origin, std::size_t count, unsigned char* have, float* tHit) {
        stream.resize(count);
        for (std::size_t r = 0; r < count; ++r) {
            RTCRayHit& rh = stream[r];
            rh.ray.org_x = origin[r].x, rh.ray.org_y = origin[r].y, rh.ray.org_z = origin[r].z;
            rh.ray.dir_x = dir.x, rh.ray.dir_y = dir.y, rh.ray.dir_z = dir.z;
            rh.ray.tnear = 0.0f;
            rh.ray.tfar = std::numeric_limits<float>::infinity();
            rh.ray.time = 0.0f;
            rh.ray.mask = 0xFFFFFFFFu;
            rh.ray.id = unsigned(r);
            rh.ray.flags = 0;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect1M(scene, &ctx->base, stream.data(), unsigned(count), sizeof(RTCRayHit));
        for (std::size_t r = 0; r < count; ++r) {
            have[r] = stream[r].hit.geomID != RTC_INVALID_GEOMETRY_ID;
            tHit[r] = stream[r].ray.tfar;
        }
    }

    void trace(TraceApi api, const glm::vec3* origin, std::size_t count, unsigned char* have,
               float* tHit) {
        detail::FlushDenormalsScope ftz; // restored before the float-exact traversal
        switch (api) {
        case TraceApi::Packet8:
            packets<8>(origin, count, have, tHit);
            break;
        case TraceApi::Packet16:
            packets<16>(origin, count, have, tHit);
            break;
        case TraceApi::Stream:
            streamed(origin, count, have, tHit);
            break;
        }
    }
};

} // namespace

const char* toString(TraceApi api) {
    switch (api) {
    case TraceApi::Packet8:
        return "packet8";
    case TraceApi::Packet16:
        return "packet16";
    case TraceApi::Stream:
        return "stream";
    }
    return "?";
}

TraceApi parseTraceApi(const std::string& name) {
    if (name == "packet8") return TraceApi::Packet8;
    if (name == "packet16") return TraceApi::Packet16;
    if (name == "stream") return TraceApi::Stream;
    throw InputError("", "--api", "expected packet8, packet16 or stream, got '" + name + "'");
}

namespace {

/// Traces the stored cells x0..x1, y0..y1 (inclusive, `rect`) of `snap` against `scene` and
/// writes the solid ones (the others are left as they are: callers pass them empty). Every cell
/// is decided by its own ray alone, exactly as vtTrace decides it, so tracing a part of a
/// snapshot gives the very bytes a full bake gives there. Adds to stats' rays, reads and
/// Embree rays.
void traceRect(const VoxelScene& scene, Snapshot& snap, glm::ivec4 rect, const BakeOptions& options,
               BakeStats* stats) {
    const VoxelGrid& grid = scene.grid();
    const kernel::SpriteGpu frame = snapshotRayFrame(snap.lattice);
    const GridVoxels voxels = voxelsOf(grid);
    const int W = snap.width();
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
    const bool withDepth = !snap.depth.empty();

    detail::BakeIntersectContext ctx;
    rtcInitIntersectContext(&ctx.base);
    ctx.base.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT; // parallel rays in lattice order
    ctx.dir = frame.dir;
    ctx.invDir = frame.invDir;
    const bool useEmbree = !scene.empty() && !exactOnly;

    auto store = [&](std::size_t k, std::uint8_t index, std::uint8_t face, float t) {
        snap.cells[k] = {index, std::uint8_t(snapshot_code::kSolid0 + face)};
        if (withDepth) snap.depth[k] = t - maxDim2;
    };
    struct Counts {
        std::uint64_t reads = 0, embree = 0;
    };
    tbb::combinable<Counts> counts;
    // Blocks of rows: the kernel's slab test and entry read settle every ray that misses the
    // model box or starts in a solid voxel, and a few more reads settle most of the rest on
    // compact models; only the remaining rays go to Embree, compacted, so packets carry no
    // dead lanes.
    constexpr int kRowsPerTask = 4;
    const int first = useEmbree ? std::max(0, options.traverseFirst) : (1 << 30);
    tbb::parallel_for(
        tbb::blocked_range<int>(rect.z, rect.w + 1, kRowsPerTask),
        [&](const tbb::blocked_range<int>& rows) {
            // One context per task: Embree pushes the instance id into it while traversing a
            // brick (voxel_scene.hpp), so it must not be shared between threads.
            detail::BakeIntersectContext taskCtx = ctx;
            EmbreeBatch batch{scene.handle(), &taskCtx, frame.dir, {}};
            std::vector<glm::vec3> origin;
            std::vector<std::size_t> cellOf;
            std::vector<KernelEntry> entry;
            Counts local;
            for (int y = rows.begin(); y < rows.end(); ++y)
                for (int x = rect.x; x <= rect.y; ++x) {
                    const glm::vec3 o = kernelRayOrigin(frame, {range.x + x, range.z + y});
                    const KernelEntry e = kernelEntry(frame, o, voxels);
                    if (e.kind == KernelEntry::Kind::Miss) continue;
                    ++local.reads;
                    const std::size_t k = std::size_t(y) * std::size_t(W) + std::size_t(x);
                    if (e.kind == KernelEntry::Kind::Hit) {
                        store(k, e.index, kernelFaceCode(frame, e.axis), e.tEnter);
                        continue;
                    }
                    // An empty scene cannot be hit past the entry cell: nothing to traverse.
                    if (!scene.empty() && first > 0) {
                        const KernelOrderHit h =
                            kernelResume(frame, o, voxels, e, true, -kernel::VT_FAR, first);
                        local.reads += std::uint64_t(h.steps);
                        if (!h.unresolved) {
                            if (h.hit) store(k, h.index, h.face, h.t);
                            continue;
                        }
                    }
                    origin.push_back(o);
                    cellOf.push_back(k);
                    entry.push_back(e);
                }
            const std::size_t n = origin.size();
            std::vector<unsigned char> have(n, exactOnly ? 1 : 0);
            std::vector<float> tHit(n, -kernel::VT_FAR);
            if (useEmbree && n > 0) {
                batch.trace(options.api, origin.data(), n, have.data(), tHit.data());
                local.embree += n;
            }
            for (std::size_t r = 0; r < n; ++r) {
                // No candidate: tHit is +inf and no bound is needed (or computed: inf - inf).
                const float tLow = exactOnly || !have[r] ? -kernel::VT_FAR : margin.apply(tHit[r]);
                const KernelOrderHit h =
                    kernelResume(frame, origin[r], voxels, entry[r], have[r] != 0, tLow);
                local.reads += std::uint64_t(h.steps);
                if (h.hit) store(cellOf[r], h.index, h.face, h.t);
            }
            counts.local().reads += local.reads;
            counts.local().embree += local.embree;
        });
    if (stats) {
        stats->rays += std::uint64_t(rect.y - rect.x + 1) * std::uint64_t(rect.w - rect.z + 1);
        counts.combine_each([&](const Counts& c) {
            stats->voxelReads += c.reads;
            stats->embreeRays += c.embree;
        });
    }
}

} // namespace

Snapshot bakeSnapshot(const VoxelScene& scene, ViewId view, double sigma,
                      const BakeOptions& options, BakeStats* stats) {
    const auto t0 = std::chrono::steady_clock::now();
    Snapshot snap = emptySnapshot(scene.grid(), view, sigma, options.snapshotScale);
    if (options.withDepth) snap.depth.assign(snap.cells.size(), 0.0f);
    traceRect(scene, snap, {0, snap.width() - 1, 0, snap.height() - 1}, options, stats);
    applyCardinalOutline(snap);
    if (stats) {
        stats->cells += snap.cells.size();
        stats->ms += msSince(t0);
    }
    return snap;
}

// Why cellsReachingBox is enough. vtTrace visits a sequence of voxels that depends on the ray
// alone (entry cell, then one step per boundary crossing), reads them in order and stops at the
// first solid one; a ray none of whose visited voxels lies in the dirty box reads the same values
// before and after the edit and gives the same cell. The voxels it visits are those the float
// ray passes through: the float origin and crossing parameters are within a few ulps of the
// exact ray through the double cell centre (coordinates <= ~3.5 * maxDim, so ~1e-4 voxel at
// 256), so every visited voxel meets the exact line grown by that much. A cell whose exact line
// stays 1/64 voxel clear of the dirty box (two orders of magnitude more) therefore cannot read
// it. The lines are parallel, so "line meets the grown box" is "cell centre lies in the box's
// projection on the sprite plane", bounded here by the rectangle of its 8 projected corners; one
// more cell on every side is slack against any slip in that argument (a grazing ray, a tie), and
// the outline, which depends on the four neighbours, is recomputed one cell further out.
glm::ivec4 cellsReachingBox(const SpriteLattice& L, Box3i box) {
    if (box.empty()) return {1, 0, 1, 0};
    constexpr double kSlack = 1.0 / 64.0;
    const glm::dvec3 lo = glm::dvec3(box.min) - kSlack, hi = glm::dvec3(box.max) + kSlack;
    double aMin = 1e300, aMax = -1e300, bMin = 1e300, bMax = -1e300;
    for (int corner = 0; corner < 8; ++corner) {
        const glm::dvec3 p((corner & 1) ? hi.x : lo.x, (corner & 2) ? hi.y : lo.y,
                           (corner & 4) ? hi.z : lo.z);
        const glm::dvec3 q = p - L.centre;
        // Cell i's ray passes the plane at u = gU + (i + 1/2) / sigma: a = i there.
        const double a = L.sigma * (glm::dot(q, L.right) - L.gU) - 0.5;
        const double b = L.sigma * (glm::dot(q, L.up) - L.gV) - 0.5;
        aMin = std::min(aMin, a), aMax = std::max(aMax, a);
        bMin = std::min(bMin, b), bMax = std::max(bMax, b);
    }
    const glm::ivec4 r{int(std::floor(aMin)) - 1, int(std::ceil(aMax)) + 1,
                       int(std::floor(bMin)) - 1, int(std::ceil(bMax)) + 1};
    const glm::ivec4 c = L.cellRange;
    const glm::ivec4 out{std::max(r.x, c.x), std::min(r.y, c.y), std::max(r.z, c.z),
                         std::min(r.w, c.w)};
    if (out.x > out.y || out.z > out.w) return {1, 0, 1, 0};
    return out;
}

Snapshot rebakeSnapshot(const VoxelScene& scene, const Snapshot& previous, Box3i dirty,
                        const BakeOptions& options, BakeStats* stats) {
    const auto t0 = std::chrono::steady_clock::now();
    const SpriteLattice& L = previous.lattice;
    const bool fits = L.dims == scene.grid().dims() &&
                      previous.cells.size() == std::size_t(L.width()) * std::size_t(L.height()) &&
                      (!options.withDepth || previous.depth.size() == previous.cells.size()) &&
                      previous.snapshotScale == options.snapshotScale;
    const glm::ivec4 reach = cellsReachingBox(L, dirty);
    const bool none = reach.x > reach.y;
    const std::uint64_t area =
        none ? 0 : std::uint64_t(reach.y - reach.x + 1) * std::uint64_t(reach.w - reach.z + 1);
    if (!fits || double(area) > options.maxIncrementalShare * double(previous.cells.size()))
        return bakeSnapshot(scene, previous.view, L.sigma, options, stats);

    Snapshot snap = previous;
    if (!options.withDepth) snap.depth.clear();
    if (!none) {
        // Stored-cell coordinates of the rectangle; its cells start empty, as in a full bake.
        const glm::ivec4 rect{reach.x - L.cellRange.x, reach.y - L.cellRange.x,
                              reach.z - L.cellRange.z, reach.w - L.cellRange.z};
        const int W = snap.width();
        for (int y = rect.z; y <= rect.w; ++y) {
            const std::size_t row = std::size_t(y) * std::size_t(W);
            std::fill(snap.cells.begin() + std::ptrdiff_t(row + std::size_t(rect.x)),
                      snap.cells.begin() + std::ptrdiff_t(row + std::size_t(rect.y) + 1),
                      SnapshotCell{});
            if (!snap.depth.empty())
                std::fill(snap.depth.begin() + std::ptrdiff_t(row + std::size_t(rect.x)),
                          snap.depth.begin() + std::ptrdiff_t(row + std::size_t(rect.y) + 1), 0.0f);
        }
        traceRect(scene, snap, rect, options, stats);
        // A cell within the outline's reach (snapshotScale cells) of the rectangle may gain or lose
        // its outline with the cells inside it.
        const int k = snap.snapshotScale;
        refreshCardinalOutline(snap, {rect.x - k, rect.y + k, rect.z - k, rect.w + k});
    }
    if (stats) {
        stats->cells += snap.cells.size();
        stats->incremental += 1;
        stats->ms += msSince(t0);
    }
    return snap;
}

Snapshot bakeSnapshotScalar(const VoxelGrid& grid, ViewId view, double sigma, BakeStats* stats) {
    const auto t0 = std::chrono::steady_clock::now();
    Snapshot snap = emptySnapshot(grid, view, sigma);
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
                snap.cells[std::size_t(y) * std::size_t(W) + std::size_t(x)] = {
                    std::uint8_t(index), std::uint8_t(snapshot_code::kSolid0 + face)};
            }
    });
    applyCardinalOutline(snap);
    if (stats) {
        stats->rays += std::uint64_t(W) * std::uint64_t(H);
        stats->cells += snap.cells.size();
        stats->ms += msSince(t0);
    }
    return snap;
}

} // namespace voxtier
