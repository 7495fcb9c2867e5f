// Helpers shared by the two-lobe (diffuse + glossy) BSDFs: the lobe-selection rule and
// cosine-power sampling.
#ifndef TRILAB_BSDF_LOBES
#define TRILAB_BSDF_LOBES

#include "bsdf/common.glsl"

// Lobe-selection rule of Phong and Blinn-Phong: a lobe is picked with probability proportional
// to the mean of its albedo's three channels (0 when both albedos are black).
float lobe_specular_probability(vec3 kd, vec3 ks) {
    float d = (kd.x + kd.y + kd.z) / 3.0;
    float s = (ks.x + ks.y + ks.z) / 3.0;
    return d + s > 0.0 ? s / (d + s) : 0.0;
}

// A direction around +z with density (n + 1) / (2 pi) cos^n(theta) per solid angle over the
// hemisphere (inverting the CDF 1 - cos^(n+1); e.g. Lafortune & Willems 1994, section 4).
vec3 cos_power_direction(vec2 u, float n) {
    float c = pow(1.0 - u.x, 1.0 / (n + 1.0));
    float s = sqrt(max(0.0, 1.0 - c * c));
    float phi = 2.0 * PI * u.y;
    return vec3(s * cos(phi), s * sin(phi), c);
}

float cos_power_pdf(float c, float n) {
    return c > 0.0 ? (n + 1.0) * (0.5 * INV_PI) * pow(c, n) : 0.0;
}

// `v` reflected about the unit vector `h` (both pointing away from the surface).
vec3 reflect_about(vec3 v, vec3 h) {
    return 2.0 * dot(v, h) * h - v;
}

// The end of every lobe-mixing BSDF's sample (phong, blinn_phong, ashikhmin_shirley), once
// `s.wi` is drawn from the chosen lobe: no sample below the surface or at pdf 0; else the pdf of
// the whole mixture (<name>_pdf) and the weight f cos / pdf (<name>_eval).
#define LOBE_SAMPLE_RETURN(name)                                                               \
    if (s.wi.z <= 0.0) {                                                                       \
        return false;                                                                          \
    }                                                                                          \
    s.pdf = name##_pdf(m, wo, s.wi);                                                           \
    if (!(s.pdf > 0.0)) {                                                                      \
        return false;                                                                          \
    }                                                                                          \
    s.weight = name##_eval(m, wo, s.wi) * (s.wi.z / s.pdf);                                    \
    return true

#endif
