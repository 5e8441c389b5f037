#pragma once
// Error channels (docs/STYLE.md): untrusted input -> InputError naming file, field and reason;
// API misuse -> assert; Vulkan -> VulkanError through VK_CHECK (device/vulkan_check.hpp);
// Embree -> EmbreeError through the device's error callback and one check after each build
// (impostor_cache/embree_error.hpp).
#include <cstddef>
#include <stdexcept>
#include <string>

namespace voxtier {

/// Bad user input: a malformed .vox, scene file, CLI argument or a limit exceeded.
/// what() is one line: "<file>: <field>: <reason>" (field may be empty).
class InputError : public std::runtime_error {
  public:
    InputError(std::string file, std::string field, std::string reason);

    const std::string& file() const { return file_; }
    const std::string& field() const { return field_; }
    const std::string& reason() const { return reason_; }

  private:
    std::string file_, field_, reason_;
};

/// A resource limit of the renderer (image size, entity count, cache budget, model size).
struct Limits {
    static constexpr int kMaxModelDim = 256;        ///< voxels per axis (MagicaVoxel's own limit)
    static constexpr int kMaxImageDim = 16384;      ///< pixels per axis of an output image
    static constexpr int kMaxEntities = 1'000'000;  ///< entities in one scene after crowds expand
    static constexpr int kMaxFramesPerModel = 4096; ///< animation frames of one model
    /// Voxel cells of all models and frames of one scene (one byte each on the CPU, again in the
    /// near tier's atlas). Per-model limits alone still let 4096 frames of a 256³ tank, or many
    /// entries of one big file, ask for 64 GB; this turns that into an error before allocation.
    static constexpr std::size_t kMaxSceneVoxelCells = std::size_t(1) << 30;
    /// Virtual pixels per voxel. A far snapshot has (2σ|c|)² cells: σ = 16 keeps the largest
    /// (256³) model's snapshot near 100 MB instead of letting a typo allocate terabytes.
    static constexpr double kMaxSigma = 16.0;
    /// `sigma` if it is in (0, kMaxSigma], else InputError(file, field, reason).
    static double checkedSigma(double sigma, const std::string& file, const std::string& field);
};

} // namespace voxtier
