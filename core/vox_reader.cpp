// Placeholder: implemented by the .vox reader work.
#include "core/vox_reader.hpp"

#include "core/error.hpp"

namespace voxtier {
std::size_t VoxFile::totalVoxels() const {
    std::size_t n = 0;
    for (const auto& m : models) n += m.solidCount();
    return n;
}
VoxFile parseVox(std::span<const std::uint8_t>, const std::string& source) {
    throw InputError(source, "", "the .vox reader is not implemented yet");
}
VoxFile readVoxFile(const std::filesystem::path& file) { return parseVox({}, file.string()); }
} // namespace voxtier
