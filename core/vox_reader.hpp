#pragma once
// MagicaVoxel .vox reader, written from the public format description (ephtracy/voxel-model:
// MagicaVoxel-file-format-vox.txt and -vox-extension.txt). Untrusted input: every failure is
// an InputError naming the file, the chunk (as the field) and the reason; never a crash.
#include "core/voxel_model.hpp"

#include <glm/glm.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace voxtier {

/// One shape instance reached by walking the scene graph from the root transform (a node
/// with several parents yields one instance per path, DESIGN of ogt_vox / MANIFEST.md).
struct VoxInstance {
    int model = 0;                  ///< index into VoxFile::models
    glm::mat<3, 3, int> rotation{1};///< voxel-space signed permutation (det may be -1: mirror)
    glm::ivec3 translation{0};      ///< world voxel position of the model's pivot floor(size/2)
    bool hidden = false;            ///< a node on the path has _hidden = 1 (or its layer is hidden)
    std::string name;               ///< _name of the nearest named transform, if any
    int frameIndex = 0;             ///< _f of the transform keyframe used (animation), 0 if none
};

struct VoxFile {
    std::string source;
    int version = 0;
    std::vector<VoxelGrid> models;  ///< SIZE/XYZI pairs, in file order
    Palette palette;                ///< RGBA chunk, or the default palette
    bool hasPaletteChunk = false;
    /// Chunk ids in the order first seen, with how often each occurred (MAIN included).
    std::vector<std::pair<std::string, int>> chunkCounts;
    std::vector<VoxInstance> instances; ///< flattened scene graph; empty when there is none
    std::optional<std::pair<int, int>> animRange; ///< META _anim_range
    std::size_t totalVoxels() const;
};

VoxFile parseVox(std::span<const std::uint8_t> bytes, const std::string& source);
VoxFile readVoxFile(const std::filesystem::path& file);

} // namespace voxtier
