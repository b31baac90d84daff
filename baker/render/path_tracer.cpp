// Path tracing with NEE + MIS and Russian roulette.
#include "baker/render/path_tracer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <utility>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "baker/render/bsdf.h"
#include "baker/render/bsdf_lanes.h"
#include "baker/render/camera.h"
#include "baker/render/scatter_lanes.h"
#include "baker/render/surface.h"
#include "baker/util/maths.h"

namespace nrad {

namespace {

inline float powerHeuristic(float fPdf, float gPdf) {
    float f2 = fPdf * fPdf, g2 = gPdf * gPdf;
    if (std::isinf(f2)) return 1.0f;
    return f2 + g2 > 0.0f ? f2 / (f2 + g2) : 0.0f;
}

inline bool isBlack(const glm::vec3& v) { return v.x <= 0.0f && v.y <= 0.0f && v.z <= 0.0f; }
inline bool isFinite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
inline float maxComponent(const glm::vec3& v) { return std::max(v.x, std::max(v.y, v.z)); }

// Whether light may travel along wi at si: above the geometric surface (the side of wo), or, through a
// transmissive surface, below it too, as long as the geometric and the shading normal agree on the side
// (otherwise light would leak through the shading normal's interpolation).
inline bool sameSideRule(const SurfaceInteraction& si, bool transmits, const glm::vec3& wi) {
    float g = glm::dot(wi, si.ng);
    if (g > 0.0f) return true;
    return g < 0.0f && transmits && glm::dot(wi, si.ns) < 0.0f;
}

// Russian roulette starts after this many segments.
constexpr int kRouletteStart = 3;

// scatteredRadiance does not cut a path at a vertex whose reflection is a sharp lobe (metal or glass rougher
// than nothing but smoother than this): what a small network draws worst would otherwise become every other
// network's target. At most this many extra bounces, then it cuts wherever it is.
constexpr float kSharpRoughness = 0.5f;
constexpr int kMaxSharpExtension = 4;
inline bool sharpLobe(const BsdfParams& b) { return b.roughness < kSharpRoughness && (b.metallic >= 0.5f || b.transmission >= 0.5f); }

}  // namespace

void shadowRay(const SurfaceInteraction& si, const LightSample& ls, glm::vec3& origin, glm::vec3& direction,
               float& tnear, float& tfar) {
    // The segment from the shading point to the light point itself, without the parts within a margin of
    // either end's surface (measured across the surface, so a grazing ray stops short of the emitter's
    // plane by the same margin as a perpendicular one). (The origin used to be moved off the surface while
    // the ray was still aimed from the unmoved point: grazing rays met the emitter's own plane before their
    // end, and light seen at less than about 16 degrees was lost; issue 12.) The light's end takes the
    // larger of the two ends' margins, since the precision of a hit along the segment is that of the
    // coordinates of both.
    origin = si.p;
    direction = ls.wi;
    tnear = si.spawnDistance(ls.wi);
    if (!std::isfinite(ls.distance)) {  // directional light or environment: the ray leaves the scene
        tfar = std::numeric_limits<float>::infinity();
        return;
    }
    const float margin = std::max(std::max(ls.margin, rayOffset(ls.lightPoint)), std::max(si.margin, rayOffset(si.p)));
    if (ls.delta) {
        tfar = ls.distance - margin;  // a punctual light has no surface, but may sit on one: stop short of it
        return;
    }
    const float c = std::abs(glm::dot(ls.wi, ls.lightNormal));
    tfar = c > 0.0f ? ls.distance - margin / c : 0.0f;
}

namespace {
// Whether light sample ls reaches si: its shadow ray finds no occluder.
bool reachesPoint(const Accel& accel, const SurfaceInteraction& si, const LightSample& ls) {
    glm::vec3 o, dir;
    float tnear, tfar;
    shadowRay(si, ls, o, dir, tnear, tfar);
    // A segment shorter than the two margins holds no occluder: the light and the point are within a margin
    // of each other's planes (and the contribution is about zero).
    return !(tfar > tnear) || !accel.occluded(o, dir, tnear, tfar);
}
}  // namespace

glm::vec3 engineDrawnDirect(const Scene& scene, const Accel& accel, const SurfaceInteraction& si) {
    glm::vec3 L(0.0f);
    Bsdf bsdf(Frame::fromNormal(si.ns), si.bsdf);
    for (const PunctualLight& light : scene.lights) {
        if (!light.runtimeDirect) continue;
        LightSample ls = punctualLightSample(light, si.p);
        if (!(ls.pdf > 0.0f) || isBlack(ls.Li) || !sameSideRule(si, bsdf.transmits(), ls.wi)) continue;
        glm::vec3 f = bsdf.eval(si.wo, ls.wi) * std::abs(glm::dot(ls.wi, si.ns));
        if (!isBlack(f) && reachesPoint(accel, si, ls)) L += f * ls.Li;
    }
    return L;
}

glm::vec3 PathTracer::radiance(glm::vec3 origin, glm::vec3 direction, Sampler& sampler, int maxDepth,
                               RayCounters& counters, std::vector<RecordedRay>* record, NeeTrace* nee) const {
    ++counters.primary;
    if (record) record->push_back({origin, direction, 0.0f, std::numeric_limits<float>::infinity(), false});
    Hit hit = accel_.intersect(origin, direction);
    if (!hit.valid()) return skyRadiance(scene_, direction);  // the sky (and suns' disks) seen directly
    return trace(makeInteraction(scene_, hit, direction), sampler, maxDepth, counters, record, nee);
}

glm::vec3 PathTracer::outgoingRadiance(const SurfaceInteraction& si, Sampler& sampler, int maxDepth,
                                       RayCounters& counters, NeeTrace* nee) const {
    return trace(si, sampler, maxDepth, counters, nullptr, nee);
}

glm::vec3 PathTracer::scatteredRadiance(const SurfaceInteraction& si, Sampler& sampler, int bounces,
                                        const ScatteredRadiance& tail, RayCounters& counters) const {
    return trace(si, sampler, 0, counters, nullptr, nullptr, std::max(1, bounces), &tail);
}

struct PathTracer::Path {
    SurfaceInteraction si;  // the vertex reached
    Sampler* sampler = nullptr;
    glm::vec3 L{0.0f}, beta{1.0f};
    float prevBsdfPdf = 0.0f;
    glm::vec3 prevP{0.0f};
    int depth = 0;  // segments traced before the one that reached si
    // Group selection probabilities at this vertex and the previous one (for the MIS weight of an emitter
    // that the previous vertex's BSDF sample hit); LightSampler::kMaxLightGroups each, used with a selector.
    float* probs = nullptr;
    float* prevProbs = nullptr;
    // What scatterEnd leaves for the rays: a shadow query and the contribution it decides (computed with the
    // throughput before the BSDF sample changes it), and the extension ray.
    bool shadowPending = false;
    bool neePending = false;  // neeRecord goes to NeeTrace::records if the shadow ray is unblocked
    glm::vec3 neeContribution{0.0f};
    RayQuery shadow;
    RayQuery extension;
    NeeRecord neeRecord;
    // Between scatterBegin and scatterEnd: the vertex's sample points, its light sample, and what shade()
    // computes of the BSDF (the light sample's value and pdf, the BSDF sample). A vertex scattered in lanes
    // (scatterBatch) leaves ls, neeEval, neePdf and bs unwritten: the lanes turn them into what follows directly.
    int cutDepth = 0;  // the bounce at which scatteredRadiance cuts the path (0: never)
    glm::vec2 uBsdf{0.0f};
    float uLobe = 0.0f, uRoulette = 0.0f;
    bool transmits = false;
    bool neeCandidate = false;  // the light sample needs the BSDF: it may contribute
    bool recordHere = false;
    int chosen = -1;
    LightSample ls;
    glm::vec3 neeEval{0.0f};
    float neePdf = 0.0f;
    BsdfSample bs;

