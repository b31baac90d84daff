// Report files: JSON, CSV, SVG plots, HTML, images.
#include "baker/validate/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>

#include "baker/util/atomic_file.h"

namespace nrad {

namespace {

namespace fs = std::filesystem;

std::string fmt(const char* f, double v) {
    char b[64];
    std::snprintf(b, sizeof b, f, v);
    return b;
}

std::string escape(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '&') o += "&amp;";
        else if (c == '<') o += "&lt;";
        else if (c == '>') o += "&gt;";
        else if (c == '"') o += "&quot;";
        else o += c;
    }
    return o;
}

// JSON numbers must be finite: inf (identical images' PSNR) becomes null.
nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json metricsJson(const ImageMetrics& m) {
    return {{"rmse", num(m.rmse)}, {"relmse", num(m.relMse)}, {"psnr_db", num(m.psnr)}, {"mean_relative_error", num(m.meanRelativeError)},
            {"ssim", num(m.ssim)}, {"ssim_exposure_stops", num(m.ssimExposure)}};
}

nlohmann::json methodJson(const MethodResult& m) {
    nlohmann::json decades = nlohmann::json::array();
    for (const DecadeError& d : m.byDecade)
        decades.push_back({{"luminance_from", d.lo}, {"luminance_to", d.hi}, {"pixels", d.pixels}, {"relmse", num(d.relMse)},
                           {"relative_rms", num(d.relativeRms)}});
    nlohmann::json regions = nlohmann::json::array();
    for (size_t k = 0; k < m.byRegion.size() && k < size_t(kRegionCount); ++k)
        regions.push_back({{"region", kRegionNames[k]}, {"pixels", m.byRegion[k].pixels}, {"relmse", num(m.byRegion[k].relMse)},
                           {"share_of_image_relmse", num(m.byRegion[k].shareOfImage)}});
    return {{"name", m.name},
            {"metrics", metricsJson(m.metrics)},
            {"error_distribution", {{"worst_1_percent_share_of_relmse", num(m.distribution.worst1PercentShare)},
                                    {"median_relative_error", num(m.distribution.medianRelativeError)},
                                    {"p99_relative_error", num(m.distribution.p99RelativeError)}}},
            {"by_region", regions},
            {"what_the_eye_sees",
             {{"surface_pixels", m.surfaces.pixels},
              {"surface_relmse", num(m.surfaces.relMse)},
              {"blocks", {{"block_pixels", m.blocks.blockSize}, {"count", m.blocks.blocks}, {"relative_error_rms", num(m.blocks.rms)},
                          {"relative_error_worst", num(m.blocks.worst)}, {"worst_signed", num(m.blocks.worstSigned)},
                          {"worst_pixel", {m.blocks.worstX, m.blocks.worstY}}, {"tint_rms", num(m.blocks.tintRms)},
                          {"tint_worst", num(m.blocks.tintWorst)}, {"chroma_worst", num(m.blocks.chroma)},
                          {"reference_chroma_worst", num(m.blocks.referenceChroma)}}},
              {"steps", {{"faces", m.steps.faces}, {"pixel_pairs", m.steps.pairs}, {"rms", num(m.steps.rms)}, {"worst", num(m.steps.worst)}}}}},
            {"seconds", m.seconds},
            {"visibility_seconds", m.visibilitySeconds},
            {"evaluation_seconds", m.evaluationSeconds},
            {"evaluations", m.evaluations},
            {"outside_grid", m.outsideGrid},
            {"empty_voxel", m.emptyVoxel},
            {"bytes", m.bytes},
            {"equal_error_path_tracer_seconds", num(m.equalErrorSeconds)},
            {"equal_error_extrapolated", m.equalErrorExtrapolated},
            {"equal_error_time_ratio_evaluation", num(m.speedupOverEvaluation)},
            {"equal_error_time_ratio_render", num(m.speedupOverRender)},
            {"by_luminance_decade", decades}};
}

// Per-pixel relative error (mean over channels) of an image against the reference.
double pixelError(const Image& img, const Image& ref, size_t i) {
    double e = 0.0;
    for (int c = 0; c < 3; ++c) {
        double d = double(img.pixels[i][c]) - double(ref.pixels[i][c]);
        e += d * d / (double(ref.pixels[i][c]) * double(ref.pixels[i][c]) + 0.01);
    }
    return e / 3.0;
}

nlohmann::json comparisonJson(const ValidationResult& r) {
    if (!r.baseline) return nullptr;
    const MethodResult &n = r.neural, &b = *r.baseline;
    size_t neuralBetter = 0, total = r.reference.pixels.size();
    for (size_t i = 0; i < total; ++i) neuralBetter += pixelError(n.image, r.reference, i) < pixelError(b.image, r.reference, i);
    nlohmann::json decades = nlohmann::json::array();
    for (const DecadeError& d : n.byDecade)
        for (const DecadeError& e : b.byDecade)
            if (d.lo == e.lo)
                decades.push_back({{"luminance_from", d.lo}, {"luminance_to", d.hi}, {"pixels", d.pixels}, {"neural_relmse", num(d.relMse)},
                                   {"baseline_relmse", num(e.relMse)}, {"better", d.relMse <= e.relMse ? "neural" : "sh-probes"}});
    return {{"better_overall", n.metrics.relMse <= b.metrics.relMse ? "neural" : "sh-probes"},
            {"relmse_ratio_baseline_over_neural", num(n.metrics.relMse > 0 ? b.metrics.relMse / n.metrics.relMse : 0.0)},
            {"pixels_where_neural_is_better", total ? double(neuralBetter) / double(total) : 0.0},
            {"by_luminance_decade", decades}};
}

void writeText(const fs::path& p, const std::string& text) { writeTextAtomically(p.string(), text); }

