#pragma once
// A contact sheet of baked snapshots for a person to look at: one tile per view, upright as
// baked (lattice up = image up), lit with a fixed light, each labelled with its position in the
// list (the view index when a whole set is drawn in order) and its lattice direction.
#include "core/image.hpp"
#include "core/voxel_model.hpp"
#include "impostor_cache/snapshot.hpp"

#include <memory>
#include <vector>

namespace voxtier {

struct ContactSheetOptions {
    int columns = 0;         ///< 0: about square
    int maxTilePixels = 200; ///< cells are magnified by an integer factor to about this size
    Rgba8 background = packRgba(40, 44, 52);
    Rgba8 tileBackground = packRgba(70, 76, 88);
    Rgba8 text = packRgba(235, 235, 235);
};

Image makeContactSheet(const std::vector<std::shared_ptr<const Snapshot>>& snapshots,
                       const Palette& palette, const ContactSheetOptions& options = {});

} // namespace voxtier
