#version 460
// Radiance mesh (§4.1.1's gathering, for the points no view sees; radiance_mesh.rs): each
// proxy-mesh vertex averages the radiance I_j of the views j that see it (depth test), weighted
// by the inverse distance to camera j, leaving out pixels on or beside a declared light.
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 0
#include "views.glsl"
#include "lights.glsl"

layout(set = 0, binding = 4, scalar) readonly buffer Verts { vec3 verts[]; };
layout(set = 0, binding = 5, scalar) readonly buffer Lights { Light lights[]; };
layout(set = 0, binding = 6) writeonly buffer Out { vec4 radiance[]; };   // rgb, w = weight sum

#include "near_light.glsl"

layout(push_constant) uniform Push { uint nverts; uint width; uint height; uint nviews; uint nlights; } pc;

void main() {
    uint v = gl_GlobalInvocationID.x;
    if (v >= pc.nverts) return;
    vec3 p = verts[v];
    vec3 sum = vec3(0.0);
    float wsum = 0.0;
    for (uint j = 0u; j < pc.nviews; ++j) {
        int q = visible_pixel(j, p, pc.width, pc.height);
        if (q < 0 || clipped(q) || near_light(q, pc.width, pc.height, pc.nlights)) continue;
        float w = 1.0 / max(distance(cam_center(cams[j]), p), 1e-3);
        sum += w * images[q].rgb;
        wsum += w;
    }
    radiance[v] = vec4(wsum > 0.0 ? sum / wsum : vec3(0.0), wsum);
}
