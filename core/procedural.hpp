#pragma once
// Procedural test models. Tests in every module reason about these voxel by voxel, so each
// layout below is exact and part of the contract: change one and you change every test that
// counts its pixels.
//
// All generators but the tank return a single-frame model whose palette is `proceduralPalette()`
// and whose name is the generator's name ("box", "sphere", "arrow", "shell", "voxel"). The tank
// (the bench's "tank army") is animated, seeded and has its own palette. Sizes outside
// 1..Limits::kMaxModelDim per axis throw InputError (from VoxelGrid), like a bad .vox would.
// Voxel coordinates are voxel space (CONTRACT.md §2: Z-up, x fastest in memory).
#include "core/voxel_model.hpp"

#include <glm/glm.hpp>

#include <cstdint>
#include <memory>

namespace voxtier {

/// Palette indices used by the procedural models (see proceduralPalette()).
namespace proc_index {
inline constexpr std::uint8_t kRed = 1;    ///< arrow shaft, default for solids
inline constexpr std::uint8_t kGreen = 2;  ///< arrow head
inline constexpr std::uint8_t kBlue = 3;   ///< arrow fin (+Z)
inline constexpr std::uint8_t kYellow = 4; ///< arrow stub (+Y)
inline constexpr std::uint8_t kMagenta = 5;
inline constexpr std::uint8_t kCyan = 6;
inline constexpr std::uint8_t kOrange = 7;
inline constexpr std::uint8_t kViolet = 8;
} // namespace proc_index

/// The shared palette of every procedural model:
/// - 0: transparent black (index 0 is "empty" and never drawn);
/// - 1..8: distinct saturated colours: red (230,40,40), green (40,200,60), blue (50,90,230),
///   yellow (240,210,40), magenta (220,50,200), cyan (40,200,220), orange (245,130,30),
///   violet (140,60,230);
/// - 9..255: a gradient (i, 255 - i, 128), so 254 = (254,1,128) and 255 = (255,0,128).
/// Every entry 1..255 is opaque (alpha 255) and distinct from every other entry and from the
/// outline black, so an image pixel identifies its palette index unambiguously (unlit).
const Palette& proceduralPalette();

/// A solid box: every voxel of `size` set to `index`. solidCount = size.x * size.y * size.z.
std::shared_ptr<VoxelModel> makeBox(glm::ivec3 size, std::uint8_t index = proc_index::kRed);

/// A voxelised ball of `radius` (1..128) in a (2r)^3 grid: voxel (x, y, z) is set to `index`
/// iff its centre (x+½, y+½, z+½) lies within distance r of the grid centre (r, r, r)
/// (boundary included), evaluated exactly in integers:
/// (2x+1-2r)² + (2y+1-2r)² + (2z+1-2r)² <= 4r². Symmetric under every axis flip and swap.
std::shared_ptr<VoxelModel> makeSphere(int radius, std::uint8_t index = proc_index::kRed);

/// An asymmetric model whose orientation is readable from every view: no rotation or mirror
/// maps it onto itself. `length` L is 8..256; dims = (L, 5, 5); the shaft axis is the line
/// y = 2, z = 2. Exact layout (all boxes half-open [min, max)):
/// - shaft, index 1 (red):    x in [0, L-3),        y = 2,        z = 2         (L-3 voxels)
/// - head,  index 2 (green):  a stepped pyramid pointing +X:
///                            x = L-3: y, z in [0, 5)  (5x5 = 25)
///                            x = L-2: y, z in [1, 4)  (3x3 =  9)
///                            x = L-1: y = 2, z = 2    (1)
/// - fin,   index 3 (blue):   x in [0, 3),          y = 2,        z in [3, 5)   (6 voxels, +Z)
/// - stub,  index 4 (yellow): x = L/2 (integer div), y in [3, 5),  z = 2         (2 voxels, +Y)
/// solidCount = L + 40 (56 for the default L = 16). Nothing occupies y < 2 except the head,
/// nothing occupies z < 2 except the head.
std::shared_ptr<VoxelModel> makeArrow(int length = 16);

/// A hollow box: voxel p is set to `index` iff it lies within `thickness` (>= 1) of a face,
/// i.e. p.a < t or p.a >= size.a - t on some axis a. solidCount = volume - Π max(0, size.a - 2t);
/// a thickness of at least half the smallest side gives a solid box.
std::shared_ptr<VoxelModel> makeShell(glm::ivec3 size, int thickness = 1,
                                      std::uint8_t index = proc_index::kRed);

/// A 1x1x1 model holding one voxel of `index`.
std::shared_ptr<VoxelModel> makeSingleVoxel(std::uint8_t index = proc_index::kRed);

/// The bench's tank: an animated model of `frames` (1..Limits::kMaxFramesPerModel)
/// frames, dims `size` (default 32x32x16, each axis 8..256), front towards +X, up +Z. Parts:
/// two tracks along X at the low and high Y sides, a hull on and between them with a sloped
/// front, a round turret, a barrel, a hatch and an antenna (at the high-Y rear, so no mirror
/// maps the tank onto itself). `seed` picks the type: hull and turret colours, track width and
/// height, hull height, turret radius and position, barrel length and starting yaw. Frame f
/// rolls the track treads by f voxels and turns the turret (with its barrel and hatch) by
/// 360°·f/frames, so no two frames are equal. Same seed, size and frames: same voxels (a
/// splitmix64 stream, independent of the standard library). Name "tank", palette
/// `tankPalette()`. Solid voxels reach the grid's front, back (tracks), bottom (tracks) and top
/// (antenna) faces.
std::shared_ptr<VoxelModel> makeTank(std::uint64_t seed = 1, int frames = 8,
                                     glm::ivec3 size = {32, 32, 16});

/// Palette of the tank: `proceduralPalette()` with entries 32..47 replaced by military tones
/// (hull colours 32..39, tracks, wheels, barrel, hatch, grille, antenna 40..46, turret trim
/// 47). Every entry 1..255 stays opaque, distinct and different from the outline black.
const Palette& tankPalette();

} // namespace voxtier
