// The validation run: reference (cached), convergence curve, neural and baseline renders, scores.
#include "baker/validate/validate.h"

#include <chrono>
#include <limits>
#include <tbb/parallel_for.h>
#include <nrad/eval.h>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "baker/bake/baker.h"
#include "baker/bake/training_samples.h"
#include "baker/bake/volume_samples.h"
#include "baker/bake/voxel_grid.h"
#include "baker/render/accel.h"
#include "baker/render/surface.h"
#include "baker/render/camera.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/neural_render.h"
#include "baker/util/atomic_file.h"
#include "baker/util/hash.h"
#include "baker/util/maths.h"

namespace nrad {

namespace {

namespace fs = std::filesystem;
using clock_type = std::chrono::steady_clock;

double since(clock_type::time_point t0) { return std::chrono::duration<double>(clock_type::now() - t0).count(); }

// Scores a first-hit render and splits its wall time by the thread-time shares.
void score(MethodResult& m, const NeuralRenderStats& st, const ValidationResult& r, float exposure) {
    const Image& reference = r.reference;
    m.metrics = compareImages(m.image, reference, exposure);
    m.byDecade = relMseByDecade(m.image, reference);
    m.distribution = errorDistribution(m.image, reference);
    m.byRegion = relMseByRegion(m.image, reference, r.regionOfPixel, kRegionCount);
    m.byMaterial = relMseByRegion(m.image, reference, r.materialOfPixel, int(r.materialNames.size()));
    {
        std::vector<int> surface(r.surfaceOfPixel.begin(), r.surfaceOfPixel.end());
        for (int& v : surface) v = v ? 0 : -1;
        m.surfaces = relMseByRegion(m.image, reference, surface, 1)[0];
    }
    m.blocks = blockFigure(m.image, reference, r.surfaceOfPixel, std::max(1, r.width / 16));
    m.steps = stepFigure(m.image, reference, r.cellOfPixel, r.surfaceOfPixel);
    m.seconds = st.seconds;
    double threadTime = st.visibilitySeconds + st.evaluationSeconds;
    double share = threadTime > 0.0 ? st.evaluationSeconds / threadTime : 0.0;
    m.evaluationSeconds = st.seconds * share;
    m.visibilitySeconds = st.seconds - m.evaluationSeconds;
    m.evaluations = st.evaluations;
    m.outsideGrid = st.outsideGrid;
    m.emptyVoxel = st.emptyVoxel;
}

}  // namespace

FirstHits firstHits(const Scene& scene, const Accel& accel, const Camera& camera, int width, int height, const eval::Partition& partition) {
    CameraRays rays(camera, width, height);
    const size_t n = size_t(width) * size_t(height);
    FirstHits h;
    h.width = width;
    h.height = height;
    h.voxel.assign(n, -1);
    h.material.assign(n, -1);
    h.inserted.assign(n, -1);
    h.emitter.assign(n, 0);
    h.points.assign(n, glm::vec3(std::numeric_limits<float>::quiet_NaN()));
    h.normals.assign(n, glm::vec3(0.0f));
    h.directions.assign(n, glm::vec3(0.0f));
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y != rows.end(); ++y)
            for (int x = 0; x < width; ++x) {
                glm::vec3 o, d;
                rays.generate(float(x) + 0.5f, float(y) + 0.5f, o, d);
                Hit hit = accel.intersect(o, d);
                if (!hit.valid()) continue;
                SurfaceInteraction si = makeInteraction(scene, hit, d);
                const size_t i = size_t(y) * size_t(width) + size_t(x);
                const float p[3] = {si.p.x, si.p.y, si.p.z};
                h.voxel[i] = partition.cellOf(p);
                h.material[i] = int(scene.mesh.materialIds[hit.triangle]);
                h.inserted[i] = scene.insertedObject(hit.triangle);
                h.emitter[i] = si.emission.x > 0.0f || si.emission.y > 0.0f || si.emission.z > 0.0f;
                h.points[i] = si.p;
                h.normals[i] = si.ns;
                h.directions[i] = si.wo;
            }
    });
    return h;
}

std::vector<int> pixelRegions(const FirstHits& h) {
    const int width = h.width, height = h.height;
    std::vector<int> region(h.voxel.size(), 2);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const size_t i = size_t(y) * size_t(width) + size_t(x);
            if (h.emitter[i]) {
                region[i] = 0;
                continue;
            }
            if (h.voxel[i] < 0) continue;
            bool border = false;
            for (int dy = -1; dy <= 1 && !border; ++dy)
                for (int dx = -1; dx <= 1 && !border; ++dx) {
                    int u = x + dx, v = y + dy;
                    if (u < 0 || v < 0 || u >= width || v >= height) continue;
                    int64_t other = h.voxel[size_t(v) * size_t(width) + size_t(u)];
                    border = other >= 0 && other != h.voxel[i];
                }
            if (border) region[i] = 1;
        }
    return region;
}

eval::Partition assetPartition(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    format::Asset a;
    if (format::decode(bytes.data(), bytes.size(), a) != format::DecodeStatus::Ok)
        throw std::runtime_error(path + ": cannot read the asset's partition");
    return eval::Partition(a);
}

SeamFigure seamFigure(const FirstHits& h, const eval::Partition& partition, NradAsset asset) {
    // For each hit near an interior face of its cell (within 2% of the cell's extent): the point on the face,
    // nudged to either side.
    const format::Grid& grid = partition.grid;
    std::vector<format::TreeBox> boxes;
    if (!partition.tree.empty()) {
        uint32_t leaves = 0;
        format::validateTree(grid.dims, partition.tree, leaves, &boxes);
    }
    std::vector<float> p, n, d;
    for (size_t i = 0; i < h.voxel.size(); ++i) {
        if (h.voxel[i] < 0 || h.emitter[i] || (!h.inserted.empty() && h.inserted[i] >= 0)) continue;  // not the objects placed after the bake
        format::TreeBox box;
        if (boxes.empty()) {
            const uint64_t v = uint64_t(h.voxel[i]);
            const uint32_t c[3] = {uint32_t(v % grid.dims[0]), uint32_t(v / grid.dims[0] % grid.dims[1]),
                                   uint32_t(v / (uint64_t(grid.dims[0]) * grid.dims[1]))};
            for (int k = 0; k < 3; ++k) {
                box.lo[k] = c[k];
                box.hi[k] = c[k] + 1;
            }
        } else {
            box = boxes[size_t(h.voxel[i])];
        }
        for (int k = 0; k < 3; ++k) {
            const float factor = partition.factor[k];
            const float t = eval::gridCoordinate(h.points[i][k], grid.lower[k], factor);
            const float extent = float(box.hi[k] - box.lo[k]);
            for (uint32_t faceAt : {box.lo[k], box.hi[k]}) {
                const float face = float(faceAt);
                if (faceAt == 0 || faceAt == grid.dims[k] || std::abs(t - face) > 0.02f * extent) continue;
                for (float side : {-1e-4f, 1e-4f}) {
                    glm::vec3 q = h.points[i];
                    q[k] = grid.lower[k] + (face + side) / factor;
                    for (int c = 0; c < 3; ++c) {
                        p.push_back(q[c]);
                        n.push_back(h.normals[i][c]);
                        d.push_back(h.directions[i][c]);
                    }
                }
            }
        }
    }
    SeamFigure f;
    {
        NradAssetInfo info;
        nradGetAssetInfo(asset, &info);
        std::vector<bool> occupied(size_t(partition.cells), false);
        for (uint32_t i = 0; i < info.occupiedVoxels; ++i) {
            uint32_t v = 0;
            if (nradGetOccupiedVoxel(asset, i, &v) == NRAD_OK && v < occupied.size()) occupied[v] = true;
        }
        size_t points = 0, evaluations = 0, blended = 0;
        for (size_t i = 0; i < h.voxel.size(); ++i) {
            if (h.voxel[i] < 0) continue;
            const float q[3] = {h.points[i].x, h.points[i].y, h.points[i].z};
            eval::Support s[eval::kMaxSupports];
            int kept = partition.supports(q, s);
            kept = eval::keepOccupied(s, kept, [&](int64_t v) { return occupied[size_t(v)]; });
            if (kept == 0) continue;
            ++points;
            evaluations += size_t(kept);
            blended += kept > 1 ? 1 : 0;
        }
        if (points > 0) {
            f.evaluationsPerPoint = double(evaluations) / double(points);
            f.blendedShare = double(blended) / double(points);
        }
    }
    const size_t count = p.size() / 3;
    if (count == 0) return f;
    std::vector<float> rgb(3 * count);
    std::vector<uint8_t> flags(count);
    if (nradEvaluateBatch(asset, count, p.data(), n.data(), d.data(), rgb.data(), flags.data()) != NRAD_OK) return f;
    for (size_t j = 0; j + 1 < count; j += 2) {
        if (flags[j] != NRAD_POINT_OK || flags[j + 1] != NRAD_POINT_OK) continue;  // a face with an empty voxel
        ++f.points;
        for (int c = 0; c < 3; ++c) {
            double a = rgb[3 * j + size_t(c)], b = rgb[3 * (j + 1) + size_t(c)], m = 0.5 * (a + b);
            f.relMse += (a - b) * (a - b) / (m * m + 0.01);
            f.meanRelativeJump += std::abs(a - b) / (m + 0.01);
        }
    }
    if (f.points > 0) {
        f.relMse /= 3.0 * double(f.points);
        f.meanRelativeJump /= 3.0 * double(f.points);
    }
    return f;
}

