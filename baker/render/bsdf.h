// BSDF of the glTF 2.0 metallic-roughness material (specification appendix B, with
// KHR_materials_specular; one documented deviation in the dielectric's diffuse weight, see bsdf.cpp and
// docs/rendering.md): Lambertian diffuse plus a GGX (Trowbridge-Reitz) specular lobe with the
// height-correlated Smith masking term, Schlick Fresnel, mixed by metallic; thin-walled transmission
// (KHR_materials_transmission without a volume) replaces that share of the dielectric's diffuse base by the
// GGX lobe mirrored through the surface (light passes straight through a smooth sheet, blurred by its
// roughness), tinted by the base colour and weighted by what the specular layer does not reflect. Sampling
// picks the diffuse lobe (cosine), the specular lobe (visible-normal sampling, Heitz 2018) or the
// transmission lobe and reports the pdf of the mixture, so eval, sample and pdf are consistent.
#pragma once

#include <glm/glm.hpp>

#include "baker/scene/geometry.h"

namespace nrad {

struct BsdfParams {
    glm::vec3 baseColor{1.0f};
    float metallic = 0.0f;
    float roughness = 1.0f;
    float specular = 1.0f;
    glm::vec3 specularColor{1.0f};
    float ior = 1.5f;
    float transmission = 0.0f;  // thin-walled KHR_materials_transmission
};

struct BsdfSample {
    glm::vec3 wi{0.0f};  // world space, away from the surface
    glm::vec3 f{0.0f};  // BSDF value (without the cosine)
    float pdf = 0.0f;  // solid-angle pdf of the whole mixture
    bool valid() const { return pdf > 0.0f; }
};

class Bsdf {
public:
    // Smallest GGX alpha used (roughness 0 is a near-perfect mirror, kept finite).
    static constexpr float kMinAlpha = 1e-3f;

    Bsdf(const Frame& shading, const BsdfParams& params);

    // What depends on the outgoing direction alone, computed once per path vertex (outgoing()) and shared by
    // every eval, pdf and sample there; the same bits as computing it in each.
    struct Outgoing {
        glm::vec3 wo{0.0f};  // local frame
        float lambda = 0.0f;  // ggxLambda(wo.z, alpha)
        float fresnel = 0.0f;  // macroFresnel(wo.z)
        float pSpec = 0.0f, pTrans = 0.0f;  // lobeProbabilities(wo.z)
    };
    Outgoing outgoing(const glm::vec3& wo) const;

    // All directions are world-space unit vectors pointing away from the surface. wo must lie above the shading
    // hemisphere; wi below it is transmission (zero unless the material transmits).
    glm::vec3 eval(const glm::vec3& wo, const glm::vec3& wi) const { return eval(outgoing(wo), wi); }
    float pdf(const glm::vec3& wo, const glm::vec3& wi) const { return pdf(outgoing(wo), wi); }
    // uLobe picks the lobe, u picks the direction.
    BsdfSample sample(const glm::vec3& wo, float uLobe, const glm::vec2& u) const { return sample(outgoing(wo), uLobe, u); }
    glm::vec3 eval(const Outgoing& o, const glm::vec3& wi) const;
    float pdf(const Outgoing& o, const glm::vec3& wi) const;
    BsdfSample sample(const Outgoing& o, float uLobe, const glm::vec2& u) const;

    const Frame& frame() const { return frame_; }
    float alpha() const { return alpha_; }

    // Local-frame pieces, exposed for tests.
    float specularProbability(float cosThetaO) const;
    float transmissionProbability(float cosThetaO) const;
    bool transmits() const { return transmits(p_); }
    static bool transmits(const BsdfParams& p) { return p.transmission > 0.0f && p.metallic < 1.0f; }
    // Largest channel of the dielectric Schlick Fresnel at the macro normal.
    float macroFresnel(float cosTheta) const;
    static float ggxD(float cosThetaH, float alpha);
    // D at the half vector h (any positive length: eval and pdf pass wo + wi), without cancellation near the
    // mirror direction.
    static float ggxD(const glm::vec3& h, float alpha);
    static float ggxLambda(float cosTheta, float alpha);

private:
    // fresnel: macroFresnel(cosThetaO).
    void lobeWeights(float fresnel, float& spec, float& diff, float& trans) const;
    // specularProbability and transmissionProbability from one lobeWeights.
    void lobeProbabilities(float fresnel, float& pSpec, float& pTrans) const;
    float pdfLocal(const Outgoing& o, const glm::vec3& wi) const;
    glm::vec3 evalLocal(const Outgoing& o, const glm::vec3& wi) const;

    Frame frame_;
    BsdfParams p_;
    float alpha_;
    glm::vec3 dielectricF0_;  // min(f0(ior) * specularColor, 1)
};

}  // namespace nrad
