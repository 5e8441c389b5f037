#pragma once
// MagicaVoxel .vox reader, written from the public format description (ephtracy/voxel-model:
// MagicaVoxel-file-format-vox.txt and -vox-extension.txt). Untrusted input: every failure is
// an InputError naming the file, the chunk (as the field) and the reason; never a crash.
#include "core/error.hpp"
#include "core/voxel_model.hpp"

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace voxtier {

/// One shape instance reached by walking the scene graph from the root transform (a node
/// with several parents yields one instance per path, as ogt_vox does; scenes/vox/MANIFEST.md).
struct VoxInstance {
    int model = 0;                   ///< index into VoxFile::models
    glm::mat<3, 3, int> rotation{1}; ///< voxel-space signed permutation (det may be -1: mirror)
    glm::ivec3 translation{0};       ///< world voxel position of the model's pivot floor(size/2)
    bool hidden = false; ///< a node on the path has _hidden = 1 (or its layer is hidden)
    std::string name;    ///< _name of the nearest named transform, if any
    int frameIndex = 0;  ///< _f of the transform keyframe used (animation), 0 if none
};

struct VoxFile {
    std::string source;
    int version = 0;
    std::vector<VoxelGrid> models; ///< SIZE/XYZI pairs, in file order
    Palette palette;               ///< RGBA chunk, or the default palette
    bool hasPaletteChunk = false;
    /// Chunk ids in the order first seen, with how often each occurred (MAIN included, then
    /// MAIN's direct children; bytes outside printable ASCII are written as \xNN).
    std::vector<std::pair<std::string, int>> chunkCounts;
    std::vector<VoxInstance> instances; ///< flattened scene graph; empty when there is none
    std::optional<std::pair<int, int>> animRange; ///< META _anim_range
    std::size_t totalVoxels() const;
};

/// Resource bounds of one read. A few hundred bytes of .vox can declare gigabytes of dense
/// grids or an exponential number of instancing paths, so every allocation the file asks for
/// is checked against these; exceeding one is an InputError, not an out-of-memory. The
/// defaults accept every real file we know of; a fuzzer may pass smaller ones.
struct VoxReadLimits {
    /// Sum over all models of sx*sy*sz (= bytes of dense grids). 32 full 256^3 models.
    std::size_t maxVoxelCells = std::size_t(1) << 29;
    /// Flattened scene-graph instances (one per path from the root to a shape).
    std::size_t maxInstances = std::size_t(Limits::kMaxEntities);
    /// Node visits while flattening (bounds the work of DAGs that expand to nothing).
    std::size_t maxSceneNodeVisits = std::size_t(1) << 22;
    /// Bytes readVoxFile accepts before reading anything.
    std::uintmax_t maxFileBytes = std::uintmax_t(1) << 30;
};

/// Every failure throws InputError(source, field, reason) with field = the chunk, e.g.
/// "XYZI[2]" (third XYZI chunk) or "nTRN node 5"; reasons include the byte offset.
VoxFile parseVox(std::span<const std::uint8_t> bytes, const std::string& source,
                 const VoxReadLimits& limits = {});
/// Reads the whole file and parses it; I/O failures are InputErrors too.
VoxFile readVoxFile(const std::filesystem::path& file, const VoxReadLimits& limits = {});

/// Decodes the packed `_r` rotation byte of the .vox scene graph (vox-extension (c)): bits 0-1
/// = column of the non-zero entry of row 0, bits 2-3 = of row 1 (row 2 takes the remaining
/// column), bits 4/5/6 = row 0/1/2 is negative; bit 7 is unused. glm is column-major, so
/// entry (row r, column c) is `m[c][r]`. nullopt when both indices are equal or one is 3.
std::optional<glm::mat<3, 3, int>> decodeVoxRotation(unsigned bits);

} // namespace voxtier
