// Power-proportional choice among the scene's lights, light groups, and the pdfs MIS needs.
#include "baker/lights/light_sampler.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "baker/scene/geometry.h"

namespace nrad {

LightSampler::LightSampler(const Scene& scene) : scene_(scene), environment_(scene.environment) {
    sceneRadius_ = std::max(scene.bounds.radius(), 1e-30f);
    lights_ = makeLights(scene, environment_, sceneRadius_, &environmentEntry_);
    entryOfTriangle_.assign(scene.mesh.triangleCount(), -1);
    std::vector<double> power;
    for (size_t i = 0; i < lights_.size(); ++i) {
        const Light& light = *lights_[i];
        power.push_back(light.power());
        if (light.triangle() >= 0) entryOfTriangle_[size_t(light.triangle())] = int32_t(i);
        if (light.unbounded()) escapedEntries_.push_back(uint32_t(i));  // what rays leaving the scene may meet
    }
    cdf_.resize(power.size());
    double sum = 0.0;
    for (size_t i = 0; i < power.size(); ++i) {
        sum += power[i];
        cdf_[i] = sum;
    }
    totalPower_ = sum;
    for (double& c : cdf_) c /= sum;
    if (!cdf_.empty()) cdf_.back() = 1.0;
    pick_.resize(cdf_.size());
    for (size_t i = 0; i < cdf_.size(); ++i) pick_[i] = float(cdf_[i] - (i > 0 ? cdf_[i - 1] : 0.0));
    buildGroups(power);
}

float LightSampler::pickProbability(size_t i) const { return pick_[i]; }

size_t cdfInterval(const std::vector<double>& cdf, float u) {
    const double x = double(u);
    const double* base = cdf.data();
    size_t n = cdf.size();
    if (n == 0) return 0;
    while (n > 1) {
        const size_t half = n / 2;
        base = x < base[half] ? base : base + half;  // as upper_bound compares (so NaN too)
        n -= half;
    }
    const size_t i = size_t(base - cdf.data()) + (x < *base ? 0 : 1);
    return std::min(i, cdf.size() - 1);
}

namespace {
// u rescaled from [lo, lo + width) to [0, 1).
float rescale(float u, double lo, double width) {
    return width > 0.0 ? float(std::clamp((double(u) - lo) / width, 0.0, double(0x1.fffffep-1f))) : 0.0f;
}

// u rescaled within interval i of `cdf`.
float remap(const std::vector<double>& cdf, size_t i, float u) {
    double lo = i > 0 ? cdf[i - 1] : 0.0;
    return rescale(u, lo, cdf[i] - lo);
}
// Index of the interval of `cdf` (ascending, ending at 1) holding u, and u rescaled to [0, 1) within it: the
// pick sample is reused as the first coordinate of the point on the light, so a stratified pick dimension
// also stratifies the points within each light.
size_t pickAndRemap(const std::vector<double>& cdf, float& u) {
    size_t i = cdfInterval(cdf, u);
    u = remap(cdf, i, u);
    return i;
}
}  // namespace

const LightSampler::Quad* LightSampler::pickEntry(glm::vec2& u, size_t& i) const {
    i = cdfInterval(cdf_, u.x);
    const EntryQuad& eq = entryQuad_[i];
    if (eq.quad < 0) return nullptr;
    u.x = rescale(u.x, eq.lo, eq.width);
    return &quads_[size_t(eq.quad)];
}

int LightSampler::quadPoint(const Quad& quad, const glm::vec2& u, glm::vec3& pl) {
    // Uniform by area over the whole quad with one 2D sample, so that stratified samples stay stratified
    // over the quad: the same density as picking one of its two equal triangles and a point in it, so the
    // pdfs (pdfTriangle, pdfTriangleInGroup) are those of the triangle the point lands in.
    pl = quad.corner + u.x * quad.edgeU + u.y * quad.edgeV;
    return u.x + u.y <= 1.0f ? 0 : 1;  // the first triangle holds the corner
}

LightSample LightSampler::sample(const glm::vec3& p, glm::vec2 u) const {
    if (lights_.empty()) return LightSample{};
    size_t i;
    if (const Quad* quad = pickEntry(u, i)) return sampleParallelogram(*quad, p, u, true);
    u.x = remap(cdf_, i, u.x);
    return sampleEntry(i, pickProbability(i), p, u);
}

bool LightSampler::pickQuad(glm::vec2 u, QuadPick& out) const {
    // sample() and sampleParallelogram() up to the call of sampleAt.
    if (lights_.empty()) return false;
    size_t i;
    const Quad* quad = pickEntry(u, i);
    if (!quad) return false;
    glm::vec3 point;
    const int half = quadPoint(*quad, u, point);
    if (quad->textured[half]) return false;
    out = quad->halves[half];
    out.point = point;
    return true;
}

LightSample LightSampler::sampleParallelogram(const Quad& quad, const glm::vec3& p, const glm::vec2& u,
                                              bool globalPick) const {
    const auto& P = scene_.mesh.positions;
    glm::vec3 pl;
    const size_t i = quad.entries[quadPoint(quad, u, pl)];
    const auto& light = static_cast<const TriangleLight&>(*lights_[i]);  // a parallelogram's entries are triangles
    float b1 = 0.0f, b2 = 0.0f;
    if (light.textured()) {
        // Barycentrics of pl in the triangle's own vertex order (for the emissive texture).
        const glm::uvec3& tri = scene_.mesh.triangles[size_t(light.triangle())];
        glm::vec3 e1 = P[tri.y] - P[tri.x], e2 = P[tri.z] - P[tri.x], d = pl - P[tri.x];
        float d11 = glm::dot(e1, e1), d12 = glm::dot(e1, e2), d22 = glm::dot(e2, e2);
        float d1 = glm::dot(d, e1), d2 = glm::dot(d, e2), den = d11 * d22 - d12 * d12;
        b1 = den > 0.0f ? std::clamp((d22 * d1 - d12 * d2) / den, 0.0f, 1.0f) : 0.0f;
        b2 = den > 0.0f ? std::clamp((d11 * d2 - d12 * d1) / den, 0.0f, 1.0f - b1) : 0.0f;
    }
    LightSample ls = light.sampleAt(p, pl, b1, b2);
    ls.pdf *= globalPick ? pickProbability(i) : pickInGroup_[i];
    ls.entry = int32_t(i);
    return ls;
}

const TriangleLight* LightSampler::triangleLight(size_t i) const {
    return lights_[i]->triangle() >= 0 ? static_cast<const TriangleLight*>(lights_[i].get()) : nullptr;
}

LightSample LightSampler::sampleGroup(size_t g, const glm::vec3& p, glm::vec2 u) const {
    const Group& group = groups_[g];
    if (group.parallelogram) return sampleParallelogram(quads_[group.quad], p, u, false);
    size_t k = pickAndRemap(group.cdf, u.x);
    size_t i = group.entries[k];
    return sampleEntry(i, pickInGroup_[i], p, u);
}

LightSample LightSampler::sampleEntry(size_t i, float pick, const glm::vec3& p, const glm::vec2& u) const {
    if (!(pick > 0.0f)) return LightSample{};
    LightSample ls = lights_[i]->sample(p, u);
    ls.pdf = ls.pdf > 0.0f ? ls.pdf * pick : 0.0f;
    ls.entry = int32_t(i);
    return ls;
}

bool LightSampler::engineDrawn(int32_t entry) const {
    return entry >= 0 && size_t(entry) < lights_.size() && lights_[size_t(entry)]->engineDrawn();
}

float LightSampler::pdfEnvironment(const glm::vec3& wi) const {
    if (environmentEntry_ < 0) return 0.0f;
    return pickProbability(size_t(environmentEntry_)) * environment_.pdf(wi);
}

float LightSampler::pdfEnvironmentInGroup(const glm::vec3& wi) const {
    if (environmentEntry_ < 0) return 0.0f;
    return pickInGroup_[size_t(environmentEntry_)] * environment_.pdf(wi);
}

float LightSampler::pdfTriangle(uint32_t triangle, const glm::vec3& p, const glm::vec3& pLight,
                                const glm::vec3& nLight) const {
    int32_t i = entryOfTriangle_[triangle];
    if (i < 0) return 0.0f;
    return pickProbability(size_t(i)) * triangleLight(size_t(i))->pdf(p, pLight, nLight);
}

float LightSampler::pdfTriangleInGroup(uint32_t triangle, const glm::vec3& p, const glm::vec3& pLight,
                                       const glm::vec3& nLight) const {
    int32_t i = entryOfTriangle_[triangle];
    if (i < 0) return 0.0f;
    return pickInGroup_[size_t(i)] * triangleLight(size_t(i))->pdf(p, pLight, nLight);
}

int32_t LightSampler::groupOfTriangle(uint32_t triangle) const {
    int32_t i = entryOfTriangle_[triangle];
    return i < 0 ? -1 : int32_t(groupOfEntry_[size_t(i)]);
}

namespace {
// The test of groupCanContribute with the group's precomputed box centre, half extents and diagonal. The
// largest value of a linear function over a box is at its centre plus the half extents weighted by the
// function's absolute coefficients.
inline bool boxCanContribute(const glm::vec3& center, const glm::vec3& half, float diagonal, bool planar,
                             const glm::vec3& normal, const glm::vec3& p, const glm::vec3& ng, float offset) {
    // Tolerance: a light lying in the tangent plane contributes nothing, so admitting it is harmless.
    float tol = 1e-4f * std::max(diagonal, offset);
    float above = glm::dot(center - p, ng) + glm::dot(half, glm::abs(ng));
    if (!(above > -tol)) return false;
    if (!planar) return true;
    float front = glm::dot(p - center, normal) + glm::dot(half, glm::abs(normal));
    return front > -tol;
}
}  // namespace

bool LightSampler::groupCanContribute(size_t g, const glm::vec3& p, const glm::vec3& ng) const {
    const Group& group = groups_[g];
    if (group.unbounded) return true;
    return boxCanContribute(group.center, group.half, group.diagonal, group.planar, group.normal, p, ng, rayOffset(p));
}

uint64_t LightSampler::candidateGroups(const glm::vec3& p, const glm::vec3& ng) const {
    const float offset = rayOffset(p);
    uint64_t mask = 0;
    for (size_t g = 0; g < groups_.size(); ++g) {
        const Group& group = groups_[g];
        if (group.unbounded ||
            boxCanContribute(group.center, group.half, group.diagonal, group.planar, group.normal, p, ng, offset))
            mask |= uint64_t(1) << g;
    }
    return mask;
}

namespace {

// The lights as the selection sees them: emissive triangles of one material that share a vertex index are one
// light (a union of entries); every other entry is one by itself. In the order of their first entry.
std::vector<std::vector<uint32_t>> connectedLights(const Scene& scene, const std::vector<std::unique_ptr<Light>>& entries) {
    const size_t n = entries.size();
    std::vector<uint32_t> parent(n);
    for (size_t i = 0; i < n; ++i) parent[i] = uint32_t(i);
    auto find = [&](uint32_t a) {
        while (parent[a] != a) a = parent[a] = parent[parent[a]];
        return a;
    };
    std::vector<std::pair<uint64_t, uint32_t>> keys;  // (material << 32 | vertex, entry)
    for (size_t i = 0; i < n; ++i) {
        if (entries[i]->triangle() < 0) continue;
        uint32_t t = uint32_t(entries[i]->triangle());
        uint64_t mat = scene.mesh.materialIds[t];
        const glm::uvec3& tri = scene.mesh.triangles[t];
        for (uint32_t v : {tri.x, tri.y, tri.z}) keys.push_back({(mat << 32) | v, uint32_t(i)});
    }
    std::sort(keys.begin(), keys.end());
    for (size_t k = 1; k < keys.size(); ++k)
        if (keys[k].first == keys[k - 1].first) {
            uint32_t a = find(keys[k].second), b = find(keys[k - 1].second);
            if (a != b) parent[std::max(a, b)] = std::min(a, b);
        }
    std::vector<std::vector<uint32_t>> lights;
    std::vector<int32_t> lightOfRoot(n, -1);
    for (size_t i = 0; i < n; ++i) {
        uint32_t r = find(uint32_t(i));
        if (lightOfRoot[r] < 0) {
            lightOfRoot[r] = int32_t(lights.size());
            lights.emplace_back();
        }
        lights[size_t(lightOfRoot[r])].push_back(uint32_t(i));
    }
    return lights;
}

// Clusters of lights, at most `maxClusters`: one per light while they are few enough; else the largest cluster
// split at the median of its lights' centres along the axis where they spread most, until there are enough.
// In the order of their first entry (`lights[l][0]`), so the numbering follows the scene.
std::vector<std::vector<uint32_t>> clusterLights(const std::vector<std::vector<uint32_t>>& lights,
                                                 const std::vector<glm::vec3>& lightCenter, size_t maxClusters) {
    std::vector<std::vector<uint32_t>> clusters(1);
    for (size_t l = 0; l < lights.size(); ++l) clusters[0].push_back(uint32_t(l));
    if (lights.size() <= maxClusters) {
        clusters.assign(lights.size(), {});
        for (size_t l = 0; l < lights.size(); ++l) clusters[l] = {uint32_t(l)};
    }
    while (clusters.size() < maxClusters) {
        size_t largest = 0;
        for (size_t c = 1; c < clusters.size(); ++c)
            if (clusters[c].size() > clusters[largest].size()) largest = c;
        if (clusters[largest].size() < 2) break;
        std::vector<uint32_t>& members = clusters[largest];
        Bounds3 b;
        for (uint32_t l : members) b.extend(lightCenter[l]);
        glm::vec3 ext = b.extent();
        int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
        std::stable_sort(members.begin(), members.end(),
                         [&](uint32_t a, uint32_t c) { return lightCenter[a][axis] < lightCenter[c][axis]; });
        std::vector<uint32_t> upperHalf(members.begin() + std::ptrdiff_t(members.size() / 2), members.end());
        members.resize(members.size() / 2);
        std::sort(members.begin(), members.end());
        std::sort(upperHalf.begin(), upperHalf.end());
        clusters.push_back(std::move(upperHalf));
    }
    for (auto& c : clusters) std::sort(c.begin(), c.end(), [&](uint32_t a, uint32_t b) { return lights[a][0] < lights[b][0]; });
    std::sort(clusters.begin(), clusters.end(), [&](const auto& a, const auto& b) { return lights[a[0]][0] < lights[b[0]][0]; });
    return clusters;
}

}  // namespace

void LightSampler::groupBounds(Group& g, const std::vector<double>& power) const {
    Bounds3 b;
    bool planar = true;
    glm::vec3 normal(0.0f);
    for (uint32_t i : g.entries) {
        g.power += power[i];
        const Light& light = *lights_[i];
        if (const Bounds3 lb = light.bounds(); !lb.empty()) {
            b.extend(lb.lower);
            b.extend(lb.upper);
        }
        if (light.unbounded()) g.unbounded = true;
        if (light.triangle() < 0) {
            planar = false;
            continue;
        }
        const size_t t = size_t(light.triangle());
        glm::vec3 nt = scene_.mesh.geometricNormal(t);
        const Material& m = scene_.materials[scene_.mesh.materialIds[t]];
        if (m.doubleSided || (normal != glm::vec3(0.0f) && glm::dot(normal, nt) < 0.9999f)) planar = false;
        if (normal == glm::vec3(0.0f)) normal = nt;
    }
    g.planar = planar && normal != glm::vec3(0.0f);
    g.normal = normal;
    if (!b.empty()) {
        g.lower = b.lower;
        g.upper = b.upper;
    }
    g.center = 0.5f * (g.lower + g.upper);
    g.half = 0.5f * (g.upper - g.lower);
    g.diagonal = glm::length(g.upper - g.lower);
}

void LightSampler::buildGroups(const std::vector<double>& power) {
    const std::vector<std::vector<uint32_t>> lights = connectedLights(scene_, lights_);
    std::vector<glm::vec3> lightCenter(lights.size());
    for (size_t l = 0; l < lights.size(); ++l) {
        glm::vec3 c(0.0f);
        for (uint32_t i : lights[l]) c += lights_[i]->center();
        lightCenter[l] = c / float(lights[l].size());
    }
    const std::vector<std::vector<uint32_t>> clusters = clusterLights(lights, lightCenter, kMaxLightGroups);
    const size_t n = lights_.size();
    groupOfEntry_.assign(n, 0);
    pickInGroup_.assign(n, 0.0f);
    entryQuad_.assign(n, EntryQuad{});
    groups_.clear();
    for (const auto& cluster : clusters) {
        Group g;
        for (uint32_t l : cluster) g.entries.insert(g.entries.end(), lights[l].begin(), lights[l].end());
        std::sort(g.entries.begin(), g.entries.end());
        groupBounds(g, power);
        double acc = 0.0;
        for (uint32_t i : g.entries) {
            acc += power[i];
            g.cdf.push_back(acc / g.power);
            groupOfEntry_[i] = uint32_t(groups_.size());
            pickInGroup_[i] = float(power[i] / g.power);
        }
        g.cdf.back() = 1.0;
        detectParallelogram(g, power);
        groups_.push_back(std::move(g));
    }
}

void LightSampler::detectParallelogram(Group& g, const std::vector<double>& power) {
    // Two emissive triangles of one untextured material with equal power (so equal area), sharing an edge
    // (a, b), whose other corners c and d satisfy c + d = a + b.
    if (g.entries.size() != 2 || !g.planar) return;
    const TriangleLight *ea = triangleLight(g.entries[0]), *eb = triangleLight(g.entries[1]);
    if (!ea || !eb) return;
    const auto& mesh = scene_.mesh;
    const size_t ia = size_t(ea->triangle()), ib = size_t(eb->triangle());
    if (mesh.materialIds[ia] != mesh.materialIds[ib]) return;
    if (scene_.materials[mesh.materialIds[ia]].emissiveTexture.valid()) return;
    if (!(std::abs(power[g.entries[0]] / g.power - 0.5) < 1e-4)) return;
    const glm::uvec3 ta = mesh.triangles[ia], tb = mesh.triangles[ib];
    uint32_t va[3] = {ta.x, ta.y, ta.z}, vb[3] = {tb.x, tb.y, tb.z};
    uint32_t shared[3], c = 0, d = 0;
    int nShared = 0;
    for (uint32_t v : va) {
        if (v == vb[0] || v == vb[1] || v == vb[2])
            shared[nShared++] = v;
        else
            c = v;
    }
    if (nShared != 2) return;
    for (uint32_t v : vb)
        if (v != shared[0] && v != shared[1]) d = v;
    const glm::vec3 &a = mesh.positions[shared[0]], &b = mesh.positions[shared[1]], &pc = mesh.positions[c],
                    &pd = mesh.positions[d];
    float size = glm::length(a - pc) + glm::length(b - pc);
    if (!(size > 0.0f) || !(glm::length(pc + pd - a - b) <= 1e-5f * size)) return;
    Quad quad;
    quad.corner = pc;
    quad.edgeU = a - pc;
    quad.edgeV = b - pc;  // the first entry's triangle is (c, a, b): u + v <= 1
    for (int h = 0; h < 2; ++h) {
        const uint32_t e = g.entries[size_t(h)];
        const TriangleLight& light = *triangleLight(e);
        quad.entries[h] = e;
        quad.textured[h] = light.textured();
        QuadPick& half = quad.halves[h];
        half.normal = light.normal();
        half.front = light.frontRadiance();
        half.back = light.backRadiance();
        half.area = light.area();
        half.margin = light.margin();
        half.pick = pickProbability(e);
    }
    g.parallelogram = true;
    g.quad = uint32_t(quads_.size());
    quads_.push_back(quad);
    // sample() picks the quad as one where its entries are neighbours in cdf_ (they are ascending).
    if (quad.entries[1] == quad.entries[0] + 1) {
        const size_t e0 = quad.entries[0], e1 = quad.entries[1];
        const double lo = e0 > 0 ? cdf_[e0 - 1] : 0.0;
        entryQuad_[e0] = entryQuad_[e1] = EntryQuad{int32_t(g.quad), lo, cdf_[e1] - lo};
    }
}

}  // namespace nrad
