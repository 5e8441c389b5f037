// loadScene and loadSceneText (core/scene_loader.hpp): the file read, the text parsed with JSON
// paths tracked (core/detail/json_tracked.hpp), the document built into a Scene by
// loadSceneJson (core/scene_builder.cpp).
#include "core/scene_loader.hpp"

#include "core/detail/json_tracked.hpp"
#include "core/error.hpp"

#include <fstream>
#include <sstream>

namespace voxtier {

namespace fs = std::filesystem;

Scene loadScene(const fs::path& file) {
    const std::string name = file.string();
    std::error_code ec;
    const auto st = fs::status(file, ec);
    if (!fs::exists(st)) throw InputError(name, "", "file not found");
    if (fs::is_directory(st)) throw InputError(name, "", "is a directory, not a scene file");
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError(name, "", "cannot open the file for reading");
    std::ostringstream buf;
    buf << in.rdbuf();
    if (in.bad()) throw InputError(name, "", "read error");
    return loadSceneText(buf.str(), name, file.parent_path());
}

Scene loadSceneText(const std::string& text, const std::string& sourceName,
                    const fs::path& baseDir) {
    const nlohmann::json j = detail::parseTracked(text, sourceName);
    return loadSceneJson(j, sourceName, baseDir);
}

} // namespace voxtier