    // A path about to start at the interaction written into si after this call (none of it traced yet), with its
    // sampler and, with a selector, its two buffers of kMaxLightGroups selection probabilities at probsBuffer. A
    // batch's buffer of paths is restarted rather than constructed anew (a Path is 480 bytes): the state a path
    // carries from vertex to vertex is reset; what a vertex writes before it reads it (its sample points, light
    // and BSDF samples, rays and records) is left as the buffer's previous path left it.
    void restart(Sampler* s, float* probsBuffer) {
        L = glm::vec3(0.0f);
        beta = glm::vec3(1.0f);
        prevBsdfPdf = 0.0f;
        prevP = glm::vec3(0.0f);
        depth = 0;
        cutDepth = 0;
        shadowPending = neePending = false;
        sampler = s;
        probs = probsBuffer;
        prevProbs = probsBuffer ? probsBuffer + LightSampler::kMaxLightGroups : nullptr;
    }
};

PathTracer::Next PathTracer::scatterBegin(Path& p, const glm::vec2* u, int maxDepth, NeeTrace* nee, const ScatteredRadiance* tail,
                                          LightSampler::QuadPick* quad) const {
    const SurfaceInteraction& si = p.si;
    const int depth = p.depth, cutDepth = p.cutDepth;
    p.shadowPending = p.neePending = p.neeCandidate = false;
    if (!isBlack(si.emission)) {
        if (depth == 0) {
            if (cutDepth == 0) p.L += p.beta * si.emission;  // scatteredRadiance leaves out si's own
        } else {
            const float lightPdf = selector_->pdfTriangle(p.prevProbs, si.triangle, p.prevP, si.p, si.ng);
            p.L += p.beta * si.emission * powerHeuristic(p.prevBsdfPdf, lightPdf);
        }
    }
    if (cutDepth > 0 && depth >= cutDepth && (depth >= cutDepth + kMaxSharpExtension || !sharpLobe(si.bsdf))) {
        // What this vertex scatters towards the previous one, from the tail (emission was counted above).
        glm::vec3 Ls = (*tail)(si);
        if (excludeEngineDrawn_) Ls += engineDrawnDirect(scene_, accel_, si);
        if (isFinite(Ls)) p.L += p.beta * Ls;
        return kEnd;
    }
    if (maxDepth > 0 && depth + 1 >= maxDepth) return kEnd;

    // The sampler's dimensions are consumed in the same order at every vertex.
    // The light pick and the point on the light share one 2D point: the pick coordinate, rescaled within
    // the chosen light's probability, is reused as the point's first coordinate, so the samples that
    // choose a light are stratified over it (in every selection mode).
    // u: the three 2D points, drawn for a whole batch at once (next2D), or here.
    glm::vec2 drawn[3];
    if (!u) {
        for (glm::vec2& d : drawn) d = p.sampler->get2D();
        u = drawn;
    }
    const glm::vec2 uLight = u[0];
    p.uBsdf = u[1];
    p.uLobe = u[2].x;  // BSDF lobe choice
    p.uRoulette = u[2].y;  // Russian roulette
    p.transmits = Bsdf::transmits(si.bsdf);

    // Next event estimation: the light sample (its BSDF terms come from shade()).
    p.recordHere = false;
    p.chosen = -1;
    // (A quad light is an area light, never one the engine draws: excludeEngineDrawn_ leaves its samples as they are.)
    // (Lanes only for a choice by power: a group distribution's pick is made one path at a time.)
    if (quad && !selector_->choosesGroups() && si.bsdf.transmission == 0.0f && lights_.pickQuad(uLight, *quad)) return kQuadLanes;
    // A transmissive surface is lit from behind its plane too: no tangent-plane culling (ng = 0).
    const LightSampleContext ctx{si.p, p.transmits ? glm::vec3(0.0f) : si.ng, si.ns, si.wo, depth};
    const LightChoice choice = selector_->sample(ctx, uLight, p.probs, &p.neeRecord);
    LightSample& ls = p.ls;
    ls = choice.ls;
    p.chosen = choice.group;
    p.recordHere = choice.networkEvaluated && nee && nee->records;
    if (depth == 0 && nee) nee->firstLight = p.chosen;
    // Mixed lighting: the engine adds the direct light of its own lights itself.
    if (excludeEngineDrawn_ && depth == 0 && lights_.engineDrawn(ls.entry)) ls.pdf = 0.0f;
    p.neeCandidate = ls.pdf > 0.0f && !isBlack(ls.Li) && sameSideRule(si, p.transmits, ls.wi);
    return kShade;
}

void PathTracer::shade(Path& p) {
    const SurfaceInteraction& si = p.si;
    Bsdf bsdf(Frame::fromNormal(si.ns), si.bsdf);
    const Bsdf::Outgoing out = bsdf.outgoing(si.wo);  // shared by this vertex's evaluations
    if (p.neeCandidate) {
        p.neeEval = bsdf.eval(out, p.ls.wi);
        p.neePdf = bsdf.pdf(out, p.ls.wi);
    }
    p.bs = bsdf.sample(out, p.uLobe, p.uBsdf);
}

bool PathTracer::scatterEnd(Path& p, RayCounters& counters, std::vector<RecordedRay>* record) const {
    const SurfaceInteraction& si = p.si;
    const LightSample& ls = p.ls;
    if (p.neeCandidate) {
        glm::vec3 f = p.neeEval * std::abs(glm::dot(ls.wi, si.ns));
        if (!isBlack(f)) {
            ++counters.shadow;
            RayQuery& q = p.shadow;
            shadowRay(si, ls, q.origin, q.direction, q.tnear, q.tfar);
            if (record) record->push_back({q.origin, q.direction, q.tnear, q.tfar, true});
            p.shadowPending = true;
            float w = ls.delta ? 1.0f : powerHeuristic(ls.pdf, p.neePdf);
            p.neeContribution = p.beta * f * ls.Li * (w / ls.pdf);
            if (p.recordHere) {
                // The group's contribution estimate (without MIS weight) over the probability of having
                // chosen it: the weight of the cross-entropy gradient.
                glm::vec3 c = f * ls.Li;
                p.neeRecord.light = uint32_t(p.chosen);
                p.neeRecord.weight = luminancef(c) / ls.pdf;
                p.neePending = p.neeRecord.weight > 0.0f && std::isfinite(p.neeRecord.weight);
            }
        }
    }

    return extend(p, counters, record);
}

bool PathTracer::extend(Path& p, RayCounters& counters, std::vector<RecordedRay>* record) const {
    // Continue the path by sampling the BSDF.
    const SurfaceInteraction& si = p.si;
    const BsdfSample& bs = p.bs;
    if (!bs.valid() || !sameSideRule(si, p.transmits, bs.wi)) return false;
    p.beta *= bs.f * (std::abs(glm::dot(bs.wi, si.ns)) / bs.pdf);
    if (isBlack(p.beta) || !isFinite(p.beta)) return false;
    p.prevBsdfPdf = bs.pdf;
    p.prevP = si.p;
    std::swap(p.probs, p.prevProbs);
    if (p.depth + 1 >= kRouletteStart && p.cutDepth == 0) {
        float q = std::min(1.0f, maxComponent(p.beta) / rouletteThreshold_);
        if (p.uRoulette >= q) return false;
        p.beta /= q;
    }
    ++counters.extension;
    p.extension = {si.p, bs.wi, si.spawnDistance(bs.wi), std::numeric_limits<float>::infinity()};
    if (record) record->push_back({si.p, bs.wi, p.extension.tnear, p.extension.tfar, false});
    return true;
}

void PathTracer::finishShadow(Path& p, bool blocked, NeeTrace* nee) const {
    p.shadowPending = false;
    if (blocked) return;
    p.L += p.neeContribution;
    if (p.neePending) nee->records->push_back(p.neeRecord);
}

bool PathTracer::arrive(Path& p, const Hit& hit) const {
    if (!hit.valid()) {
        // The ray leaves the scene: the environment and soft suns it meets, each weighted against having been
        // sampled by NEE at the vertex it left.
        lights_.forEachEscaped(p.extension.direction, [&](const glm::vec3& Le, float pdf, uint32_t group, float pdfInGroup) {
            const float lightPdf = selector_->pdfEscaped(p.prevProbs, pdf, group, pdfInGroup);
            p.L += p.beta * Le * powerHeuristic(p.prevBsdfPdf, lightPdf);
        });
        return false;
    }
    makeInteraction(scene_, hit, p.extension.direction, p.si);
    ++p.depth;
    return true;
}

glm::vec3 PathTracer::trace(SurfaceInteraction si, Sampler& sampler, int maxDepth, RayCounters& counters,
                            std::vector<RecordedRay>* record, NeeTrace* nee, int cutDepth,
                            const ScatteredRadiance* tail) const {
    float probs[2 * LightSampler::kMaxLightGroups];
    Path p;
    p.restart(&sampler, probs);
    p.si = si;
    p.cutDepth = cutDepth;
    for (;;) {
        bool more = scatterBegin(p, nullptr, maxDepth, nee, tail) != kEnd;
        if (more) {
            shade(p);
            more = scatterEnd(p, counters, record);
        }
        if (p.shadowPending) {
            // A segment shorter than the two margins holds no occluder: the light and the point are within a
            // margin of each other's planes (and the contribution is about zero).
            const RayQuery& q = p.shadow;
            finishShadow(p, q.tfar > q.tnear && accel_.occluded(q.origin, q.direction, q.tnear, q.tfar), nee);
        }
        if (!more || !arrive(p, accel_.intersect(p.extension.origin, p.extension.direction, p.extension.tnear)))
            break;
    }
    return p.L;
}

struct PathTracer::BatchScratch {
    BsdfLanes lanes;
    ScatterLanes scatter;
    std::vector<uint32_t> inLanes;
    std::vector<uint32_t> active, shading, quadPaths, shadowPaths, extensionPaths;
    std::vector<LightSampler::QuadPick> quadPicks;  // of quadPaths
    std::vector<uint8_t> quadMore;  // of quadPaths: whether the path goes on
    std::vector<RayQuery> queries;
    std::vector<uint8_t> blocked;
    std::vector<Hit> hits;
    std::vector<Sampler*> samplers;
    std::vector<glm::vec2> points;
};

namespace {
// Lane k of `L`: the vertex si, its lobe choice and BSDF sample point (the light direction is the caller's).
inline void packBsdf(BsdfLanes& L, size_t k, const SurfaceInteraction& si, float uLobe, const glm::vec2& uBsdf) {
    L.nx[k] = si.ns.x, L.ny[k] = si.ns.y, L.nz[k] = si.ns.z;
    L.wox[k] = si.wo.x, L.woy[k] = si.wo.y, L.woz[k] = si.wo.z;
    L.baseR[k] = si.bsdf.baseColor.x, L.baseG[k] = si.bsdf.baseColor.y, L.baseB[k] = si.bsdf.baseColor.z;
    L.metallic[k] = si.bsdf.metallic, L.roughness[k] = si.bsdf.roughness, L.specular[k] = si.bsdf.specular;
    L.specR[k] = si.bsdf.specularColor.x, L.specG[k] = si.bsdf.specularColor.y, L.specB[k] = si.bsdf.specularColor.z;
    L.ior[k] = si.bsdf.ior;
    L.uLobe[k] = uLobe, L.u0[k] = uBsdf.x, L.u1[k] = uBsdf.y;
}

inline BsdfSample sampleOf(const BsdfLanes& L, size_t k) {
    BsdfSample bs;
    bs.wi = glm::vec3(L.sampleX[k], L.sampleY[k], L.sampleZ[k]);
    bs.f = glm::vec3(L.sampleR[k], L.sampleG[k], L.sampleB[k]);
    bs.pdf = L.samplePdf[k];
    return bs;
}
}  // namespace

void PathTracer::shadeBatch(Path* paths, BatchScratch& scratch) {
    // Materials without transmission in SIMD lanes (bsdf_lanes.h, the same bits as shade()), the rest one by one.
    std::vector<uint32_t>& inLanes = scratch.inLanes;
    inLanes.clear();
    for (uint32_t i : scratch.shading) {
        if (paths[i].si.bsdf.transmission == 0.0f)
            inLanes.push_back(i);
        else
            shade(paths[i]);
    }
    BsdfLanes& L = scratch.lanes;
    for (size_t first = 0; first < inLanes.size(); first += BsdfLanes::kLanes) {
        const size_t n = std::min(BsdfLanes::kLanes, inLanes.size() - first);
        for (size_t k = 0; k < n; ++k) {
            const Path& p = paths[inLanes[first + k]];
            packBsdf(L, k, p.si, p.uLobe, p.uBsdf);
            const glm::vec3 l = p.neeCandidate ? p.ls.wi : p.si.ns;
            L.lx[k] = l.x, L.ly[k] = l.y, L.lz[k] = l.z;
        }
        shadeLanes(L, n);
        for (size_t k = 0; k < n; ++k) {
            Path& p = paths[inLanes[first + k]];
            if (p.neeCandidate) {
                p.neeEval = glm::vec3(L.evalR[k], L.evalG[k], L.evalB[k]);
                p.neePdf = L.evalPdf[k];
            }
            p.bs = sampleOf(L, k);
        }
    }
}

void PathTracer::scatterBatch(Path* paths, BatchScratch& scratch, RayCounters& counters) const {
    ScatterLanes& L = scratch.scatter;
    L.rouletteThreshold = rouletteThreshold_;
    const std::vector<uint32_t>& quadPaths = scratch.quadPaths;
    scratch.quadMore.resize(quadPaths.size());
    for (size_t first = 0; first < quadPaths.size(); first += ScatterLanes::kLanes) {
        const size_t n = std::min(ScatterLanes::kLanes, quadPaths.size() - first);
        for (size_t k = 0; k < n; ++k) {
            const Path& p = paths[quadPaths[first + k]];
            const SurfaceInteraction& si = p.si;
            const LightSampler::QuadPick& q = scratch.quadPicks[first + k];
            L.px[k] = si.p.x, L.py[k] = si.p.y, L.pz[k] = si.p.z;
            L.ngx[k] = si.ng.x, L.ngy[k] = si.ng.y, L.ngz[k] = si.ng.z;
            L.margin[k] = si.margin;
            L.betaR[k] = p.beta.x, L.betaG[k] = p.beta.y, L.betaB[k] = p.beta.z;
            L.uRoulette[k] = p.uRoulette;
            L.roulette[k] = p.depth + 1 >= kRouletteStart && p.cutDepth == 0 ? 1.0f : 0.0f;
            L.plx[k] = q.point.x, L.ply[k] = q.point.y, L.plz[k] = q.point.z;
            L.lnx[k] = q.normal.x, L.lny[k] = q.normal.y, L.lnz[k] = q.normal.z;
            L.frontR[k] = q.front.x, L.frontG[k] = q.front.y, L.frontB[k] = q.front.z;
            L.backR[k] = q.back.x, L.backG[k] = q.back.y, L.backB[k] = q.back.z;
            L.area[k] = q.area, L.lightMargin[k] = q.margin, L.pick[k] = q.pick;
            packBsdf(L.bsdf, k, si, p.uLobe, p.uBsdf);
        }
        scatterLanes(L, n);
        for (size_t k = 0; k < n; ++k) {
            Path& p = paths[quadPaths[first + k]];
            if (L.pending[k] > 0.0f) {
                ++counters.shadow;
                p.shadow = {p.si.p, glm::vec3(L.wix[k], L.wiy[k], L.wiz[k]), L.tnear[k], L.tfar[k]};
                p.shadowPending = true;
                p.neeContribution = glm::vec3(L.contribR[k], L.contribG[k], L.contribB[k]);
            }
            // extend()
            const bool more = L.more[k] > 0.0f;
            scratch.quadMore[first + k] = more;
            if (!more) continue;
            p.beta = glm::vec3(L.betaR[k], L.betaG[k], L.betaB[k]);
            p.prevBsdfPdf = L.bsdf.samplePdf[k];
            p.prevP = p.si.p;
            std::swap(p.probs, p.prevProbs);
            ++counters.extension;
            p.extension = {p.si.p, glm::vec3(L.bsdf.sampleX[k], L.bsdf.sampleY[k], L.bsdf.sampleZ[k]), L.extensionTnear[k],
                           std::numeric_limits<float>::infinity()};
        }
    }
}

void PathTracer::traceBatch(Path* paths, size_t n, int maxDepth, RayCounters& counters, BatchScratch& scratch, int cutDepth,
                            const ScatteredRadiance* tail) const {
    std::vector<uint32_t>& active = scratch.active;
    active.resize(n);
    for (size_t i = 0; i < n; ++i) {
        active[i] = uint32_t(i);
        paths[i].cutDepth = cutDepth;
    }
    while (!active.empty()) {
        // One vertex of every path still going, then all their shadow rays, then all their extension rays: the
        // same operations on each path in the same order as trace(), so the same bits.
        scratch.shadowPaths.clear();
        scratch.extensionPaths.clear();
        // The vertex's three 2D points of every path (those whose path ends before it draws them go unused).
        scratch.samplers.resize(active.size());
        scratch.points.resize(3 * active.size());
        for (size_t k = 0; k < active.size(); ++k) scratch.samplers[k] = paths[active[k]].sampler;
        next2D(scratch.samplers.data(), active.size(), 3, scratch.points.data());
        scratch.shading.clear();
        scratch.quadPaths.clear();
        scratch.quadPicks.resize(active.size());
        for (size_t k = 0; k < active.size(); ++k) {
            const Next next = scatterBegin(paths[active[k]], &scratch.points[3 * k], maxDepth, nullptr, tail,
                                           &scratch.quadPicks[scratch.quadPaths.size()]);
            if (next == kShade)
                scratch.shading.push_back(active[k]);
            else if (next == kQuadLanes)
                scratch.quadPaths.push_back(active[k]);
        }
        shadeBatch(paths, scratch);
        scatterBatch(paths, scratch, counters);
        // The shadow query (unless there is no room for an occluder, see trace) and the extension ray.
        auto rays = [&](uint32_t i, bool more) {
            Path& p = paths[i];
            if (p.shadowPending) {
                if (p.shadow.tfar > p.shadow.tnear)
                    scratch.shadowPaths.push_back(i);
                else
                    finishShadow(p, false, nullptr);
            }
            if (more) scratch.extensionPaths.push_back(i);
        };
        for (uint32_t i : scratch.shading) rays(i, scatterEnd(paths[i], counters, nullptr));
        for (size_t k = 0; k < scratch.quadPaths.size(); ++k) rays(scratch.quadPaths[k], scratch.quadMore[k] != 0);
        const size_t shadows = scratch.shadowPaths.size(), extensions = scratch.extensionPaths.size();
        scratch.queries.resize(std::max(shadows, extensions));
        scratch.blocked.resize(shadows);
        for (size_t k = 0; k < shadows; ++k) scratch.queries[k] = paths[scratch.shadowPaths[k]].shadow;
        accel_.occluded(scratch.queries.data(), shadows, scratch.blocked.data());
        for (size_t k = 0; k < shadows; ++k) finishShadow(paths[scratch.shadowPaths[k]], scratch.blocked[k] != 0, nullptr);
        scratch.hits.resize(extensions);
        for (size_t k = 0; k < extensions; ++k) scratch.queries[k] = paths[scratch.extensionPaths[k]].extension;
        accel_.intersect(scratch.queries.data(), extensions, scratch.hits.data());
        if (!scene_.textures.empty())
            for (size_t k = 0; k < extensions; ++k)
                if (scratch.hits[k].valid()) prefetchInteraction(scene_, scratch.hits[k]);
        active.clear();
        for (size_t k = 0; k < extensions; ++k)
            if (arrive(paths[scratch.extensionPaths[k]], scratch.hits[k])) active.push_back(scratch.extensionPaths[k]);
    }
}

void PathTracer::estimate(const PathStart* starts, size_t n, int maxDepth, const ScatteredRadiance* tail, int bounces,
                          RayCounters& counters, glm::vec3* out) const {
    constexpr size_t kBatch = size_t(kBatchSize);
    const size_t probsPerPath = selector_->choosesGroups() ? 2 * LightSampler::kMaxLightGroups : 0;
    // The buffers of this thread, kept from call to call (bakes call this for every range of a few hundred paths);
    // the paths point into `samplers`, which never grows past its reserve.
    struct EstimateBuffers {
        std::vector<Sampler> samplers;
        std::vector<Path> paths;
        std::vector<float> probs;
        BatchScratch scratch;
    };
    static thread_local EstimateBuffers buffers;
    std::vector<Sampler>& samplers = buffers.samplers;
    std::vector<Path>& paths = buffers.paths;
    std::vector<float>& probs = buffers.probs;
    BatchScratch& scratch = buffers.scratch;
    if (probs.size() < probsPerPath * std::min(n, kBatch)) probs.resize(probsPerPath * std::min(n, kBatch));
    samplers.reserve(kBatch);
    for (size_t first = 0; first < n; first += kBatch) {
        const size_t m = std::min(kBatch, n - first);
        samplers.clear();
        if (paths.size() < m) paths.resize(m);
        for (size_t k = 0; k < m; ++k) {
            const PathStart& start = starts[first + k];
            samplers.emplace_back(start.stream, start.index);
            paths[k].restart(&samplers[k], probsPerPath > 0 ? probs.data() + probsPerPath * k : nullptr);
            paths[k].si = *start.si;
        }
        if (tail)
            traceBatch(paths.data(), m, 0, counters, scratch, std::max(1, bounces), tail);
        else
            traceBatch(paths.data(), m, maxDepth, counters, scratch);
        for (size_t k = 0; k < m; ++k) out[first + k] = paths[k].L;
    }
}

bool PathTracer::viewable(const SurfaceInteraction& si) const {
    Hit hit = accel_.intersect(si.p, si.wo, si.spawnDistance(si.wo));
    if (!hit.valid()) return true;
    const Material& m = scene_.materials[scene_.mesh.materialIds[hit.triangle]];
    // A viewer may stand beyond a surface it sees through (transmission, alpha blending): only opaque backs hide.
    const bool seeThrough = m.transmission > 0.0f || m.alphaMode == Material::AlphaMode::Blend;
    return m.doubleSided || seeThrough || glm::dot(hit.ng, si.wo) <= 0.0f;
}

// One render's tiles: each a tile of the image, one path at a time (plain) or in batches of paths (batched).
struct PathTracer::TileRender {
    const PathTracer& tracer;
    const RenderSettings& settings;
    const CameraRays& rays;
    Image& image;
    const size_t batch, probsPerPath;
    // What a camera ray that leaves the scene sees, computed once where it is the same in every direction.
    const bool uniformSky;
    const glm::vec3 uniformSkyRadiance;

