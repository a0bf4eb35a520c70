#version 460
// Source mirror image M_src of one input view (§4.2.1, Fig. 5–6): one ray per pixel in the
// mirror direction at the first surface; its hit y takes the colour of the view (other than
// this one) whose viewing direction onto y is closest to the reflected ray, among the views that
// see y.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 1
#include "views.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 5) writeonly buffer Out { vec4 mirror[]; };   // rgb, w = 1 if found

layout(push_constant) uniform Push { uint view; uint width; uint height; uint nviews; } pc;

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    uint gi = pc.view * npix + p;
    vec4 xp = gpos[gi];
    mirror[p] = vec4(0.0);
    if (xp.w <= 0.0) return;
    vec3 x = xp.xyz;
    vec3 n = gnrm[gi].xyz;
    vec3 eye = cam_center(cams[pc.view]);
    if (dot(n, eye - x) < 0.0) n = -n;
    vec3 r = reflect(normalize(x - eye), n);
    rayQueryEXT rq;
    rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFF, x + n * 1e-3, 1e-3, r, 1e4);
    while (rayQueryProceedEXT(rq)) {}
    if (rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionTriangleEXT) return;
    vec3 y = x + n * 1e-3 + r * rayQueryGetIntersectionTEXT(rq, true);
    int q = best_view(y, r, pc.view, pc.nviews, pc.width, pc.height);
    if (q >= 0) mirror[p] = vec4(images[q].rgb, 1.0);
}
