#version 460
// Writes world position + camera depth, the triangle's geometric normal (winding order,
// counter-clockwise = front; computed per triangle with the mesh's corners), and the triangle
// id + 1 (0 = background).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#include "camera.glsl"

layout(push_constant, scalar) uniform Push { Camera cam; } pc;

layout(location = 0) in vec3 world_pos;
layout(location = 1) in float cam_z;
layout(location = 2) flat in uint tri;
layout(location = 3) flat in vec3 normal;
layout(location = 0) out vec4 out_pos_depth;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out uint out_tri;

void main() {
    out_pos_depth = vec4(world_pos, cam_z);
    out_normal = vec4(normal, 0.0);
    out_tri = tri + 1u;
}
