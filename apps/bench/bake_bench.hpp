#pragma once
// `voxtier bake --bench [MODEL.vox...]` (an option of `bake`, apps/cmd_bake.cpp, measured here):
// the Embree bake against the near kernel's scalar DDA over the same rays, side by side in one
// run (medians over repeats), plus the memory one cached model costs.
#include "core/sprite.hpp"
#include "core/view_set.hpp"

#include <memory>
#include <string>
#include <vector>

namespace voxtier::cli {

struct BakeBenchModel {
    std::string name;
    std::shared_ptr<VoxelModel> model;
};

struct BakeBenchArgs {
    std::vector<BakeBenchModel> models; ///< none: voxelised balls, 16^3..128^3
    ViewSet views = ViewSet::Cube26;
    double sigma = 1.0;
    int repeats = 5;
};

/// Prints, per model, the scalar DDA and every Embree configuration (ms, Mrays/s, speed-up) and
/// whether they bake identical snapshots, then the memory of one cached model.
void runBakeBench(const BakeBenchArgs& a);

} // namespace voxtier::cli
