#version 460
// trilab:variants all lambert=BSDF_MASK:0x1 oren_nayar=BSDF_MASK:0x2 phong=BSDF_MASK:0x4 blinn_phong=BSDF_MASK:0x8 ashikhmin_shirley=BSDF_MASK:0x10 glass=BSDF_MASK:0x20 mirror=BSDF_MASK:0x40 all_storage=SCENE_STORAGE
// trilab:layouts all all_storage
// Unidirectional path tracer, one pixel per invocation, `pc.sample_count` samples per dispatch
// accumulated in sample order (so the image does not depend on how samples are batched).
//
// Per vertex: closest hit (the variant's intersector and traverse.glsl, as in raycast.comp),
// emission weighted by MIS, next-event estimation towards one emissive triangle with an
// occlusion ray, next-event estimation towards the sun with an occlusion ray, BSDF sampling,
// Russian roulette. Lights: the environment (a sky gradient and a ground, reached by BSDF
// sampling only; a constant environment is the case of equal colours), the sun (a small disc of
// constant radiance, sampled uniformly over its cone) and emissive triangles (sampled by area x
// mean emitted radiance). Each light is found two ways, by its own next-event sample and by BSDF
// sampling, and the two are combined by multiple importance sampling with the power heuristic,
// beta = 2: w_s = p_s^2 / (p_light^2 + p_bsdf^2), both densities per unit solid angle (Veach &
// Guibas, SIGGRAPH 1995; Veach's thesis, 1997, section 9.2; pbrt-v3, section 13.10.1).
//
// Variants: `all` carries every BSDF; the others carry one each (BSDF_MASK). SPEC_BSDF_MASK,
// a specialisation constant, narrows `all` to a scene's set at pipeline creation, so the driver
// drops the BSDFs the scene does not use. `all_storage` (SCENE_STORAGE, issue 38) reads the scene,
// the shading records and the lights from storage buffers instead of texel buffers
// (glsl/types.glsl): for devices whose texel buffers are too small for the scene (SwiftShader).
#extension GL_GOOGLE_include_directive : require

#include "types.glsl"
#include "rng.glsl"

layout(constant_id = 0) const uint SPEC_BSDF_MASK = BSDF_MASK_ALL;
#define BSDF_SPEC_MASK SPEC_BSDF_MASK
#include "bsdf.glsl"

// Per-render parameters (Rust twin: render::GpuParams).
layout(std140, set = 0, binding = BINDING_PARAMS) uniform Params {
    vec4 cam_eye;       // xyz: eye; w: tan(fov_y / 2)
    vec4 cam_right;     // xyz: unit right; w: width / height
    vec4 cam_up;        // xyz: unit up
    vec4 cam_forward;   // xyz: unit forward
    vec4 env;           // rgb: environment radiance below the horizon (ground); w: total light weight (sum over emissive triangles of area * mean Ke)
    uint width;
    uint height;
    uint max_depth;     // most scattering events per path
    uint rr_depth;      // Russian roulette from this many scattering events on
    uint seed;
    uint light_count;   // emissive triangles
    float ray_eps;      // spawn offset, relative to max(|p|, scene_extent)
    float scene_extent; // largest side of the scene's bounds
    vec4 sky_zenith;    // rgb: environment radiance towards +y (linear in d.y down to the horizon)
    vec4 sky_horizon;   // rgb: environment radiance at the horizon
    vec4 sun_dir;       // xyz: unit direction towards the sun; w: cos of its angular radius
    vec4 sun_radiance;  // rgb: radiance within the sun's disc (beyond the sky); w: 1 / its solid angle, 0 without next-event estimation
} params;

// Sum of radiance (rgb) and of primary-ray coverage (a) per pixel, over all samples so far.
layout(std430, set = 0, binding = BINDING_ACCUM) buffer Accum { vec4 accum[]; };
// Counters for the current submit: closest-hit rays, occlusion rays, samples dropped because
// their radiance was NaN or infinite.
layout(std430, set = 0, binding = BINDING_STATS) buffer Stats { uint stats[]; };