// A map of which method is closer to the reference per pixel: green neural, orange baseline, grey where
// both are within 1e-4 relMSE of each other.
Image winnerMap(const ValidationResult& r) {
    Image out(r.width, r.height);
    for (size_t i = 0; i < out.pixels.size(); ++i) {
        double en = pixelError(r.neural.image, r.reference, i), eb = pixelError(r.baseline->image, r.reference, i);
        out.pixels[i] = std::abs(en - eb) < 1e-4 ? glm::vec3(0.2f) : en < eb ? glm::vec3(0.05f, 0.5f, 0.1f) : glm::vec3(0.9f, 0.35f, 0.02f);
    }
    return out;
}

std::string headlineSentence(const ValidationResult& r) {
    std::ostringstream s;
    s << "The neural asset (" << r.neural.bytes << " bytes of weights) renders with relMSE " << fmt("%.4g", r.neural.metrics.relMse);
    if (referenceIsBlack(r))
        s << "; " << kNoLightToCompare << ".";
    else
        s << "; the path tracer needs " << fmt("%.3g", r.neural.equalErrorSeconds) << " s"
          << (r.neural.equalErrorExtrapolated ? " (extrapolated beyond its measured curve)" : "") << " to reach that error, "
          << fmt("%.3g", r.neural.speedupOverEvaluation) << "x the network evaluation time and "
          << fmt("%.3g", r.neural.speedupOverRender) << "x the whole neural render (visibility included).";
    if (r.baseline) {
        const MethodResult& b = *r.baseline;
        bool neuralWins = r.neural.metrics.relMse <= b.metrics.relMse;
        s << " At " << b.bytes << " bytes, L2 SH probes reach relMSE " << fmt("%.4g", b.metrics.relMse) << ": the "
          << (neuralWins ? "neural asset" : "SH probe baseline") << " is better overall ("
          << fmt("%.3g", neuralWins ? b.metrics.relMse / std::max(r.neural.metrics.relMse, 1e-300)
                                    : r.neural.metrics.relMse / std::max(b.metrics.relMse, 1e-300))
          << "x lower relMSE).";
    }
    const MethodResult& n = r.neural;
    if (n.surfaces.pixels > 0 && !referenceIsBlack(r)) {
        s << " What the eye sees: SSIM " << fmt("%.4f", n.metrics.ssim) << " at the exposure a viewer adapts to ("
          << fmt("%+.1f", n.metrics.ssimExposure) << " stops)";
        if (r.baseline) s << " (SH probes " << fmt("%.4f", r.baseline->metrics.ssim) << ")";
        s << "; over the " << n.surfaces.pixels << " pixels on surfaces, relMSE " << fmt("%.3g", n.surfaces.relMse);
        if (n.blocks.blocks > 0)
            s << "; averaged over " << n.blocks.blockSize << " x " << n.blocks.blockSize << "-pixel blocks the light is off by "
              << fmt("%.3g", n.blocks.rms) << " rms (worst block " << fmt("%.3g", n.blocks.worst)
              << (r.referenceBlockNoise >= 0.0 ? "; the reference's own noise there: about " + fmt("%.3g", r.referenceBlockNoise) + " rms" : std::string())
              << ") and tinted by "
              << fmt("%.3g", n.blocks.tintRms) << " rms (worst " << fmt("%.3g", n.blocks.tintWorst) << "; the reference's chroma "
              << fmt("%.3g", n.blocks.referenceChroma) << ", the asset's " << fmt("%.3g", n.blocks.chroma) << ")";
        if (n.steps.faces > 0)
            s << "; where the image crosses a cell face it steps by " << fmt("%.3g", n.steps.rms) << " rms (worst "
              << fmt("%.3g", n.steps.worst) << ", " << n.steps.faces << " faces) beyond the reference's change there";
        s << ".";
    }
    return s.str();
}

}  // namespace

const char* const kNoLightToCompare =
    "the view has no light to compare: the reference is black (choose a lit view: --camera, --look-from)";

bool referenceIsBlack(const ValidationResult& r) {
    for (const glm::vec3& p : r.reference.pixels)
        if (p.x >= kBlackRadiance || p.y >= kBlackRadiance || p.z >= kBlackRadiance) return false;
    return true;
}

