// TEMPORARY stub (Lambert only) until the BSDF files land; same API as the real dispatcher.
#ifndef TRILAB_BSDF
#define TRILAB_BSDF
#include "bsdf/common.glsl"
#ifndef BSDF_MASK
#define BSDF_MASK BSDF_MASK_ALL
#endif
bool bsdf_is_delta(uint kind) { return kind == BSDF_GLASS || kind == BSDF_MIRROR; }
vec3 bsdf_eval(Material m, vec3 wo, vec3 wi) {
    if (wo.z * wi.z <= 0.0) return vec3(0.0);
    return m.diffuse * INV_PI;
}
float bsdf_pdf(Material m, vec3 wo, vec3 wi) {
    if (wo.z * wi.z <= 0.0) return 0.0;
    return abs(wi.z) * INV_PI;
}
bool bsdf_sample(Material m, vec3 wo, vec3 u, out BsdfSample s) {
    s.wi = cosine_hemisphere(u.xy);
    if (wo.z < 0.0) s.wi.z = -s.wi.z;
    s.pdf = abs(s.wi.z) * INV_PI;
    s.weight = m.diffuse;
    s.delta = false;
    return s.pdf > 0.0;
}
#endif
