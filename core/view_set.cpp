#include "core/view_set.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <mutex>
#include <numeric>
#include <stdexcept>

namespace voxtier {

namespace {

std::vector<glm::ivec3> canonical26() {
    std::vector<glm::ivec3> v;
    for (int axis = 0; axis < 3; ++axis)
        for (int s : {1, -1}) {
            glm::ivec3 p(0);
            p[axis] = s;
            v.push_back(p);
        }
    // Edge pairs of axes (x,y), (x,z), (y,z); signs of the first axis vary slowest.
    const std::array<std::pair<int, int>, 3> pairs{{{0, 1}, {0, 2}, {1, 2}}};
    for (auto [a, b] : pairs)
        for (int sa : {1, -1})
            for (int sb : {1, -1}) {
                glm::ivec3 p(0);
                p[a] = sa;
                p[b] = sb;
                v.push_back(p);
            }
    for (int sx : {1, -1})
        for (int sy : {1, -1})
            for (int sz : {1, -1}) v.push_back({sx, sy, sz});
    return v;
}

std::vector<glm::ivec3> latticeSet(int n) {
    std::vector<glm::ivec3> v;
    for (glm::ivec3 c : canonical26()) v.push_back(c * n);
    for (int x = -n; x <= n; ++x)
        for (int y = -n; y <= n; ++y)
            for (int z = -n; z <= n; ++z) {
                const glm::ivec3 p{x, y, z};
                if (std::max({std::abs(x), std::abs(y), std::abs(z)}) != n) continue;
                if (std::find(v.begin(), v.begin() + 26, p) != v.begin() + 26) continue;
                v.push_back(p);
            }
    return v;
}

int latticeN(ViewSet set) {
    switch (set) {
    case ViewSet::Cube26:
        return 1;
    case ViewSet::Cube98:
        return 2;
    case ViewSet::Cube218:
        return 3;
    }
    return 1;
}

struct Tables {
    std::array<std::vector<glm::ivec3>, 3> points;
    std::array<std::vector<glm::dvec3>, 3> dirs;
    std::array<std::vector<ViewId>, 3> ids; ///< viewIdOf of each point (two gcds each, else)
    /// Per set and octant (bit 0: x < 0, bit 1: y < 0, bit 2: z < 0), the indices of the views
    /// in the closed octant, ascending: the only candidates nearestView must compare there.
    std::array<std::array<std::vector<int>, 8>, 3> octants;
    Tables() {
        for (int n = 1; n <= 3; ++n) {
            const std::size_t k = std::size_t(n - 1);
            points[k] = latticeSet(n);
            // From the primitive vector, so a direction is the very same double vector in every
            // set (normalising (2,2,0) and (1,1,0) can differ in the last bit).
            for (const glm::ivec3 p : points[k]) {
                ids[k].push_back(viewIdOf(p));
                dirs[k].push_back(viewDirection(ids[k].back()));
            }
            for (int o = 0; o < 8; ++o)
                for (std::size_t i = 0; i < points[k].size(); ++i) {
                    const glm::ivec3 p = points[k][i];
                    const auto within = [&](int c, int bit) {
                        return o >> bit & 1 ? c <= 0 : c >= 0;
                    };
                    if (within(p.x, 0) && within(p.y, 1) && within(p.z, 2))
                        octants[k][std::size_t(o)].push_back(int(i));
                }
        }
    }
};
const Tables& tables() {
    static const Tables t;
    return t;
}

} // namespace

ViewId viewIdOf(glm::ivec3 p) {
    const int g = std::gcd(std::gcd(std::abs(p.x), std::abs(p.y)), std::abs(p.z));
    if (g == 0) throw std::invalid_argument("viewIdOf: the zero vector is not a direction");
    return {p / g};
}

ViewId viewIdOf(ViewSet set, int index) {
    return tables().ids[std::size_t(latticeN(set) - 1)].at(std::size_t(index));
}

glm::dvec3 viewDirection(ViewId view) {
    return glm::normalize(glm::dvec3(view.lattice));
}

ViewSet viewSetFromSize(int size, const std::string& field) {
    if (size == 26) return ViewSet::Cube26;
    if (size == 98) return ViewSet::Cube98;
    if (size == 218) return ViewSet::Cube218;
    throw InputError("", field, "expected 26, 98 or 218 views, got " + std::to_string(size));
}

int viewCount(ViewSet set) {
    return int(set);
}

const std::vector<glm::ivec3>& viewLatticePoints(ViewSet set) {
    return tables().points[std::size_t(latticeN(set) - 1)];
}

const std::vector<glm::dvec3>& viewDirections(ViewSet set) {
    return tables().dirs[std::size_t(latticeN(set) - 1)];
}

int nearestView(ViewSet set, glm::dvec3 towardViewer) {
    const glm::dvec3 t = towardViewer;
    const auto& dirs = viewDirections(set);
    const auto firstBest = [&](const auto& indices) {
        int best = int(indices[0]);
        double bestDot = glm::dot(dirs[std::size_t(best)], t);
        for (std::size_t k = 1; k < indices.size(); ++k) {
            const double d = glm::dot(dirs[std::size_t(indices[k])], t);
            if (d > bestDot) {
                bestDot = d;
                best = int(indices[k]);
            }
        }
        return best;
    };
    // Only the views in t's closed octant can be nearest, and they alone are compared (7 of 26,
    // 19 of 98). The same answer as comparing all, ties to the lower index included: the sets
    // are symmetric under sign flips, and a view with a component against t's sign computes a
    // dot strictly below the view with that component flipped (the same products but for that
    // one's sign, and addition is monotone), which lies in the octant, provided that product
    // does not vanish in the sum's rounding. Hence every component of t at least 1e-9 of the
    // largest (a product >= 2e-10 of it, the sum's ulp ~4e-16 of it); else, and for a t that is
    // zero or not finite, every view is compared.
    const double m = std::max({std::abs(t.x), std::abs(t.y), std::abs(t.z)});
    const double least = std::min({std::abs(t.x), std::abs(t.y), std::abs(t.z)});
    if (std::isfinite(m) && m >= 1e-200 && least >= 1e-9 * m) {
        const int octant = (t.x < 0.0 ? 1 : 0) | (t.y < 0.0 ? 2 : 0) | (t.z < 0.0 ? 4 : 0);
        return firstBest(tables().octants[std::size_t(latticeN(set) - 1)][std::size_t(octant)]);
    }
    struct All {
        std::size_t n;
        std::size_t size() const { return n; }
        std::size_t operator[](std::size_t i) const { return i; }
    };
    return firstBest(All{dirs.size()});
}

double predictedDisplacementVpx(glm::dvec3 halfExtent, double sigma, glm::dvec3 towardViewer,
                                ViewId view) {
    return DisplacementPredictor(halfExtent, sigma, towardViewer).vpx(viewDirection(view));
}

DisplacementPredictor::DisplacementPredictor(glm::dvec3 halfExtent, double sigma,
                                             glm::dvec3 towardViewer)
    : d_(-glm::normalize(towardViewer)), sigmaDepth_(sigma * glm::dot(halfExtent, glm::abs(d_))) {}

double DisplacementPredictor::vpx(glm::dvec3 w) const {
    const double cosTheta = std::clamp(-glm::dot(w, d_), -1.0, 1.0);
    if (cosTheta <= 0.0) return std::numeric_limits<double>::infinity();
    // sin from the cross product: exact 0 at w = -d, and accurate at small angles where
    // sqrt(1 - cos^2) loses digits.
    const double sinTheta = glm::length(glm::cross(w, d_));
    return sigmaDepth_ * sinTheta / cosTheta;
}

long long cubeSurfaceCount(int n) {
    return 24LL * n * n + 2;
}

std::vector<ViewId> cubeSurfaceViews(int n) {
    std::vector<ViewId> views;
    for (glm::ivec3 p : latticeSet(n)) views.push_back(viewIdOf(p));
    return views;
}

namespace {

/// Something built once, on first use, by the first thread that asks. call_once alone costs two
/// thread-local lookups per call in this position-independent code, on paths the error-budget
/// planner takes ~600,000 times a frame: a flag is loaded first, set once the build is done.
class BuiltOnce {
  public:
    template <class Build> void ensure(Build&& build) {
        if (ready_.load(std::memory_order_acquire)) [[likely]]
            return;
        buildOnce(build);
    }

