// The bench's scenes and their edits (apps/bench/scene_edits.hpp).
#include "apps/bench/scene_edits.hpp"

#include "core/scene_loader.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

namespace voxtier::bench {

namespace fs = std::filesystem;
using nlohmann::json;

SceneSource loadSource(const std::string& file) {
    SceneSource s;
    s.file = file;
    s.scene = loadScene(file); // validates, with the loader's one-line errors
    std::ifstream in(file);
    s.doc = json::parse(in);
    return s;
}

Scene sceneFromJson(const SceneSource& src, const json& doc) {
    return loadSceneJson(doc, src.file, fs::path(src.file).parent_path());
}

std::optional<json> withEntityCount(json doc, int total) {
    if (!doc.contains("crowds") || doc["crowds"].empty()) return std::nullopt;
    const int plain = doc.contains("entities") ? int(doc["entities"].size()) : 0;
    long long crowd = 0;
    for (const json& c : doc["crowds"]) crowd += c.value("count", 0);
    if (crowd <= 0) return std::nullopt;
    const int want = std::max(0, total - plain);
    int assigned = 0;
    for (std::size_t i = 0; i < doc["crowds"].size(); ++i) {
        json& c = doc["crowds"][i];
        const bool last = i + 1 == doc["crowds"].size();
        const int n = last ? want - assigned
                           : int(std::lround(double(c.value("count", 0)) * want / double(crowd)));
        c["count"] = std::max(0, n);
        assigned += std::max(0, n);
    }
    return doc;
}

std::optional<json> withTankSide(json doc, int side) {
    double baseSide = 0.0;
    for (json& m : doc["models"]) {
        if (m.value("generator", "") != "tank") continue;
        if (baseSide == 0.0) baseSide = m.contains("size") ? m["size"][0].get<double>() : 32.0;
        m["size"] = {side, side, std::max(8, side / 2)};
        m["frames"] = 1;
    }
    if (baseSide == 0.0) return std::nullopt;
    doc["voxel_size"] = doc.value("voxel_size", 0.1) * baseSide / side;
    for (json& c : doc["crowds"]) c.erase("fps");
    return doc;
}

} // namespace voxtier::bench
