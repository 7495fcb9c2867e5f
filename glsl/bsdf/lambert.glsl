// Lambert: the ideal diffuse reflector, f = Kd / pi, cosine-weighted hemisphere sampling
// (pbrt-v3 section 8.3, LambertianReflection; Malley's method, pbrt-v3 section 13.6.3).
// Reads: diffuse. Opaque, one-sided here (bsdf.glsl makes it two-sided): wo.z > 0.
#ifndef TRILAB_BSDF_LAMBERT
#define TRILAB_BSDF_LAMBERT

#include "bsdf/common.glsl"

vec3 lambert_eval(Material m, vec3 wo, vec3 wi) {
    return wi.z > 0.0 ? m.diffuse * INV_PI : vec3(0.0);
}

float lambert_pdf(Material m, vec3 wo, vec3 wi) {
    return wi.z > 0.0 ? wi.z * INV_PI : 0.0;
}

bool lambert_sample(Material m, vec3 wo, vec3 u, out BsdfSample s) {
    s.wi = cosine_hemisphere(u.xy);
    s.pdf = lambert_pdf(m, wo, s.wi);
    s.delta = false;
    // f cos / pdf = (Kd / pi) cos / (cos / pi) = Kd.
    s.weight = m.diffuse;
    return s.pdf > 0.0;
}

#endif