namespace {

void equalError(MethodResult& m, const std::vector<CurvePoint>& curve) {
    m.equalErrorSeconds = equalErrorTime(curve, m.metrics.relMse, m.equalErrorExtrapolated);
    m.speedupOverEvaluation = m.evaluationSeconds > 0.0 ? m.equalErrorSeconds / m.evaluationSeconds : 0.0;
    m.speedupOverRender = m.seconds > 0.0 ? m.equalErrorSeconds / m.seconds : 0.0;
}

}  // namespace

namespace {

// Bump when the renderer's output changes (2: issue 12; 3: issue 14); "key 2" (issue 37): the scene's part of the
// reference's key became referenceSceneHash, and near-mirror GGX and soft suns changed glossy and sunlit images.
// Both cache keys hash it: the baseline's samples are traced by the same renderer.
constexpr char kRendererVersion[] = "nrad path tracer 3, key 2";

// A cache key's file-name form: 16 hex digits.
std::string hexKey(uint64_t h) {
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", (unsigned long long)h);
    return hex;
}

template <class T>
void fnvAll(uint64_t& h, const std::vector<T>& v) {
    const uint64_t count = v.size();
    fnv1a(h, &count, sizeof count);
    if (!v.empty()) fnv1a(h, v.data(), v.size() * sizeof(T));
}

void fnvTextureRef(uint64_t& h, const TextureRef& t) {
    const int i[] = {t.texture, t.texCoord};
    const float f[] = {t.offset.x, t.offset.y, t.rotation, t.scale.x, t.scale.y};
    fnv1a(h, i, sizeof i);
    fnv1a(h, f, sizeof f);
}

}  // namespace

uint64_t referenceSceneHash(const Scene& scene) {
    uint64_t h = kFnvOffsetBasis;
    const TriangleMesh& m = scene.mesh;
    fnvAll(h, m.positions);
    fnvAll(h, m.normals);
    fnvAll(h, m.uv0);
    fnvAll(h, m.uv1);
    fnvAll(h, m.colors);
    fnvAll(h, m.tangents);
    fnvAll(h, m.triangles);
    fnvAll(h, m.materialIds);
    const uint64_t materials = scene.materials.size();
    fnv1a(h, &materials, sizeof materials);
    for (const Material& mat : scene.materials) {  // everything but the name
        const float f[] = {mat.baseColor.x, mat.baseColor.y, mat.baseColor.z, mat.metallic, mat.roughness, mat.emission.x,
                           mat.emission.y, mat.emission.z, mat.specular, mat.specularColor.x, mat.specularColor.y, mat.specularColor.z,
                           mat.ior, float(mat.doubleSided), mat.transmission, mat.normalScale, float(int(mat.alphaMode)), mat.alpha,
                           mat.alphaCutoff};
        fnv1a(h, f, sizeof f);
        for (const TextureRef* t : {&mat.baseColorTexture, &mat.metallicRoughnessTexture, &mat.emissiveTexture,
                                    &mat.transmissionTexture, &mat.normalTexture})
            fnvTextureRef(h, *t);
    }
    const uint64_t textures = scene.textures.size();
    fnv1a(h, &textures, sizeof textures);
    for (const Texture& t : scene.textures) {
        const int i[] = {t.width, t.height, int(t.wrapS), int(t.wrapT)};
        fnv1a(h, i, sizeof i);
        if (t.bytes.empty()) {
            const uint64_t count = t.texels.size();
            fnv1a(h, &count, sizeof count);
            if (count > 0) fnv1a(h, t.texels.data(), t.texels.size() * sizeof t.texels[0]);
        } else {  // the bytes and the tables that decode them (sRGB or linear)
            const uint64_t count = t.bytes.size();
            fnv1a(h, &count, sizeof count);
            fnv1a(h, t.bytes.data(), t.bytes.size());
            if (t.colour) fnv1a(h, t.colour, 256 * sizeof(float));
            if (t.alpha) fnv1a(h, t.alpha, 256 * sizeof(float));
        }
    }
    const uint64_t lights = scene.lights.size();
    fnv1a(h, &lights, sizeof lights);
    for (const PunctualLight& l : scene.lights) {  // not runtimeDirect: the reference draws every light whole
        const float f[] = {float(int(l.type)), l.position.x, l.position.y, l.position.z, l.direction.x, l.direction.y, l.direction.z,
                           l.intensity.x, l.intensity.y, l.intensity.z, l.cosInnerCone, l.cosOuterCone, l.cosAngularRadius};
        fnv1a(h, f, sizeof f);
    }
    const Environment& e = scene.environment;
    const int active = e.active() ? 1 : 0;
    fnv1a(h, &active, sizeof active);
    if (active) {
        const float f[] = {float(int(e.kind)), e.color.x, e.color.y, e.color.z, e.intensity, e.rotationDegrees, float(e.width), float(e.height)};
        fnv1a(h, f, sizeof f);
        fnvAll(h, e.texels);
    }
    return h;
}

std::string referenceKey(const Scene& scene, const ValidateSettings& s, int width, int height) {
    uint64_t h = referenceSceneHash(scene);
    const Camera& c = s.camera;
    int type = int(c.type);
    fnv1a(h, &type, sizeof type);
    fnv1a(h, &c.position, sizeof c.position);
    fnv1a(h, &c.worldFromCamera, sizeof c.worldFromCamera);
    float f[] = {c.yfov, c.aspectRatio, c.xmag, c.ymag};
    fnv1a(h, f, sizeof f);
    int v[] = {width, height, s.referenceSpp, s.maxDepth, int(s.seed)};
    fnv1a(h, v, sizeof v);
    fnv1a(h, kRendererVersion, sizeof kRendererVersion);
    return hexKey(h);
}

