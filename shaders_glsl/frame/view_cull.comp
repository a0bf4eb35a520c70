#version 460
// Per-frame view culling (§4.3 at the paper's scale, 250–350 views): which input views see which
// of a coarse grid of the novel view's surface points, by the same depth test the composites
// use. frame/view_cull.rs chooses the frame's active views from these bits on the host.
// One invocation per (view j, word w): the 32 grid points w*32 .. w*32+31, bit k set when view j
// sees point w*32+k. The invocations of view 0 also write the points (w = 0: no surface).
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#include "frame.glsl"

layout(set = 0, binding = 27) writeonly buffer CullSeen { uint seen[]; };
layout(set = 0, binding = 28) writeonly buffer CullPoints { vec4 points[]; };

layout(push_constant) uniform Push {
    vec4 eye;
    uint width; uint height; uint grid_w; uint grid_h;
    uint nviews; uint view_w; uint view_h; uint words;
} pc;

// The novel-view pixel of grid point s: the pixel under the centre of its grid cell.
uint grid_pixel(uint s) {
    uint gx = s % pc.grid_w, gy = s / pc.grid_w;
    uint x = ((2u * gx + 1u) * pc.width) / (2u * pc.grid_w);
    uint y = ((2u * gy + 1u) * pc.height) / (2u * pc.grid_h);
    return y * pc.width + x;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.words * pc.nviews) return;
    uint j = i / pc.words, w = i % pc.words;
    uint npts = pc.grid_w * pc.grid_h;
    uint bits = 0u;
    for (uint k = 0u; k < 32u; ++k) {
        uint s = w * 32u + k;
        if (s >= npts) break;
        vec3 x, n;
        float depth;
        bool hit = surface(grid_pixel(s), pc.width, pc.eye.xyz, x, n, depth);
        if (j == 0u) points[s] = hit ? vec4(x, 1.0) : vec4(0.0);
        if (hit && visible_pixel(j, x, pc.view_w, pc.view_h) >= 0) bits |= 1u << k;
    }
    seen[i] = bits;
}
