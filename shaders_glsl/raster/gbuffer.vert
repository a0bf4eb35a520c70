#version 460
// G-buffer of a mesh seen from a camera: rasterized with the camera's exact pinhole projection
// so that pixel (i, j) samples the ray through (i + 0.5, j + 0.5). Drawn without index buffer
// from the mesh's corners (RayScene::corners: position and face normal per triangle corner):
// vertex k of the draw is corner k % 3 of triangle k / 3, which gives the fragment shader the
// triangle id without gl_PrimitiveID (that would need the geometryShader feature), and no
// shader reads a storage buffer (a per-lane loop per load on Mesa 25's llvmpipe).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_scalar_block_layout : require
#include "camera.glsl"

layout(push_constant, scalar) uniform Push { Camera cam; } pc;
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 face_normal;

layout(location = 0) out vec3 world_pos;
layout(location = 1) out float cam_z;
layout(location = 2) flat out uint tri;
layout(location = 3) flat out vec3 normal;

void main() {
    vec3 q = cam_from_world(pc.cam, position);
    vec2 size = pc.cam.size_clip.xy;
    float n = pc.cam.size_clip.z, f = pc.cam.size_clip.w;
    // Clip space from intrinsics: x_ndc = 2 u / W - 1 with u = fx x / z + cx (Vulkan's y points
    // down like OpenCV's); depth maps [near, far] to [0, 1].
    gl_Position = vec4(
        2.0 * pc.cam.intrinsics.x / size.x * q.x + (2.0 * pc.cam.intrinsics.z / size.x - 1.0) * q.z,
        2.0 * pc.cam.intrinsics.y / size.y * q.y + (2.0 * pc.cam.intrinsics.w / size.y - 1.0) * q.z,
        f / (f - n) * q.z - f * n / (f - n),
        q.z);
    world_pos = position;
    cam_z = q.z;
    tri = uint(gl_VertexIndex) / 3u;
    normal = face_normal;
}
