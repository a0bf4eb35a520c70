#version 460
// Source irradiance (§4.1.1) at proxy-mesh vertices instead of pixels, for the radiance mesh:
// the points no view sees get their radiance as albedo × this irradiance / π
// (radiance_mesh.rs). No view is excluded; each vertex is estimated on the side of its normal.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 1
#include "source_irradiance.glsl"

layout(set = 0, binding = 9, scalar) readonly buffer Verts { vec3 verts[]; };
layout(set = 0, binding = 10) readonly buffer Normals { vec4 normals[]; };

// Random streams of vertices start past every pixel's (keys are pixel indices there).
const uint VERTEX_KEY = 0x80000000u;

void main() {
    uint v = pc.view + gl_GlobalInvocationID.x;
    if (gl_GlobalInvocationID.x >= pc.count) return;
    vec3 n = normals[v].xyz;
    if (dot(n, n) < 0.5) { e_src[gl_GlobalInvocationID.x] = vec4(0.0); return; }
    e_src[gl_GlobalInvocationID.x] = source_irradiance(verts[v], n, 0xFFFFFFFFu, VERTEX_KEY + v);
}
