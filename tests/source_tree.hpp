#pragma once
// Files of the source tree in tests: a path by its name relative to the repository root, and
// every model of the .vox files shipped in scenes/vox/.
#include "core/vox_reader.hpp"
#include "core/voxel_model.hpp"

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace voxtier::test {

/// A file of the source tree (scenes, models) by its path relative to the repository root.
inline std::string sourcePath(const std::string& rel) {
    return std::string(VOXTIER_SOURCE_DIR) + "/" + rel;
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

} // namespace voxtier::test