std::string svgLogLogPlot(const std::string& title, const std::string& xLabel, const std::string& yLabel,
                          const std::vector<PlotSeries>& series, int width, int height) {
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (const PlotSeries& s : series)
        for (auto [x, y] : s.points)
            if (x > 0 && y > 0 && std::isfinite(x) && std::isfinite(y)) {
                x0 = std::min(x0, std::log10(x)), x1 = std::max(x1, std::log10(x));
                y0 = std::min(y0, std::log10(y)), y1 = std::max(y1, std::log10(y));
            }
    if (x0 > x1) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
    x0 = std::floor(x0), x1 = std::max(std::ceil(x1), x0 + 1), y0 = std::floor(y0), y1 = std::max(std::ceil(y1), y0 + 1);
    const double left = 70, right = 20, top = 36, bottom = 52;
    const double pw = width - left - right, ph = height - top - bottom;
    auto X = [&](double x) { return left + (std::log10(x) - x0) / (x1 - x0) * pw; };
    auto Y = [&](double y) { return top + (1.0 - (std::log10(y) - y0) / (y1 - y0)) * ph; };
    std::ostringstream o;
    o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\"" << height << "\" viewBox=\"0 0 " << width << ' '
      << height << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
    o << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    o << "<text x=\"" << width / 2 << "\" y=\"20\" text-anchor=\"middle\" font-size=\"14\">" << escape(title) << "</text>\n";
    for (int e = int(x0); e <= int(x1); ++e) {
        double x = left + (e - x0) / (x1 - x0) * pw;
        o << "<line x1=\"" << x << "\" y1=\"" << top << "\" x2=\"" << x << "\" y2=\"" << top + ph << "\" stroke=\"#ddd\"/>";
        o << "<text x=\"" << x << "\" y=\"" << top + ph + 16 << "\" text-anchor=\"middle\">1e" << e << "</text>\n";
    }
    for (int e = int(y0); e <= int(y1); ++e) {
        double y = top + (1.0 - (e - y0) / (y1 - y0)) * ph;
        o << "<line x1=\"" << left << "\" y1=\"" << y << "\" x2=\"" << left + pw << "\" y2=\"" << y << "\" stroke=\"#ddd\"/>";
        o << "<text x=\"" << left - 6 << "\" y=\"" << y + 4 << "\" text-anchor=\"end\">1e" << e << "</text>\n";
    }
    o << "<rect x=\"" << left << "\" y=\"" << top << "\" width=\"" << pw << "\" height=\"" << ph << "\" fill=\"none\" stroke=\"#333\"/>\n";
    o << "<text x=\"" << left + pw / 2 << "\" y=\"" << height - 12 << "\" text-anchor=\"middle\">" << escape(xLabel) << "</text>\n";
    o << "<text transform=\"translate(16," << top + ph / 2 << ") rotate(-90)\" text-anchor=\"middle\">" << escape(yLabel) << "</text>\n";
    int legend = 0;
    for (const PlotSeries& s : series) {
        std::vector<std::pair<double, double>> pts;
        for (auto [x, y] : s.points)
            if (x > 0 && y > 0 && std::isfinite(x) && std::isfinite(y)) pts.emplace_back(X(x), Y(y));
        if (s.line && pts.size() > 1) {
            o << "<polyline fill=\"none\" stroke=\"" << s.colour << "\" stroke-width=\"2\" points=\"";
            for (auto [x, y] : pts) o << x << ',' << y << ' ';
            o << "\"/>\n";
        }
        for (auto [x, y] : pts) o << "<circle cx=\"" << x << "\" cy=\"" << y << "\" r=\"" << (s.line ? 3 : 6) << "\" fill=\"" << s.colour << "\"/>\n";
        double ly = top + 14 + 16 * legend++;
        o << "<circle cx=\"" << left + pw - 150 << "\" cy=\"" << ly - 4 << "\" r=\"5\" fill=\"" << s.colour << "\"/>";
        o << "<text x=\"" << left + pw - 140 << "\" y=\"" << ly << "\">" << escape(s.name) << "</text>\n";
    }
    o << "</svg>\n";
    return o.str();
}

std::vector<BakeCurvePoint> bakeTrainingCurve(const nlohmann::json& bakeStats) {
    std::vector<BakeCurvePoint> out;
    if (!bakeStats.is_object() || !bakeStats.contains("voxels") || !bakeStats["voxels"].is_array()) return out;
    std::vector<std::vector<std::pair<double, double>>> curves;  // per voxel: (seconds, relMSE)
    std::vector<double> times;
    for (const auto& v : bakeStats["voxels"]) {
        std::vector<std::pair<double, double>> c;
        if (v.contains("curve_epoch_seconds_relmse") && v["curve_epoch_seconds_relmse"].is_array())
            for (const auto& p : v["curve_epoch_seconds_relmse"])
                if (p.is_array() && p.size() == 3 && p[1].is_number() && p[2].is_number()) {
                    c.emplace_back(p[1].get<double>(), p[2].get<double>());
                    times.push_back(p[1].get<double>());
                }
        if (!c.empty()) curves.push_back(std::move(c));
    }
    std::sort(times.begin(), times.end());
    times.erase(std::unique(times.begin(), times.end()), times.end());
    // At most 200 points, spread over the times.
    std::vector<double> at;
    for (size_t i = 0; i < times.size(); i += std::max<size_t>(1, times.size() / 200)) at.push_back(times[i]);
    if (!times.empty() && at.back() != times.back()) at.push_back(times.back());
    for (double t : at) {
        std::vector<double> errs;
        for (const auto& c : curves) {
            double e = c.front().second;  // a voxel not started yet counts with its first error
            for (auto [s, v] : c)
                if (s <= t) e = v;
            errs.push_back(e);
        }
        if (errs.empty()) continue;
        double mean = 0.0;
        for (double e : errs) mean += e;
        std::sort(errs.begin(), errs.end());
        double median = errs.size() % 2 ? errs[errs.size() / 2] : 0.5 * (errs[errs.size() / 2 - 1] + errs[errs.size() / 2]);
        out.push_back({t, mean / double(errs.size()), median});
    }
    return out;
}

