// Paths the tests read from: the project's scenes and data, the external scenes, the nrad executable.
#pragma once

#include <string>

namespace nrad::test {

std::string sourcePath(const std::string& relative);  // inside the project
std::string externalScene(const std::string& relative);  // inside ../shared/scenes-external
std::string nradExecutable();
std::string temporaryDirectory();  // a fresh folder per call, removed at exit

// A shell command's exit code (-1: it did not exit) and its stdout and stderr together.
struct CommandResult {
    int exitCode;
    std::string output;
};
CommandResult runCommand(const std::string& command);

std::string fileBytes(const std::string& path);  // empty if the file cannot be read

}  // namespace nrad::test
