// The validation report: images (EXR and PNG), report.json, convergence.csv, SVG plots and report.html,
// all written atomically into one folder.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "baker/validate/validate.h"

namespace nrad {

struct PlotSeries {
    std::string name;
    std::string colour;  // CSS colour
    std::vector<std::pair<double, double>> points;  // (x, y), both > 0
    bool line = true;  // else markers only
};

// A log-log plot as a self-contained SVG document. Non-positive or non-finite points are left out.
std::string svgLogLogPlot(const std::string& title, const std::string& xLabel, const std::string& yLabel,
                          const std::vector<PlotSeries>& series, int width = 640, int height = 420);

// The bake's held-out error against training time, aggregated over voxels from `nrad bake --stats`: at
// every time any voxel recorded a point, the mean and the median over voxels of each voxel's latest
// held-out relMSE (voxels train in parallel, each from its own t = 0). Empty if the stats have no curves.
struct BakeCurvePoint {
    double seconds = 0.0, meanRelMse = 0.0, medianRelMse = 0.0;
};
std::vector<BakeCurvePoint> bakeTrainingCurve(const nlohmann::json& bakeStats);

// Everything the report states, as JSON (report.json).
nlohmann::json reportJson(const ValidationResult& r, const nlohmann::json& bakeStats);

// Writes the report into `dir` (created if needed); returns the path of report.html. Throws IoError.
std::string writeReport(const ValidationResult& r, const nlohmann::json& bakeStats, const std::string& dir);

// Whether the reference is black (every channel of every pixel below kBlackRadiance, 20 stops under the default
// sky's radiance 1): then there is no error to compare, and an equal-error time (1e-13 s) would mislead.
constexpr float kBlackRadiance = 1e-6f;
bool referenceIsBlack(const ValidationResult& r);
extern const char* const kNoLightToCompare;

}  // namespace nrad
