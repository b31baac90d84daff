// Error metrics and error images.
#include "baker/validate/metrics.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <stdexcept>

#include "baker/util/maths.h"

namespace nrad {

namespace {

void requireSameSize(const Image& a, const Image& b) {
    if (a.width != b.width || a.height != b.height)
        throw std::invalid_argument("images differ in size: " + std::to_string(a.width) + "x" + std::to_string(a.height) +
                                    " and " + std::to_string(b.width) + "x" + std::to_string(b.height));
}

double tonemap(double v, double gain) {
    v = std::isfinite(v) ? std::clamp(v * gain, 0.0, 1.0) : 0.0;
    return linearToSrgb(v);
}

// Separable Gaussian blur (sigma 1.5, 11 taps, normalised; edges clamped) of a w x h plane.
std::vector<double> gaussian11(const std::vector<double>& in, int w, int h) {
    double k[11], sum = 0.0;
    for (int i = 0; i < 11; ++i) sum += k[i] = std::exp(-double((i - 5) * (i - 5)) / (2.0 * 1.5 * 1.5));
    for (double& v : k) v /= sum;
    std::vector<double> tmp(in.size()), out(in.size());
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double s = 0.0;
            for (int i = 0; i < 11; ++i) s += k[i] * in[size_t(y) * size_t(w) + size_t(std::clamp(x + i - 5, 0, w - 1))];
            tmp[size_t(y) * size_t(w) + size_t(x)] = s;
        }
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double s = 0.0;
            for (int i = 0; i < 11; ++i) s += k[i] * tmp[size_t(std::clamp(y + i - 5, 0, h - 1)) * size_t(w) + size_t(x)];
            out[size_t(y) * size_t(w) + size_t(x)] = s;
        }
    return out;
}

// Mean SSIM of the two images' luminances displayed at `gain` (sRGB-encoded, clamped to [0, 1]).
double ssim(const Image& image, const Image& reference, double gain) {
    const int w = reference.width, h = reference.height;
    const size_t n = reference.pixels.size();
    if (n == 0) return 1.0;
    std::vector<double> x(n), y(n), xx(n), yy(n), xy(n);
    for (size_t i = 0; i < n; ++i) {
        const double a = tonemap(luminance(image.pixels[i]), gain), b = tonemap(luminance(reference.pixels[i]), gain);
        x[i] = a, y[i] = b, xx[i] = a * a, yy[i] = b * b, xy[i] = a * b;
    }
    const std::vector<double> mx = gaussian11(x, w, h), my = gaussian11(y, w, h), sxx = gaussian11(xx, w, h),
                              syy = gaussian11(yy, w, h), sxy = gaussian11(xy, w, h);
    constexpr double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;
    double sum = 0.0;
    for (size_t i = 0; i < n; ++i) {
        const double vx = std::max(0.0, sxx[i] - mx[i] * mx[i]), vy = std::max(0.0, syy[i] - my[i] * my[i]), cov = sxy[i] - mx[i] * my[i];
        sum += (2.0 * mx[i] * my[i] + c1) * (2.0 * cov + c2) / ((mx[i] * mx[i] + my[i] * my[i] + c1) * (vx + vy + c2));
    }
    return sum / double(n);
}

}  // namespace

ImageMetrics compareImages(const Image& image, const Image& reference, float exposure) {
    requireSameSize(image, reference);
    const double gain = std::exp2(double(exposure));
    double se = 0.0, rel = 0.0, tse = 0.0, mre = 0.0;
    for (size_t i = 0; i < image.pixels.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            double ref = reference.pixels[i][c], x = image.pixels[i][c];
            if (!std::isfinite(x)) x = 0.0;
            double d = x - ref;
            se += d * d;
            rel += relMseTerm(x, ref);
            mre += std::abs(d) / (std::abs(ref) + 0.01);
            double t = tonemap(x, gain) - tonemap(ref, gain);
            tse += t * t;
        }
    const double count = double(image.pixels.size()) * 3.0;
    ImageMetrics m;
    if (count == 0.0) return m;
    m.rmse = std::sqrt(se / count);
    m.relMse = rel / count;
    m.meanRelativeError = mre / count;
    m.psnr = tse > 0.0 ? 10.0 * std::log10(count / tse) : std::numeric_limits<double>::infinity();
    m.ssimExposure = viewerExposure(reference);
    m.ssim = ssim(image, reference, std::exp2(m.ssimExposure));
    return m;
}

