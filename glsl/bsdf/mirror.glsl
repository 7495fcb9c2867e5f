// Mirror: perfect specular reflection wi = (-wo.x, -wo.y, wo.z), f = Ks delta(wi - r) / |cos_i|
// (pbrt-v3 section 8.2.2, SpecularReflection with a Fresnel of 1), tinted by Ks.
// Reads: specular. Delta: sample only. Works on either side (bsdf.glsl flips anyway).
#ifndef TRILAB_BSDF_MIRROR
#define TRILAB_BSDF_MIRROR

#include "bsdf/common.glsl"

bool mirror_sample(Material m, vec3 wo, vec3 u, out BsdfSample s) {
    s.wi = vec3(-wo.x, -wo.y, wo.z);
    s.pdf = 1.0;
    s.weight = m.specular;
    s.delta = true;
    return wo.z != 0.0;
}

#endif
