// `voxtier info MODEL.vox` (placeholder until the .vox reader lands).
#include "apps/commands.hpp"

namespace voxtier::cli {
void addInfoCommand(CLI::App& app) { app.add_subcommand("info", "Describe a .vox file"); }
} // namespace voxtier::cli
