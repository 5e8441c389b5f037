// Renders a procedural model through the installed voxtier (the CPU reference, no GPU needed),
// checks the entity covers pixels, and writes the frame through the installed image_files module
// (a .pam: the library-free format; the file must be the header plus 4 bytes a pixel). Includes
// the installed headers as a consumer does, <voxtier/module/header.hpp>.
#include <voxtier/compose/frame.hpp>
#include <voxtier/core/model_view.hpp>
#include <voxtier/core/procedural.hpp>
#include <voxtier/image_files/image_files.hpp>

#include <cstdio>
#include <filesystem>
#include <string>
#include <unistd.h>

int main() {
    voxtier::ModelView view;
    view.width = 96;
    view.height = 72;
    voxtier::Scene scene = voxtier::sceneForModel(voxtier::makeArrow(16), view);
    voxtier::FrameOptions options;
    options.nearBackend = voxtier::NearBackend::Reference;
    voxtier::FrameRenderer renderer(scene, options);
    const auto reference = renderer.render(0.0, voxtier::RenderMode::Reference);
    const std::size_t drawn = reference.image.countEntity(0);
    std::printf("consumer: %zu pixels of the arrow drawn\n", drawn);
    const std::filesystem::path pam = std::filesystem::temp_directory_path() /
                                      ("voxtier_consumer_" + std::to_string(getpid()) + ".pam");
    voxtier::writeImage(pam, reference.image);
    const auto bytes = std::filesystem::file_size(pam);
    std::filesystem::remove(pam);
    std::printf("consumer: %ju bytes of .pam\n", std::uintmax_t(bytes));
    return drawn > 100 && bytes == 67 + 96 * 72 * 4 ? 0 : 1;
}
