// Paths the tests read from: the project's scenes and data, the external scenes, the nrad executable.
#pragma once

#include <string>

namespace nrad::test {

std::string sourcePath(const std::string& relative);  // inside the project
std::string externalScene(const std::string& relative);  // inside ../shared/scenes-external
std::string nradExecutable();
std::string temporaryDirectory();  // a fresh folder per call, removed at exit

}  // namespace nrad::test
