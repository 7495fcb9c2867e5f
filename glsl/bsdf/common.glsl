// What every BSDF shares: the material record, the sample record and shading-frame helpers.
//
// Conventions (pbrt's): every direction is in the local shading frame, where the surface normal
// is +z; `wo` (towards the viewer / previous vertex) and `wi` (towards the light / next vertex)
// both point away from the surface and are unit length. `eval` returns f(wo, wi) without the
// cosine; `pdf` is the solid-angle density with which `sample` picks wi; `sample` returns the
// throughput factor f * |cos(theta_i)| / pdf. The dispatcher (bsdf.glsl) makes the opaque BSDFs
// two-sided, so their files may assume wo.z > 0.
#ifndef TRILAB_BSDF_COMMON
#define TRILAB_BSDF_COMMON

#include "shared.glsl"  // includes resolve from glsl/ (build.rs), not from this file

const float PI = 3.14159265358979323846;
const float INV_PI = 0.31830988618379067154;

// One material, 64 bytes = four rgba32f texels (Rust twin: scene::GpuMaterial). Which fields
// a BSDF reads is listed in its file and in src/scene/material.rs.
struct Material {
    vec3 diffuse;      // Kd: diffuse albedo; glass: transmission tint (Tf)
    uint kind;         // BSDF_* (shared.glsl)
    vec3 specular;     // Ks: specular albedo; mirror and glass: reflection tint
    float exponent;    // Phong and Blinn-Phong exponent (Ns); Ashikhmin-Shirley nu
    vec3 emission;     // Ke: emitted radiance (any kind may emit; two-sided)
    float ior;         // glass: index of refraction inside relative to outside (Ni)
    float exponent_v;  // Ashikhmin-Shirley nv (= nu when isotropic)
    float sigma;       // Oren-Nayar roughness: standard deviation of facet slope angle, radians
    float reserved0;
    float reserved1;
};

layout(set = 0, binding = BINDING_MATERIALS, rgba32f) uniform readonly restrict imageBuffer scene_materials;

Material load_material(uint i) {
    vec4 a = imageLoad(scene_materials, int(4u * i));
    vec4 b = imageLoad(scene_materials, int(4u * i + 1u));
    vec4 c = imageLoad(scene_materials, int(4u * i + 2u));
    vec4 d = imageLoad(scene_materials, int(4u * i + 3u));
    Material m;
    m.diffuse = a.xyz;
    m.kind = floatBitsToUint(a.w);
    m.specular = b.xyz;
    m.exponent = b.w;
    m.emission = c.xyz;
    m.ior = c.w;
    m.exponent_v = d.x;
    m.sigma = d.y;
    m.reserved0 = d.z;
    m.reserved1 = d.w;
    return m;
}

struct BsdfSample {
    vec3 wi;       // sampled direction, local frame, unit length
    float pdf;     // solid-angle pdf of wi; for a delta lobe, the probability of choosing it
    vec3 weight;   // f(wo, wi) * |cos theta_i| / pdf (for a delta lobe: its weight / probability)
    bool delta;    // wi came from a delta lobe (mirror, glass): no light sampling, no MIS
};

float cos_theta(vec3 w) { return w.z; }
float abs_cos_theta(vec3 w) { return abs(w.z); }
float sin2_theta(vec3 w) { return max(0.0, 1.0 - w.z * w.z); }

// Cosine-weighted hemisphere direction (Malley's method through a concentric disk map,
// Shirley & Chiu 1997), pdf = cos(theta) / pi.
vec2 concentric_disk(vec2 u) {
    vec2 o = 2.0 * u - 1.0;
    if (o.x == 0.0 && o.y == 0.0) {
        return vec2(0.0);
    }
    float r, phi;
    if (abs(o.x) > abs(o.y)) {
        r = o.x;
        phi = (PI / 4.0) * (o.y / o.x);
    } else {
        r = o.y;
        phi = (PI / 2.0) - (PI / 4.0) * (o.x / o.y);
    }
    return r * vec2(cos(phi), sin(phi));
}

vec3 cosine_hemisphere(vec2 u) {
    vec2 d = concentric_disk(u);
    float z = sqrt(max(0.0, 1.0 - dot(d, d)));
    return vec3(d, z);
}

// An orthonormal basis with `n` as its third axis (Duff et al., "Building an Orthonormal Basis,
// Revisited", JCGT 6(1), 2017).
void basis_from(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

#endif
