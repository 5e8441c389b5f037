// `voxtier info MODEL.vox [--json]`: what the .vox reader found in a file. The text form is
// for people; --json is for scripts and tests. A bad file throws InputError, which main.cpp
// prints as one line with exit status 1.
#include "apps/commands.hpp"
#include "core/error.hpp"
#include "core/vox_reader.hpp"

#include <nlohmann/json.hpp>

#include <cctype>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>

namespace voxtier::cli {

namespace {

struct InfoOptions {
    std::string file;
    bool json = false;
};

std::string sizeText(glm::ivec3 d) {
    return std::to_string(d.x) + "x" + std::to_string(d.y) + "x" + std::to_string(d.z);
}

std::size_t hiddenInstances(const VoxFile& vox) {
    std::size_t n = 0;
    for (const auto& inst : vox.instances) n += inst.hidden ? 1 : 0;
    return n;
}

bool hasSceneGraph(const VoxFile& vox) {
    for (const auto& [id, count] : vox.chunkCounts)
        if (id == "nTRN" || id == "nGRP" || id == "nSHP") return true;
    return false;
}

const char* paletteSource(const VoxFile& vox) {
    return vox.hasPaletteChunk ? "RGBA chunk" : "default palette";
}

void printJson(const VoxFile& vox) {
    // ordered_json keeps the chunks in file order, like the text form.
    nlohmann::ordered_json j;
    j["file"] = vox.source;
    j["version"] = vox.version;
    auto& models = j["models"] = nlohmann::ordered_json::array();
    for (const auto& m : vox.models) {
        const glm::ivec3 d = m.dims();
        models.push_back({{"size", {d.x, d.y, d.z}}, {"voxels", m.solidCount()}});
    }
    j["total_voxels"] = vox.totalVoxels();
    j["palette"] = paletteSource(vox);
    auto& chunks = j["chunks"] = nlohmann::ordered_json::object();
    for (const auto& [id, count] : vox.chunkCounts) chunks[id] = count;
    j["instances"] = vox.instances.size();
    j["hidden_instances"] = hiddenInstances(vox);
    j["anim_range"] = vox.animRange
                          ? nlohmann::ordered_json{vox.animRange->first, vox.animRange->second}
                          : nlohmann::ordered_json(nullptr);
    // The path is the only text not produced by the reader's escaping; it need not be UTF-8.
    std::cout << j.dump(2, ' ', false, nlohmann::ordered_json::error_handler_t::replace) << '\n';
}

void printText(const VoxFile& vox) {
    std::cout << "file:         " << vox.source << '\n'
              << "version:      " << vox.version << '\n'
              << "models:       " << vox.models.size() << '\n';
    for (std::size_t i = 0; i < vox.models.size(); ++i)
        std::cout << "  model " << i << ": " << sizeText(vox.models[i].dims()) << ", "
                  << vox.models[i].solidCount() << " voxels\n";
    std::cout << "total voxels: " << vox.totalVoxels() << '\n'
              << "palette:      " << paletteSource(vox) << '\n'
              << "chunks:       ";
    for (std::size_t i = 0; i < vox.chunkCounts.size(); ++i)
        std::cout << (i ? ", " : "") << vox.chunkCounts[i].first << " "
                  << vox.chunkCounts[i].second;
    std::cout << '\n';
    std::cout << "instances:    " << vox.instances.size() << " (" << hiddenInstances(vox)
              << " hidden)" << (hasSceneGraph(vox) ? "" : ", no scene graph") << '\n';
    if (vox.animRange)
        std::cout << "anim range:   " << vox.animRange->first << ".." << vox.animRange->second
                  << '\n';
}

/// A scene file given to info would fail on the .vox magic ("not a MagicaVoxel .vox file (magic
/// '{\x0a  ')"), which tells a user nothing: say what the file is and what reads it.
void rejectSceneFile(const std::string& file) {
    std::string ext = std::filesystem::path(file).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    std::ifstream in(file, std::ios::binary);
    char first = 0;
    while (in.get(first) && std::isspace(static_cast<unsigned char>(first))) {
    }
    if (ext == ".json" || (in && first == '{'))
        throw InputError(file, "",
                         "is a scene file (JSON), not a MagicaVoxel .vox file: `voxtier render " +
                             file +
                             "` draws it (and names any error in it); `voxtier info` "
                             "describes .vox files, such as the models a scene names");
}

} // namespace

void addInfoCommand(CLI::App& app) {
    auto* cmd = app.add_subcommand("info", "Describe a MagicaVoxel .vox file");
    auto options = std::make_shared<InfoOptions>();
    cmd->add_option("file", options->file, "the .vox file")->required()->check(CLI::ExistingFile);
    cmd->add_flag("--json", options->json, "print JSON instead of text");
    cmd->callback([options] {
        rejectSceneFile(options->file);
        const VoxFile vox = readVoxFile(options->file);
        if (options->json)
            printJson(vox);
        else
            printText(vox);
    });
}

} // namespace voxtier::cli