// Per triangle slot: geometric normal (unit, from the vertex order) and material, one texel.
SCENE_BUFFER(BINDING_SHADING, rgba32f, F4, scene_shading);
// Emissive triangles, three texels each: (v0, cdf), (e1 = v1 - v0, material), (e2 = v2 - v0, area).
SCENE_BUFFER(BINDING_LIGHTS, rgba32f, F4, scene_lights);

layout(push_constant) uniform Push {
    uint sample_first;  // first sample index of this dispatch
    uint sample_count;  // samples per pixel in this dispatch
    uint pixel_first;   // first pixel (y * width + x) of this dispatch
    uint pixel_count;   // pixels in this dispatch
} pc;

#include "intersector.glsl"
#include "traverse.glsl"

layout(local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

// Draws per scattering event (dimension = DIMS_PER_VERTEX * depth + one of the offsets below).
const uint DIMS_PER_VERTEX = 12u;
const uint DIM_PIXEL_X = 0u;
const uint DIM_PIXEL_Y = 1u;
const uint DIM_LIGHT_PICK = 2u;
const uint DIM_LIGHT_U = 3u;
const uint DIM_LIGHT_V = 4u;
const uint DIM_BSDF = 5u; // three draws
const uint DIM_RR = 8u;
const uint DIM_SUN_U = 9u;
const uint DIM_SUN_V = 10u;

float mean3(vec3 c) {
    return (c.x + c.y + c.z) * (1.0 / 3.0);
}

float max3(vec3 c) {
    return max(c.x, max(c.y, c.z));
}

float power_heuristic(float f, float g) {
    float f2 = f * f;
    float g2 = g * g;
    return f2 + g2 > 0.0 ? f2 / (f2 + g2) : 0.0;
}

// Origin for a ray leaving `p` on the side of `n` that `dir` goes to.
vec3 spawn(vec3 p, vec3 n, vec3 dir) {
    vec3 a = abs(p);
    float eps = params.ray_eps * max(max(a.x, max(a.y, a.z)), params.scene_extent);
    return p + (dot(n, dir) >= 0.0 ? eps : -eps) * n;
}

HitState trace_closest(vec3 o, vec3 d) {
    Ray ray;
    ray.origin = o;
    ray.tmin = 0.0;
    ray.dir = d;
    ray.tmax = uintBitsToFloat(0x7f800000u);
    HitState h = hit_start(ray.tmax);
    trace(make_trace_ray(ray), h, false);
    return h;
}

bool occluded(vec3 o, vec3 d, float tmax) {
    Ray ray;
    ray.origin = o;
    ray.tmin = 0.0;
    ray.dir = d;
    ray.tmax = tmax;
    HitState h = hit_start(tmax);
    trace(make_trace_ray(ray), h, true);
    return h.slot != MISS_ID;
}

// Environment radiance towards `d` (unit), the sun excluded: the ground below the horizon, above
// it a gradient linear in d.y from the horizon's colour to the zenith's.
vec3 sky_radiance(vec3 d) {
    return d.y < 0.0 ? params.env.rgb : mix(params.sky_horizon.rgb, params.sky_zenith.rgb, d.y);
}

// Whether unit direction `d` falls within the sun's disc.
bool in_sun(vec3 d) {
    return dot(d, params.sun_dir.xyz) >= params.sun_dir.w;
}

// Light selection: the first light whose cdf exceeds u (binary search).
uint pick_light(float u) {
    uint lo = 0u;
    uint hi = params.light_count - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (SCENE_TEXEL(scene_lights, 3u * mid).w > u) {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    return lo;
}

// Area density of next-event estimation choosing a point on a triangle emitting `ke`:
// (area * mean(ke) / total) / area.
float light_area_pdf(vec3 ke) {
    return mean3(ke) / params.env.w;
}

void main() {
    uint gid = gl_GlobalInvocationID.x;
    if (gid >= pc.pixel_count) {
        return;
    }
    uint pixel = pc.pixel_first + gid;
    uint px = pixel % params.width;
    uint py = pixel / params.width;
    vec4 acc = accum[pixel];
    uint closest_rays = 0u;
    uint shadow_rays = 0u;
    uint dropped = 0u;
    bool lights = params.light_count > 0u;

    for (uint si = 0u; si < pc.sample_count; ++si) {
        uint key = path_key(params.seed, pixel, pc.sample_first + si);
        // Camera ray through a uniformly jittered point of the pixel (y down in the image).
        float sx = (float(px) + rand01(key, DIM_PIXEL_X)) / float(params.width);
        float sy = (float(py) + rand01(key, DIM_PIXEL_Y)) / float(params.height);
        vec2 ndc = vec2(2.0 * sx - 1.0, 1.0 - 2.0 * sy);
        float th = params.cam_eye.w;
        vec3 dir = normalize(params.cam_forward.xyz + ndc.x * th * params.cam_right.w * params.cam_right.xyz +
                             ndc.y * th * params.cam_up.xyz);
        vec3 origin = params.cam_eye.xyz;

        vec3 radiance = vec3(0.0);
        vec3 beta = vec3(1.0);
        float prev_pdf = 0.0;
        bool prev_delta = true; // the camera vertex: emission seen directly gets full weight
        bool sun_nee = params.sun_radiance.w > 0.0 && max3(params.sun_radiance.rgb) > 0.0;
        float coverage = 0.0;
        for (uint depth = 0u;; ++depth) {
            HitState h = trace_closest(origin, dir);
            ++closest_rays;
            if (h.slot == MISS_ID) {
                radiance += beta * sky_radiance(dir);
                if (in_sun(dir)) {
                    // The sun found by BSDF sampling, weighted against its next-event sample
                    // (full weight when that could not have drawn it).
                    float w = 1.0;
                    if (sun_nee && !prev_delta) {
                        w = power_heuristic(prev_pdf, params.sun_radiance.w);
                    }
                    radiance += beta * params.sun_radiance.rgb * w;
                }
                break;
            }
            if (depth == 0u) {
                coverage = 1.0;
            }
            vec4 sh = SCENE_TEXEL(scene_shading, h.slot);
            vec3 n = sh.xyz;
            Material m = load_material(floatBitsToUint(sh.w));
            vec3 p = origin + h.t * dir;

            // Emission (one-sided: the front face is the one the vertex order winds
            // counter-clockwise around), weighted against next-event estimation.
            float cos_l = -dot(n, dir);
            if (cos_l > 0.0 && max3(m.emission) > 0.0) {
                float w = 1.0;
                if (lights && !prev_delta) {
                    float light_pdf = light_area_pdf(m.emission) * h.t * h.t / cos_l;
                    w = power_heuristic(prev_pdf, light_pdf);
                }
                radiance += beta * m.emission * w;
            }
            if (depth >= params.max_depth) {
                break;
            }

            vec3 tx, ty;
            basis_from(n, tx, ty);
            vec3 wo = vec3(dot(-dir, tx), dot(-dir, ty), dot(-dir, n));
            uint dim = DIMS_PER_VERTEX * depth;

            // Next-event estimation, one sample per light kind: k = 0, one point on one emissive
            // triangle; k = 1, a direction uniform over the sun's cone (density 1 / solid angle).
            // One occlusion ray each; one loop, so the traversal is compiled once.
            if (!bsdf_is_delta(m.kind)) {
                for (uint k = 0u; k < 2u; ++k) {
                    vec3 o;
                    vec3 wl;
                    float tmax;
                    vec3 le;
                    float light_pdf = 0.0;
                    if (k == 0u) {
                        if (!lights) {
                            continue;
                        }
                        uint li = pick_light(rand01(key, dim + DIM_LIGHT_PICK));
                        vec4 l0 = SCENE_TEXEL(scene_lights, 3u * li);
                        vec4 l1 = SCENE_TEXEL(scene_lights, 3u * li + 1u);
                        vec4 l2 = SCENE_TEXEL(scene_lights, 3u * li + 2u);
                        float a = rand01(key, dim + DIM_LIGHT_U);
                        float b = rand01(key, dim + DIM_LIGHT_V);
                        if (a + b > 1.0) {
                            a = 1.0 - a;
                            b = 1.0 - b;
                        }
                        vec3 lp = l0.xyz + a * l1.xyz + b * l2.xyz;
                        vec3 ln = normalize(cross(l1.xyz, l2.xyz));
                        o = spawn(p, n, lp - p);
                        vec3 to_light = lp - o;
                        float dist2 = dot(to_light, to_light);
                        float dist = sqrt(dist2);
                        wl = to_light / dist;
                        tmax = dist * (1.0 - 1.0e-4);
                        float cos_light = -dot(ln, wl);
                        le = load_material(floatBitsToUint(l1.w)).emission;
                        if (cos_light > 0.0 && max3(le) > 0.0) {
                            light_pdf = light_area_pdf(le) * dist2 / cos_light;
                        }
                    } else {
                        if (!sun_nee) {
                            continue;
                        }
                        float cos_max = params.sun_dir.w;
                        float cos_t = 1.0 - rand01(key, dim + DIM_SUN_U) * (1.0 - cos_max);
                        float sin_t = sqrt(max(0.0, 1.0 - cos_t * cos_t));
                        float phi = 6.28318530717958647692 * rand01(key, dim + DIM_SUN_V);
                        vec3 sx, sy;
                        basis_from(params.sun_dir.xyz, sx, sy);
                        wl = normalize(sin_t * (cos(phi) * sx + sin(phi) * sy) + cos_t * params.sun_dir.xyz);
                        o = spawn(p, n, wl);
                        tmax = uintBitsToFloat(0x7f800000u);
                        le = params.sun_radiance.rgb;
                        light_pdf = params.sun_radiance.w;
                    }
                    vec3 wi = vec3(dot(wl, tx), dot(wl, ty), dot(wl, n));
                    vec3 f = bsdf_eval(m, wo, wi);
                    if (light_pdf > 0.0 && max3(f) > 0.0) {
                        ++shadow_rays;
                        if (!occluded(o, wl, tmax)) {
                            float w = power_heuristic(light_pdf, bsdf_pdf(m, wo, wi));
                            radiance += beta * f * abs(wi.z) * le * (w / light_pdf);
                        }
                    }
                }
            }

            // Continue the path by sampling the BSDF.
            BsdfSample s;
            vec3 u = vec3(rand01(key, dim + DIM_BSDF), rand01(key, dim + DIM_BSDF + 1u),
                          rand01(key, dim + DIM_BSDF + 2u));
            if (!bsdf_sample(m, wo, u, s)) {
                break;
            }
            beta *= s.weight;
            prev_pdf = s.pdf;
            prev_delta = s.delta;
            dir = normalize(s.wi.x * tx + s.wi.y * ty + s.wi.z * n);
            origin = spawn(p, n, dir);

            // Russian roulette on the throughput (pbrt-v3 style, survival at most 0.95).
            if (depth + 1u >= params.rr_depth) {
                float q = min(max3(beta), 0.95);
                if (!(rand01(key, dim + DIM_RR) < q)) {
                    break;
                }
                beta /= q;
            }
        }
        if (any(isnan(radiance)) || any(isinf(radiance))) {
            ++dropped;
        } else {
            acc.rgb += radiance;
        }
        acc.a += coverage;
    }
    accum[pixel] = acc;
    atomicAdd(stats[0], closest_rays);
    atomicAdd(stats[1], shadow_rays);
    if (dropped > 0u) {
        atomicAdd(stats[2], dropped);
    }
}
