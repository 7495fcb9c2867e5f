// Modified Phong, energy-normalised: E. P. Lafortune and Y. D. Willems, "Using the modified
// Phong reflectance model for physically based rendering", tech. report CW 197, KU Leuven, 1994:
//   f = Kd / pi + Ks (n + 2) / (2 pi) max(0, cos alpha)^n,
// alpha the angle between wi and the mirror reflection r of wo. Energy is conserved when
// Kd + Ks <= 1 per channel (the glossy albedo is at most Ks, reached at normal incidence).
// Sampling: the diffuse or the glossy lobe with probability proportional to the mean of Kd
// and of Ks (lobes.glsl); diffuse: cosine-weighted; glossy: cos^n around r, pdf
// (n + 1) / (2 pi) cos^n alpha; a glossy direction below the horizon is no sample (absorbed),
// so `phong_pdf` (the mixture, not renormalised) integrates to <= 1 over the hemisphere.
// Reads: diffuse, specular, exponent. Opaque; wo.z > 0 (bsdf.glsl flips).
#ifndef TRILAB_BSDF_PHONG
#define TRILAB_BSDF_PHONG

#include "bsdf/common.glsl"
#include "bsdf/lobes.glsl"

vec3 phong_reflect(vec3 wo) {
    return vec3(-wo.x, -wo.y, wo.z);
}

vec3 phong_eval(Material m, vec3 wo, vec3 wi) {
    if (wi.z <= 0.0) {
        return vec3(0.0);
    }
    float n = m.exponent;
    float c = dot(wi, phong_reflect(wo));
    float lobe = c > 0.0 ? (n + 2.0) * (0.5 * INV_PI) * pow(c, n) : 0.0;
    return m.diffuse * INV_PI + m.specular * lobe;
}

float phong_pdf(Material m, vec3 wo, vec3 wi) {
    if (wi.z <= 0.0) {
        return 0.0;
    }
    float ps = lobe_specular_probability(m.diffuse, m.specular);
    return (1.0 - ps) * wi.z * INV_PI + ps * cos_power_pdf(dot(wi, phong_reflect(wo)), m.exponent);
}

bool phong_sample(Material m, vec3 wo, vec3 u, out BsdfSample s) {
    s.delta = false;
    s.weight = vec3(0.0);
    s.pdf = 0.0;
    float ps = lobe_specular_probability(m.diffuse, m.specular);
    if (u.z < ps) {
        vec3 r = phong_reflect(wo);
        vec3 t, b;
        basis_from(r, t, b);
        vec3 l = cos_power_direction(u.xy, m.exponent);
        s.wi = normalize(l.x * t + l.y * b + l.z * r);
    } else {
        s.wi = cosine_hemisphere(u.xy);
    }
    LOBE_SAMPLE_RETURN(phong);
}

#endif
