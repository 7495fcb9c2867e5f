// Ashikhmin-Shirley: M. Ashikhmin and P. Shirley, "An anisotropic Phong BRDF model", Journal of
// Graphics Tools 5(2), 2000. With h = normalize(wo + wi), k = wo (or wi: k.h is the same) and
// the tangent frame u = +x, v = +y:
//   specular: sqrt((nu + 1)(nv + 1)) / (8 pi)
//             * (n.h)^((nu (h.u)^2 + nv (h.v)^2) / (1 - (n.h)^2)) / ((h.k) max(n.wo, n.wi)) * F(h.k),
//   Schlick Fresnel: F(c) = Rs + (1 - Rs)(1 - c)^5,
//   diffuse: 28 Rd / (23 pi) (1 - Rs) (1 - (1 - n.wo / 2)^5) (1 - (1 - n.wi / 2)^5).
// Rs = specular, Rd = diffuse, nu = exponent, nv = exponent_v.
// Sampling (as in the paper): h with phi = atan(sqrt((nu + 1)/(nv + 1)) tan(pi xi1 / 2)) per
// quadrant and cos theta_h = (1 - xi2)^(1 / (nu cos^2 phi + nv sin^2 phi + 1)), whose density is
// p_h = sqrt((nu + 1)(nv + 1)) / (2 pi) (n.h)^(nu cos^2 phi + nv sin^2 phi) exactly; wi = wo reflected
// about h, p(wi) = p_h / (4 wo.h); a wi below the horizon is no sample (absorbed).
// Lobe choice: diffuse or specular with probability 1/2 each (as pbrt-v2's FresnelBlend), or
// always specular when Rd is black: the specular lobe is never zero (F >= (1 - c)^5), so it must
// always be sampled.
// Reads: diffuse, specular, exponent (nu), exponent_v (nv). Opaque; wo.z > 0 (bsdf.glsl flips).
#ifndef TRILAB_BSDF_ASHIKHMIN_SHIRLEY
#define TRILAB_BSDF_ASHIKHMIN_SHIRLEY

#include "bsdf/common.glsl"
#include "bsdf/lobes.glsl"

float ashikhmin_shirley_specular_probability(Material m) {
    return m.diffuse.x + m.diffuse.y + m.diffuse.z > 0.0 ? 0.5 : 1.0;
}

// nu cos^2 phi_h + nv sin^2 phi_h for the half vector h.
float ashikhmin_shirley_exponent(Material m, vec3 h) {
    float s2 = h.x * h.x + h.y * h.y;
    return s2 > 0.0 ? (m.exponent * h.x * h.x + m.exponent_v * h.y * h.y) / s2 : m.exponent;
}

// Density of the half vector h (h.z > 0), per solid angle.
float ashikhmin_shirley_half_pdf(Material m, vec3 h) {
    return sqrt((m.exponent + 1.0) * (m.exponent_v + 1.0)) * (0.5 * INV_PI) *
           pow(h.z, ashikhmin_shirley_exponent(m, h));
}

float ashikhmin_shirley_pow5(float x) {
    float x2 = x * x;
    return x2 * x2 * x;
}

vec3 ashikhmin_shirley_eval(Material m, vec3 wo, vec3 wi) {
    if (wi.z <= 0.0) {
        return vec3(0.0);
    }
    vec3 h = normalize(wo + wi);
    float kh = dot(wo, h);
    vec3 fresnel = m.specular + (vec3(1.0) - m.specular) * ashikhmin_shirley_pow5(1.0 - kh);
    // p_h / (4 k.h) / max(cos) = the paper's sqrt(..) / (8 pi) (n.h)^e / ((h.k) max(cos)).
    vec3 spec = fresnel * (ashikhmin_shirley_half_pdf(m, h) / (4.0 * kh * max(wo.z, wi.z)));
    vec3 diff = (28.0 / 23.0) * INV_PI * m.diffuse * (vec3(1.0) - m.specular) *
                (1.0 - ashikhmin_shirley_pow5(1.0 - 0.5 * wo.z)) * (1.0 - ashikhmin_shirley_pow5(1.0 - 0.5 * wi.z));
    return spec + diff;
}

float ashikhmin_shirley_pdf(Material m, vec3 wo, vec3 wi) {
    if (wi.z <= 0.0) {
        return 0.0;
    }
    float ps = ashikhmin_shirley_specular_probability(m);
    vec3 h = normalize(wo + wi);
    float glossy = ashikhmin_shirley_half_pdf(m, h) / (4.0 * dot(wo, h));
    return (1.0 - ps) * wi.z * INV_PI + ps * glossy;
}

// The paper's half-vector sampling in the first quadrant: phi in [0, pi/2) from u1, then cos theta_h from u2.
vec2 ashikhmin_shirley_first_quadrant(Material m, float u1, float u2) {
    float phi = 0.5 * PI * u1;
    if (m.exponent != m.exponent_v) {
        phi = atan(sqrt((m.exponent + 1.0) / (m.exponent_v + 1.0)) * tan(phi));
    }
    float c = cos(phi);
    float s = sin(phi);
    float e = m.exponent * c * c + m.exponent_v * s * s;
    return vec2(phi, pow(1.0 - u2, 1.0 / (e + 1.0)));
}

bool ashikhmin_shirley_sample(Material m, vec3 wo, vec3 u, out BsdfSample s) {
    s.delta = false;
    s.weight = vec3(0.0);
    s.pdf = 0.0;
    float ps = ashikhmin_shirley_specular_probability(m);
    if (u.z < ps) {
        // The four quadrants, each a quarter of u.x, mirrored so that u.x is continuous.
        vec2 q;
        float phi;
        if (u.x < 0.25) {
            q = ashikhmin_shirley_first_quadrant(m, 4.0 * u.x, u.y);
            phi = q.x;
        } else if (u.x < 0.5) {
            q = ashikhmin_shirley_first_quadrant(m, 4.0 * (0.5 - u.x), u.y);
            phi = PI - q.x;
        } else if (u.x < 0.75) {
            q = ashikhmin_shirley_first_quadrant(m, 4.0 * (u.x - 0.5), u.y);
            phi = PI + q.x;
        } else {
            q = ashikhmin_shirley_first_quadrant(m, 4.0 * (1.0 - u.x), u.y);
            phi = 2.0 * PI - q.x;
        }
        float ct = q.y;
        float st = sqrt(max(0.0, 1.0 - ct * ct));
        vec3 h = vec3(st * cos(phi), st * sin(phi), ct);
        s.wi = normalize(reflect_about(wo, h));
    } else {
        s.wi = cosine_hemisphere(u.xy);
    }
    LOBE_SAMPLE_RETURN(ashikhmin_shirley);
}

#endif
