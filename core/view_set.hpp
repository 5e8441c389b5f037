#pragma once
// The far tier's snapshot directions (CONTRACT.md §4). A view is the unit vector w from the model
// centre towards the viewer, in voxel space; its snapshot is the near image seen along d = -w.
// Pure view math, in core (ARCHITECTURE.md): impostor_cache bakes and keys snapshots by these
// views, lod/ predicts the error of drawing from them.
#include <glm/glm.hpp>

#include <array>
#include <string>
#include <vector>

namespace voxtier {

/// Which directions are baked: the cube lattice {-n..n}^3 restricted to the cube's surface
/// (max |component| = n), normalised. n = 1 is the 26 canonical directions.
enum class ViewSet {
    Cube26 = 26,   ///< n = 1: 6 faces, 12 edges, 8 corners
    Cube98 = 98,   ///< n = 2
    Cube218 = 218, ///< n = 3
};
/// 26, 98 or 218 -> the set; anything else throws InputError(field `field`).
ViewSet viewSetFromSize(int size, const std::string& field = "view_set");
int viewCount(ViewSet set);

/// The integer lattice vectors of a set, in the fixed order that view indices refer to:
///  - indices 0..5, the faces: +X, -X, +Y, -Y, +Z, -Z;
///  - 6..17, the edges: (±1,±1,0) then (±1,0,±1) then (0,±1,±1), within each group the
///    first non-zero component's sign varies slowest, + before -;
///  - 18..25, the corners (±1,±1,±1), x's sign slowest, then y, then z, + before -;
///  - for the denser sets, the canonical 26 come first (scaled by n, so index i < 26 is the
///    same direction in every set), then the remaining surface points in lexicographic order
///    of (x, y, z), each from -n to n.
const std::vector<glm::ivec3>& viewLatticePoints(ViewSet set);
/// The same, normalised: element i is viewDirection(viewIdOf(set, i)).
const std::vector<glm::dvec3>& viewDirections(ViewSet set);

/// What a snapshot is a view *of*: its direction as the primitive integer lattice vector (the
/// components' gcd is 1), whatever set it was picked from. Every set here is a cube-surface
/// lattice, and a denser one holds the coarser directions scaled (n = 2 has (2, 2, 0) for the
/// edge view (1, 1, 0)), so keying snapshots by the primitive vector makes one snapshot serve
/// every set that contains its direction, and its unit vector (viewDirection) is computed from
/// the primitive vector alone: bit-identical whichever set asked.
struct ViewId {
    glm::ivec3 lattice{0, 0, 1};
    bool operator==(const ViewId&) const = default;
};
/// The primitive vector of a non-zero lattice point (divided by the gcd of its components).
ViewId viewIdOf(glm::ivec3 latticePoint);
/// The id of view `index` of `set`.
ViewId viewIdOf(ViewSet set, int index);
/// The unit vector w of a view: normalize(lattice) in double; face views are exact axis vectors.
glm::dvec3 viewDirection(ViewId view);

/// The view w* maximising w . towardViewer (CONTRACT.md §4: towardViewer = -d, d the entity's
/// per-entity ray direction in voxel space). Ties go to the lower index, so the choice is a
/// deterministic function of the direction.
int nearestView(ViewSet set, glm::dvec3 towardViewer);

/// The refinement ladder (CONTRACT.md §4): the cube-surface lattices {-n..n}^3 with max |component|
/// = n for these n, 26 ... 98,306 directions. n doubles from level to level, so every level holds
/// the coarser ones' directions (scaled), and a snapshot keyed by ViewId serves all of them.
inline constexpr std::array<int, 7> kViewLadder{1, 2, 4, 8, 16, 32, 64};
/// Surface points of {-n..n}^3: (2n+1)^3 - (2n-1)^3 = 24n^2 + 2.
long long cubeSurfaceCount(int n);
/// Every view of the cube-surface lattice of size n (n >= 1), the 26 canonical ones first: what
/// a pre-bake of ladder level n writes (n = 1, 2, 3 are the sets of 26, 98 and 218).
std::vector<ViewId> cubeSurfaceViews(int n);

/// The view of the cube-surface lattice of size n (any n >= 1) maximising
/// viewDirection(p) . towardViewer, in O(1): towardViewer is projected onto its dominant cube face,
/// and only the surface points within 1.5 lattice steps of that point in each coordinate are
/// compared (the gnomonic map stretches angles at most sqrt(3)-fold across a face, so the nearest
/// view lies within 1.3 steps of the projection; the tests find none beyond 0.9). Ties go to the
/// lexicographically smallest (x, y, z) lattice point, so the result equals a brute-force scan in
/// that order. towardViewer need not be normalised but must not be zero.
glm::ivec3 nearestLatticePoint(int n, glm::dvec3 towardViewer);
/// CONTRACT.md §5: how far (virtual pixels, before quantisation) the far tier moves a silhouette
/// when it draws a model with half extents `halfExtent` (voxels) from the snapshot of `view` while
/// the near tier would look along d = -towardViewer. The blit reads the snapshot at the oblique
/// projection (along w) of each sprite-plane point, so a point X of the model (voxels from its
/// centre) lands |X . d| tan(theta) from where the near tier draws it, theta the angle between w
/// and -d; over the model's box |X . d| <= sum_i halfExtent_i |d_i|, and a voxel spans sigma
/// virtual pixels. 0 when w = -d, +inf from 90 degrees on.
double predictedDisplacementVpx(glm::dvec3 halfExtent, double sigma, glm::dvec3 towardViewer,
                                ViewId view);
/// predictedDisplacementVpx of one line of sight against several views: what the sprite fixes
/// (the direction normalised, the box's depth extent along it) computed once. The error budget
/// predicts every ladder level of each far entity waiting for a view, ~80,000 entities a frame
/// when bakes are scarce; predictedDisplacementVpx is this, so the two are bit for bit the same.
class DisplacementPredictor {
  public:
    DisplacementPredictor(glm::dvec3 halfExtent, double sigma, glm::dvec3 towardViewer);
    /// Predicts for no line of sight (SpriteSelectionInputs of a culled sprite, never asked).
    DisplacementPredictor() = default;
    /// From the two values the constructor derives (-normalize(towardViewer) and sigma times the
    /// box's half depth along it), where they were computed elsewhere with the same operations
    /// (the SIMD sprite set-up: SpriteSelectionInputs).
    static DisplacementPredictor fromParts(glm::dvec3 lineOfSight, double sigmaDepth) {
        DisplacementPredictor p;
        p.d_ = lineOfSight, p.sigmaDepth_ = sigmaDepth;
        return p;
    }
    glm::dvec3 lineOfSight() const { return d_; }
    double sigmaDepth() const { return sigmaDepth_; }
    /// The prediction for the view whose unit vector (viewDirection) is `w`.
    double vpx(glm::dvec3 w) const;

  private:
    glm::dvec3 d_{0.0};       ///< -normalize(towardViewer)
    double sigmaDepth_ = 0.0; ///< sigma x the box's half depth along d
};

/// The same as a snapshot key.
inline ViewId nearestLadderView(int n, glm::dvec3 towardViewer) {
    return viewIdOf(nearestLatticePoint(n, towardViewer));
}
/// A view with its unit vector.
struct DirectedView {
    ViewId id;
    glm::dvec3 direction{0.0, 0.0, 1.0}; ///< viewDirection(id)
};
/// nearestLadderView and its viewDirection, both read from the search's table where n has one
/// (n <= 64: no gcd and no square root per call); the same values.
DirectedView nearestDirectedLadderView(int n, glm::dvec3 towardViewer);

} // namespace voxtier
