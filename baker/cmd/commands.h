// The `nrad` subcommands and the exit codes they share (documented in docs/usage.md).
#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "baker/cmd/settings_table.h"
#include "baker/scene/gltf_loader.h"
#include "baker/scene/scene.h"

namespace nrad {

enum ExitCode : int {
    kExitOk = 0,
    kExitInternal = 1,  // a bug or an unexpected failure
    kExitUsage = 2,  // bad flags or flag values
    kExitBadInput = 3,  // the scene (or another input file) is unreadable or invalid
    kExitIo = 4,  // an output could not be written
};

// Loads the scene for command `command`; on failure prints "nrad COMMAND: FILE: problem" and returns
// kExitBadInput, else kExitOk. A scene without triangles is a failure too. Unless quiet, prints the import
// summary and the importer's warnings on stderr.
int loadSceneForCommand(const char* command, const std::string& path, bool quiet, Scene& scene, const ImportLimits& limits = {});
// --insert FILE[@x,y,z] (repeatable): objects that were not in the bake placed into the loaded scene (insertObject),
// each moved so its own origin lies at x,y,z. Prints "nrad COMMAND: ..." and returns kExitUsage for a bad position,
// kExitBadInput for an object that cannot be loaded; says what was inserted unless quiet.
int insertObjectsForCommand(const char* command, const std::vector<std::string>& specs, const ImportLimits& limits, bool quiet,
                            Scene& scene);
void addInsertOption(CLI::App* cmd, std::vector<std::string>& specs);
// --max-texture-pixels and --max-triangles: what one scene may ask of the machine (ImportLimits).
void addImportOptions(CLI::App* cmd, ImportLimits& limits);
void addImportSettings(SettingsTable& t, ImportLimits& limits);  // the same, as rows of a command's settings

// Every output a command will write, checked before any work (a typo in -o must cost a second, not a bake):
// prints "nrad COMMAND: PATH: why" and returns kExitUsage for a file output that names a folder (or a folder
// output that names a file), kExitIo for one that cannot be created, else kExitOk.
int checkOutputsForCommand(const char* command, const std::vector<std::string>& files,
                           const std::vector<std::string>& folders = {});

// --look-from x,y,z --look-at x,y,z [--up x,y,z] [--fov DEG]: a perspective camera instead of the scene's; --fov
// alone changes the chosen camera's vertical field of view.
struct ViewOptions {
    std::string lookFrom, lookAt, up = "0,1,0";
    float fovDegrees = 0.0f;  // 0: keep
};
void addViewOptions(CLI::App* cmd, ViewOptions& o);

// The camera a command renders from: --look-from/--look-at if given, else scene camera `index`, or (index < 0)
// the first, or a camera framing the bounds if the scene has none; then --fov. Says which on stderr unless
// quiet. Prints "nrad COMMAND: ..." and returns kExitUsage for an index the scene does not have or a bad view.
int chooseCameraForCommand(const char* command, const Scene& scene, int index, const ViewOptions& view, bool quiet,
                           Camera& camera);
// Applies the view options to `camera` (after chooseCameraForCommand); kExitUsage with a message when bad.
int applyViewForCommand(const char* command, const ViewOptions& o, Camera& camera);

// The lighting options every command that renders shares: --environment none|r,g,b|FILE,
// --environment-intensity, --environment-rotation (degrees about +Y), --sun x,y,z (towards the sun),
// --sun-illuminance (lux), --sun-angle (angular diameter, degrees; 0 = sharp), --runtime-direct (mixed lighting:
// all | sun | comma-separated light names or indices).
struct LightingOptions {
    std::string environment;  // empty: not given
    float intensity = 1.0f;
    float rotationDegrees = 0.0f;
    std::string sun;  // empty: none
    float sunIlluminance = 100000.0f;  // lux: a clear day's sun
    float sunAngle = 0.0f;  // degrees across
    std::string runtimeDirect;  // empty: the asset holds every light's scattered light
};
void addLightingOptions(CLI::App* cmd, LightingOptions& o);
void addLightingSettings(SettingsTable& t, LightingOptions& o);  // the same, as rows of a command's settings
// The names of the lighting flags (for `given` tests) and their config keys.
bool lightingFlagsGiven(CLI::App* cmd);

// Lights the scene as the options say: a sun is added to scene.lights; the environment is the one given;
// lights are marked as drawn by the engine; a scene with no light of its own and no environment given gets the
// default sky (said on stderr unless quiet). environmentGiven: --environment (or a config's key) was given.
// Without any lighting flag and with `recordedMetadata` (an asset's META), the lighting the asset recorded is
// replayed instead. On success lightingJson holds the lighting to record in a bake's metadata. A bad value or map
// prints "nrad COMMAND: ..." and returns kExitUsage or kExitBadInput.
int applyLightingForCommand(const char* command, const LightingOptions& o, bool anyFlagGiven, bool environmentGiven,
                            bool quiet, Scene& scene, const std::string& recordedMetadata = {},
                            std::string* lightingJson = nullptr);

// validate and render --asset: refuses (kExitBadInput, naming both files) an asset whose recorded scene hash
// is not the scene's as loaded and lit, unless force. An asset without metadata cannot be checked (said on
// stderr unless quiet).
int checkAssetSceneForCommand(const char* command, const std::string& assetPath, const std::string& metadata,
                              const Scene& scene, bool force, bool quiet);

// The image size from --width and --height (0: not given): both given, or one and the other from the camera's
// aspect ratio, or the default width. kExitUsage (with a message) when a derived side would exceed 32768.
int imageSizeForCommand(const char* command, int width, int height, float aspect, int defaultWidth, int& outWidth,
                        int& outHeight);

// kExitUsage with "nrad COMMAND: WHAT needs about N GiB; this process can allocate M GiB now" when `bytes` is more
// than the process can allocate (availableMemoryBytes), else kExitOk.
int checkMemoryForCommand(const char* command, uint64_t bytes, const std::string& what);

// CLI::Range for a floating-point flag that also refuses nan and inf (CLI::Range lets NaN through: every
// comparison with it is false, and `--exposure nan` wrote a black image).
CLI::Validator finiteRange(double lo, double hi);

// The comma-separated parts of s ("" gives one empty part).
std::vector<std::string> splitCommas(const std::string& s);

// Each registers its subcommand; the returned callback runs it and returns an exit code.
std::function<int()> addRenderCommand(CLI::App& app);
std::function<int()> addBakeCommand(CLI::App& app);
std::function<int()> addInfoCommand(CLI::App& app);
std::function<int()> addValidateCommand(CLI::App& app);
std::function<int()> addMergeCommand(CLI::App& app);

}  // namespace nrad