std::string baselineKey(const Scene& baked, const BaselineKeyInputs& in) {
    uint64_t h = referenceSceneHash(baked);
    for (const PunctualLight& l : baked.lights) {  // the lights whose direct light the samples leave out
        const int drawn = l.runtimeDirect ? 1 : 0;
        fnv1a(h, &drawn, sizeof drawn);
    }
    const SampleSettings& ss = in.samples;
    // Every field of SampleSettings below: a new one must join them (or say why the probes do not depend on it).
    static_assert(sizeof(SampleSettings) == 48, "SampleSettings changed: add the new field to baselineKey");
    const uint64_t u[] = {ss.points, ss.paths, uint64_t(int64_t(ss.maxDepth)), ss.seed, ss.minSamplesPerVoxel, ss.dropHidden ? 1u : 0u,
                          ss.neeWarmupPaths, ss.firstPoint, ss.generation, ss.extraPathsFactor, in.samplingDims.x, in.samplingDims.y,
                          in.samplingDims.z, in.probes.x, in.probes.y, in.probes.z, in.demodulated ? 1u : 0u};
    fnv1a(h, u, sizeof u);
    const float f[] = {ss.noisyRelativeError, in.lower.x, in.lower.y, in.lower.z, in.upper.x, in.upper.y, in.upper.z};
    fnv1a(h, f, sizeof f);
    // The renderer's version, and the fit's: bump it when the samples' use or the fit changes what it gives.
    fnv1a(h, kRendererVersion, sizeof kRendererVersion);
    const char version[] = "nrad sh baseline 1";
    fnv1a(h, version, sizeof version);
    return hexKey(h);
}

std::vector<size_t> materialsByNeuralShare(const ValidationResult& r) {
    const std::vector<RegionError>& m = r.neural.byMaterial;
    std::vector<size_t> order;
    for (size_t k = 0; k < r.materialNames.size() && k < m.size(); ++k)
        if (m[k].pixels > 0) order.push_back(k);
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return m[a].shareOfImage > m[b].shareOfImage; });
    return order;
}

double referenceNoise(const std::vector<CurvePoint>& curve, int referenceSpp) {
    if (curve.empty() || referenceSpp <= 0) return 0.0;
    const CurvePoint& last = curve.back();
    return last.metrics.relMse * double(last.spp) / (double(last.spp) + double(referenceSpp));
}

double referenceBlockNoise(double rms, int spp, int referenceSpp) {
    if (spp <= 0 || referenceSpp <= 0 || !(rms >= 0.0)) return 0.0;
    return rms * std::sqrt(double(spp) / (double(spp) + double(referenceSpp)));
}

double equalErrorTime(const std::vector<CurvePoint>& curve, double relMse, bool& extrapolated) {
    extrapolated = true;
    if (curve.empty() || !(relMse > 0.0)) return 0.0;
    // relMSE falls with time; find the segment that brackets the target, interpolate log-log.
    for (size_t i = 1; i < curve.size(); ++i) {
        double e0 = curve[i - 1].metrics.relMse, e1 = curve[i].metrics.relMse;
        if ((e0 >= relMse && relMse >= e1) && e0 > 0.0 && e1 > 0.0 && e0 != e1) {
            double t = (std::log(relMse) - std::log(e0)) / (std::log(e1) - std::log(e0));
            extrapolated = false;
            return std::exp(std::log(curve[i - 1].seconds) + t * (std::log(curve[i].seconds) - std::log(curve[i - 1].seconds)));
        }
    }
    // Outside the curve: Monte Carlo error ~ 1 / samples ~ 1 / time, from the nearer end.
    const CurvePoint& end = relMse > curve.front().metrics.relMse ? curve.front() : curve.back();
    return end.metrics.relMse > 0.0 ? end.seconds * end.metrics.relMse / relMse : 0.0;
}

