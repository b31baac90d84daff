// Environment importance sampling (piecewise-constant 2D distribution over the map).
#include "baker/lights/environment_light.h"
#include "baker/util/maths.h"

#include <algorithm>
#include <cmath>

#include "baker/scene/scene.h"  // luminance()

namespace nrad {

namespace {


// Index i with cdf[i] <= u < cdf[i + 1] (cdf ascending from 0 to 1, intervals of zero width never chosen),
// and u rescaled to [0, 1) within that interval.
size_t invert(const double* cdf, size_t n, double& u) {
    size_t i = size_t(std::upper_bound(cdf, cdf + n + 1, u) - cdf);
    i = std::clamp<size_t>(i, 1, n) - 1;
    while (i > 0 && !(cdf[i + 1] > cdf[i])) --i;  // u at the end: the last interval that has width
    double width = cdf[i + 1] - cdf[i];
    u = width > 0.0 ? std::clamp((u - cdf[i]) / width, 0.0, 1.0 - 1e-12) : 0.0;
    return i;
}

}  // namespace

EnvironmentSampler::EnvironmentSampler(const Environment& env) : env_(env) {
    if (!env.active()) return;
    if (env.kind == Environment::Kind::Constant) {
        active_ = true;
        return;
    }
    const size_t W = size_t(env.width), H = size_t(env.height);
    marginal_.assign(H + 1, 0.0);
    conditional_.assign(H * (W + 1), 0.0);
    density_.assign(W * H, 0.0f);
    std::vector<double> weight(W * H);
    double total = 0.0;
    for (size_t y = 0; y < H; ++y) {
        double sinTheta = std::sin(kPiDouble * (double(y) + 0.5) / double(H));
        double* row = &conditional_[y * (W + 1)];
        double acc = 0.0;
        for (size_t x = 0; x < W; ++x) {
            double w = luminance(env.texels[y * W + x]) * sinTheta;
            weight[y * W + x] = w;
            acc += w;
            row[x + 1] = acc;
        }
        for (size_t x = 1; x <= W; ++x) row[x] = acc > 0.0 ? row[x] / acc : double(x) / double(W);
        row[W] = 1.0;
        total += acc;
        marginal_[y + 1] = total;
    }
    if (!(total > 0.0) || !std::isfinite(total)) return;
    for (size_t y = 1; y <= H; ++y) marginal_[y] /= total;
    marginal_[H] = 1.0;
    const double mean = total / double(W * H);
    for (size_t i = 0; i < W * H; ++i) density_[i] = float(weight[i] / mean);
    active_ = true;
}

glm::vec3 EnvironmentSampler::sample(glm::vec2 u, float& pdf, glm::vec3& radiance) const {
    pdf = 0.0f;
    radiance = glm::vec3(0.0f);
    if (!active_) return glm::vec3(0.0f, 1.0f, 0.0f);
    if (env_.kind == Environment::Kind::Constant) {
        float z = 1.0f - 2.0f * u.y, r = std::sqrt(std::max(0.0f, 1.0f - z * z)), phi = float(2.0 * kPiDouble) * u.x;
        glm::vec3 d(r * std::cos(phi), z, r * std::sin(phi));
        pdf = float(1.0 / (4.0 * kPiDouble));
        radiance = env_.radiance(d);
        return d;
    }
    const size_t W = size_t(env_.width), H = size_t(env_.height);
    double uy = double(u.y), ux = double(u.x);
    size_t y = invert(marginal_.data(), H, uy);
    size_t x = invert(&conditional_[y * (W + 1)], W, ux);
    glm::vec2 uv(float((double(x) + ux) / double(W)), float((double(y) + uy) / double(H)));
    glm::vec3 d = env_.direction(uv);
    float sinTheta = std::sin(uv.y * float(kPiDouble));
    float density = density_[y * W + x];
    if (!(sinTheta > 0.0f) || !(density > 0.0f)) return d;
    pdf = density / (float(2.0 * kPiDouble * kPiDouble) * sinTheta);
    // The texel sampled, not a lookup of d (which could round into the neighbour at a texel's edge).
    radiance = env_.intensity * env_.texels[y * W + x];
    if (!std::isfinite(pdf)) pdf = 0.0f;
    return d;
}

float EnvironmentSampler::pdf(const glm::vec3& towards) const {
    if (!active_) return 0.0f;
    if (env_.kind == Environment::Kind::Constant) return float(1.0 / (4.0 * kPiDouble));
    const int W = env_.width, H = env_.height;
    glm::vec2 uv = env_.mapCoordinates(towards);
    int x = std::min(W - 1, int(uv.x * float(W))), y = std::min(H - 1, int(uv.y * float(H)));
    float sinTheta = std::sqrt(std::max(0.0f, 1.0f - towards.y * towards.y));
    if (!(sinTheta > 0.0f)) return 0.0f;
    float p = density_[size_t(y) * size_t(W) + size_t(x)] / (float(2.0 * kPiDouble * kPiDouble) * sinTheta);
    return std::isfinite(p) ? p : 0.0f;
}

}  // namespace nrad
