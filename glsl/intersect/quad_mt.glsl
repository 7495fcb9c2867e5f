// Quad Möller–Trumbore (Shumskiy & Parshin, sec. 3.1): the Möller–Trumbore solve of mt.glsl
// for four triangles at once, one triangle per vec4 lane, no early exit inside a quad.
// Data (src/encoding/quad_mt.rs): leaves hold quads of 4 triangles in SoA form (vec4 of the
// four triangles' v0.x, v0.y, ...), the last quad of a leaf padded with degenerate triangles
// (all vertices equal: det == 0, so they are rejected exactly and never hit).
// Leaf `first` counts quads; quad q holds triangle slots 4q .. 4q+3.
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

struct QuadMt {
    vec4 v0x; vec4 v0y; vec4 v0z;
    vec4 v1x; vec4 v1y; vec4 v1z;
    vec4 v2x; vec4 v2y; vec4 v2z;
};

// Nine rgba32f texels per quad, in member order.
SCENE_BUFFER(BINDING_PRIMS, rgba32f, F4, quad_mts);

#define PRIM_STRUCT QuadMt
// Triangle slots one primitive holds (a quad of four slots, padding included).
#define PRIM_TRIANGLES 4
QuadMt load_prim(uint qi) {
    int b = int(9u * qi);
    QuadMt q;
    q.v0x = SCENE_TEXEL(quad_mts, b + 0);
    q.v0y = SCENE_TEXEL(quad_mts, b + 1);
    q.v0z = SCENE_TEXEL(quad_mts, b + 2);
    q.v1x = SCENE_TEXEL(quad_mts, b + 3);
    q.v1y = SCENE_TEXEL(quad_mts, b + 4);
    q.v1z = SCENE_TEXEL(quad_mts, b + 5);
    q.v2x = SCENE_TEXEL(quad_mts, b + 6);
    q.v2y = SCENE_TEXEL(quad_mts, b + 7);
    q.v2z = SCENE_TEXEL(quad_mts, b + 8);
    return q;
}

// Whether lane `c` (x, y, z or w) is a valid hit at t >= tmin (the leaf loop compares t with
// the closest hit so far, lane by lane).
#define QUAD_MT_HIT(c) (det.c != 0.0 && u.c >= 0.0 && v.c >= 0.0 && u.c + v.c <= 1.0 && t.c >= r.tmin)

bvec4 intersect_quad(TraceRay r, uint qi, out vec4 t, out vec4 u, out vec4 v) {
    QuadMt q = load_prim(qi);
    vec4 e1x = q.v1x - q.v0x, e1y = q.v1y - q.v0y, e1z = q.v1z - q.v0z;
    vec4 e2x = q.v2x - q.v0x, e2y = q.v2y - q.v0y, e2z = q.v2z - q.v0z;
    // P = D x E2
    vec4 px = r.dir.y * e2z - r.dir.z * e2y;
    vec4 py = r.dir.z * e2x - r.dir.x * e2z;
    vec4 pz = r.dir.x * e2y - r.dir.y * e2x;
    vec4 det = e1x * px + e1y * py + e1z * pz;
    vec4 inv_det = 1.0 / det;
    // T = O - V0
    vec4 tx = r.origin.x - q.v0x, ty = r.origin.y - q.v0y, tz = r.origin.z - q.v0z;
    u = (tx * px + ty * py + tz * pz) * inv_det;
    // Q = T x E1
    vec4 qx = ty * e1z - tz * e1y;
    vec4 qy = tz * e1x - tx * e1z;
    vec4 qz = tx * e1y - ty * e1x;
    v = (r.dir.x * qx + r.dir.y * qy + r.dir.z * qz) * inv_det;
    t = (e2x * qx + e2y * qy + e2z * qz) * inv_det;
    return bvec4(QUAD_MT_HIT(x), QUAD_MT_HIT(y), QUAD_MT_HIT(z), QUAD_MT_HIT(w));
}

#endif