    // A batch's camera rays, traced (and their hits' texels asked for) one batch ahead of its paths, so that the
    // memory system fetches a batch's texels while the previous batch's paths are traced.
    struct CameraBatch {
        std::vector<Sampler> samplers;
        std::vector<uint32_t> pixelOf;  // per path: its pixel in the tile
        std::vector<RayQuery> rays;
        std::vector<Hit> hits;
    };
    // The batched tracer's buffers: one set per worker thread for the whole render (every range is one tile, and
    // buffers made per range were made, and their paths constructed, 64 times for a 128 x 128 image).
    struct Buffers {
        std::vector<uint32_t> streams;
        std::vector<int> pixelX, pixelY;  // of the tile's pixels
        std::vector<glm::dvec3> sums;
        CameraBatch cameraBatches[2];
        std::vector<Sampler*> samplerOf;
        std::vector<glm::vec2> jitters;
        std::vector<float> rasterX, rasterY;
        std::vector<Path> paths;
        std::vector<uint32_t> pathOf;  // per camera ray: its path, or UINT32_MAX where it saw the sky
        std::vector<float> probs;
        BatchScratch scratch;
    };

    TileRender(const PathTracer& t, const RenderSettings& s, const CameraRays& r, Image& i)
        : tracer(t), settings(s), rays(r), image(i), batch(size_t(std::max(1, s.batchSize))),
          probsPerPath(t.selector_->choosesGroups() ? 2 * LightSampler::kMaxLightGroups : 0), uniformSky(skyIsUniform(t.scene_)),
          uniformSkyRadiance(uniformSky ? skyRadiance(t.scene_, glm::vec3(0.0f, 0.0f, 1.0f)) : glm::vec3(0.0f)) {}