double viewerExposure(const Image& image) {
    if (image.pixels.empty()) return 0.0;
    double sum = 0.0;
    for (const glm::vec3& p : image.pixels) {
        const double l = luminance(p);
        sum += std::log(1e-6 + (std::isfinite(l) && l > 0.0 ? l : 0.0));
    }
    const double average = std::exp(sum / double(image.pixels.size()));
    return std::clamp(std::log2(0.18 / average), -64.0, 64.0);
}

Image squaredDifferenceImage(const Image& image, const Image& reference, float scale) {
    requireSameSize(image, reference);
    Image out(image.width, image.height);
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        glm::vec3 d = image.pixels[i] - reference.pixels[i];
        out.pixels[i] = glm::vec3(scale) * d * d;
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(out.pixels[i][c])) out.pixels[i][c] = 1.0f;
    }
    return out;
}

void errorRamp(float t, float srgb[3]) {
    // Dark blue, blue, cyan, green, yellow, red, dark red at t = 0, 1/6, ..., 1.
    static const float stops[7][3] = {{0.05f, 0.03f, 0.35f}, {0.10f, 0.35f, 0.90f}, {0.10f, 0.80f, 0.90f}, {0.20f, 0.80f, 0.20f},
                                      {0.95f, 0.90f, 0.15f}, {0.95f, 0.35f, 0.10f}, {0.50f, 0.02f, 0.02f}};
    t = std::isfinite(t) ? std::clamp(t, 0.0f, 1.0f) * 6.0f : 6.0f;
    int i = std::min(int(t), 5);
    float f = t - float(i);
    for (int c = 0; c < 3; ++c) srgb[c] = stops[i][c] * (1.0f - f) + stops[i + 1][c] * f;
}

Image relativeErrorMap(const Image& image, const Image& reference) {
    requireSameSize(image, reference);
    Image out(image.width, image.height);
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        double e = 0.0;
        for (int c = 0; c < 3; ++c) {
            double x = image.pixels[i][c], ref = reference.pixels[i][c];
            e += std::isfinite(x) ? std::abs(x - ref) / (std::abs(ref) + 0.01) : 1e9;
        }
        e /= 3.0;
        // log10(e) from -3 to 0 -> 0..1.
        float t = float((std::log10(std::max(e, 1e-6)) + 3.0) / 3.0);
        float srgb[3];
        errorRamp(t, srgb);
        for (int c = 0; c < 3; ++c) out.pixels[i][c] = float(srgbToLinear(srgb[c]));
    }
    return out;
}

namespace {
double pixelRelMse(const glm::vec3& x, const glm::vec3& ref) {
    glm::vec3 v;
    for (int c = 0; c < 3; ++c) v[c] = std::isfinite(x[c]) ? x[c] : 0.0f;
    return relMse(v, ref);
}
double pixelRelativeError(const glm::vec3& x, const glm::vec3& ref) {
    double e = 0.0;
    for (int c = 0; c < 3; ++c) {
        double v = std::isfinite(x[c]) ? double(x[c]) : 0.0;
        e += std::abs(v - double(ref[c])) / (std::abs(double(ref[c])) + 0.01);
    }
    return e / 3.0;
}
// The q-quantile (0..1) of v by the nearest-rank rule; v is reordered.
double quantile(std::vector<double>& v, double q) {
    if (v.empty()) return 0.0;
    size_t k = std::min(v.size() - 1, size_t(std::ceil(q * double(v.size()))) - (q > 0.0 ? 1 : 0));
    std::nth_element(v.begin(), v.begin() + long(k), v.end());
    return v[k];
}
}  // namespace

ErrorDistribution errorDistribution(const Image& image, const Image& reference) {
    requireSameSize(image, reference);
    const size_t n = image.pixels.size();
    ErrorDistribution d;
    if (n == 0) return d;
    std::vector<double> rel(n), err(n);
    double total = 0.0;
    for (size_t i = 0; i < n; ++i) {
        rel[i] = pixelRelMse(image.pixels[i], reference.pixels[i]);
        err[i] = pixelRelativeError(image.pixels[i], reference.pixels[i]);
        total += rel[i];
    }
    const size_t worst = (n + 99) / 100;  // ceil(1%)
    std::partial_sort(rel.begin(), rel.begin() + long(worst), rel.end(), std::greater<double>());
    double top = 0.0;
    for (size_t i = 0; i < worst; ++i) top += rel[i];
    d.worst1PercentShare = total > 0.0 ? top / total : 0.0;
    d.medianRelativeError = quantile(err, 0.5);
    d.p99RelativeError = quantile(err, 0.99);
    return d;
}

