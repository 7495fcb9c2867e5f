// Oren-Nayar: the qualitative model of M. Oren and S. K. Nayar, "Generalization of Lambert's
// Reflectance Model", SIGGRAPH 1994 (its qualitative model, no inter-reflection term), in the form of
// pbrt-v3 section 8.4.2 (OrenNayar):
//   f = Kd / pi * (A + B max(0, cos(phi_i - phi_o)) sin(alpha) tan(beta)),
//   A = 1 - sigma^2 / (2 (sigma^2 + 0.33)), B = 0.45 sigma^2 / (sigma^2 + 0.09),
//   alpha = max(theta_i, theta_o), beta = min(theta_i, theta_o).
// sigma = 0 is Lambert. Sampling: cosine-weighted hemisphere.
// Reads: diffuse, sigma (radians). Opaque; wo.z > 0 (bsdf.glsl flips).
#ifndef TRILAB_BSDF_OREN_NAYAR
#define TRILAB_BSDF_OREN_NAYAR

#include "bsdf/common.glsl"

vec3 oren_nayar_eval(Material m, vec3 wo, vec3 wi) {
    if (wi.z <= 0.0) {
        return vec3(0.0);
    }
    float s2 = m.sigma * m.sigma;
    float a = 1.0 - s2 / (2.0 * (s2 + 0.33));
    float b = 0.45 * s2 / (s2 + 0.09);
    float sin_i = sqrt(sin2_theta(wi));
    float sin_o = sqrt(sin2_theta(wo));
    // cos(phi_i - phi_o) = (wi.xy . wo.xy) / (sin_i sin_o); 0 when either is at the pole.
    float max_cos = 0.0;
    if (sin_i > 1e-4 && sin_o > 1e-4) {
        max_cos = max(0.0, dot(wi.xy, wo.xy) / (sin_i * sin_o));
    }
    // The larger angle has the smaller cosine.
    float sin_alpha, tan_beta;
    if (wi.z > wo.z) {
        sin_alpha = sin_o;
        tan_beta = sin_i / wi.z;
    } else {
        sin_alpha = sin_i;
        tan_beta = sin_o / wo.z;
    }
    return m.diffuse * INV_PI * (a + b * max_cos * sin_alpha * tan_beta);
}

float oren_nayar_pdf(Material m, vec3 wo, vec3 wi) {
    return wi.z > 0.0 ? wi.z * INV_PI : 0.0;
}

bool oren_nayar_sample(Material m, vec3 wo, vec3 u, out BsdfSample s) {
    s.wi = cosine_hemisphere(u.xy);
    s.pdf = oren_nayar_pdf(m, wo, s.wi);
    s.delta = false;
    s.weight = s.pdf > 0.0 ? oren_nayar_eval(m, wo, s.wi) * (s.wi.z / s.pdf) : vec3(0.0);
    return s.pdf > 0.0;
}

#endif