    // The tile's pixels [x0, x1) x [y0, y1), one sample's path at a time.
    void plain(int x0, int y0, int x1, int y1, RayCounters& counters) const {
        for (int y = y0; y < y1; ++y)
            for (int x = x0; x < x1; ++x) {
                glm::dvec3 sum(0.0);
                for (int s = 0; s < settings.spp; ++s) {
                    glm::vec3 o, d;
                    Sampler sampler = cameraSample(rays, x, y, settings.seed, uint32_t(s), o, d);
                    glm::vec3 L = tracer.radiance(o, d, sampler, settings.maxDepth, counters);
                    if (isFinite(L))
                        sum += glm::dvec3(L);
                    else
                        ++counters.nonFiniteSamples;
                }
                image.at(x, y) = glm::vec3(sum / double(std::max(1, settings.spp)));
            }
    }

    // The tile's samples in batches, pixel by pixel: each pixel's samples are summed in the same order as plain().
    // Path q is sample q % spp of pixel q / spp: a pixel's samples are consecutive paths of a batch, so the texels
    // one sample's lookups bring into the cache serve the pixel's other samples (whose camera rays land within its
    // footprint).
    void batched(Buffers& b, int x0, int y0, int x1, int y1, RayCounters& counters) const {
        b.probs.resize(probsPerPath * batch);
        const size_t pixels = tilePixels(b, x0, y0, x1, y1);
        const size_t count = pixels * spp();
        if (count > 0) traceCameraRays(b, b.cameraBatches[0], 0, std::min(batch, count), counters);
        for (size_t first = 0, k = 0; first < count; first += batch, ++k) {
            const size_t m = std::min(batch, count - first);
            CameraBatch& c = b.cameraBatches[k & 1];
            const size_t next = first + batch;
            if (next < count) traceCameraRays(b, b.cameraBatches[(k + 1) & 1], next, std::min(batch, count - next), counters);
            // The texels again, now: the requests made a batch ahead do not all survive the previous batch
            // (docs/design.md).
            prefetchHits(c, m);
            tracer.traceBatch(b.paths.data(), startPaths(b, c, m), settings.maxDepth, counters, b.scratch);
            addSamples(b, c, m, counters);
        }
        for (size_t i = 0; i < pixels; ++i) image.at(b.pixelX[i], b.pixelY[i]) = glm::vec3(b.sums[i] / double(std::max(1, settings.spp)));
    }

private:
    size_t spp() const { return size_t(std::max(0, settings.spp)); }