std::vector<RegionError> relMseByRegion(const Image& image, const Image& reference, const std::vector<int>& region,
                                        int regionCount) {
    requireSameSize(image, reference);
    if (region.size() != image.pixels.size()) throw std::invalid_argument("region map and image differ in size");
    std::vector<RegionError> out(size_t(std::max(0, regionCount)));
    double total = 0.0;
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        double e = pixelRelMse(image.pixels[i], reference.pixels[i]);
        total += e;
        if (region[i] < 0 || region[i] >= regionCount) continue;
        RegionError& r = out[size_t(region[i])];
        ++r.pixels;
        r.relMse += e;
    }
    for (RegionError& r : out) {
        r.shareOfImage = total > 0.0 ? r.relMse / total : 0.0;
        r.relMse = r.pixels > 0 ? r.relMse / double(r.pixels) : 0.0;
    }
    return out;
}

std::vector<DecadeError> relMseByDecade(const Image& image, const Image& reference) {
    requireSameSize(image, reference);
    std::vector<DecadeError> decades;
    for (int e = -6; e < 8; ++e) decades.push_back({std::pow(10.0, e), std::pow(10.0, e + 1), 0, 0.0, 0.0});
    std::vector<size_t> positive(decades.size(), 0);
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        double lum = luminance(reference.pixels[i]);
        for (DecadeError& d : decades)
            if (lum >= d.lo && lum < d.hi) {
                ++d.pixels;
                for (int c = 0; c < 3; ++c) {
                    double ref = reference.pixels[i][c], x = image.pixels[i][c];
                    double diff = (std::isfinite(x) ? x : 0.0) - ref;
                    d.relMse += relMseTerm(std::isfinite(x) ? x : 0.0, ref);
                    if (ref > 0.0) {
                        d.relativeRms += diff * diff / (ref * ref);
                        ++positive[size_t(&d - decades.data())];
                    }
                }
            }
    }
    std::vector<DecadeError> out;
    for (DecadeError& d : decades)
        if (d.pixels > 0) {
            d.relMse /= 3.0 * double(d.pixels);
            size_t n = positive[size_t(&d - decades.data())];
            d.relativeRms = n > 0 ? std::sqrt(d.relativeRms / double(n)) : 0.0;
            out.push_back(d);
        }
    return out;
}

BlockFigure blockFigure(const Image& image, const Image& reference, const std::vector<uint8_t>& mask, int blockSize) {
    requireSameSize(image, reference);
    if (mask.size() != reference.pixels.size()) throw std::invalid_argument("mask size differs from the image's");
    BlockFigure f;
    f.blockSize = std::max(1, blockSize);
    double maskedSum = 0.0;
    size_t masked = 0;
    for (size_t i = 0; i < mask.size(); ++i)
        if (mask[i] && std::isfinite(luminance(reference.pixels[i]))) {
            maskedSum += luminance(reference.pixels[i]);
            ++masked;
        }
    if (masked == 0 || !(maskedSum > 0.0)) return f;
    const double floor = 1e-3 * maskedSum / double(masked);
    const int b = f.blockSize;
    double sum2 = 0.0, tint2 = 0.0;
    for (int by = 0; by + b <= reference.height; by += b)
        for (int bx = 0; bx + b <= reference.width; bx += b) {
            glm::dvec3 x(0.0), r(0.0);
            bool whole = true;
            for (int y = by; y < by + b && whole; ++y)
                for (int xx = bx; xx < bx + b; ++xx) {
                    const size_t i = size_t(y) * size_t(reference.width) + size_t(xx);
                    if (!mask[i]) {
                        whole = false;
                        break;
                    }
                    // A non-finite pixel counts as black (it should never occur; compareImages counts it too).
                    for (int c = 0; c < 3; ++c) {
                        if (std::isfinite(image.pixels[i][c])) x[c] += image.pixels[i][c];
                        if (std::isfinite(reference.pixels[i][c])) r[c] += reference.pixels[i][c];
                    }
                }
            if (!whole) continue;
            x /= double(b) * double(b);
            r /= double(b) * double(b);
            const double lr = 0.2126 * r.x + 0.7152 * r.y + 0.0722 * r.z, lx = 0.2126 * x.x + 0.7152 * x.y + 0.0722 * x.z;
            if (!(lr >= floor) || !(lr > 0.0)) continue;
            ++f.blocks;
            const double e = (lx - lr) / lr;
            sum2 += e * e;
            if (std::abs(e) > f.worst || f.worstX < 0) {
                f.worst = std::abs(e);
                f.worstSigned = e;
                f.worstX = bx;
                f.worstY = by;
            }
            const double mx = (x.x + x.y + x.z) / 3.0, mr = (r.x + r.y + r.z) / 3.0;
            double tint = 0.0;
            for (int c = 0; c < 3; ++c) tint = std::max(tint, std::abs((mx > 0.0 ? x[c] / mx : 1.0) - r[c] / mr));
            tint2 += tint * tint;
            f.tintWorst = std::max(f.tintWorst, tint);
            if (mx > 0.0) f.chroma = std::max(f.chroma, (std::max({x.x, x.y, x.z}) - std::min({x.x, x.y, x.z})) / mx);
            f.referenceChroma = std::max(f.referenceChroma, (std::max({r.x, r.y, r.z}) - std::min({r.x, r.y, r.z})) / mr);
        }
    if (f.blocks > 0) {
        f.rms = std::sqrt(sum2 / double(f.blocks));
        f.tintRms = std::sqrt(tint2 / double(f.blocks));
    }
    return f;
}

