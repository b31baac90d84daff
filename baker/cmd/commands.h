// The `nrad` subcommands and the exit codes they share (documented in docs/usage.md).
#pragma once

#include <CLI/CLI.hpp>

namespace nrad {

enum ExitCode : int {
    kExitOk = 0,
    kExitInternal = 1,  // a bug or an unexpected failure
    kExitUsage = 2,  // bad flags or flag values
    kExitBadInput = 3,  // the scene (or another input file) is unreadable or invalid
    kExitIo = 4,  // an output could not be written
};

// Each registers its subcommand; the returned callback runs it and returns an exit code.
std::function<int()> addRenderCommand(CLI::App& app);
std::function<int()> addBakeCommand(CLI::App& app);
std::function<int()> addInfoCommand(CLI::App& app);

}  // namespace nrad