    // The tile's pixels, their sample streams and sums; returns their number.
    size_t tilePixels(Buffers& b, int x0, int y0, int x1, int y1) const {
        const int tw = x1 - x0;
        const size_t pixels = size_t(tw) * size_t(y1 - y0);
        b.streams.resize(pixels);
        b.pixelX.resize(pixels);
        b.pixelY.resize(pixels);
        b.sums.assign(pixels, glm::dvec3(0.0));
        for (size_t i = 0; i < pixels; ++i) {
            b.pixelX[i] = x0 + int(i) % tw;
            b.pixelY[i] = y0 + int(i) / tw;
            b.streams[i] = pixelStream(uint32_t(b.pixelX[i]), uint32_t(b.pixelY[i]), settings.seed);
        }
        return pixels;
    }

    // Asks for the texels the interactions of a batch's camera hits will read.
    void prefetchHits(const CameraBatch& c, size_t m) const {
        if (!tracer.scene_.textures.empty())
            for (size_t k = 0; k < m; ++k)
                if (c.hits[k].valid()) prefetchInteraction(tracer.scene_, c.hits[k]);
    }

    // The camera rays of the batch of paths [first, first + m), traced, their hits' texels prefetched.
    void traceCameraRays(Buffers& b, CameraBatch& c, size_t first, size_t m, RayCounters& counters) const {
        c.samplers.clear();
        c.rays.resize(m);
        c.hits.resize(m);
        c.pixelOf.resize(m);
        b.samplerOf.resize(m);
        b.jitters.resize(m);
        // Each path's pixel and sample number, counted on from the batch's first path's.
        for (size_t k = 0, pixel = first / spp(), sample = first % spp(); k < m; ++k) {
            c.pixelOf[k] = uint32_t(pixel);
            c.samplers.emplace_back(b.streams[pixel], uint32_t(sample));
            if (++sample == spp()) {
                sample = 0;
                ++pixel;
            }
        }
        for (size_t k = 0; k < m; ++k) b.samplerOf[k] = &c.samplers[k];
        next2D(b.samplerOf.data(), m, 1, b.jitters.data());
        b.rasterX.resize(m);
        b.rasterY.resize(m);
        for (size_t k = 0; k < m; ++k) {
            b.rasterX[k] = float(b.pixelX[c.pixelOf[k]]) + b.jitters[k].x;
            b.rasterY[k] = float(b.pixelY[c.pixelOf[k]]) + b.jitters[k].y;
        }
        rays.generate(b.rasterX.data(), b.rasterY.data(), m, c.rays.data());
        counters.primary += m;
        tracer.accel_.intersect(c.rays.data(), m, c.hits.data(), settings.coherentCameraRays);
        prefetchHits(c, m);
    }

