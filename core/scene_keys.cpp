#include "core/scene_keys.hpp"

#include <stdexcept>
#include <string>

namespace voxtier {

const std::vector<SceneObjectKeys>& sceneObjectKeys() {
    static const std::vector<SceneObjectKeys> table = {
        {"scene",
         {"$schema", "description", "voxel_size", "sigma", "view_mode", "background", "camera",
          "camera_path", "light", "ground", "selector", "models", "entities", "crowds",
          "vox_scenes", "edits"}},
        {"camera", {"position", "target", "up", "fov_y", "size", "near"}},
        {"camera_path", {"fps", "keys"}},
        {"camera_key", {"time", "position", "target", "up", "fov_y"}},
        {"light", {"direction", "ambient", "diffuse"}},
        {"ground", {"height", "spacing", "line_width", "fade_distance", "color", "line_color"}},
        {"selector",
         {"metric", "near_at", "far_at", "view_hysteresis_deg", "crossfade_frames", "view_set",
          "budget_vpx", "ladder_cap", "max_bakes_per_frame", "snapshot_scale"}},
        {"vox_model", {"name", "vox", "model", "frames"}},
        {"box_model", {"name", "generator", "size", "index", "color"}},
        {"sphere_model", {"name", "generator", "radius", "index", "color"}},
        {"arrow_model", {"name", "generator", "length"}},
        {"shell_model", {"name", "generator", "size", "thickness", "index", "color"}},
        {"voxel_model", {"name", "generator", "index", "color"}},
        {"tank_model", {"name", "generator", "seed", "frames", "size"}},
        {"entity",
         {"model", "position", "rotation_deg", "quaternion", "scale", "anchor", "frame", "fps",
          "name"}},
        {"grid_crowd",
         {"models", "layout", "count", "seed", "random_yaw", "scale", "name", "fps", "random_frame",
          "origin", "spacing", "columns"}},
        {"random_crowd",
         {"models", "layout", "count", "seed", "random_yaw", "scale", "name", "fps", "random_frame",
          "area", "y"}},
        {"crowd_area", {"min", "max"}},
        {"vox_scene", {"vox", "position", "scale", "include_hidden"}},
        {"set_edit", {"frame", "model", "model_frame", "op", "at", "index"}},
        {"fill_edit", {"frame", "model", "model_frame", "op", "min", "max", "index"}},
        {"clear_edit", {"frame", "model", "model_frame", "op", "min", "max"}},
    };
    return table;
}

const std::vector<std::string_view>& sceneKeysOf(std::string_view object) {
    for (const SceneObjectKeys& o : sceneObjectKeys())
        if (o.object == object) return o.keys;
    throw std::logic_error("no scene object kind '" + std::string(object) + "'");
}

} // namespace voxtier
