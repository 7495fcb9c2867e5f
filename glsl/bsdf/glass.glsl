// Glass: a smooth dielectric interface (pbrt-v3 section 8.2, FresnelSpecular). The exact
// unpolarised dielectric Fresnel reflectance (pbrt-v3 section 8.2.1, FrDielectric)
//   r_par  = (eta cos_i - cos_t) / (eta cos_i + cos_t),
//   r_perp = (cos_i - eta cos_t) / (cos_i + eta cos_t),   F = (r_par^2 + r_perp^2) / 2,
// eta = eta_t / eta_i, picks reflection with probability F and refraction (Snell's law) with
// 1 - F; total internal reflection (sin_t >= 1) always reflects.
// Sides: wo.z > 0 is outside, the ray enters (eta = ior); wo.z < 0 is inside (eta = 1 / ior).
// Weights: reflection Ks (= F Ks / F), refraction Kd (= (1 - F) Kd / (1 - F)). Refraction is NOT
// scaled by 1 / eta^2: the path tracer carries radiance divided by n^2 (the "basic radiance",
// invariant along a refracted ray), which equals radiance wherever the medium is air, i.e. at
// the camera and at every light outside glass. This is pbrt's TransportMode::Importance rule; a
// light inside glass would be seen n^2 too bright. src/render/bsdf.rs's glass_reference does the same.
// Reads: diffuse (transmission tint), specular (reflection tint), ior. Delta: sample only.
#ifndef TRILAB_BSDF_GLASS
#define TRILAB_BSDF_GLASS

#include "bsdf/common.glsl"

// Fresnel reflectance for a wave arriving at cos_i > 0 on the side eta_i, eta = eta_t / eta_i.
float fresnel_dielectric(float cos_i, float eta) {
    float sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0) {
        return 1.0;
    }
    float cos_t = sqrt(1.0 - sin2_t);
    float r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (r_par * r_par + r_perp * r_perp);
}

bool glass_sample(Material m, vec3 wo, vec3 u, out BsdfSample s) {
    s.delta = true;
    bool entering = wo.z > 0.0;
    float eta = entering ? m.ior : 1.0 / m.ior;
    float cos_i = abs(wo.z);
    float f = fresnel_dielectric(cos_i, eta);
    if (u.x < f) {
        s.wi = vec3(-wo.x, -wo.y, wo.z);
        s.pdf = f;
        s.weight = m.specular;
    } else {
        // Snell: the tangential part scales by 1 / eta, the normal part flips side.
        float sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
        float cos_t = sqrt(max(0.0, 1.0 - sin2_t));
        s.wi = vec3(-wo.x / eta, -wo.y / eta, entering ? -cos_t : cos_t);
        s.pdf = 1.0 - f;
        s.weight = m.diffuse;
    }
    return s.pdf > 0.0 && wo.z != 0.0;
}

#endif