  private:
    /// Out of line, so that the caller's fast path is the load alone (inlined, call_once's
    /// closure was set up on the stack before the flag was tested).
    template <class Build> [[gnu::noinline, gnu::cold]] void buildOnce(Build& build) {
        std::call_once(once_, [&] {
            build();
            ready_.store(true, std::memory_order_release);
        });
    }

    std::once_flag once_;
    std::atomic<bool> ready_{false};
};

/// viewDirection(viewIdOf(p)) of every surface point p of {-n..n}^3, per n up to kTabledN,
/// computed on the first lookup of that n: nearestLatticePoint compares up to 25 of them per
/// call, and the error-budget planner calls it for each ladder level of each entity every frame
/// (two gcds and a square root each, otherwise: most of the planner's time on the tank army).
/// The same doubles, so every result is the same.
class SurfaceDirections {
  public:
    static constexpr int kTabledN = 64;

    /// Level n's table, indexed by index(n, p); null past kTabledN.
    const glm::dvec3* table(int n) {
        if (n > kTabledN) return nullptr;
        built_[std::size_t(n)].ensure([&] { build(n); });
        return table_[std::size_t(n)].data();
    }
    /// viewIdOf(p) by the same index, once table(n) was asked for.
    const ViewId* ids(int n) const { return ids_[std::size_t(n)].data(); }
    /// Face (the first axis at +-n, and its sign), then the two other coordinates.
    static std::size_t index(int n, glm::ivec3 p) {
        const int side = 2 * n + 1;
        const int axis = std::abs(p.x) == n ? 0 : (std::abs(p.y) == n ? 1 : 2);
        const int face = axis * 2 + (p[axis] < 0 ? 1 : 0);
        const int u = p[(axis + 1) % 3] + n, v = p[(axis + 2) % 3] + n;
        return std::size_t((face * side + u) * side + v);
    }

