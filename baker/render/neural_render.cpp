// Tile-by-tile primary visibility and batched runtime evaluation.
#include "baker/render/neural_render.h"

#include <atomic>
#include <chrono>
#include <mutex>

#include <nrad/eval.h>
#include <tbb/parallel_for.h>

#include "baker/render/camera.h"
#include "baker/lights/light_sampler.h"
#include "baker/render/sampler.h"
#include "baker/render/surface.h"

namespace nrad {

NradStatus renderThroughAsset(const Scene& scene, const Accel& accel, NradAsset asset, const Camera& camera,
                              const RenderSettings& settings, Image& image, NeuralRenderStats* stats,
                              const std::function<void(double)>& progress) {
    FirstHitEvaluator evaluate = [asset](size_t n, const float* p, const float* nrm, const float* d, float* rgb, uint8_t* flags) {
        return nradEvaluateBatch(asset, n, p, nrm, d, rgb, flags);
    };
    NradAssetInfo info;
    if (NradStatus st = nradGetAssetInfo(asset, &info); st != NRAD_OK) return st;
    VolumeEvaluator volume;
    if (info.volumeNetworks > 0 && !scene.insertedObjects.empty())
        volume = [asset](size_t n, const float* p, const float* nrm, float* rgb, uint8_t* flags) {
            return nradEvaluateVolumeBatch(asset, n, p, nrm, rgb, flags);
        };
    GlossyEvaluator glossy;
    if (volume && info.glossyNetworks > 0)
        glossy = [asset](size_t n, const float* p, const float* nrm, const float* d, float* rgb, uint8_t* flags) {
            return nradEvaluateVolumeGlossyBatch(asset, n, p, nrm, d, rgb, flags);
        };
    return renderFirstHit(scene, accel, evaluate, info.contentFlags, camera, settings, image, stats, progress, volume, glossy);
}

NradStatus renderFirstHit(const Scene& scene, const Accel& accel, const FirstHitEvaluator& evaluate, uint32_t contentFlags,
                          const Camera& camera, const RenderSettings& settings, Image& image, NeuralRenderStats* stats,
                          const std::function<void(double)>& progress, const VolumeEvaluator& volume, const GlossyEvaluator& glossy) {
    using clock = std::chrono::steady_clock;
    auto start = clock::now();
    image = Image(settings.width, settings.height);
    CameraRays rays(camera, settings.width, settings.height);
    const int ts = std::max(1, settings.tileSize);
    const int tilesX = (settings.width + ts - 1) / ts, tilesY = (settings.height + ts - 1) / ts;
    const int tileCount = tilesX * tilesY;
    std::atomic<int> tilesDone{0};
    std::atomic<int> failure{NRAD_OK};
    std::mutex statsMutex;
    NeuralRenderStats total;

    tbb::parallel_for(tbb::blocked_range<int>(0, tileCount, 1), [&](const tbb::blocked_range<int>& range) {
        std::vector<float> pos, nrm, dir, rgb, cosNV;
        std::vector<eval::Surface> surfaces;
        std::vector<uint8_t> flags;
        std::vector<uint32_t> pixelOf;  // batch entry -> pixel index within the tile
        // The inserted objects' hits (with `volume`): their points, normals, surfaces, cosines and pixels.
        std::vector<float> vpos, vnrm, vdir, vrgb, vglossy, vcos;
        std::vector<eval::Surface> vsurfaces;
        std::vector<uint8_t> vflags, gflags;
        std::vector<uint32_t> vpixelOf;
        std::vector<glm::vec3> vdirect;
        std::vector<glm::vec3> direct;  // engine-drawn lights' direct light at each hit (mixed lighting)
        bool mixed = false;
        for (const PunctualLight& l : scene.lights) mixed = mixed || l.runtimeDirect;
        NeuralRenderStats local;
        for (int tile = range.begin(); tile != range.end(); ++tile) {
            int x0 = (tile % tilesX) * ts, y0 = (tile / tilesX) * ts;
            int x1 = std::min(x0 + ts, settings.width), y1 = std::min(y0 + ts, settings.height);
            auto t0 = clock::now();
            pos.clear();
            nrm.clear();
            dir.clear();
            surfaces.clear();
            cosNV.clear();
            pixelOf.clear();
            direct.clear();
            vpos.clear();
            vnrm.clear();
            vdir.clear();
            vcos.clear();
            vsurfaces.clear();
            vpixelOf.clear();
            vdirect.clear();
            std::vector<glm::dvec3> sum(size_t(ts) * size_t(ts), glm::dvec3(0.0));
            for (int y = y0; y < y1; ++y)
                for (int x = x0; x < x1; ++x) {
                    for (int s = 0; s < settings.spp; ++s) {
                        glm::vec3 o, d;
                        cameraSample(rays, x, y, settings.seed, uint32_t(s), o, d);  // first hits only: no more dimensions
                        Hit hit = accel.intersect(o, d);
                        if (!hit.valid()) {
                            // The sky seen directly: the engine draws it, exactly, as it draws emission.
                            sum[size_t((y - y0) * ts + (x - x0))] += glm::dvec3(skyRadiance(scene, d));
                            continue;
                        }
                        SurfaceInteraction si = makeInteraction(scene, hit, d);
                        if (volume && scene.insertedObject(hit.triangle) >= 0) {
                            for (int k = 0; k < 3; ++k) {
                                vpos.push_back(si.p[k]);
                                vnrm.push_back(si.ns[k]);
                                vdir.push_back(si.wo[k]);
                            }
                            vsurfaces.push_back(shadingSurface(si));
                            vcos.push_back(glm::dot(si.ns, si.wo));
                            vpixelOf.push_back(uint32_t((y - y0) * ts + (x - x0)));
                            if (mixed) vdirect.push_back(engineDrawnDirect(scene, accel, si));
                            continue;
                        }
                        for (int k = 0; k < 3; ++k) {
                            pos.push_back(si.p[k]);
                            nrm.push_back(si.ns[k]);
                            dir.push_back(si.wo[k]);
                        }
                        surfaces.push_back(shadingSurface(si));
                        cosNV.push_back(glm::dot(si.ns, si.wo));
                        pixelOf.push_back(uint32_t((y - y0) * ts + (x - x0)));
                        if (mixed) direct.push_back(engineDrawnDirect(scene, accel, si));
                    }
                }
            auto t1 = clock::now();
            size_t n = pixelOf.size();
            rgb.assign(3 * n, 0.0f);
            flags.assign(n, 0);
            NradStatus st = n > 0 ? evaluate(n, pos.data(), nrm.data(), dir.data(), rgb.data(), flags.data()) : NRAD_OK;
            const size_t vn = vpixelOf.size();
            vrgb.assign(3 * vn, 0.0f);
            vflags.assign(vn, 0);
            if (vn > 0 && st == NRAD_OK) st = volume(vn, vpos.data(), vnrm.data(), vrgb.data(), vflags.data());
            vglossy.assign(glossy ? 3 * vn : 0, 0.0f);
            gflags.assign(glossy ? vn : 0, 0);  // the volume query's flags are the ones counted
            if (glossy && vn > 0 && st == NRAD_OK) st = glossy(vn, vpos.data(), vnrm.data(), vdir.data(), vglossy.data(), gflags.data());
            auto t2 = clock::now();
            if (st != NRAD_OK) failure = st;
            for (size_t i = 0; i < vn; ++i) {
                float L[3];
                if (glossy)
                    eval::shadeVolumeGlossy(&vrgb[3 * i], &vglossy[3 * i], vsurfaces[i], vcos[i], L);
                else
                    eval::shadeVolume(&vrgb[3 * i], vsurfaces[i], vcos[i], L);
                sum[vpixelOf[i]] += glm::dvec3(L[0], L[1], L[2]);
                if (mixed) sum[vpixelOf[i]] += glm::dvec3(vdirect[i]);
                local.outsideGrid += vflags[i] == NRAD_POINT_OUTSIDE_GRID;
                local.emptyVoxel += vflags[i] == NRAD_POINT_EMPTY_VOXEL;
                local.invalidInput += vflags[i] == NRAD_POINT_INVALID_INPUT;
            }
            for (size_t i = 0; i < n; ++i) {
                float L[3];
                eval::shade(contentFlags, &rgb[3 * i], surfaces[i], cosNV[i], L);
                sum[pixelOf[i]] += glm::dvec3(L[0], L[1], L[2]);
                if (mixed) sum[pixelOf[i]] += glm::dvec3(direct[i]);
                local.outsideGrid += flags[i] == NRAD_POINT_OUTSIDE_GRID;
                local.emptyVoxel += flags[i] == NRAD_POINT_EMPTY_VOXEL;
                local.invalidInput += flags[i] == NRAD_POINT_INVALID_INPUT;
            }
            for (int y = y0; y < y1; ++y)
                for (int x = x0; x < x1; ++x)
                    image.at(x, y) = glm::vec3(sum[size_t((y - y0) * ts + (x - x0))] / double(std::max(1, settings.spp)));
            local.evaluations += n;
            local.volumeEvaluations += vn;
            local.visibilitySeconds += std::chrono::duration<double>(t1 - t0).count();
            local.evaluationSeconds += std::chrono::duration<double>(t2 - t1).count();
            int done = ++tilesDone;
            if (progress) progress(double(done) / double(tileCount));
        }
        std::lock_guard<std::mutex> lock(statsMutex);
        total.visibilitySeconds += local.visibilitySeconds;
        total.evaluationSeconds += local.evaluationSeconds;
        total.evaluations += local.evaluations;
        total.volumeEvaluations += local.volumeEvaluations;
        total.outsideGrid += local.outsideGrid;
        total.emptyVoxel += local.emptyVoxel;
        total.invalidInput += local.invalidInput;
    }, tbb::simple_partitioner());
    total.seconds = std::chrono::duration<double>(clock::now() - start).count();
    if (stats) *stats = total;
    return NradStatus(failure.load());
}

}  // namespace nrad
