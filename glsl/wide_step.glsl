// What every wide layout's step shares, whatever its node format (glsl/layout/bvh4.glsl,
// bvh8.glsl through wide.glsl, and qbvh4.glsl): the empty-slot marker, the sorting networks'
// swap, and the 4-wide step's end (WIDE4_ORDER_AND_PUSH: the hit children sorted far to near,
// all but the nearest pushed, the nearest visited next).
#ifndef TRILAB_WIDE_STEP
#define TRILAB_WIDE_STEP

// bvh::EMPTY_CHILD: the child word (bvh4, bvh8) or packed entry (qbvh4) of an empty slot.
const uint EMPTY_CHILD = 0xFFFFFFFFu;

// -FLT_MAX: below every entry distance (tnear >= the ray's tmin), so misses sort after every hit.
const float NO_HIT = -3.40282347e38;

// The body of one child's test, in a function with parameters `BoxRay b`, `float tmax`,
// `float miss`, `inout uint hits` and `out uint entry`: the child's box [bmin, bmax] against
// [tmin, tmax] when `occupied`, returning its entry distance and setting `entry` to `e` (`hits`
// counted up) when hit, else `miss` and 0. Only an occupied child is tested (an empty slot's box
// may be hit: wide.glsl). A macro, so that `e` is computed only for a hit.
#define WIDE_TEST_CHILD(occupied, bmin, bmax, e)                                               \
    float t = miss;                                                                            \
    entry = 0u;                                                                                \
    if (occupied) {                                                                            \
        COUNT_BOXES(1u);                                                                       \
        float tn;                                                                              \
        if (hit_box(b, bmin, bmax, tmax, tn)) {                                                \
            entry = e;                                                                         \
            hits += 1u;                                                                        \
            t = tn;                                                                            \
        }                                                                                      \
    }                                                                                          \
    return t;

// Sorting-network comparator over (t<i>, e<i>) locals: swaps pairs a and b when t<a> < t<b>.
#define WIDE_SWAP_IF_LESS(a, b)                                                                \
    if (t##a < t##b) {                                                                         \
        float ts = t##a;                                                                       \
        t##a = t##b;                                                                           \
        t##b = ts;                                                                             \
        uint es = e##a;                                                                        \
        e##a = e##b;                                                                           \
        e##b = es;                                                                             \
    }

// The end of a 4-wide step over locals (t0..t3, e0..e3: each child's entry distance, NO_HIT for
// a miss, and packed entry) and `hits` (how many were hit): far to near by a 5-comparator network
// (the misses end up last), all hit children but the nearest pushed with their entry distance,
// the nearest into `next` (0 when none is hit).
#define WIDE4_ORDER_AND_PUSH(next)                                                             \
    next = 0u;                                                                                 \
    if (hits > 0u) {                                                                           \
        WIDE_SWAP_IF_LESS(0, 1)                                                                \
        WIDE_SWAP_IF_LESS(2, 3)                                                                \
        WIDE_SWAP_IF_LESS(0, 2)                                                                \
        WIDE_SWAP_IF_LESS(1, 3)                                                                \
        WIDE_SWAP_IF_LESS(1, 2)                                                                \
        if (hits == 1u) {                                                                      \
            next = e0;                                                                         \
        } else {                                                                               \
            stack_push(e0, t0);                                                                \
            if (hits == 2u) {                                                                  \
                next = e1;                                                                     \
            } else {                                                                           \
                stack_push(e1, t1);                                                            \
                if (hits == 3u) {                                                              \
                    next = e2;                                                                 \
                } else {                                                                       \
                    stack_push(e2, t2);                                                        \
                    next = e3;                                                                 \
                }                                                                              \
            }                                                                                  \
        }                                                                                      \
    }

#endif
