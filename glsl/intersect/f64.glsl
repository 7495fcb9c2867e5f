// Möller–Trumbore in double precision: a GPU reference (T. Möller, B. Trumbore, "Fast, minimum
// storage ray-triangle intersection", JGT 2(1), 1997). It reads MT's data (src/encoding/mt.rs:
// f32 vertices, one rgba32f texel each, and one rgba32ui texel of vertex indices per slot),
// widens vertices and ray exactly to double, and solves in the same operation order as the CPU
// reference (src/reference.rs `intersect`, glam's `cross` and `dot`), every result `precise` so
// that nothing is fused or reassociated. A hit's t, u, v are therefore the reference's values
// rounded to f32, unless two triangles tie (traversal order then picks one).
// Closest hit is decided in double: `f64_best` holds the best t so far, set to the ray's tmax
// once per ray (INTERSECTOR_RAY_SETUP) and lowered with every hit accepted. The leaf loop's
// h.t = float(t) is what traversal culls boxes with (f32, conservative: box.glsl scales the
// far distance up by more than the half ULP float() may round down).
// Needs shaderFloat64 (SPIR-V capability Float64): kernel creation fails with
// Error::Unsupported on devices without it.
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

#include "mt_scene.glsl"

// The layout probe (probe.comp) includes intersectors for their data layout only: no double
// may be declared then, or its module would need shaderFloat64 for copying integers.
#ifndef LAYOUT_ONLY

// The closest t so far in double (the ray's tmax before the first hit). One traced ray at a
// time per invocation, so one variable; trace() sets it once per ray.
double f64_best;

#define INTERSECTOR_RAY_SETUP(r, h) f64_best = double(h.t)

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

bool intersect_triangle(TraceRay r, uint s, float tmax, out float t, out float u, out float v) {
    dvec3 origin = dvec3(r.origin);
    dvec3 dir = dvec3(r.dir);
    double tmin = double(r.tmin);
    uvec3 idx = SCENE_TEXEL(mt_triangles, s).xyz;
    dvec3 a = load_vertex64(idx.x);
    precise dvec3 e1 = load_vertex64(idx.y) - a;
    precise dvec3 e2 = load_vertex64(idx.z) - a;
    dvec3 p = cross64(dir, e2);
    double det = dot64(e1, p);
    if (det == 0.0lf || cross64(e1, e2) == dvec3(0.0lf)) {
        return false; // parallel to the plane, or a zero-area triangle (as the reference)
    }
    precise double inv = 1.0lf / det;
    precise dvec3 tv = origin - a;
    precise double u64 = dot64(tv, p) * inv;
    if (!(u64 >= 0.0lf)) {
        return false; // u + v <= 1 with v >= 0 bounds u above
    }
    dvec3 q = cross64(tv, e1);
    precise double v64 = dot64(dir, q) * inv;
    precise double uv = u64 + v64;
    if (!(v64 >= 0.0lf && uv <= 1.0lf)) {
        return false;
    }
    precise double t64 = dot64(e2, q) * inv;
    // `tmax` is float(f64_best): the bound is decided in double.
    if (!(t64 >= tmin && t64 <= f64_best)) {
        return false;
    }
    f64_best = t64;
    t = float(t64);
    u = float(u64);
    v = float(v64);
    return true;
}

#endif // LAYOUT_ONLY

#endif