    // A path for every camera ray of the batch that hit the scene; returns their number.
    size_t startPaths(Buffers& b, CameraBatch& c, size_t m) const {
        if (b.paths.size() < m) b.paths.resize(m);  // constructed once, restarted by every batch
        size_t started = 0;
        b.pathOf.resize(m);
        for (size_t k = 0; k < m; ++k) {
            if (!c.hits[k].valid()) {
                b.pathOf[k] = UINT32_MAX;
                continue;
            }
            b.pathOf[k] = uint32_t(started);
            Path& p = b.paths[started++];
            p.restart(&c.samplers[k], probsPerPath > 0 ? b.probs.data() + probsPerPath * k : nullptr);
            makeInteraction(tracer.scene_, c.hits[k], c.rays[k].direction, p.si);
        }
        return started;
    }

    // The batch's samples into their pixels' sums. A pixel's samples are a run of the batch: summed in a
    // register, stored where the run ends (the same additions in the same order as into sums[] one by one).
    void addSamples(Buffers& b, const CameraBatch& c, size_t m, RayCounters& counters) const {
        uint32_t runPixel = c.pixelOf[0];
        glm::dvec3 run = b.sums[runPixel];
        for (size_t k = 0; k < m; ++k) {
            if (c.pixelOf[k] != runPixel) {
                b.sums[runPixel] = run;
                runPixel = c.pixelOf[k];
                run = b.sums[runPixel];
            }
            // The sky (and suns' disks) where the camera ray left the scene.
            const glm::vec3 L = b.pathOf[k] != UINT32_MAX ? b.paths[b.pathOf[k]].L
                                : uniformSky              ? uniformSkyRadiance
                                                          : skyRadiance(tracer.scene_, c.rays[k].direction);
            if (isFinite(L))
                run += glm::dvec3(L);
            else
                ++counters.nonFiniteSamples;
        }
        b.sums[runPixel] = run;
    }
};

Image PathTracer::render(const Camera& camera, const RenderSettings& settings, RenderStats* stats,
                         const std::function<void(double)>& progress) const {
    auto start = std::chrono::steady_clock::now();
    Image image(settings.width, settings.height);
    CameraRays rays(camera, settings.width, settings.height);
    const int ts = std::max(1, settings.tileSize);
    const int tilesX = (settings.width + ts - 1) / ts, tilesY = (settings.height + ts - 1) / ts;
    const int tileCount = tilesX * tilesY;
    std::mutex statsMutex;
    RayCounters total;
    std::atomic<int> tilesDone{0};
    const TileRender tiles(*this, settings, rays, image);
    tbb::enumerable_thread_specific<TileRender::Buffers> threadBuffers;

    tbb::parallel_for(tbb::blocked_range<int>(0, tileCount, 1), [&](const tbb::blocked_range<int>& range) {
        RayCounters counters;
        for (int tile = range.begin(); tile != range.end(); ++tile) {
            int x0 = (tile % tilesX) * ts, y0 = (tile / tilesX) * ts;
            int x1 = std::min(x0 + ts, settings.width), y1 = std::min(y0 + ts, settings.height);
            if (settings.batchSize > 1)
                tiles.batched(threadBuffers.local(), x0, y0, x1, y1, counters);
            else
                tiles.plain(x0, y0, x1, y1, counters);
            int done = ++tilesDone;
            if (progress) progress(double(done) / double(tileCount));
        }
        std::lock_guard<std::mutex> lock(statsMutex);
        total += counters;
    }, tbb::simple_partitioner());

    if (stats) {
        stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        stats->samples = uint64_t(settings.width) * uint64_t(settings.height) * uint64_t(std::max(0, settings.spp));
        stats->rays = total;
    }
    return image;
}

std::vector<RecordedRay> PathTracer::recordRays(const Camera& camera, const RenderSettings& settings) const {
    std::vector<RecordedRay> out;
    CameraRays rays(camera, settings.width, settings.height);
    RayCounters counters;
    for (int y = 0; y < settings.height; ++y)
        for (int x = 0; x < settings.width; ++x) {
            for (int s = 0; s < settings.spp; ++s) {
                glm::vec3 o, d;
                Sampler sampler = cameraSample(rays, x, y, settings.seed, uint32_t(s), o, d);
                radiance(o, d, sampler, settings.maxDepth, counters, &out);
            }
        }
    return out;
}

}  // namespace nrad
