#version 460
// trilab:intersector none
// trilab:variants closest any=ANY_HIT
// The driver's own ray tracing as a peer of raycast.comp: the same rays in, the same hits out,
// but traced with VK_KHR_ray_query through the driver's acceleration structure (built by
// gpu::accel from the same triangles) instead of our BVH and intersectors.
// Closest hit, or with ANY_HIT the first hit the driver accepts (occlusion).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_query : require

#include "types.glsl"

layout(std430, set = 0, binding = BINDING_RAYS) readonly buffer Rays { Ray rays[]; };
layout(std430, set = 0, binding = BINDING_HITS) writeonly buffer Hits { Hit hits[]; };
layout(set = 0, binding = BINDING_TLAS) uniform accelerationStructureEXT tlas;
// scene_slot_ids (types.glsl, BINDING_SLOT_IDS) maps the BLAS's primitive index to the OBJ
// triangle id: zero-area triangles are left out of the BLAS, so the two can differ.

layout(push_constant) uniform Push {
    uint ray_count; // rays in this dispatch (the bound ray/hit ranges hold exactly these)
} pc;

#ifdef ANY_HIT
const uint RAY_FLAGS = gl_RayFlagsOpaqueEXT | gl_RayFlagsTerminateOnFirstHitEXT;
#else
const uint RAY_FLAGS = gl_RayFlagsOpaqueEXT;
#endif

layout(local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

bool finite3(vec3 x) {
    return !any(isnan(x)) && !any(isinf(x));
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.ray_count) {
        return;
    }
    Ray ray = rays[i];
    Hit o;
    o.t = uintBitsToFloat(0x7f800000u); // +inf
    o.id = MISS_ID;
    o.u = 0.0;
    o.v = 0.0;
    // Vulkan requires finite origin and direction, 0 <= tmin <= tmax and no NaN
    // (VUID-RuntimeSpirv-OpRayQueryInitializeKHR-06348..06351). Ray files never hold NaN or
    // infinite origins and directions; a negative tmin is traced from 0 (the driver cannot
    // report hits behind the origin), and an empty interval is a miss, as in raycast.comp.
    float tmin = max(ray.tmin, 0.0);
    bool valid = finite3(ray.origin) && finite3(ray.dir) && any(notEqual(ray.dir, vec3(0.0)))
        && !isnan(ray.tmin) && !isnan(ray.tmax) && tmin <= ray.tmax;
    if (valid) {
        rayQueryEXT q;
        rayQueryInitializeEXT(q, tlas, RAY_FLAGS, 0xFFu, ray.origin, tmin, ray.dir, ray.tmax);
        // Opaque geometry and an opaque ray: the driver commits triangle hits itself and
        // never returns a candidate to confirm.
        while (rayQueryProceedEXT(q)) {
        }
        if (rayQueryGetIntersectionTypeEXT(q, true) == gl_RayQueryCommittedIntersectionTriangleEXT) {
            vec2 b = rayQueryGetIntersectionBarycentricsEXT(q, true);
            o.t = rayQueryGetIntersectionTEXT(q, true);
            o.id = load_slot_id(uint(rayQueryGetIntersectionPrimitiveIndexEXT(q, true)));
            o.u = b.x;
            o.v = b.y;
        }
    }
    hits[i] = o;
}
