#include "apps/commands.hpp"

namespace voxtier::cli {
void addRenderCommand(CLI::App& app) { app.add_subcommand("render", "Render a scene or a .vox model"); }
} // namespace voxtier::cli
