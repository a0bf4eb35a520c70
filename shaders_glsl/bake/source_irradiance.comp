#version 460
// Source irradiance E_src of one input view (§4.1.1, Fig. 3). For each pixel's point x on the
// proxy mesh, SAMPLES cosine-weighted rays; each hit y takes its radiance from the input view
// (other than this one) whose camera→y direction is closest to the ray, among the views that see
// y. Rays without such a view are dropped and the estimate renormalized: E = π · mean(L).
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 1
#include "views.glsl"
#include "random.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 5) writeonly buffer Out { vec4 e_src[]; };   // rgb, w = valid rays

layout(push_constant) uniform Push {
    uint view; uint width; uint height; uint nviews; uint samples; uint seed;
} pc;

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    uint gi = pc.view * npix + p;
    vec4 xp = gpos[gi];
    if (xp.w <= 0.0) { e_src[p] = vec4(0.0); return; }
    vec3 x = xp.xyz;
    vec3 n = gnrm[gi].xyz;
    vec3 eye = cam_center(cams[pc.view]);
    if (dot(n, eye - x) < 0.0) n = -n;   // the side the camera sees
    vec3 sum = vec3(0.0);
    uint valid = 0u;
    for (uint s = 0u; s < pc.samples; ++s) {
        vec3 d = cosine_dir(n, rand2(uvec3(gi, s, pc.seed)));
        rayQueryEXT rq;
        rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFF, x + n * 1e-3, 1e-3, d, 1e4);
        while (rayQueryProceedEXT(rq)) {}
        if (rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionTriangleEXT) continue;
        vec3 y = x + n * 1e-3 + d * rayQueryGetIntersectionTEXT(rq, true);
        int best_px = best_view(y, d, pc.view, pc.nviews, pc.width, pc.height);
        if (best_px < 0) continue;
        sum += images[best_px].rgb;
        valid += 1u;
    }
    e_src[p] = vec4(valid > 0u ? 3.14159265359 * sum / float(valid) : vec3(0.0), float(valid));
}