namespace {

// Says a line to the validation's log, if it has one.
struct Say {
    const std::function<void(const std::string&)>& log;
    void operator()(const std::string& line) const {
        if (log) log(line);
    }
};

// What every phase of a validation uses: the scene and its tracing, the settings, the log, the result.
struct ValidationRun {
    const Scene& scene;
    const ValidateSettings& settings;
    const Say say;
    ValidationResult& r;
    const Accel& accel;
    const LightSampler& lights;
    const PathTracer& tracer;
    RenderSettings rs;  // the image size and path length every render shares
    // The scene as baked (without the objects --insert placed; the same as `scene` without any): what the
    // baselines are fitted in and the exact volume light is traced in, as the asset was baked.
    const Scene& baked;
    const Accel& bakedAccel;
    const LightSampler& bakedLights;
};

// The result's description of the run, and the image size (height from the camera's aspect ratio if unset).
void describeRun(ValidationResult& r, const Scene& scene, const std::string& scenePath, const std::string& assetPath,
                 const ValidateSettings& settings) {
    r.scenePath = scenePath;
    r.assetPath = assetPath;
    r.environment = scene.environment.describe();
    r.settings = settings;
    const Camera& camera = settings.camera;
    float aspect = camera.aspectRatio > 0.0f ? camera.aspectRatio : 1.0f;
    r.width = std::max(1, settings.width);
    r.height = settings.height > 0 ? settings.height : std::max(1, int(std::lround(float(r.width) / aspect)));
}

// 1. The reference: given, cached, or rendered (and cached).
void obtainReference(ValidationRun& v) {
    ValidationResult& r = v.r;
    const ValidateSettings& settings = v.settings;
    if (!settings.referenceImage.empty()) {
        r.reference = readExr(settings.referenceImage);
        if (r.reference.width != r.width || r.reference.height != r.height)
            throw std::runtime_error(settings.referenceImage + ": the reference is " + std::to_string(r.reference.width) + "x" +
                                     std::to_string(r.reference.height) + ", the validation renders " + std::to_string(r.width) +
                                     "x" + std::to_string(r.height));
        r.referenceSource = settings.referenceImage;
        return;
    }
    std::string key = referenceKey(v.scene, settings, r.width, r.height);
    if (!settings.cacheDir.empty()) r.referenceCacheFile = (fs::path(settings.cacheDir) / ("reference-" + key + ".exr")).string();
    if (!r.referenceCacheFile.empty() && fs::exists(r.referenceCacheFile)) {
        try {
            Image cached = readExr(r.referenceCacheFile);
            if (cached.width == r.width && cached.height == r.height) {
                r.reference = std::move(cached);
                r.referenceSource = "cache";
            }
        } catch (const std::exception&) {
            // unreadable cache entry: render again and replace it
        }
    }
    if (!r.referenceSource.empty()) {
        v.say("reference: from the cache, " + r.referenceCacheFile);
        return;
    }
    v.say("reference: path tracing " + std::to_string(r.width) + "x" + std::to_string(r.height) + " at " +
          std::to_string(settings.referenceSpp) + " spp, path length " +
          (settings.maxDepth ? std::to_string(settings.maxDepth) : std::string("unbounded")));
    RenderSettings ref = v.rs;
    ref.spp = settings.referenceSpp;
    ref.seed = settings.seed;
    RenderStats st;
    r.reference = v.tracer.render(settings.camera, ref, &st);
    r.referenceSeconds = st.seconds;
    r.referenceSource = "rendered";
    if (!r.referenceCacheFile.empty()) {
        fs::create_directories(settings.cacheDir);
        writeExr(r.referenceCacheFile, r.reference);
    }
}

// 2. The path tracer's convergence against the reference, with an independent seed, and the reference's
// noise estimated from it. Returns the curve's last image (for the reference's block noise, once the surface
// pixels are known).
Image convergenceCurve(ValidationRun& v) {
    ValidationResult& r = v.r;
    const ValidateSettings& settings = v.settings;
    Image lastCurveImage;
    for (long long spp = 1; spp <= std::max(1, settings.curveMaxSpp); spp *= 2) {
        RenderSettings c = v.rs;
        c.spp = int(spp);
        c.seed = settings.seed + 1;
        RenderStats st;
        Image img = v.tracer.render(settings.camera, c, &st);
        r.curve.push_back({int(spp), st.seconds, compareImages(img, r.reference, settings.exposure)});
        char line[160];
        std::snprintf(line, sizeof line, "path tracer %4lld spp: %.3f s, relMSE %.4g", spp, st.seconds, r.curve.back().metrics.relMse);
        v.say(line);
        lastCurveImage = std::move(img);
    }
    if (settings.referenceImage.empty()) {
        r.referenceNoise = referenceNoise(r.curve, settings.referenceSpp);
        char line[200];
        std::snprintf(line, sizeof line, "reference noise: about %.3g of every relMSE against it (from the curve's %d spp point)",
                      r.referenceNoise, r.curve.empty() ? 0 : r.curve.back().spp);
        v.say(line);
    }
    return lastCurveImage;
}

// The asset's partition: from its file (a kd-tree needs it); an asset given only in memory is a grid,
// whose partition its info holds.
eval::Partition partitionOf(const NradAssetInfo& info, const std::string& assetPath) {
    if (!assetPath.empty() && std::filesystem::is_regular_file(assetPath)) return assetPartition(assetPath);
    if (info.contentFlags & NRAD_CONTENT_TREE) throw std::runtime_error("a kd-tree asset must be validated from its file");
    format::Grid g;
    for (int k = 0; k < 3; ++k) {
        g.lower[k] = info.gridLower[k];
        g.upper[k] = info.gridUpper[k];
        g.dims[k] = info.gridDims[k];
    }
    return eval::Partition(g, info.blendBand, {}, 0);
}

// What each pixel's centre sees (region, material, cell, surface), the reference's block noise (from the
// curve's last image, now that the surface pixels are known) and the materials' names.
void mapPixels(ValidationRun& v, const FirstHits& hits, const Image& lastCurveImage) {
    ValidationResult& r = v.r;
    r.regionOfPixel = pixelRegions(hits);
    r.materialOfPixel = hits.material;
    r.cellOfPixel = hits.voxel;
    r.surfaceOfPixel.assign(hits.material.size(), 0);
    for (size_t i = 0; i < hits.material.size(); ++i) r.surfaceOfPixel[i] = hits.material[i] >= 0 && !hits.emitter[i];
    if (v.settings.referenceImage.empty() && !r.curve.empty() && lastCurveImage.width == r.reference.width &&
        lastCurveImage.height == r.reference.height) {
        const BlockFigure curveBlocks = blockFigure(lastCurveImage, r.reference, r.surfaceOfPixel, std::max(1, r.width / 16));
        if (curveBlocks.blocks > 0) r.referenceBlockNoise = referenceBlockNoise(curveBlocks.rms, r.curve.back().spp, v.settings.referenceSpp);
    }
    for (size_t k = 0; k < v.scene.materials.size(); ++k)
        r.materialNames.push_back(v.scene.materials[k].name.empty() ? "material " + std::to_string(k) : v.scene.materials[k].name);
}

// The seam figure, said.
void measureSeams(ValidationRun& v, const FirstHits& hits, const eval::Partition& partition, NradAsset asset) {
    ValidationResult& r = v.r;
    r.seams = seamFigure(hits, partition, asset);
    char line[320];
    std::snprintf(line, sizeof line,
                  "seams: %zu points on shared voxel faces, relMSE across them %.4g, mean relative jump %.4g; "
                  "%.3g network evaluations per visible point (%.1f%% blended)",
                  r.seams.points, r.seams.relMse, r.seams.meanRelativeJump, r.seams.evaluationsPerPoint, 100.0 * r.seams.blendedShare);
    v.say(line);
}

// 3. Through the asset, as an engine would (the public runtime API): rendered at first hits and scored.
void renderNeural(ValidationRun& v, NradAsset asset, const std::string& assetPath, const NradAssetInfo& info,
                  const eval::Partition& partition, const RenderSettings& fh) {
    ValidationResult& r = v.r;
    MethodResult m;
    m.name = "neural";
    NeuralRenderStats st;
    if (NradStatus s = renderThroughAsset(v.scene, v.accel, asset, v.settings.camera, fh, m.image, &st); s != NRAD_OK)
        throw std::runtime_error(assetPath + ": evaluation failed: " + nradStatusString(s));
    score(m, st, r, v.settings.exposure);
    // The networks' weights and, for an adaptive asset, its tree's nodes (8 bytes each).
    m.bytes = size_t(info.occupiedVoxels) * info.parametersPerNetwork * (info.weightEncoding == 1 ? 2 : 4) + partition.tree.size() * 8;
    equalError(m, r.curve);
    r.neural = std::move(m);
    char line[200];
    std::snprintf(line, sizeof line, "neural (%d spp): %.3g s (evaluation %.3g s), relMSE %.4g", v.settings.neuralSpp, r.neural.seconds,
                  r.neural.evaluationSeconds, r.neural.metrics.relMse);
    v.say(line);
}

// The asset's metadata, and the notes on truncated light transport (the reference's cut, the bake's).
void readMetadataAndBias(ValidationRun& v, NradAsset asset) {
    ValidationResult& r = v.r;
    const ValidateSettings& settings = v.settings;
    const char* json = nullptr;
    size_t length = 0;
    if (nradGetMetadata(asset, &json, &length) == NRAD_OK && length > 0)
        r.assetMetadata = nlohmann::json::parse(std::string(json, length), nullptr, false);
    if (r.assetMetadata.is_discarded()) r.assetMetadata = nullptr;
    if (settings.maxDepth > 0)
        r.biasNotes.push_back("the reference's paths are cut at " + std::to_string(settings.maxDepth) +
                              " segments: it lacks the light of longer paths, and every figure here is against that cut "
                              "solution, not the full light transport (--max-depth 0, the default)");
    if (r.assetMetadata.is_object()) {
        const nlohmann::json bake = r.assetMetadata.value("bake", nlohmann::json());
        const nlohmann::json depth = bake.is_object() ? bake.value("max_depth", nlohmann::json()) : nlohmann::json();
        if (depth.is_number_integer() && depth.get<int>() > 0)
            r.biasNotes.push_back("the asset was baked with paths cut at " + std::to_string(depth.get<int>()) +
                                  " segments (--max-depth): it lacks the light of longer paths" +
                                  (settings.maxDepth == 0 ? std::string(", a bias in the figures against the unbounded reference")
                                                          : std::string()));
    }
    for (const std::string& note : r.biasNotes) v.say("bias: " + note);
}

// The baseline's sample settings: the bake's own (from the asset's metadata) or the defaults; `dims` receives
// the sampling grid (the bake's grid, else the asset's).
SampleSettings bakeSampleSettings(ValidationResult& r, const NradAssetInfo& info, glm::uvec3& dims) {
    SampleSettings ss = defaultBakeSamples();  // a bake's at the defaults
    dims = glm::uvec3(info.gridDims[0], info.gridDims[1], info.gridDims[2]);  // the sampling grid (its floor)
    const nlohmann::json& bake = r.assetMetadata.is_object() ? r.assetMetadata.value("bake", nlohmann::json()) : nlohmann::json();
    if (!bake.is_object()) {
        r.baselineSamplesNote = "default bake settings (the asset has no metadata)";
        return ss;
    }
    ss.points = bake.value("points", ss.points);
    ss.paths = bake.value("paths", ss.paths);
    ss.maxDepth = bake.value("max_depth", ss.maxDepth);
    ss.seed = bake.value("seed", ss.seed);
    ss.minSamplesPerVoxel = bake.value("min_samples_per_voxel", ss.minSamplesPerVoxel);
    const nlohmann::json g = bake.value("grid", nlohmann::json());  // a kd-tree's lattice is not the sampling grid
    if (g.is_array() && g.size() == 3) dims = glm::uvec3(g[0].get<uint32_t>(), g[1].get<uint32_t>(), g[2].get<uint32_t>());
    r.baselineSamplesNote = "the bake's own settings, from the asset's metadata";
    const nlohmann::json training = bake.value("training", nlohmann::json());
    if (training.is_object() && training.value("method", std::string()) == "integral") {
        // Trained within the integral equation: its own samples are one-bounce targets against its
        // networks, of no use to probes, and its start's few paths would handicap them. The probes get
        // what a Monte Carlo bake at the defaults would have given them.
        const SampleSettings defaults = defaultBakeSamples();
        ss.points = defaults.points;
        ss.paths = defaults.paths;
        ss.maxDepth = 0;
        r.baselineSamplesNote = "Monte Carlo samples at the bake defaults, unbounded (the asset was trained within the integral equation)";
    }
    return ss;
}

// The baseline's training budget for `probeCount` probes (kBaselinePointsPerProbe says why): the first
// points of the sequence, then fewer paths a point.
void capBaselineBudget(ValidationResult& r, const ValidateSettings& settings, uint64_t probeCount, SampleSettings& ss) {
    if (settings.baselinePointsPerProbe > 0) {
        const uint64_t budget = std::max<uint64_t>(settings.baselineMinPoints, uint64_t(settings.baselinePointsPerProbe) * probeCount);
        if (uint64_t(ss.points) > budget) {
            // The first points of the same sequence: a subset of the very points the networks learnt from.
            ss.points = uint32_t(budget);
            r.baselineSamplesNote += "; its first " + std::to_string(ss.points) + " points (at most max(" +
                                     std::to_string(settings.baselineMinPoints) + ", " + std::to_string(settings.baselinePointsPerProbe) +
                                     " per probe))";
        }
    }
    if (settings.baselinePathsPerProbe > 0 && ss.points > 0) {
        const uint64_t budget = std::max<uint64_t>(settings.baselineMinPaths, uint64_t(settings.baselinePathsPerProbe) * probeCount);
        const uint32_t paths = uint32_t(std::clamp<uint64_t>(budget / ss.points, 1, ss.paths));
        if (paths < ss.paths) {
            // The same points, each with fewer paths: least squares averages the noise over a probe's points.
            r.baselineSamplesNote += "; " + std::to_string(paths) + " paths a point, not " + std::to_string(ss.paths) + " (at most max(" +
                                     std::to_string(settings.baselineMinPaths) + ", " + std::to_string(settings.baselinePathsPerProbe) +
                                     " per probe) paths)";
            ss.paths = paths;
        }
    }
    // No extra paths for noisy targets: least squares averages a probe's noise over its points, and the
    // extra paths cost time for no better probes (docs/usage.md, "Baseline"). The paths budget above
    // counts every path.
    ss.extraPathsFactor = 1;
}

// The baseline's training samples (traced like the asset's networks' own) and the probes fitted to them,
// with progress lines at every tenth and the time since t0, when the baseline began.
ShProbeGrid fitBaseline(ValidationRun& v, const NradAssetInfo& info, const SampleSettings& ss, const glm::uvec3& dims,
                        clock_type::time_point t0) {
    ValidationResult& r = v.r;
    const glm::vec3 lower(info.gridLower[0], info.gridLower[1], info.gridLower[2]);
    const glm::vec3 upper(info.gridUpper[0], info.gridUpper[1], info.gridUpper[2]);
    const uint64_t probeCount = uint64_t(r.baselineProbes.x) * r.baselineProbes.y * r.baselineProbes.z;
    VoxelGrid grid(v.baked.bounds, dims);
    SurfacePieces pieces(v.baked.mesh, grid);
    SampleStats sst;
    v.say("baseline: training samples (" + std::to_string(ss.points) + " points x " + std::to_string(ss.paths) + " paths, for " +
          std::to_string(probeCount) + " probes)");
    // Progress lines at every tenth (the sampler calls from its worker threads).
    std::mutex progressMutex;
    auto tenths = [&](const char* what) {
        return [&, what, last = 0](double fraction) mutable {
            std::lock_guard<std::mutex> lock(progressMutex);
            const int tenth = std::min(10, int(fraction * 10.0 + 1e-9));
            if (tenth <= last) return;
            last = tenth;
            char line[120];
            std::snprintf(line, sizeof line, "baseline: %s %d%% (%.1f s)", what, 10 * tenth, since(t0));
            v.say(line);
        };
    };
    // Trained like the asset's networks: without the direct light of lights the engine draws.
    PathTracer baselineTracer(v.baked, v.bakedAccel, v.bakedLights);
    baselineTracer.setExcludeEngineDrawnDirect(true);
    baselineTracer.setRouletteThreshold(kTrainingRouletteThreshold);
    std::vector<TrainingSample> samples =
        generateTrainingSamples(v.baked, baselineTracer, grid, pieces, ss, sst, std::function<void(double)>(tenths("sampling")));
    const double samplingSeconds = since(t0);
    // The probes follow the asset's contract: demodulated like its networks where it is (as engines'
    // probes store lighting and multiply by the albedo), so both are shaded alike.
    if (info.contentFlags & NRAD_CONTENT_DEMODULATED)
        for (TrainingSample& t : samples) t.radiance /= demodulationDivisor(t);
    r.baselineTrainingSamples = samples.size();
    r.baselineTrainingPaths = (sst.points + sst.floorPoints) * ss.paths + sst.extraPaths;
    v.say("baseline: fitting " + std::to_string(r.baselineProbes.x) + "x" + std::to_string(r.baselineProbes.y) + "x" +
          std::to_string(r.baselineProbes.z) + " probes to " + std::to_string(samples.size()) + " samples");
    ShProbeGrid probes =
        fitShProbeGrid(samples, lower, upper, r.baselineProbes, &r.baselineFit, 1e-4, std::function<void(double)>(tenths("fit")));
    r.baselineSeconds = since(t0);
    char line[160];
    std::snprintf(line, sizeof line, "baseline: %.1f s (sampling %.1f s, fit %.1f s, %d CG iterations)", r.baselineSeconds,
                  samplingSeconds, r.baselineSeconds - samplingSeconds, r.baselineFit.iterations);
    v.say(line);
    return probes;
}

// The probes' first-hit render, scored like the asset's.
void renderBaseline(ValidationRun& v, const ShProbeGrid& probes, const ShIrradianceGrid* irradiance, const NradAssetInfo& info,
                    const RenderSettings& fh) {
    ValidationResult& r = v.r;
    FirstHitEvaluator evaluate = [&probes](size_t n, const float* p, const float* /*normals*/, const float* d, float* rgb,
                                           uint8_t* flags) {
        for (size_t i = 0; i < n; ++i) {
            glm::vec3 L = probes.evaluate({p[3 * i], p[3 * i + 1], p[3 * i + 2]}, {d[3 * i], d[3 * i + 1], d[3 * i + 2]});
            for (int c = 0; c < 3; ++c) rgb[3 * i + size_t(c)] = std::isfinite(L[c]) ? L[c] : 0.0f;
            flags[i] = NRAD_POINT_OK;
        }
        return NRAD_OK;
    };
    VolumeEvaluator volume;  // inserted objects: the irradiance probes
    if (irradiance)
        volume = [irradiance](size_t n, const float* p, const float* nrm, float* rgb, uint8_t* flags) {
            for (size_t i = 0; i < n; ++i) {
                const glm::vec3 D = irradiance->evaluate({p[3 * i], p[3 * i + 1], p[3 * i + 2]}, {nrm[3 * i], nrm[3 * i + 1], nrm[3 * i + 2]});
                for (int c = 0; c < 3; ++c) rgb[3 * i + size_t(c)] = std::isfinite(D[c]) ? D[c] : 0.0f;
                flags[i] = NRAD_POINT_OK;
            }
            return NRAD_OK;
        };
    MethodResult m;
    m.name = "sh-probes";
    NeuralRenderStats st;
    renderFirstHit(v.scene, v.accel, evaluate, info.contentFlags, v.settings.camera, fh, m.image, &st, {}, volume);
    score(m, st, r, v.settings.exposure);
    m.bytes = probes.bytes();
    equalError(m, r.curve);
    r.baseline = std::move(m);
    char line[200];
    std::snprintf(line, sizeof line, "baseline: %ux%ux%u L2 SH probes (%zu bytes), fit relMSE %.4g, image relMSE %.4g", r.baselineProbes.x,
                  r.baselineProbes.y, r.baselineProbes.z, r.baseline->bytes, r.baselineFit.trainRelMse, r.baseline->metrics.relMse);
    v.say(line);
}

// The inserted objects' baseline: L2 SH irradiance probes over the asset's grid, of the volume networks' bytes (of
// the surfaces' where the asset has no volume), estimated as the volume is trained (the bake's path length, no
// engine-drawn direct light).
ShIrradianceGrid fitIrradianceBaseline(ValidationRun& v, const NradAssetInfo& info, const SampleSettings& ss) {
    ValidationResult& r = v.r;
    const glm::vec3 lower(info.gridLower[0], info.gridLower[1], info.gridLower[2]);
    const glm::vec3 upper(info.gridUpper[0], info.gridUpper[1], info.gridUpper[2]);
    r.irradianceProbes = irradianceDimsForBudget(lower, upper, r.volumeBytes > 0 ? r.volumeBytes : r.neural.bytes);
    PathTracer tracer(v.baked, v.bakedAccel, v.bakedLights);
    tracer.setExcludeEngineDrawnDirect(true);
    tracer.setRouletteThreshold(kTrainingRouletteThreshold);
    ShIrradianceFit fit;
    fit.seed = ss.seed;
    fit.maxDepth = ss.maxDepth;
    const uint64_t probes = uint64_t(r.irradianceProbes.x) * r.irradianceProbes.y * r.irradianceProbes.z;
    const uint64_t cap = std::max<uint64_t>(uint64_t(1) << 22, 256 * probes);  // paths in all
    fit.pathsPerNormal = uint32_t(std::clamp<uint64_t>(cap / (probes * fit.normalsPerProbe), 1, fit.pathsPerNormal));
    const ShIrradianceGrid g = fitShIrradianceGrid(tracer, lower, upper, r.irradianceProbes, fit, &r.irradianceFit);
    char line[256];
    std::snprintf(line, sizeof line, "baseline: %ux%ux%u L2 SH irradiance probes for the inserted objects (%zu bytes; %llu inside solids left out), %.1f s",
                  r.irradianceProbes.x, r.irradianceProbes.y, r.irradianceProbes.z, g.bytes(), (unsigned long long)r.irradianceFit.leftOut,
                  r.irradianceFit.seconds);
    v.say(line);
    return g;
}

// The baseline's cache file: "NRADSHB1", then the probes (dims, box, fp16-rounded coefficients as float) and what
// the report says of their fit. Anything else read (another layout, a short file) is no entry.
constexpr char kBaselineCacheMagic[8] = {'N', 'R', 'A', 'D', 'S', 'H', 'B', '1'};

struct CachedBaseline {
    ShProbeGrid probes;
    ShFitStats fit;
    uint64_t trainingSamples = 0, trainingPaths = 0;
    double seconds = 0.0;
};

template <class T>
void appendBytes(std::vector<uint8_t>& out, const T& value) {
    const auto* b = reinterpret_cast<const uint8_t*>(&value);
    out.insert(out.end(), b, b + sizeof value);
}

std::vector<uint8_t> encodeBaseline(const CachedBaseline& c) {
    std::vector<uint8_t> out(kBaselineCacheMagic, kBaselineCacheMagic + 8);
    for (int k = 0; k < 3; ++k) appendBytes(out, uint32_t(c.probes.dims[k]));
    for (int k = 0; k < 3; ++k) appendBytes(out, c.probes.lower[k]);
    for (int k = 0; k < 3; ++k) appendBytes(out, c.probes.upper[k]);
    appendBytes(out, int32_t(c.fit.iterations));
    appendBytes(out, c.fit.relativeResidual);
    appendBytes(out, c.fit.trainRelMse);
    appendBytes(out, c.trainingSamples);
    appendBytes(out, c.trainingPaths);
    appendBytes(out, c.seconds);
    appendBytes(out, uint64_t(c.probes.coeffs.size()));
    const auto* b = reinterpret_cast<const uint8_t*>(c.probes.coeffs.data());
    out.insert(out.end(), b, b + c.probes.coeffs.size() * sizeof(float));
    return out;
}

// The entry, if `bytes` is one for probes of `dims` over lower..upper (else nullopt).
std::optional<CachedBaseline> decodeBaseline(const std::vector<uint8_t>& bytes, const glm::uvec3& dims, const glm::vec3& lower,
                                             const glm::vec3& upper) {
    size_t at = 0;
    auto take = [&](auto& value) {
        if (bytes.size() - at < sizeof value) return false;
        std::memcpy(&value, bytes.data() + at, sizeof value);
        at += sizeof value;
        return true;
    };
    if (bytes.size() < 8 || std::memcmp(bytes.data(), kBaselineCacheMagic, 8) != 0) return std::nullopt;
    at = 8;
    CachedBaseline c;
    uint32_t d[3];
    int32_t iterations = 0;
    uint64_t count = 0;
    bool ok = take(d[0]) && take(d[1]) && take(d[2]);
    for (int k = 0; k < 3; ++k) ok = ok && take(c.probes.lower[k]);
    for (int k = 0; k < 3; ++k) ok = ok && take(c.probes.upper[k]);
    ok = ok && take(iterations) && take(c.fit.relativeResidual) && take(c.fit.trainRelMse) && take(c.trainingSamples) &&
         take(c.trainingPaths) && take(c.seconds) && take(count);
    if (!ok || glm::uvec3(d[0], d[1], d[2]) != dims || c.probes.lower != lower || c.probes.upper != upper) return std::nullopt;
    for (double x : {c.fit.relativeResidual, c.fit.trainRelMse, c.seconds})
        if (!std::isfinite(x)) return std::nullopt;
    c.probes.dims = dims;
    if (count != uint64_t(c.probes.probeCount()) * 27 || bytes.size() - at != count * sizeof(float)) return std::nullopt;
    c.probes.coeffs.resize(size_t(count));
    std::memcpy(c.probes.coeffs.data(), bytes.data() + at, size_t(count) * sizeof(float));
    for (float x : c.probes.coeffs)
        if (!std::isfinite(x)) return std::nullopt;
    c.fit.iterations = iterations;
    return c;
}

// The baseline's probes: from the cache, where the same probes were fitted before (baselineKey), else fitted now
// (fitBaseline) and cached; r's baseline fields either way.
ShProbeGrid cachedOrFittedProbes(ValidationRun& v, const NradAssetInfo& info, const SampleSettings& ss, const glm::uvec3& dims,
                                 const glm::vec3& lower, const glm::vec3& upper, clock_type::time_point t0) {
    ValidationResult& r = v.r;
    if (!v.settings.cacheDir.empty()) {
        BaselineKeyInputs key;
        key.samples = ss;
        key.samplingDims = dims;
        key.lower = lower;
        key.upper = upper;
        key.probes = r.baselineProbes;
        key.demodulated = (info.contentFlags & NRAD_CONTENT_DEMODULATED) != 0;
        r.baselineCacheFile = (fs::path(v.settings.cacheDir) / ("baseline-" + baselineKey(v.baked, key) + ".bin")).string();
    }
    std::optional<CachedBaseline> cached;
    std::error_code noEntry;
    if (!r.baselineCacheFile.empty() && fs::exists(r.baselineCacheFile, noEntry)) {
        try {
            cached = decodeBaseline(readFileBytes(r.baselineCacheFile), r.baselineProbes, lower, upper);
        } catch (const std::exception&) {
            // unreadable cache entry: fit again and replace it
        }
    }
    if (cached) {
        r.baselineFit = cached->fit;
        r.baselineTrainingSamples = size_t(cached->trainingSamples);
        r.baselineTrainingPaths = cached->trainingPaths;
        r.baselineFittedSeconds = cached->seconds;
        r.baselineSeconds = since(t0);
        r.baselineSource = "cache";
        char line[120];
        std::snprintf(line, sizeof line, " (fitted in %.1f s)", r.baselineFittedSeconds);
        v.say("baseline: probes from the cache, " + r.baselineCacheFile + line);
        return std::move(cached->probes);
    }
    ShProbeGrid probes = fitBaseline(v, info, ss, dims, t0);
    r.baselineFittedSeconds = r.baselineSeconds;
    r.baselineSource = "fitted";
    if (!r.baselineCacheFile.empty()) {
        try {  // the probes are fitted: a cache that cannot take them costs the next validation the fit, no more
            fs::create_directories(v.settings.cacheDir);
            writeBytesAtomically(r.baselineCacheFile,
                                 encodeBaseline({probes, r.baselineFit, r.baselineTrainingSamples, r.baselineTrainingPaths, r.baselineSeconds}));
        } catch (const std::exception& e) {
            v.say(std::string("warning: the baseline's probes were not cached: ") + e.what());
            r.baselineCacheFile.clear();
        }
    }
    return probes;
}

// 4. The baseline: L2 SH probes of the same bytes, fitted to the same training samples (or read from the cache).
void runBaseline(ValidationRun& v, const NradAssetInfo& info, const RenderSettings& fh) {
    ValidationResult& r = v.r;
    auto t0 = clock_type::now();
    glm::uvec3 dims;
    SampleSettings ss = bakeSampleSettings(r, info, dims);
    // The probes first: the training budget follows their count.
    const glm::vec3 lower(info.gridLower[0], info.gridLower[1], info.gridLower[2]);
    const glm::vec3 upper(info.gridUpper[0], info.gridUpper[1], info.gridUpper[2]);
    r.baselineProbes = probeDimsForBudget(lower, upper, r.neural.bytes);
    capBaselineBudget(r, v.settings, uint64_t(r.baselineProbes.x) * r.baselineProbes.y * r.baselineProbes.z, ss);
    const ShProbeGrid probes = cachedOrFittedProbes(v, info, ss, dims, lower, upper, t0);
    if (v.scene.insertedObjects.empty()) return renderBaseline(v, probes, nullptr, info, fh);
    const ShIrradianceGrid irradiance = fitIrradianceBaseline(v, info, ss);
    renderBaseline(v, probes, &irradiance, info, fh);
}

// The exact volume quantity on the inserted objects (InsertedFigure): D(x, n) (and with `glossy` the glossy response
// towards the camera) traced in the scene without them at the centres of the pixels where `use` is set, shaded as
// the asset's queries are; the other pixels 0.
Image exactVolumeImage(ValidationRun& v, const std::vector<uint8_t>& use, uint32_t paths, bool glossy) {
    PathTracer tracer(v.baked, v.bakedAccel, v.bakedLights);
    tracer.setRouletteThreshold(kTrainingRouletteThreshold);
    const int w = v.r.width, h = v.r.height;
    Image out(w, h);
    CameraRays rays(v.settings.camera, w, h);
    tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
        RayCounters counters;
        std::vector<PathStart> batch;
        std::vector<glm::vec3> estimates(paths);
        for (int y = rows.begin(); y != rows.end(); ++y)
            for (int x = 0; x < w; ++x) {
                const size_t i = size_t(y) * size_t(w) + size_t(x);
                if (!use[i]) continue;
                glm::vec3 o, d;
                rays.generate(float(x) + 0.5f, float(y) + 0.5f, o, d);
                const Hit hit = v.accel.intersect(o, d);
                if (!hit.valid()) continue;
                const SurfaceInteraction si = makeInteraction(v.scene, hit, d);
                auto traced = [&](const SurfaceInteraction& receiver, uint32_t salt) {
                    batch.clear();
                    for (uint32_t j = 0; j < paths; ++j) batch.push_back({&receiver, uint32_t(i * 0x9e3779b1u) ^ salt, j});
                    tracer.estimate(batch.data(), batch.size(), v.rs.maxDepth, nullptr, 1, counters, estimates.data());
                    glm::dvec3 sum(0.0);
                    uint32_t n = 0;
                    for (const glm::vec3& L : estimates)
                        if (std::isfinite(L.x) && std::isfinite(L.y) && std::isfinite(L.z)) sum += glm::dvec3(L), ++n;
                    return n ? glm::vec3(sum / double(n)) : glm::vec3(0.0f);
                };
                const glm::vec3 D = traced(receiverAt(si.p, si.ns), 0x6578616du);
                const float Dv[3] = {D.x, D.y, D.z};
                const float cosNV = glm::dot(si.ns, si.wo);
                float L[3];
                if (glossy) {
                    const glm::vec3 G = traced(glossyReceiverAt(si.p, si.ns, si.wo), 0x676c6f73u) / eval::glossyAlbedo(cosNV);
                    const float Gv[3] = {G.x, G.y, G.z};
                    eval::shadeVolumeGlossy(Dv, Gv, shadingSurface(si), cosNV, L);
                } else {
                    eval::shadeVolume(Dv, shadingSurface(si), cosNV, L);
                }
                out.at(x, y) = glm::vec3(L[0], L[1], L[2]);
            }
    });
    return out;
}

