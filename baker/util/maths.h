// What the baker computes in many places, written once: pi, luminance, relMSE and the sRGB curve. Each comes
// in the precision its callers compute in (a float and a double version are not interchangeable: images and
// assets are byte-identical only if every caller keeps its precision).
#pragma once

#include <cmath>

#include <glm/glm.hpp>

namespace nrad {

constexpr float kPi = 3.14159265358979323846f;
constexpr double kPiDouble = 3.14159265358979323846;

// Rec. 709 luminance of linear RGB, in double (figures) and in float (the tracer's and the trainer's own).
inline double luminance(const glm::vec3& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }
inline float luminancef(const glm::vec3& c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

// relMSE, the error of every figure: per channel (x - ref)^2 / (ref^2 + 0.01), the 0.01 making it an absolute
// error where the reference is dark; of a colour, the mean over its channels.
inline double relMseTerm(double x, double ref) {
    const double d = x - ref;
    return d * d / (ref * ref + 0.01);
}
inline double relMse(const glm::vec3& x, const glm::vec3& ref) {
    double e = 0.0;
    for (int c = 0; c < 3; ++c) e += relMseTerm(double(x[c]), double(ref[c]));
    return e / 3.0;
}

// The sRGB transfer curve (IEC 61966-2-1): encoded [0, 1] to linear and back.
inline float srgbToLinear(float c) { return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f); }
inline float linearToSrgb(float c) { return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f; }
inline double srgbToLinear(double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); }
inline double linearToSrgb(double v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055; }

}  // namespace nrad
