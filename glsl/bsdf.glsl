// The BSDF dispatcher: the only BSDF API the kernels call. Every direction is in the local
// shading frame (normal +z, NOT flipped towards the viewer), wo and wi point away from the
// surface (bsdf/common.glsl has the conventions).
//   vec3  bsdf_eval(Material m, vec3 wo, vec3 wi);    f(wo, wi) without the cosine; 0 for delta BSDFs
//   float bsdf_pdf(Material m, vec3 wo, vec3 wi);     solid-angle pdf of sampling wi; 0 for delta BSDFs
//   bool  bsdf_sample(Material m, vec3 wo, vec3 u, out BsdfSample s);   u in [0,1)^3; false: absorbed
//   bool  bsdf_is_delta(uint kind);                   glass and mirror
// A kernel compiles in only the kinds whose bit (1 << BSDF_*) is set in BSDF_MASK (default
// BSDF_MASK_ALL); an excluded or unknown kind evaluates to 0 and never samples.
// Opaque BSDFs are two-sided: for wo.z < 0 the z of wo (and of wi, and of the sampled wi) is
// flipped, so each file sees wo.z > 0; wi on the other side of an opaque surface from wo gives
// eval = pdf = 0, and wo.z == 0 gives nothing. Glass reads the sign of wo.z (entering or leaving).
#ifndef TRILAB_BSDF
#define TRILAB_BSDF

#include "bsdf/common.glsl"

#ifndef BSDF_MASK
#define BSDF_MASK BSDF_MASK_ALL
#endif
// A kernel may narrow the set further at pipeline creation by defining BSDF_SPEC_MASK as a
// specialisation constant (pathtrace.comp does): the cases outside it are then constant-false
// and the driver drops them when it specialises the pipeline.
#ifndef BSDF_SPEC_MASK
#define BSDF_SPEC_MASK BSDF_MASK_ALL
#endif
#define BSDF_LIVE(k) ((uint(BSDF_SPEC_MASK) & (1u << uint(k))) != 0u)

#if (BSDF_MASK & (1 << BSDF_LAMBERT)) != 0
#include "bsdf/lambert.glsl"
#endif
#if (BSDF_MASK & (1 << BSDF_OREN_NAYAR)) != 0
#include "bsdf/oren_nayar.glsl"
#endif
#if (BSDF_MASK & (1 << BSDF_PHONG)) != 0
#include "bsdf/phong.glsl"
#endif
#if (BSDF_MASK & (1 << BSDF_BLINN_PHONG)) != 0
#include "bsdf/blinn_phong.glsl"
#endif
#if (BSDF_MASK & (1 << BSDF_ASHIKHMIN_SHIRLEY)) != 0
#include "bsdf/ashikhmin_shirley.glsl"
#endif
#if (BSDF_MASK & (1 << BSDF_GLASS)) != 0
#include "bsdf/glass.glsl"
#endif
#if (BSDF_MASK & (1 << BSDF_MIRROR)) != 0
#include "bsdf/mirror.glsl"
#endif

bool bsdf_is_delta(uint kind) {
    return kind == BSDF_GLASS || kind == BSDF_MIRROR;
}

vec3 bsdf_eval(Material m, vec3 wo, vec3 wi) {
    if (bsdf_is_delta(m.kind)) {
        return vec3(0.0);
    }
    if (wo.z < 0.0) {
        wo.z = -wo.z;
        wi.z = -wi.z;
    }
    if (!(wo.z > 0.0) || !(wi.z > 0.0)) {
        return vec3(0.0);
    }
    switch (m.kind) {
#if (BSDF_MASK & (1 << BSDF_LAMBERT)) != 0
    case BSDF_LAMBERT:
        return BSDF_LIVE(BSDF_LAMBERT) ? lambert_eval(m, wo, wi) : vec3(0.0);
#endif
#if (BSDF_MASK & (1 << BSDF_OREN_NAYAR)) != 0
    case BSDF_OREN_NAYAR:
        return BSDF_LIVE(BSDF_OREN_NAYAR) ? oren_nayar_eval(m, wo, wi) : vec3(0.0);
#endif
#if (BSDF_MASK & (1 << BSDF_PHONG)) != 0
    case BSDF_PHONG:
        return BSDF_LIVE(BSDF_PHONG) ? phong_eval(m, wo, wi) : vec3(0.0);
#endif
#if (BSDF_MASK & (1 << BSDF_BLINN_PHONG)) != 0
    case BSDF_BLINN_PHONG:
        return BSDF_LIVE(BSDF_BLINN_PHONG) ? blinn_phong_eval(m, wo, wi) : vec3(0.0);
#endif
#if (BSDF_MASK & (1 << BSDF_ASHIKHMIN_SHIRLEY)) != 0
    case BSDF_ASHIKHMIN_SHIRLEY:
        return BSDF_LIVE(BSDF_ASHIKHMIN_SHIRLEY) ? ashikhmin_shirley_eval(m, wo, wi) : vec3(0.0);
#endif
    default:
        return vec3(0.0);
    }
}