  private:
    void build(int n) {
        const int side = 2 * n + 1;
        std::vector<glm::dvec3>& t = table_[std::size_t(n)];
        std::vector<ViewId>& ids = ids_[std::size_t(n)];
        t.resize(std::size_t(6 * side * side));
        ids.resize(t.size());
        for (int axis = 0; axis < 3; ++axis)
            for (int sign : {1, -1})
                for (int u = -n; u <= n; ++u)
                    for (int v = -n; v <= n; ++v) {
                        glm::ivec3 p;
                        p[axis] = sign * n;
                        p[(axis + 1) % 3] = u;
                        p[(axis + 2) % 3] = v;
                        ids[index(n, p)] = viewIdOf(p);
                        t[index(n, p)] = viewDirection(ids[index(n, p)]);
                    }
    }

    std::array<BuiltOnce, kTabledN + 1> built_;
    std::array<std::vector<glm::dvec3>, kTabledN + 1> table_;
    std::array<std::vector<ViewId>, kTabledN + 1> ids_;
};

SurfaceDirections& surfaceDirections() {
    static SurfaceDirections directions;
    return directions;
}

/// The search's box along one coordinate: the lattice values within kReach steps of [from, to]
/// (of a projection, from = to; of every projection in a cell, its sides), clamped to [-n, n].
/// The gnomonic map stretches angles at most sqrt(3)-fold across a face, so the nearest view
/// lies within 1.3 steps of the projection. One rule for nearestSurfacePoint's box and for the
/// cells', whose lists rest on holding every point the box of each of their projections holds.
constexpr double kReach = 1.5;
int reachFrom(double from, int n) {
    return std::max(-n, int(std::ceil(from - kReach)));
}
int reachTo(double to, int n) {
    return std::min(n, int(std::floor(to + kReach)));
}

/// Where the nearest view of a level up to kGridN can lie, precomputed: each cube face's square
/// [-n, n]^2 (the direction's projection onto its dominant face, in lattice steps) cut into
/// kCellsPerStep x kCellsPerStep cells per step, and each cell listing, in lexicographic order,
/// the surface points of nearestSurfacePoint's box over the cell that no other point of it beats
/// by more than kMargin at each of the cell's corners. Which of two views is nearer, w_i . t
/// against w_j . t, is a linear test in the projection, so a point beaten at every corner is
/// beaten everywhere in the cell; the margin (against dots of at most sqrt(3) at the corners)
/// covers the rounding of the corners' dots, of the projection that finds a direction's cell,
/// and of the search's own dots, which differ from the exact ones by ~1e-15 of |t|. A point left
/// out is thus never the search's maximum, and every point left in is compared, in the scan's
/// order, with the same doubles: the same point as the box's scan. The box's scan compares up to
/// 25 points per call, most of them far from the nearest, at ~45 ns a call in the error-budget
/// planner, which calls it ~600,000 times a frame where 100,000 tanks wait for bakes; a cell
/// holds one to four (2.7 on average; level 16's cells take 2.2 MB).
class NearestCandidates {
  public:
    static constexpr int kGridN = 16;
    static constexpr int kCellsPerStep = 2;
    static constexpr double kMargin = 1e-9;
    struct Candidate {
        glm::dvec3 direction; ///< the point's, as tabled (beside the rest: one cache line)
        std::uint32_t entry;  ///< SurfaceDirections::index of the point
        std::int8_t x, y, z;  ///< the point
    };
    struct Level {
        int cellsPerSide = 0;
        std::vector<std::uint32_t> first; ///< per cell (face, b, c), and one past the last
        std::vector<Candidate> candidates;
    };