nlohmann::json reportJson(const ValidationResult& r, const nlohmann::json& bakeStats) {
    const ValidateSettings& s = r.settings;
    nlohmann::json j;
    j["scene"] = r.scenePath;
    j["asset"] = r.assetPath;
    j["environment"] = r.environment;
    j["image"] = {{"width", r.width}, {"height", r.height}};
    j["settings"] = {{"reference_spp", s.referenceSpp}, {"max_depth", s.maxDepth}, {"neural_spp", s.neuralSpp},
                     {"curve_max_spp", s.curveMaxSpp}, {"seed", s.seed}, {"exposure", s.exposure}};
    j["reference"] = {{"source", r.referenceSource}, {"cache_file", r.referenceCacheFile}, {"seconds", r.referenceSeconds}};
    j["bias_notes"] = r.biasNotes;
    if (r.referenceNoise >= 0.0) j["reference"]["noise_relmse_estimate"] = num(r.referenceNoise);
    if (r.referenceBlockNoise >= 0.0) j["reference"]["block_noise_rms_estimate"] = num(r.referenceBlockNoise);
    nlohmann::json curve = nlohmann::json::array();
    for (const CurvePoint& c : r.curve) curve.push_back({{"spp", c.spp}, {"seconds", c.seconds}, {"metrics", metricsJson(c.metrics)}});
    j["path_tracer_convergence"] = curve;
    j["neural"] = methodJson(r.neural);
    if (!r.inserted.empty()) {
        nlohmann::json objects = nlohmann::json::array();
        for (const InsertedFigure& f : r.inserted) {
            nlohmann::json o = {{"name", f.name}, {"pixels", f.pixels}, {"neural_relmse", num(f.neuralRelMse)},
                                {"neural_mean_ratio", num(f.neuralMeanRatio)},
                                {"exact_volume_light", {{"pixels", f.exactPixels}, {"relmse", num(f.exactRelMse)},
                                                        {"mean_ratio", num(f.exactMeanRatio)}, {"neural_relmse_against_it", num(f.neuralVsExact)}}}};
            if (r.baseline) {
                o["baseline_relmse"] = num(f.baselineRelMse);
                o["baseline_mean_ratio"] = num(f.baselineMeanRatio);
                o["relmse_ratio_baseline_over_neural"] = num(f.neuralRelMse > 0.0 ? f.baselineRelMse / f.neuralRelMse : 0.0);
                o["exact_volume_light"]["baseline_relmse_against_it"] = num(f.baselineVsExact);
                o["exact_volume_light"]["relmse_ratio_baseline_over_neural"] = num(f.neuralVsExact > 0.0 ? f.baselineVsExact / f.neuralVsExact : 0.0);
                // how far below the baseline a perfect query of the volume would read (InsertedFigure::bestRatio)
                o["exact_volume_light"]["baseline_relmse_on_its_pixels"] = num(f.baselineAtExact);
                o["exact_volume_light"]["best_ratio_baseline_over_exact"] = num(f.bestRatio);
            }
            objects.push_back(o);
        }
        j["inserted"] = {{"objects", objects}, {"through", r.insertedThroughGlossy ? "volume query and glossy response" : r.insertedThroughVolume ? "volume query" : "surface networks"},
                         {"volume_bytes", r.volumeBytes}, {"exact_volume_light_paths_per_pixel", r.exactPaths}};
        if (r.baseline)
            j["inserted"]["baseline"] = {{"kind", "L2 SH irradiance probes"},
                                         {"probes", {r.irradianceProbes.x, r.irradianceProbes.y, r.irradianceProbes.z}},
                                         {"left_out_inside_solids", r.irradianceFit.leftOut},
                                         {"paths", r.irradianceFit.paths},
                                         {"seconds", num(r.irradianceFit.seconds)}};
    }
    j["seams"] = {{"points", r.seams.points}, {"relmse_across_faces", num(r.seams.relMse)},
                  {"mean_relative_jump", num(r.seams.meanRelativeJump)},
                  {"evaluations_per_point", num(r.seams.evaluationsPerPoint)},
                  {"blended_share", num(r.seams.blendedShare)}};
    // Per material (the surface each pixel's centre sees): where a method's error lives by what is shaded there.
    nlohmann::json materials = nlohmann::json::array();
    auto entry = [](const RegionError& e) {
        return nlohmann::json{{"relmse", num(e.relMse)}, {"share_of_image_relmse", num(e.shareOfImage)}};
    };
    for (size_t k = 0; k < r.materialNames.size() && k < r.neural.byMaterial.size(); ++k) {
        if (r.neural.byMaterial[k].pixels == 0) continue;
        nlohmann::json m = {{"material", r.materialNames[k]}, {"index", k}, {"pixels", r.neural.byMaterial[k].pixels},
                            {"neural", entry(r.neural.byMaterial[k])}};
        if (r.baseline && k < r.baseline->byMaterial.size()) m["baseline"] = entry(r.baseline->byMaterial[k]);
        materials.push_back(m);
    }
    j["by_material"] = materials;
    if (r.baseline) {
        j["baseline"] = methodJson(*r.baseline);
        j["baseline"]["probes"] = {r.baselineProbes.x, r.baselineProbes.y, r.baselineProbes.z};
        j["baseline"]["training_samples"] = r.baselineTrainingSamples;
        j["baseline"]["training_paths"] = r.baselineTrainingPaths;
        j["baseline"]["training_settings"] = r.baselineSamplesNote;
        j["baseline"]["fit"] = {{"cg_iterations", r.baselineFit.iterations}, {"relative_residual", r.baselineFit.relativeResidual},
                                {"train_relmse", r.baselineFit.trainRelMse}};
        j["baseline"]["sampling_and_fit_seconds"] = r.baselineFittedSeconds;  // from the cache: when they were fitted
        j["baseline"]["source"] = r.baselineSource;
        j["baseline"]["cache_file"] = r.baselineCacheFile;
        j["baseline"]["seconds"] = r.baselineSeconds;  // this validation's: the fit, or reading the cache
        j["comparison"] = comparisonJson(r);
    }
    if (bakeStats.is_object()) {
        nlohmann::json b;
        b["seconds"] = bakeStats.value("seconds", nlohmann::json());
        b["asset_bytes"] = bakeStats.value("asset_bytes", nlohmann::json());
        b["held_out_relmse"] = bakeStats.value("held_out_relmse", nlohmann::json());
        nlohmann::json c = nlohmann::json::array();
        for (const BakeCurvePoint& p : bakeTrainingCurve(bakeStats))
            c.push_back({{"seconds", p.seconds}, {"mean_relmse", num(p.meanRelMse)}, {"median_relmse", num(p.medianRelMse)}});
        b["training_curve"] = c;
        double total = 0.0;
        if (b["seconds"].is_object())
            for (auto& [k, v] : b["seconds"].items())
                if (v.is_number()) total += v.get<double>();
        b["total_seconds"] = total;
        j["bake"] = b;
    }
    j["summary"] = headlineSentence(r);
    return j;
}

