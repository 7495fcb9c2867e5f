// Quad unit triangle (Shumskiy & Parshin, sec. 3.1, applied to Woop's test of unit.glsl): four
// triangles' affine maps in SoA form, the ray mapped into all four unit spaces at once.
// Data (src/encoding/quad_unit.rs): per quad, for each of the three rows of [M | N], one vec4
// per column holding that entry for the four triangles. Padding lanes store the map
// row0 = row1 = (0,0,0,-1), row2 = (0,0,0,1): D'z = +-0 exactly for every ray, so the lane is
// rejected by the exact test D'z != 0 (as Quad MT rejects det == 0), without relying on how a
// driver treats the resulting inf/NaN (Vulkan leaves that to float controls).
// Leaf `first` counts quads; quad q holds triangle slots 4q .. 4q+3.
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

struct QuadUnit {
    vec4 m0x; vec4 m0y; vec4 m0z; vec4 n0; // row 0 -> u
    vec4 m1x; vec4 m1y; vec4 m1z; vec4 n1; // row 1 -> v
    vec4 m2x; vec4 m2y; vec4 m2z; vec4 n2; // row 2 -> distance from the plane
};

// Twelve rgba32f texels per quad, in member order.
SCENE_BUFFER(BINDING_PRIMS, rgba32f, F4, quad_units);

#define PRIM_STRUCT QuadUnit
// Triangle slots one primitive holds (a quad of four slots, padding included).
#define PRIM_TRIANGLES 4
QuadUnit load_prim(uint qi) {
    int b = int(12u * qi);
    QuadUnit q;
    q.m0x = SCENE_TEXEL(quad_units, b + 0);
    q.m0y = SCENE_TEXEL(quad_units, b + 1);
    q.m0z = SCENE_TEXEL(quad_units, b + 2);
    q.n0 = SCENE_TEXEL(quad_units, b + 3);
    q.m1x = SCENE_TEXEL(quad_units, b + 4);
    q.m1y = SCENE_TEXEL(quad_units, b + 5);
    q.m1z = SCENE_TEXEL(quad_units, b + 6);
    q.n1 = SCENE_TEXEL(quad_units, b + 7);
    q.m2x = SCENE_TEXEL(quad_units, b + 8);
    q.m2y = SCENE_TEXEL(quad_units, b + 9);
    q.m2z = SCENE_TEXEL(quad_units, b + 10);
    q.n2 = SCENE_TEXEL(quad_units, b + 11);
    return q;
}

// Whether lane `c` (x, y, z or w) is a valid hit at t >= tmin (the leaf loop compares t with
// the closest hit so far, lane by lane).
#define QUAD_UNIT_HIT(c) (dz.c != 0.0 && t.c >= r.tmin && u.c >= 0.0 && v.c >= 0.0 && u.c + v.c <= 1.0)

bvec4 intersect_quad(TraceRay r, uint qi, out vec4 t, out vec4 u, out vec4 v) {
    vec3 o = r.origin;
    vec3 d = r.dir;
    QuadUnit q = load_prim(qi);
    vec4 oz = q.m2x * o.x + q.m2y * o.y + q.m2z * o.z + q.n2;
    vec4 dz = q.m2x * d.x + q.m2y * d.y + q.m2z * d.z;
    t = -oz / dz;
    u = (q.m0x * o.x + q.m0y * o.y + q.m0z * o.z + q.n0) + t * (q.m0x * d.x + q.m0y * d.y + q.m0z * d.z);
    v = (q.m1x * o.x + q.m1y * o.y + q.m1z * o.z + q.n1) + t * (q.m1x * d.x + q.m1y * d.y + q.m1z * d.z);
    return bvec4(QUAD_UNIT_HIT(x), QUAD_UNIT_HIT(y), QUAD_UNIT_HIT(z), QUAD_UNIT_HIT(w));
}

#endif