StepFigure stepFigure(const Image& image, const Image& reference, const std::vector<int64_t>& cell, const std::vector<uint8_t>& mask,
                      int reach, size_t minPairs) {
    requireSameSize(image, reference);
    if (mask.size() != reference.pixels.size() || cell.size() != reference.pixels.size())
        throw std::invalid_argument("mask or cell size differs from the image's");
    reach = std::max(1, reach);
    struct Group {
        size_t pairs = 0;
        double jump = 0.0, level = 0.0;  // summed (image jump - reference jump), summed mean luminance of the four
    };
    std::map<std::pair<int64_t, int64_t>, Group> groups;  // ordered: the same figure on every machine
    const int w = reference.width, h = reference.height;
    auto lum = [](const glm::vec3& c) {
        const double l = luminance(c);
        return std::isfinite(l) ? l : 0.0;
    };
    for (int axis = 0; axis < 2; ++axis) {
        const int dx = axis == 0 ? 1 : 0, dy = axis == 0 ? 0 : 1;
        for (int y = 0; y + dy < h; ++y)
            for (int x = 0; x + dx < w; ++x) {
                const size_t i = size_t(y) * size_t(w) + size_t(x), j = size_t(y + dy) * size_t(w) + size_t(x + dx);
                if (cell[i] < 0 || cell[j] < 0 || cell[i] == cell[j]) continue;
                // The pixels `reach` away on either side of the change, each still in its side's cell.
                const int ax = x - dx * (reach - 1), ay = y - dy * (reach - 1), bx = x + dx * reach, by = y + dy * reach;
                if (ax < 0 || ay < 0 || bx >= w || by >= h) continue;
                const size_t a = size_t(ay) * size_t(w) + size_t(ax), b = size_t(by) * size_t(w) + size_t(bx);
                if (!mask[a] || !mask[b] || cell[a] != cell[i] || cell[b] != cell[j]) continue;
                const bool flip = cell[i] > cell[j];
                Group& g = groups[flip ? std::make_pair(cell[j], cell[i]) : std::make_pair(cell[i], cell[j])];
                const double d = (lum(image.pixels[a]) - lum(image.pixels[b])) - (lum(reference.pixels[a]) - lum(reference.pixels[b]));
                g.jump += flip ? -d : d;
                g.level += 0.25 * (lum(image.pixels[a]) + lum(image.pixels[b]) + lum(reference.pixels[a]) + lum(reference.pixels[b]));
                ++g.pairs;
            }
    }
    StepFigure f;
    double sum2 = 0.0;
    for (const auto& [key, g] : groups) {
        if (g.pairs < minPairs || !(g.level > 0.0)) continue;
        const double step = g.jump / g.level;  // (sum of differences / n) / (sum of levels / n)
        ++f.faces;
        f.pairs += g.pairs;
        sum2 += step * step * double(g.pairs);
        f.worst = std::max(f.worst, std::abs(step));
    }
    if (f.pairs > 0) f.rms = std::sqrt(sum2 / double(f.pairs));
    return f;
}

}  // namespace nrad
