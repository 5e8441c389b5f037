#pragma once
// Each CLI subcommand registers itself on the root CLI11 app; apps/main.cpp lists them.
#include <CLI/CLI.hpp>

namespace voxtier::cli {

void addRenderCommand(CLI::App& app);
void addInfoCommand(CLI::App& app);
void addBakeCommand(CLI::App& app);
/// `check SCENES...`: Vulkan near tier == CPU reference, in memory (apps/cmd_check.cpp).
void addCheckCommand(CLI::App& app);
/// `bench [SCENES...]` and its subcommands (apps/bench/cmd_bench.cpp registers them all).
void addBenchCommand(CLI::App& app);
void addBenchNearCommand(CLI::App& bench);  ///< `bench near` (apps/bench/cmd_bench_near.cpp)
void addBenchEditsCommand(CLI::App& bench); ///< `bench edits` (apps/bench/cmd_bench_edits.cpp)

} // namespace voxtier::cli
