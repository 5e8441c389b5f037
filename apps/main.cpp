// voxtier: render voxel-entity scenes across LOD tiers. See README.md.
#include "apps/commands.hpp"
#include "core/error.hpp"

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
    CLI::App app{"voxtier: hybrid level-of-detail renderer for voxel game entities"};
    app.require_subcommand(1);
    voxtier::cli::addRenderCommand(app);
    voxtier::cli::addInfoCommand(app);
    voxtier::cli::addBakeCommand(app);
    voxtier::cli::addBenchCommand(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        // --help and friends print and exit 0; real argument errors get the same one-line form
        // as every other bad input (CLI11's own printer adds a second line).
        if (e.get_exit_code() == 0) return app.exit(e);
        std::fprintf(stderr, "voxtier: error: %s (see --help)\n", e.what());
        return 2;
    } catch (const voxtier::InputError& e) {
        std::fprintf(stderr, "voxtier: error: %s\n", e.what());
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "voxtier: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