// The inserted objects' figures (InsertedFigure): each object's interior pixels, then all of them together.
void measureInserted(ValidationRun& v, const FirstHits& hits, bool glossy) {
    ValidationResult& r = v.r;
    const size_t objects = v.scene.insertedObjects.size();
    const int w = hits.width, h = hits.height;
    std::vector<uint8_t> interior(size_t(w) * size_t(h), 0), exactAt(interior.size(), 0);
    size_t exactCount = 0;
    for (int y = 1; y + 1 < h; ++y)
        for (int x = 1; x + 1 < w; ++x) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            const int o = hits.inserted[i];
            if (o < 0) continue;
            bool in = true;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) in = in && hits.inserted[size_t(y + dy) * size_t(w) + size_t(x + dx)] == o;
            interior[i] = in;
            exactAt[i] = in && x % 2 == 0 && y % 2 == 0;
            exactCount += exactAt[i];
        }
    // The exact quantity's paths: 1024 per pixel, fewer where the objects cover many (4 M paths in all at most).
    r.exactPaths = uint32_t(std::clamp<size_t>(exactCount ? (size_t(1) << 22) / exactCount : 1024, 64, 1024));
    const Image exact = exactVolumeImage(v, exactAt, r.exactPaths, glossy);
    // Per object, then all together: sums of relMSE and luminance over the interior pixels (against the reference)
    // and over those of them with the exact light (against the reference, and the asset and probes against it).
    struct Sums {
        size_t pixels = 0, exactPixels = 0;
        double neural = 0.0, baseline = 0.0, refLum = 0.0, neuralLum = 0.0, baselineLum = 0.0;
        double exact = 0.0, exactLum = 0.0, exactRefLum = 0.0, neuralVsExact = 0.0, baselineVsExact = 0.0, baselineAtExact = 0.0;
    };
    std::vector<Sums> sums(objects + 1);
    for (size_t i = 0; i < interior.size(); ++i) {
        if (!interior[i]) continue;
        const glm::vec3 ref = r.reference.pixels[i], a = r.neural.image.pixels[i];
        const glm::vec3 b = r.baseline ? r.baseline->image.pixels[i] : glm::vec3(0.0f), t = exact.pixels[i];
        for (Sums* s : {&sums[size_t(hits.inserted[i])], &sums[objects]}) {
            ++s->pixels;
            s->neural += relMse(a, ref);
            s->baseline += relMse(b, ref);
            s->refLum += luminance(ref);
            s->neuralLum += luminance(a);
            s->baselineLum += luminance(b);
            if (!exactAt[i]) continue;
            ++s->exactPixels;
            s->exact += relMse(t, ref);
            s->exactLum += luminance(t);
            s->exactRefLum += luminance(ref);
            s->neuralVsExact += relMse(a, t);
            s->baselineVsExact += relMse(b, t);
            s->baselineAtExact += relMse(b, ref);
        }
    }
    auto ratio = [](double a, double b) { return b > 0.0 ? a / b : 0.0; };
    for (size_t o = 0; o <= objects; ++o) {
        if (o == objects && objects == 1) break;
        const Sums& s = sums[o];
        InsertedFigure f;
        f.name = o < objects ? v.scene.insertedNames[o] : "all inserted objects";
        f.pixels = s.pixels;
        f.neuralRelMse = ratio(s.neural, double(s.pixels));
        f.baselineRelMse = ratio(s.baseline, double(s.pixels));
        f.neuralMeanRatio = ratio(s.neuralLum, s.refLum);
        f.baselineMeanRatio = ratio(s.baselineLum, s.refLum);
        f.exactPixels = s.exactPixels;
        f.exactRelMse = ratio(s.exact, double(s.exactPixels));
        f.exactMeanRatio = ratio(s.exactLum, s.exactRefLum);
        f.neuralVsExact = ratio(s.neuralVsExact, double(s.exactPixels));
        f.baselineVsExact = ratio(s.baselineVsExact, double(s.exactPixels));
        if (r.baseline) {
            f.baselineAtExact = ratio(s.baselineAtExact, double(s.exactPixels));
            f.bestRatio = ratio(s.baselineAtExact, s.exact);
        }
        r.inserted.push_back(f);
        char line[640];
        if (r.baseline)
            std::snprintf(line, sizeof line,
                          "inserted %s: %zu pixels, relMSE asset %.4g, SH irradiance probes %.4g (%.3gx), exact volume light %.4g; "
                          "mean %.3f, %.3f, %.3f of the reference's; against the exact volume light: asset %.4g, SH %.4g (%.3gx); "
                          "a perfect volume query would read %.3gx below SH",
                          f.name.c_str(), f.pixels, f.neuralRelMse, f.baselineRelMse, ratio(f.baselineRelMse, f.neuralRelMse),
                          f.exactRelMse, f.neuralMeanRatio, f.baselineMeanRatio, f.exactMeanRatio, f.neuralVsExact,
                          f.baselineVsExact, ratio(f.baselineVsExact, f.neuralVsExact), f.bestRatio);
        else
            std::snprintf(line, sizeof line, "inserted %s: %zu pixels, relMSE asset %.4g, exact volume light %.4g; mean %.3f, %.3f of the reference's",
                          f.name.c_str(), f.pixels, f.neuralRelMse, f.exactRelMse, f.neuralMeanRatio, f.exactMeanRatio);
        v.say(line);
    }
}

}  // namespace