    /// Level n's cells, n <= kGridN.
    const Level& level(int n, const glm::dvec3* directions) {
        built_[std::size_t(n)].ensure([&] { build(n, directions); });
        return levels_[std::size_t(n)];
    }
    /// The cell of `onFace` (nearestSurfacePoint's projection, finite) on the face of `axis`.
    static std::size_t cell(const Level& level, int n, int axis, glm::dvec3 onFace) {
        const int b = (axis + 1) % 3, c = (axis + 2) % 3;
        const auto along = [&](double x) {
            return std::clamp(int(std::floor((x + double(n)) * kCellsPerStep)), 0,
                              level.cellsPerSide - 1);
        };
        const std::size_t face = std::size_t(axis * 2 + (onFace[axis] < 0.0 ? 1 : 0));
        return (face * std::size_t(level.cellsPerSide) + std::size_t(along(onFace[b]))) *
                   std::size_t(level.cellsPerSide) +
               std::size_t(along(onFace[c]));
    }

  private:
    void build(int n, const glm::dvec3* directions) {
        Level& level = levels_[std::size_t(n)];
        const int side = 2 * n * kCellsPerStep;
        level.cellsPerSide = side;
        level.first.reserve(std::size_t(6 * side * side) + 1);
        std::vector<glm::ivec3> box;
        for (int axis = 0; axis < 3; ++axis)
            for (int sign : {1, -1}) {
                const int b = (axis + 1) % 3, c = (axis + 2) % 3;
                for (int cb = 0; cb < side; ++cb)
                    for (int cc = 0; cc < side; ++cc) {
                        // The cell's corners, in lattice steps on the face, and the box of every
                        // projection within it (nearestSurfacePoint's, over the cell).
                        const double b0 = -n + double(cb) / kCellsPerStep;
                        const double c0 = -n + double(cc) / kCellsPerStep;
                        const double b1 = b0 + 1.0 / kCellsPerStep;
                        const double c1 = c0 + 1.0 / kCellsPerStep;
                        glm::ivec3 lo, hi;
                        lo[axis] = reachFrom(sign * n, n), hi[axis] = reachTo(sign * n, n);
                        lo[b] = reachFrom(b0, n), hi[b] = reachTo(b1, n);
                        lo[c] = reachFrom(c0, n), hi[c] = reachTo(c1, n);
                        box.clear();
                        for (int x = lo.x; x <= hi.x; ++x)
                            for (int y = lo.y; y <= hi.y; ++y)
                                for (int z = lo.z; z <= hi.z; ++z)
                                    if (std::max({std::abs(x), std::abs(y), std::abs(z)}) == n)
                                        box.push_back({x, y, z});
                        std::array<glm::dvec3, 4> corners;
                        for (int k = 0; k < 4; ++k) {
                            glm::dvec3 t;
                            t[axis] = double(sign);
                            t[b] = (k & 1 ? b1 : b0) / n;
                            t[c] = (k & 2 ? c1 : c0) / n;
                            corners[std::size_t(k)] = t;
                        }
                        const auto w = [&](const glm::ivec3& p) {
                            return directions[SurfaceDirections::index(n, p)];
                        };
                        // The point nearest the cell's centre beats most others at every corner:
                        // tried first.
                        const glm::dvec3 centre = (corners[0] + corners[3]) * 0.5;
                        std::size_t lead = 0;
                        for (std::size_t i = 1; i < box.size(); ++i)
                            if (glm::dot(w(box[i]), centre) > glm::dot(w(box[lead]), centre))
                                lead = i;
                        const auto beats = [&](std::size_t j, std::size_t i) {
                            for (const glm::dvec3& t : corners)
                                if (!(glm::dot(w(box[i]), t) - glm::dot(w(box[j]), t) < -kMargin))
                                    return false;
                            return true;
                        };
                        level.first.push_back(std::uint32_t(level.candidates.size()));
                        for (std::size_t i = 0; i < box.size(); ++i) {
                            bool beaten = i != lead && beats(lead, i);
                            for (std::size_t j = 0; j < box.size() && !beaten; ++j)
                                beaten = j != i && beats(j, i);
                            if (beaten) continue;
                            const glm::ivec3& p = box[i];
                            const std::size_t entry = SurfaceDirections::index(n, p);
                            level.candidates.push_back({directions[entry], std::uint32_t(entry),
                                                        std::int8_t(p.x), std::int8_t(p.y),
                                                        std::int8_t(p.z)});
                        }
                    }
            }
        level.first.push_back(std::uint32_t(level.candidates.size()));
    }

