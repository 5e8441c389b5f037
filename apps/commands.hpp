#pragma once
// Each CLI subcommand registers itself on the root CLI11 app; apps/main.cpp lists them.
#include <CLI/CLI.hpp>

namespace voxtier::cli {

void addRenderCommand(CLI::App& app);
void addInfoCommand(CLI::App& app);
void addBakeCommand(CLI::App& app);
void addBenchCommand(CLI::App& app); ///< `bench near` (apps/cmd_bench_near.cpp)
void addBenchEditsCommand(CLI::App& bench); ///< `bench edits` (apps/cmd_bench_edits.cpp)

} // namespace voxtier::cli
