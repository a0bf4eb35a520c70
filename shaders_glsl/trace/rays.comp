#version 460
// Generic ray casting with ray queries: closest hit (t, triangle, barycentrics) or, in
// occlusion mode, whether anything lies on the segment (first hit found, not the closest).
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require

layout(local_size_x = 64) in;

struct Ray { vec3 origin; float tmin; vec3 dir; float tmax; };
struct Hit { float t; uint tri; vec2 bary; };   // tri = ~0u when nothing was hit

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 1, scalar) readonly buffer Rays { Ray rays[]; };
layout(set = 0, binding = 2, scalar) writeonly buffer Hits { Hit hits[]; };

layout(push_constant) uniform Push { uint count; uint occlusion; } pc;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) return;
    Ray r = rays[i];
    uint flags = gl_RayFlagsOpaqueEXT;
    if (pc.occlusion != 0u) flags |= gl_RayFlagsTerminateOnFirstHitEXT;
    rayQueryEXT rq;
    rayQueryInitializeEXT(rq, tlas, flags, 0xFF, r.origin, r.tmin, r.dir, r.tmax);
    while (rayQueryProceedEXT(rq)) {}
    Hit h = Hit(-1.0, ~0u, vec2(0.0));
    if (rayQueryGetIntersectionTypeEXT(rq, true) == gl_RayQueryCommittedIntersectionTriangleEXT) {
        h.t = rayQueryGetIntersectionTEXT(rq, true);
        h.tri = uint(rayQueryGetIntersectionPrimitiveIndexEXT(rq, true));
        h.bary = rayQueryGetIntersectionBarycentricsEXT(rq, true);
    }
    hits[i] = h;
}
