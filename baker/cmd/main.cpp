// main(): `nrad <subcommand>`; maps every failure to a message on stderr and a documented exit code.
#include <cstdio>
#include <exception>
#include <map>
#include <string>

#include "baker/cmd/commands.h"

int main(int argc, char** argv) {
    CLI::App app{"nrad: bake glTF scenes into neural radiance assets, render them, and validate them"};
    app.require_subcommand(1);
    app.set_version_flag("--version", "nrad 0.1.0");
    std::map<std::string, std::function<int()>> commands = {{"bake", nrad::addBakeCommand(app)},
                                                            {"render", nrad::addRenderCommand(app)},
                                                            {"info", nrad::addInfoCommand(app)},
                                                            {"validate", nrad::addValidateCommand(app)},
                                                            {"merge", nrad::addMergeCommand(app)}};
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        std::fprintf(stderr, "nrad: %s\nRun 'nrad --help' for usage.\n", e.what());
        return nrad::kExitUsage;
    }
    try {
        for (CLI::App* sub : app.get_subcommands()) return commands.at(sub->get_name())();
    } catch (const std::exception& e) {
        std::fprintf(stderr, "nrad: internal error: %s\n", e.what());
        return nrad::kExitInternal;
    }
    return nrad::kExitUsage;
}
