// Stack-based "while-if" BVH traversal (Shumskiy & Parshin, appendix 8.3; after Aila & Laine
// 2009): one node per loop iteration, both children's boxes tested, the nearer child visited
// first and the farther pushed. Needs `intersect_leaf` from the intersector, included before.
#ifndef TRILAB_TRAVERSE
#define TRILAB_TRAVERSE

#include "types.glsl"

// |dir| components below this are replaced by it (with the component's sign) before 1/dir,
// so axis-parallel rays give large finite slopes instead of inf * 0 = NaN in the slab test.
const float TINY_DIR = 1.0e-30;
// pbrt-v3/v4's conservative slab test: scale the far distance up by 1 + 2*gamma(3) so that
// rounding never culls a box the ray grazes (Pharr, Jakob & Humphreys, PBR 3rd ed., 3.9.2).
const float SLAB_FAR_SCALE = 1.0000003576;

TraceRay make_trace_ray(Ray r) {
    TraceRay tr;
    tr.origin = r.origin;
    tr.dir = r.dir;
    vec3 s = mix(vec3(1.0), vec3(-1.0), lessThan(r.dir, vec3(0.0)));
    vec3 safe = s * max(abs(r.dir), vec3(TINY_DIR));
    tr.inv_dir = 1.0 / safe;
    tr.origin_scaled = r.origin * tr.inv_dir;
    tr.tmin = r.tmin;
    return tr;
}

// Slab test against [tmin, tfar]; returns the entry distance in `tnear`.
bool hit_box(TraceRay r, vec3 bmin, vec3 bmax, float tfar, out float tnear) {
    vec3 t0 = bmin * r.inv_dir - r.origin_scaled;
    vec3 t1 = bmax * r.inv_dir - r.origin_scaled;
    vec3 lo = min(t0, t1);
    vec3 hi = max(t0, t1);
    tnear = max(max(lo.x, lo.y), max(lo.z, r.tmin));
    float tf = min(min(hi.x, hi.y), min(hi.z, tfar)) * SLAB_FAR_SCALE;
    return tnear <= tf;
}

// Traces `r` through the BVH, updating `h` (h.t must start at the ray's tmax).
// With ANY_HIT defined it returns at the first accepted intersection.
void trace(TraceRay r, inout HitState h) {
    float troot;
    BvhNode current = load_node(0u);
    if (!hit_box(r, current.bmin, current.bmax, h.t, troot)) {
        return;
    }
    uint stack[STACK_SIZE];
    uint sp = 0u;
    while (true) {
        if (current.count > 0u) {
            // Leaf.
            bool found = intersect_leaf(r, current.left_or_first, current.count, h);
#ifdef ANY_HIT
            if (found) {
                return;
            }
#endif
            if (sp == 0u) {
                return;
            }
            current = load_node(stack[--sp]);
        } else {
            uint left = current.left_or_first;
            BvhNode l = load_node(left);
            BvhNode rr = load_node(left + 1u);
            float tl, tr;
            bool want_l = hit_box(r, l.bmin, l.bmax, h.t, tl);
            bool want_r = hit_box(r, rr.bmin, rr.bmax, h.t, tr);
            if (want_l && want_r) {
                if (tl <= tr) {
                    stack[sp++] = left + 1u;
                    current = l;
                } else {
                    stack[sp++] = left;
                    current = rr;
                }
            } else if (want_l) {
                current = l;
            } else if (want_r) {
                current = rr;
            } else {
                if (sp == 0u) {
                    return;
                }
                current = load_node(stack[--sp]);
            }
        }
    }
}

#endif
