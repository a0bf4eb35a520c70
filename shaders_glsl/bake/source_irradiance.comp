#version 460
// Source irradiance E_src of one input view (§4.1.1, Fig. 3) at each pixel's point on the proxy
// mesh; the estimator is source_irradiance.glsl's.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 1
#include "source_irradiance.glsl"

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    uint gi = pc.view * npix + p;
    vec4 xp = gpos[gi];
    if (xp.w <= 0.0) { e_src[p] = vec4(0.0); return; }
    vec3 n = gnrm[gi].xyz;
    if (dot(n, cam_center(cams[pc.view]) - xp.xyz) < 0.0) n = -n;   // the side the camera sees
    e_src[p] = source_irradiance(xp.xyz, n, pc.view, gi);
}
