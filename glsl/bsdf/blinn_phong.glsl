// Blinn-Phong, normalised: J. F. Blinn, "Models of light reflection for computer synthesized
// pictures", SIGGRAPH 1977, with a diffuse term:
//   f = Kd / pi + Ks N(n) cos^n(theta_h),   h = normalize(wo + wi),
// and the exact normalisation N(n) = (n + 2)(n + 4) / (8 pi (2^(-n/2) + n)) of F. Giesen,
// "Derivation of Phong and Blinn-Phong BRDF normalization factors" (2009): with it the glossy
// albedo is exactly Ks at normal incidence and less elsewhere, so Kd + Ks <= 1 per channel
// conserves energy. (The popular approximation (n + 8) / (8 pi) overshoots it by up to 7.5%,
// near n = 9, which breaks a white furnace; (n + 2) / (2 pi) normalises the half-vector
// distribution, not the BRDF, and overshoots by up to 4x.)
// Sampling: lobe chosen as for Phong (lobes.glsl); glossy: h with density (n + 1) / (2 pi)
// cos^n(theta_h), wi = wo reflected about h, pdf (n + 1) / (2 pi) cos^n(theta_h) / (4 wo.h)
// (the reflection Jacobian 1 / (4 wo.h): Walter et al., "Microfacet models for refraction", EGSR 2007); a wi below the horizon is no sample (absorbed).
// Reads: diffuse, specular, exponent. Opaque; wo.z > 0 (bsdf.glsl flips).
#ifndef TRILAB_BSDF_BLINN_PHONG
#define TRILAB_BSDF_BLINN_PHONG

#include "bsdf/common.glsl"
#include "bsdf/lobes.glsl"

float blinn_phong_norm(float n) {
    return (n + 2.0) * (n + 4.0) / (8.0 * PI * (exp2(-0.5 * n) + n));
}

vec3 blinn_phong_eval(Material m, vec3 wo, vec3 wi) {
    if (wi.z <= 0.0) {
        return vec3(0.0);
    }
    vec3 h = normalize(wo + wi);
    float lobe = h.z > 0.0 ? blinn_phong_norm(m.exponent) * pow(h.z, m.exponent) : 0.0;
    return m.diffuse * INV_PI + m.specular * lobe;
}

float blinn_phong_pdf(Material m, vec3 wo, vec3 wi) {
    if (wi.z <= 0.0) {
        return 0.0;
    }
    float ps = lobe_specular_probability(m.diffuse, m.specular);
    vec3 h = normalize(wo + wi);
    // wo.z > 0 and wi.z > 0 make h.z > 0 and wo.h = |wo + wi| / 2 > 0.
    float glossy = cos_power_pdf(h.z, m.exponent) / (4.0 * dot(wo, h));
    return (1.0 - ps) * wi.z * INV_PI + ps * glossy;
}

bool blinn_phong_sample(Material m, vec3 wo, vec3 u, out BsdfSample s) {
    s.delta = false;
    s.weight = vec3(0.0);
    s.pdf = 0.0;
    float ps = lobe_specular_probability(m.diffuse, m.specular);
    if (u.z < ps) {
        vec3 h = cos_power_direction(u.xy, m.exponent);
        s.wi = normalize(reflect_about(wo, h));
    } else {
        s.wi = cosine_hemisphere(u.xy);
    }
    LOBE_SAMPLE_RETURN(blinn_phong);
}

#endif
