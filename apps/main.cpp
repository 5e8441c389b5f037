// voxtier: render voxel-entity scenes across LOD tiers. See README.md.
#include "apps/commands.hpp"
#include "core/detail/json_fields.hpp"
#include "core/error.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <exception>
#include <malloc.h>
#include <string>
#include <vector>

namespace {

/// " (did you mean 'render'?)" when the first argument is a misspelt subcommand.
std::string subcommandSuggestion(const CLI::App& app, int argc, char** argv) {
    if (argc < 2 || argv[1][0] == '-') return "";
    std::vector<std::string> names;
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
        names.push_back(sub->get_name());
    for (const std::string& n : names)
        if (n == argv[1]) return "";
    const std::string s = voxtier::detail::suggestion(argv[1], names);
    return s.rfind(" (did you mean", 0) == 0 ? s : "";
}

/// Every option name `cmd` takes ("--size", "-o"), its option groups' included.
void optionNames(const CLI::App& cmd, std::vector<std::string>& names) {
    for (const CLI::Option* o : cmd.get_options()) {
        for (const std::string& n : o->get_lnames()) names.push_back("--" + n);
        for (const std::string& n : o->get_snames()) names.push_back("-" + n);
    }
    for (const CLI::App* sub : cmd.get_subcommands([](const CLI::App*) { return true; }))
        if (dynamic_cast<const CLI::Option_group*>(sub)) optionNames(*sub, names);
}

/// "unknown option '--sizes' for render (did you mean '--size'?)" for the first argument that
/// looks like an option and that the subcommand does not take; "" when there is none (CLI11's
/// "arguments were not expected" then stands). A value such as "-30,20" is not an option.
std::string unknownOption(const CLI::App& app, int argc, char** argv) {
    if (argc < 2) return "";
    const CLI::App* cmd = &app;
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
        if (sub->get_name() == argv[1]) cmd = sub;
    std::vector<std::string> names;
    optionNames(app, names);
    if (cmd != &app) optionNames(*cmd, names);
    for (int i = cmd == &app ? 1 : 2; i < argc; ++i) {
        const std::string arg = argv[i];
        if (arg.size() < 2 || arg[0] != '-' || std::isdigit(static_cast<unsigned char>(arg[1])) ||
            arg[1] == '.' || arg == "--")
            continue;
        const std::string name = arg.substr(0, arg.find('='));
        if (std::find(names.begin(), names.end(), name) != names.end()) continue;
        const std::string s = voxtier::detail::suggestion(name, names);
        return "unknown option '" + name + "'" +
               (cmd != &app ? " for " + cmd->get_name() : std::string()) +
               (s.rfind(" (did you mean", 0) == 0 ? s : std::string());
    }
    return "";
}

} // namespace

int main(int argc, char** argv) {
    // Every frame allocates its image (12 bytes per pixel: colour, depth, id; 6 MB at 960x540).
    // By default glibc serves blocks that large with mmap, or trims them off the heap top when
    // they are freed, so every frame page-faults its image back in: 1,500 faults, ~11 ms per
    // 960x540 frame on the bench machine, more than the far blit itself (`voxtier bench`). Keep
    // freed memory in the heap instead.
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    mallopt(M_TRIM_THRESHOLD, 512 << 20);
    CLI::App app{"voxtier: hybrid level-of-detail renderer for voxel game entities"};
    app.set_version_flag("--version", std::string("voxtier ") + VOXTIER_VERSION);
    app.require_subcommand(1);
    voxtier::cli::addRenderCommand(app);
    voxtier::cli::addInfoCommand(app);
    voxtier::cli::addBakeCommand(app);
    voxtier::cli::addBenchCommand(app);
    voxtier::cli::addCheckCommand(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        // Exit status 2: the command line itself is wrong (an unknown option, a value its
        // validator rejects, options that do not go together); every value is checked this way
        // before any work starts (apps/cli_options.hpp). Exit status 1 (below): an input file
        // is bad, or the run failed. Both are one line "voxtier: error: ..."; this one points to
        // --help, which lists the allowed values (CLI11's own printer adds a second line).
        // --help and friends print and exit 0.
        if (e.get_exit_code() == 0) return app.exit(e);
        const std::string suggestion = subcommandSuggestion(app, argc, argv);
        const std::string unknown =
            dynamic_cast<const CLI::ExtrasError*>(&e) ? unknownOption(app, argc, argv) : "";
        if (!suggestion.empty())
            std::fprintf(stderr, "voxtier: error: unknown command '%s'%s (see --help)\n", argv[1],
                         suggestion.c_str());
        else if (!unknown.empty())
            std::fprintf(stderr, "voxtier: error: %s (see --help)\n", unknown.c_str());
        else
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