    std::array<BuiltOnce, kGridN + 1> built_;
    std::array<Level, kGridN + 1> levels_;
};

NearestCandidates& nearestCandidates() {
    static NearestCandidates candidates;
    return candidates;
}

/// nearestLatticePoint, with its view's direction and id from the tables where n has them.
struct SurfaceHit {
    glm::ivec3 point{0};
    const glm::dvec3* direction = nullptr;
    const ViewId* id = nullptr;
};

SurfaceHit nearestSurfacePoint(int n, glm::dvec3 towardViewer) {
    const glm::dvec3 a = glm::abs(towardViewer);
    const int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
    // The point where the ray along towardViewer leaves the cube [-n, n]^3.
    const glm::dvec3 onFace = towardViewer * (double(n) / a[axis]);
    SurfaceDirections& tables = surfaceDirections();
    const glm::dvec3* directions = tables.table(n);
    SurfaceHit hit;
    double bestDot = -2.0;
    // The cell's candidates where n has cells and the direction is of a size whose dots round
    // as NearestCandidates assumes (any unit or lattice vector is).
    if (n <= NearestCandidates::kGridN && a[axis] >= 1e-100 && a[axis] <= 1e100 &&
        std::isfinite(onFace.x) && std::isfinite(onFace.y) && std::isfinite(onFace.z)) {
        const NearestCandidates::Level& level = nearestCandidates().level(n, directions);
        const std::size_t cell = NearestCandidates::cell(level, n, axis, onFace);
        const NearestCandidates::Candidate* best = nullptr;
        for (std::uint32_t k = level.first[cell]; k != level.first[cell + 1]; ++k) {
            const NearestCandidates::Candidate& candidate = level.candidates[k];
            const double d = glm::dot(candidate.direction, towardViewer);
            if (d > bestDot) bestDot = d, best = &candidate;
        }
        // (A cell lists at least the point nearest its centre.)
        hit.point = {best->x, best->y, best->z};
        hit.direction = &best->direction;
        hit.id = &tables.ids(n)[best->entry];
        return hit;
    }
    // The lattice points within kReach steps of the projection in each coordinate: 3 x 3 on its
    // face, and the next faces' points where it is that near an edge.
    glm::ivec3 lo, hi;
    for (int c = 0; c < 3; ++c) lo[c] = reachFrom(onFace[c], n), hi[c] = reachTo(onFace[c], n);
    const auto consider = [&](const glm::ivec3& p) {
        const glm::dvec3 w =
            directions ? directions[SurfaceDirections::index(n, p)] : viewDirection(viewIdOf(p));
        const double d = glm::dot(w, towardViewer);
        if (d > bestDot) bestDot = d, hit.point = p;
    };
    // Lexicographic scan of the box's surface points, strict '>': the first of equal dots wins,
    // as in a brute-force scan of the whole lattice in the same order. Where neither x nor y is
    // at +-n, only z = -n and z = n are on the surface: the box's other points are skipped
    // without a test (the error-budget planner calls this for every far entity and ladder level
    // each frame: a box of 5^3 points tested one by one was most of its inputs' time).
    for (int x = lo.x; x <= hi.x; ++x)
        for (int y = lo.y; y <= hi.y; ++y) {
            if (std::abs(x) == n || std::abs(y) == n) {
                for (int z = lo.z; z <= hi.z; ++z) consider({x, y, z});
            } else {
                if (lo.z == -n) consider({x, y, -n});
                if (hi.z == n) consider({x, y, n});
            }
        }
    // (No point found, for a direction that is not finite: viewIdOf refuses the zero vector.)
    if (directions && hit.point != glm::ivec3(0)) {
        const std::size_t entry = SurfaceDirections::index(n, hit.point);
        hit.direction = &directions[entry];
        hit.id = &tables.ids(n)[entry];
    }
    return hit;
}

} // namespace

glm::ivec3 nearestLatticePoint(int n, glm::dvec3 towardViewer) {
    return nearestSurfacePoint(n, towardViewer).point;
}

DirectedView nearestDirectedLadderView(int n, glm::dvec3 towardViewer) {
    const SurfaceHit hit = nearestSurfacePoint(n, towardViewer);
    if (!hit.direction) {
        const ViewId id = viewIdOf(hit.point);
        return {id, viewDirection(id)};
    }
    return {*hit.id, *hit.direction};
}

} // namespace voxtier
