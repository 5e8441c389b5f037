// libFuzzer target: the scene loader on arbitrary text. Relative .vox paths resolve against
// the repository's scenes/ folder, so valid inputs can reach the .vox reader too.
#include "core/error.hpp"
#include "core/scene_loader.hpp"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    try {
        const voxtier::Scene s = voxtier::loadSceneText(text, "fuzz.json", VOXTIER_SCENES_DIR);
        (void)s.entities.size();
    } catch (const voxtier::InputError&) {
    }
    return 0;
}