float bsdf_pdf(Material m, vec3 wo, vec3 wi) {
    if (bsdf_is_delta(m.kind)) {
        return 0.0;
    }
    if (wo.z < 0.0) {
        wo.z = -wo.z;
        wi.z = -wi.z;
    }
    if (!(wo.z > 0.0) || !(wi.z > 0.0)) {
        return 0.0;
    }
    switch (m.kind) {
#if (BSDF_MASK & (1 << BSDF_LAMBERT)) != 0
    case BSDF_LAMBERT:
        return BSDF_LIVE(BSDF_LAMBERT) ? lambert_pdf(m, wo, wi) : 0.0;
#endif
#if (BSDF_MASK & (1 << BSDF_OREN_NAYAR)) != 0
    case BSDF_OREN_NAYAR:
        return BSDF_LIVE(BSDF_OREN_NAYAR) ? oren_nayar_pdf(m, wo, wi) : 0.0;
#endif
#if (BSDF_MASK & (1 << BSDF_PHONG)) != 0
    case BSDF_PHONG:
        return BSDF_LIVE(BSDF_PHONG) ? phong_pdf(m, wo, wi) : 0.0;
#endif
#if (BSDF_MASK & (1 << BSDF_BLINN_PHONG)) != 0
    case BSDF_BLINN_PHONG:
        return BSDF_LIVE(BSDF_BLINN_PHONG) ? blinn_phong_pdf(m, wo, wi) : 0.0;
#endif
#if (BSDF_MASK & (1 << BSDF_ASHIKHMIN_SHIRLEY)) != 0
    case BSDF_ASHIKHMIN_SHIRLEY:
        return BSDF_LIVE(BSDF_ASHIKHMIN_SHIRLEY) ? ashikhmin_shirley_pdf(m, wo, wi) : 0.0;
#endif
    default:
        return 0.0;
    }
}

bool bsdf_sample(Material m, vec3 wo, vec3 u, out BsdfSample s) {
    s.wi = vec3(0.0, 0.0, 1.0);
    s.pdf = 0.0;
    s.weight = vec3(0.0);
    s.delta = false;
#if (BSDF_MASK & (1 << BSDF_GLASS)) != 0
    if (m.kind == BSDF_GLASS && BSDF_LIVE(BSDF_GLASS)) {
        return glass_sample(m, wo, u, s);
    }
#endif
    bool flip = wo.z < 0.0;
    if (flip) {
        wo.z = -wo.z;
    }
    if (!(wo.z > 0.0)) {
        return false;
    }
    bool ok = false;
    switch (m.kind) {
#if (BSDF_MASK & (1 << BSDF_LAMBERT)) != 0
    case BSDF_LAMBERT:
        ok = BSDF_LIVE(BSDF_LAMBERT) && lambert_sample(m, wo, u, s);
        break;
#endif
#if (BSDF_MASK & (1 << BSDF_OREN_NAYAR)) != 0
    case BSDF_OREN_NAYAR:
        ok = BSDF_LIVE(BSDF_OREN_NAYAR) && oren_nayar_sample(m, wo, u, s);
        break;
#endif
#if (BSDF_MASK & (1 << BSDF_PHONG)) != 0
    case BSDF_PHONG:
        ok = BSDF_LIVE(BSDF_PHONG) && phong_sample(m, wo, u, s);
        break;
#endif
#if (BSDF_MASK & (1 << BSDF_BLINN_PHONG)) != 0
    case BSDF_BLINN_PHONG:
        ok = BSDF_LIVE(BSDF_BLINN_PHONG) && blinn_phong_sample(m, wo, u, s);
        break;
#endif
#if (BSDF_MASK & (1 << BSDF_ASHIKHMIN_SHIRLEY)) != 0
    case BSDF_ASHIKHMIN_SHIRLEY:
        ok = BSDF_LIVE(BSDF_ASHIKHMIN_SHIRLEY) && ashikhmin_shirley_sample(m, wo, u, s);
        break;
#endif
#if (BSDF_MASK & (1 << BSDF_MIRROR)) != 0
    case BSDF_MIRROR:
        ok = BSDF_LIVE(BSDF_MIRROR) && mirror_sample(m, wo, u, s);
        break;
#endif
    default:
        ok = false;
        break;
    }
    if (flip) {
        s.wi.z = -s.wi.z;
    }
    return ok;
}

#endif
