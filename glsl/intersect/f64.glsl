// Möller–Trumbore in double precision: a GPU reference (T. Möller, B. Trumbore, "Fast, minimum
// storage ray-triangle intersection", JGT 2(1), 1997). It reads MT's data (src/encoding/mt.rs:
// f32 vertices, one rgba32f texel each, and one rgba32ui texel of vertex indices per slot),
// widens vertices and ray exactly to double, and solves in the same operation order as the CPU
// reference (src/reference.rs `intersect`, glam's `cross` and `dot`), every result `precise` so
// that nothing is fused or reassociated. A hit's t, u, v are therefore the reference's values
// rounded to f32, unless two triangles tie (traversal order then picks one).
// Closest hit is decided in double: HitState.t64 (types.glsl, METHOD_F64) holds the best t so
// far, valid once h.slot != MISS_ID; before the first hit the bound is double(h.t), the ray's
// tmax. h.t = float(t64) is what traversal culls boxes with (f32, conservative: traverse.glsl
// scales the far distance up by more than the half ULP float() may round down).
// Needs shaderFloat64 (SPIR-V capability Float64): kernel creation fails with
// Error::Unsupported on devices without it.
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

#ifndef METHOD_F64
#error "f64.glsl needs METHOD_F64 (HitState.t64), which build.rs defines for this intersector"
#endif

#include "mt_layout.glsl"

// A vertex widened exactly to double.
dvec3 load_vertex64(uint i) {
    return dvec3(load_vertex(i));
}

// glam's DVec3::cross: (a.y b.z - b.y a.z, a.z b.x - b.z a.x, a.x b.y - b.x a.y).
dvec3 cross64(dvec3 a, dvec3 b) {
    precise double x = a.y * b.z - b.y * a.z;
    precise double y = a.z * b.x - b.z * a.x;
    precise double z = a.x * b.y - b.x * a.y;
    return dvec3(x, y, z);
}

// glam's DVec3::dot: (a.x b.x + a.y b.y) + a.z b.z.
double dot64(dvec3 a, dvec3 b) {
    precise double d = a.x * b.x + a.y * b.y + a.z * b.z;
    return d;
}

bool intersect_leaf(TraceRay r, uint first, uint count, inout HitState h, bool any_hit) {
    bool found = false;
    dvec3 origin = dvec3(r.origin);
    dvec3 dir = dvec3(r.dir);
    double tmin = double(r.tmin);
    for (uint s = first; s < first + count; ++s) {
        uvec3 idx = SCENE_TEXEL(mt_triangles, s).xyz;
        dvec3 a = load_vertex64(idx.x);
        precise dvec3 e1 = load_vertex64(idx.y) - a;
        precise dvec3 e2 = load_vertex64(idx.z) - a;
        dvec3 p = cross64(dir, e2);
        double det = dot64(e1, p);
        if (det == 0.0lf || cross64(e1, e2) == dvec3(0.0lf)) {
            continue; // parallel to the plane, or a zero-area triangle (as the reference)
        }
        precise double inv = 1.0lf / det;
        precise dvec3 tv = origin - a;
        precise double u = dot64(tv, p) * inv;
        if (!(u >= 0.0lf)) {
            continue; // u + v <= 1 with v >= 0 bounds u above
        }
        dvec3 q = cross64(tv, e1);
        precise double v = dot64(dir, q) * inv;
        precise double uv = u + v;
        if (!(v >= 0.0lf && uv <= 1.0lf)) {
            continue;
        }
        precise double t = dot64(e2, q) * inv;
        double best = h.slot == MISS_ID ? double(h.t) : h.t64;
        if (t >= tmin && t <= best) {
            h.t64 = t;
            h.t = float(t);
            h.slot = s;
            h.u = float(u);
            h.v = float(v);
            found = true;
            if (any_hit) {
                return true;
            }
        }
    }
    return found;
}

#endif