namespace {

// A method's image (EXR and PNG), its squared difference from the reference and its relative error map.
void writeMethodImages(const fs::path& dir, const std::string& stem, const Image& img, const Image& reference, float exposure) {
    writeExr((dir / (stem + ".exr")).string(), img);
    writePng((dir / (stem + ".png")).string(), img, exposure);
    Image sq = squaredDifferenceImage(img, reference);
    writeExr((dir / (stem + "-sqdiff.exr")).string(), sq);
    writePng((dir / (stem + "-sqdiff.png")).string(), sq);
    writePng((dir / (stem + "-relerr.png")).string(), relativeErrorMap(img, reference));
}

// convergence.csv: each render's spp, time and error.
void writeConvergenceCsv(const ValidationResult& r, const fs::path& dir) {
    std::ostringstream csv;
    csv << "method,spp,seconds,relmse,rmse,psnr_db\n";
    auto row = [&](const std::string& name, int spp, double sec, const ImageMetrics& m) {
        csv << name << ',' << spp << ',' << fmt("%.6g", sec) << ',' << fmt("%.6g", m.relMse) << ',' << fmt("%.6g", m.rmse) << ','
            << (std::isfinite(m.psnr) ? fmt("%.4f", m.psnr) : "inf") << '\n';
    };
    for (const CurvePoint& c : r.curve) row("path-tracer", c.spp, c.seconds, c.metrics);
    row("neural", r.settings.neuralSpp, r.neural.seconds, r.neural.metrics);
    if (r.baseline) row("sh-probes", r.settings.neuralSpp, r.baseline->seconds, r.baseline->metrics);
    writeText(dir / "convergence.csv", csv.str());
}

// The SVG plots: error against run time, against bytes, and the bake's training curve (if `bc` has one).
void writePlots(const ValidationResult& r, const std::vector<BakeCurvePoint>& bc, const fs::path& dir) {
    std::vector<PlotSeries> series;
    PlotSeries pt{"path tracer (1, 2, 4, ... spp)", "#1f5fbf", {}, true};
    for (const CurvePoint& c : r.curve) pt.points.emplace_back(c.seconds, c.metrics.relMse);
    series.push_back(pt);
    series.push_back({"neural: whole render", "#2ca02c", {{r.neural.seconds, r.neural.metrics.relMse}}, false});
    series.push_back({"neural: evaluation only", "#98df8a", {{r.neural.evaluationSeconds, r.neural.metrics.relMse}}, false});
    if (r.baseline) series.push_back({"SH probes: whole render", "#ff7f0e", {{r.baseline->seconds, r.baseline->metrics.relMse}}, false});
    writeText(dir / "error-vs-time.svg", svgLogLogPlot("Error against run time", "wall time (s)", "relMSE against the reference", series));
    {  // Error against bytes: the asset and the SH probes of (about) its bytes.
        std::vector<PlotSeries> bytes = {{"neural asset (networks + tree)", "#2ca02c", {{double(r.neural.bytes), r.neural.metrics.relMse}}, false}};
        if (r.baseline) bytes.push_back({"L2 SH probes", "#ff7f0e", {{double(r.baseline->bytes), r.baseline->metrics.relMse}}, false});
        writeText(dir / "error-vs-bytes.svg", svgLogLogPlot("Error against bytes", "bytes", "relMSE against the reference", bytes));
    }
    if (!bc.empty()) {
        PlotSeries mean{"mean over voxels", "#d62728", {}, true}, median{"median over voxels", "#9467bd", {}, true};
        for (const BakeCurvePoint& p : bc) {
            mean.points.emplace_back(p.seconds, p.meanRelMse);
            median.points.emplace_back(p.seconds, p.medianRelMse);
        }
        writeText(dir / "bake-training.svg",
                  svgLogLogPlot("Bake: held-out error during training", "training time per voxel (s)", "held-out relMSE", {mean, median}));
    }
}

void htmlFigure(std::ostringstream& h, const std::string& src, const std::string& caption) {
    h << "<figure><img src=\"" << escape(src) << "\" alt=\"" << escape(caption) << "\"><figcaption>" << escape(caption)
      << "</figcaption></figure>\n";
}

// report.html's head, its paragraph on the run (scene, asset, reference, its biases and noise), the
// headline and the images.
void htmlIntroAndImages(std::ostringstream& h, const ValidationResult& r) {
    h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>nrad validation: " << escape(r.scenePath)
      << "</title>\n<style>body{font-family:sans-serif;margin:24px;max-width:1400px}figure{display:inline-block;margin:6px;"
         "vertical-align:top}figure img{width:300px;image-rendering:pixelated;border:1px solid #ccc}figcaption{font-size:13px;"
         "max-width:300px}table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}"
         "td:first-child,th:first-child{text-align:left}.plots img{width:640px}p.summary{font-size:16px;max-width:1000px}</style>\n"
         "</head><body>\n";
    h << "<h1>nrad validation</h1>\n<p>Scene <code>" << escape(r.scenePath) << "</code>, asset <code>" << escape(r.assetPath) << "</code>, "
      << r.width << "x" << r.height << " pixels, environment: " << escape(r.environment) << ". Reference: " << r.settings.referenceSpp << " paths per pixel, path length "
      << (r.settings.maxDepth ? std::to_string(r.settings.maxDepth) : std::string("unbounded")) << " ("
      << escape(r.referenceSource) << ")";
    for (const std::string& note : r.biasNotes) h << "; <b>bias</b>: " << escape(note);
    if (r.referenceNoise >= 0.0)
        h << "; its own noise adds about " << fmt("%.3g", r.referenceNoise)
          << " to every relMSE measured against it (estimated from the path tracer's curve)";
    if (r.referenceBlockNoise >= 0.0)
        h << " and about " << fmt("%.3g", r.referenceBlockNoise) << " rms to the block figure";
    h << ". Neural and baseline: " << r.settings.neuralSpp << " primary samples per pixel.</p>\n";
    h << "<p class=\"summary\">" << escape(headlineSentence(r)) << "</p>\n";
    h << "<h2>Images</h2>\n<div>";
    htmlFigure(h, "reference.png", "reference (path traced)");
    htmlFigure(h, "neural.png", "through the neural asset");
    if (r.baseline) htmlFigure(h, "sh-probes.png", "L2 SH probes, same bytes");
    h << "</div><div>";
    htmlFigure(h, "neural-sqdiff.png", "neural: squared difference x10");
    htmlFigure(h, "neural-relerr.png", "neural: relative error, log colour scale 1e-3 (blue) to 1 (red)");
    if (r.baseline) {
        htmlFigure(h, "sh-probes-sqdiff.png", "SH probes: squared difference x10");
        htmlFigure(h, "sh-probes-relerr.png", "SH probes: relative error, same scale");
        htmlFigure(h, "winner.png", "closer to the reference: green neural, orange SH probes, grey tie");
    }
    h << "</div>\n";
}

// Error against run time, per render.
void htmlTimeTable(std::ostringstream& h, const ValidationResult& r) {
    h << "<h2>Error against run time</h2>\n<table><tr><th>method</th><th>relMSE</th><th>RMSE</th><th>PSNR (dB)</th>"
         "<th>wall time (s)</th><th>notes</th></tr>\n";
    auto metricRow = [&](const std::string& name, const ImageMetrics& m, double sec, const std::string& extra) {
        h << "<tr><td>" << escape(name) << "</td><td>" << fmt("%.4g", m.relMse) << "</td><td>" << fmt("%.4g", m.rmse) << "</td><td>"
          << (std::isfinite(m.psnr) ? fmt("%.2f", m.psnr) : "inf") << "</td><td>" << fmt("%.3f", sec) << "</td><td>" << extra
          << "</td></tr>\n";
    };
    for (const CurvePoint& c : r.curve) metricRow("path tracer " + std::to_string(c.spp) + " spp", c.metrics, c.seconds, "");
    auto methodNote = [&](const MethodResult& m) {
        return fmt("%.3f", m.visibilitySeconds) + " s visibility + " + fmt("%.3f", m.evaluationSeconds) + " s evaluation; " +
               std::to_string(m.bytes) + " bytes; path tracer at equal error " + fmt("%.3g", m.equalErrorSeconds) + " s" +
               (m.equalErrorExtrapolated ? " (extrapolated)" : "") + " = " + fmt("%.3g", m.speedupOverEvaluation) +
               "x the evaluation time, " + fmt("%.3g", m.speedupOverRender) + "x the render";
    };
    metricRow("neural", r.neural.metrics, r.neural.seconds, methodNote(r.neural));
    if (r.baseline) metricRow("SH probes", r.baseline->metrics, r.baseline->seconds, methodNote(*r.baseline));
    h << "</table>\n";
}

// Where the error lives: by pixel share and region, then by material (the neural share first: which
// surfaces carry the error, and how the probes fare on them).
void htmlErrorTables(std::ostringstream& h, const ValidationResult& r) {
    h << "<h2>Where the error is</h2>\n<table><tr><th>method</th><th>worst 1% of pixels: share of relMSE</th>"
         "<th>median relative error</th><th>99th percentile</th>";
    for (int k = 0; k < kRegionCount; ++k) h << "<th>relMSE: " << kRegionNames[k] << " (pixels; share)</th>";
    h << "</tr>\n";
    auto whereRow = [&](const std::string& name, const MethodResult& m) {
        h << "<tr><td>" << escape(name) << "</td><td>" << fmt("%.1f%%", 100.0 * m.distribution.worst1PercentShare) << "</td><td>"
          << fmt("%.3g", m.distribution.medianRelativeError) << "</td><td>" << fmt("%.3g", m.distribution.p99RelativeError) << "</td>";
        for (const RegionError& e : m.byRegion)
            h << "<td>" << fmt("%.3g", e.relMse) << " (" << e.pixels << "; " << fmt("%.1f%%", 100.0 * e.shareOfImage) << ")</td>";
        h << "</tr>\n";
    };
    whereRow("neural", r.neural);
    if (r.baseline) whereRow("SH probes", *r.baseline);
    h << "</table>\n";
    const std::vector<size_t> order = materialsByNeuralShare(r);
    h << "<table><tr><th>material</th><th>pixels</th><th>neural relMSE (share)</th>";
    if (r.baseline) h << "<th>SH probes relMSE (share)</th><th>SH / neural</th>";
    h << "</tr>\n";
    for (size_t k : order) {
        const RegionError& e = r.neural.byMaterial[k];
        h << "<tr><td>" << escape(r.materialNames[k]) << "</td><td>" << e.pixels << "</td><td>" << fmt("%.3g", e.relMse) << " ("
          << fmt("%.1f%%", 100.0 * e.shareOfImage) << ")</td>";
        if (r.baseline && k < r.baseline->byMaterial.size()) {
            const RegionError& b = r.baseline->byMaterial[k];
            h << "<td>" << fmt("%.3g", b.relMse) << " (" << fmt("%.1f%%", 100.0 * b.shareOfImage) << ")</td><td>"
              << (e.relMse > 0.0 ? fmt("%.3g", b.relMse / e.relMse) : std::string("-")) << "</td>";
        }
        h << "</tr>\n";
    }
    h << "</table>\n";
}

// The seams paragraph and the plots.
void htmlSeamsAndPlots(std::ostringstream& h, const ValidationResult& r, bool bakeCurve) {
    h << "<p>Seams: at " << r.seams.points << " surface points on faces shared by two occupied voxels, the asset's "
      << "radiance on either side differs by a relMSE of " << fmt("%.3g", r.seams.relMse) << " (mean relative jump "
      << fmt("%.3g", r.seams.meanRelativeJump) << "). Networks evaluated per visible surface point: "
      << fmt("%.3g", r.seams.evaluationsPerPoint) << " (" << fmt("%.1f", 100.0 * r.seams.blendedShare)
      << "% of the points in a blending band).</p>\n";
    h << "<div class=\"plots\"><img src=\"error-vs-time.svg\" alt=\"error against time\">"
         "<img src=\"error-vs-bytes.svg\" alt=\"error against bytes\">";
    if (bakeCurve) h << "<img src=\"bake-training.svg\" alt=\"bake training curve\">";
    h << "</div>\n";
}

// Neural against SH probes, by luminance decade (`c`: report.json's comparison, computed once).
void htmlComparison(std::ostringstream& h, const ValidationResult& r, const nlohmann::json& c) {
    h << "<h2>Neural against SH probes</h2>\n<p>Better overall: <b>" << c["better_overall"].get<std::string>()
      << "</b>. The neural image is closer to the reference in "
      << fmt("%.1f", 100.0 * c["pixels_where_neural_is_better"].get<double>()) << "% of the pixels.</p>\n"
      << "<table><tr><th>reference luminance</th><th>pixels</th><th>neural relMSE</th><th>SH relMSE</th><th>better</th></tr>\n";
    for (const auto& d : c["by_luminance_decade"])
        h << "<tr><td>" << fmt("%.0e", d["luminance_from"].get<double>()) << " to " << fmt("%.0e", d["luminance_to"].get<double>())
          << "</td><td>" << d["pixels"].get<size_t>() << "</td><td>" << fmt("%.4g", d["neural_relmse"].is_number() ? d["neural_relmse"].get<double>() : 0.0)
          << "</td><td>" << fmt("%.4g", d["baseline_relmse"].is_number() ? d["baseline_relmse"].get<double>() : 0.0) << "</td><td>"
          << d["better"].get<std::string>() << "</td></tr>\n";
    h << "</table>\n<p>Baseline: " << r.baselineProbes.x << "x" << r.baselineProbes.y << "x" << r.baselineProbes.z
      << " probes fitted by least squares to " << r.baselineTrainingSamples << " training samples (" << escape(r.baselineSamplesNote)
      << "); fit relMSE on those samples " << fmt("%.4g", r.baselineFit.trainRelMse) << ".</p>\n";
}

// The adaptive partition (from the bake's stats): its cells, their depth and error, the worst first.
void htmlPartition(std::ostringstream& h, const nlohmann::json& bakeStats) {
    const nlohmann::json& p = bakeStats["partition"];
    std::map<uint64_t, const nlohmann::json*> byLeaf;
    if (bakeStats.contains("voxels") && bakeStats["voxels"].is_array())
        for (const auto& v : bakeStats["voxels"])
            if (v.contains("voxel") && v["voxel"].is_number_unsigned()) byLeaf[v["voxel"].get<uint64_t>()] = &v;
    std::vector<std::pair<double, const nlohmann::json*>> cells;
    std::map<int, int> depths;
    if (p.contains("cells") && p["cells"].is_array())
        for (const auto& c : p["cells"]) {
            const uint64_t leaf = c.value("leaf", uint64_t(0));
            const auto it = byLeaf.find(leaf);
            const double err = it != byLeaf.end() ? it->second->value("held_out_relmse", 0.0) : -1.0;
            cells.emplace_back(err, &c);
            ++depths[c.value("depth", 0)];
        }
    std::sort(cells.begin(), cells.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    h << "<h2>Partition</h2>\n<p>kd-tree of " << p.value("leaves", 0) << " leaves (" << p.value("networks", 0)
      << " with surface, each a network) on a lattice of ";
    if (p.contains("lattice") && p["lattice"].is_array() && p["lattice"].size() == 3)
        h << p["lattice"][0].get<int>() << "x" << p["lattice"][1].get<int>() << "x" << p["lattice"][2].get<int>();
    h << " voxels, refined under a budget of " << p.value("budget_bytes", uint64_t(0)) << " bytes. Leaves per depth:";
    for (auto [d, n] : depths) h << " " << d << ": " << n << ";";
    h << "</p>\n<table><tr><th>leaf</th><th>depth</th><th>lattice box</th><th>samples</th><th>held-out relMSE</th></tr>\n";
    size_t shown = 0;
    for (const auto& [err, c] : cells) {
        if (shown++ == 32) break;
        const auto& lo = (*c)["lo"];
        const auto& hi = (*c)["hi"];
        h << "<tr><td>" << c->value("leaf", 0) << "</td><td>" << c->value("depth", 0) << "</td><td>[" << lo[0] << "," << lo[1]
          << "," << lo[2] << ") - [" << hi[0] << "," << hi[1] << "," << hi[2] << ")</td><td>" << c->value("samples", 0)
          << "</td><td>" << (err >= 0.0 ? fmt("%.4g", err) : std::string("no network")) << "</td></tr>\n";
    }
    h << "</table>\n<p>The " << std::min<size_t>(32, cells.size()) << " worst of " << cells.size()
      << " leaves; all of them are in the bake's --stats.</p>\n";
}

// The bake's phase times (`b`: report.json's bake entry), then the links to the data and the script that
// records how many images loaded.
void htmlBakeAndEnd(std::ostringstream& h, const nlohmann::json* b) {
    if (b) {
        h << "<h2>Bake</h2>\n<table><tr><th>phase</th><th>seconds</th></tr>\n";
        if ((*b)["seconds"].is_object())
            for (auto& [k, v] : (*b)["seconds"].items())
                if (v.is_number()) h << "<tr><td>" << escape(k) << "</td><td>" << fmt("%.3f", v.get<double>()) << "</td></tr>\n";
        h << "<tr><td>total</td><td>" << fmt("%.3f", (*b)["total_seconds"].get<double>()) << "</td></tr></table>\n";
    }
    h << "<p>All numbers: <a href=\"report.json\">report.json</a>, <a href=\"convergence.csv\">convergence.csv</a>.</p>\n"
         "<script>window.addEventListener('load',function(){var im=document.images,ok=0;for(var i=0;i<im.length;++i)"
         "if(im[i].complete&&im[i].naturalWidth>0)++ok;document.body.setAttribute('data-images-total',im.length);"
         "document.body.setAttribute('data-images-loaded',ok);});</script>\n</body></html>\n";
}

}  // namespace

// The objects placed after the bake: their interior pixels' error, the asset's volume query against the probes.
static void htmlInserted(std::ostringstream& h, const ValidationResult& r) {
    h << "<h2>Inserted objects</h2>\n<p>Objects that were not in the bake, shaded through the asset's "
      << (r.insertedThroughGlossy    ? "volume query and glossy response"
          : r.insertedThroughVolume ? "volume query"
                                    : "surface networks (it has no volume networks: an extrapolation)");
    if (r.baseline)
        h << ", against " << r.irradianceProbes.x << "x" << r.irradianceProbes.y << "x" << r.irradianceProbes.z
          << " L2 SH irradiance probes of the volume's bytes";
    h << ". Over each object's interior pixels, against the reference and (every other pixel) against the exact light "
      << "in the volume: D(x, n) path traced in the scene without the objects, shaded alike, the floor of any volume "
      << "representation (the reference also holds what the objects do to their surroundings: their own shadows):</p>\n<table><tr><th>object</th><th>pixels</th><th>relMSE asset</th>";
    if (r.baseline) h << "<th>relMSE SH probes</th><th>SH / asset</th>";
    h << "<th>mean / reference (asset)</th>";
    if (r.baseline) h << "<th>mean / reference (SH)</th>";
    h << "<th>relMSE exact volume light</th><th>asset against it</th>";
    if (r.baseline) h << "<th>SH against it</th><th>a perfect volume query: x below SH</th>";
    h << "</tr>\n";
    for (const InsertedFigure& f : r.inserted) {
        h << "<tr><td>" << escape(f.name) << "</td><td>" << f.pixels << "</td><td>" << fmt("%.4g", f.neuralRelMse) << "</td>";
        if (r.baseline)
            h << "<td>" << fmt("%.4g", f.baselineRelMse) << "</td><td>"
              << fmt("%.3g", f.neuralRelMse > 0.0 ? f.baselineRelMse / f.neuralRelMse : 0.0) << "</td>";
        h << "<td>" << fmt("%.3f", f.neuralMeanRatio) << "</td>";
        if (r.baseline) h << "<td>" << fmt("%.3f", f.baselineMeanRatio) << "</td>";
        h << "<td>" << fmt("%.4g", f.exactRelMse) << "</td><td>" << fmt("%.4g", f.neuralVsExact) << "</td>";
        if (r.baseline) h << "<td>" << fmt("%.4g", f.baselineVsExact) << "</td><td>" << fmt("%.3g", f.bestRatio) << "</td>";
        h << "</tr>\n";
    }
    h << "</table>\n";
}

static void writeReportFiles(const ValidationResult& r, const nlohmann::json& bakeStats, const fs::path& dir) {
    const float exposure = r.settings.exposure;
    writeExr((dir / "reference.exr").string(), r.reference);
    writePng((dir / "reference.png").string(), r.reference, exposure);
    writeMethodImages(dir, "neural", r.neural.image, r.reference, exposure);
    if (r.baseline) {
        writeMethodImages(dir, "sh-probes", r.baseline->image, r.reference, exposure);
        writePng((dir / "winner.png").string(), winnerMap(r));
    }
    const nlohmann::json j = reportJson(r, bakeStats);
    writeText(dir / "report.json", j.dump(1) + "\n");
    writeConvergenceCsv(r, dir);
    const std::vector<BakeCurvePoint> bc = bakeTrainingCurve(bakeStats);
    writePlots(r, bc, dir);

    // report.html: images, error maps and plots side by side; a script records how many images loaded.
    std::ostringstream h;
    htmlIntroAndImages(h, r);
    htmlTimeTable(h, r);
    htmlErrorTables(h, r);
    htmlSeamsAndPlots(h, r, !bc.empty());
    if (r.baseline) htmlComparison(h, r, j["comparison"]);
    if (!r.inserted.empty()) htmlInserted(h, r);
    if (bakeStats.is_object() && bakeStats.contains("partition") && bakeStats["partition"].is_object()) htmlPartition(h, bakeStats);
    htmlBakeAndEnd(h, j.contains("bake") ? &j["bake"] : nullptr);
    writeText(dir / "report.html", h.str());
}

std::string writeReport(const ValidationResult& r, const nlohmann::json& bakeStats, const std::string& dirPath) {
    // Into a temporary folder that then replaces dirPath: a failed write (a full disk) leaves the last
    // report as it was, never a folder of some images and no report.html.
    writeFolderAtomically(dirPath, [&](const std::string& tmp) { writeReportFiles(r, bakeStats, fs::path(tmp)); });
    return (fs::path(dirPath) / "report.html").string();
}

}  // namespace nrad