ValidationResult runValidation(const Scene& scene, const std::string& scenePath, NradAsset asset, const std::string& assetPath,
                               const ValidateSettings& settings, const std::function<void(const std::string&)>& log) {
    ValidationResult r;
    describeRun(r, scene, scenePath, assetPath, settings);
    Accel accel(scene);
    LightSampler lights(scene);
    PathTracer tracer(scene, accel, lights);
    // The scene as baked, where objects were placed after the bake.
    std::unique_ptr<const Scene> bare;
    std::unique_ptr<const Accel> bareAccel;
    std::unique_ptr<const LightSampler> bareLights;
    if (!scene.insertedObjects.empty()) {
        bare = std::make_unique<const Scene>(withoutInsertedObjects(scene));
        bareAccel = std::make_unique<const Accel>(*bare);
        bareLights = std::make_unique<const LightSampler>(*bare);
    }
    ValidationRun v{scene, settings, Say{log}, r, accel, lights, tracer, RenderSettings(), bare ? *bare : scene,
                    bareAccel ? *bareAccel : accel, bareLights ? *bareLights : lights};
    v.rs.width = r.width;
    v.rs.height = r.height;
    v.rs.maxDepth = settings.maxDepth;

    obtainReference(v);
    Image lastCurveImage = convergenceCurve(v);

    // 3. Through the asset, as an engine would (the public runtime API).
    NradAssetInfo info;
    if (NradStatus st = nradGetAssetInfo(asset, &info); st != NRAD_OK) throw std::runtime_error(nradStatusString(st));
    const eval::Partition partition = partitionOf(info, assetPath);
    const FirstHits hits = firstHits(scene, accel, settings.camera, r.width, r.height, partition);
    mapPixels(v, hits, lastCurveImage);
    lastCurveImage = Image();
    measureSeams(v, hits, partition, asset);
    RenderSettings fh = v.rs;
    fh.spp = settings.neuralSpp;
    fh.seed = settings.seed;
    // The volume's weights, its glossy response's included: the probes of the baseline get as many bytes.
    r.volumeBytes = size_t(info.volumeNetworks + info.glossyNetworks) * info.parametersPerNetwork * (info.weightEncoding == 1 ? 2 : 4);
    r.insertedThroughVolume = info.volumeNetworks > 0 && !scene.insertedObjects.empty();
    r.insertedThroughGlossy = r.insertedThroughVolume && info.glossyNetworks > 0;
    if (!scene.insertedObjects.empty() && info.volumeNetworks == 0)
        v.say("inserted objects: the asset has no volume networks (bake with --volume-points): they are shaded by the surfaces' networks, "
              "an extrapolation nobody trained");
    renderNeural(v, asset, assetPath, info, partition, fh);
    readMetadataAndBias(v, asset);

    if (settings.baseline) runBaseline(v, info, fh);
    if (!scene.insertedObjects.empty()) measureInserted(v, hits, info.glossyNetworks > 0);
    return r;
}

}  // namespace nrad
