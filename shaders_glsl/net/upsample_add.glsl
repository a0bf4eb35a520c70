// Bilinear upsampling of a pyramid level to full size, added into the running sum (§5.1):
// dst += up(src). Sampling matches PyTorch's interpolate(mode="bilinear", align_corners=False):
// source coordinate (d + 0.5) * in/out - 0.5, clamped at 0, neighbours clamped to the edge.
// Tensors in pack4 layout (conv.glsl). One invocation per destination pixel and channel group.
#include "act_storage.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Src { ACT4 src[]; };
layout(set = 0, binding = 1) buffer Dst { ACT4 dst[]; };

layout(push_constant) uniform Push { uint src_w; uint src_h; uint dst_w; uint dst_h; uint c4; } pc;

float src_coord(uint d, uint n_in, uint n_out, out uint i0, out uint i1) {
    float s = max((float(d) + 0.5) * float(n_in) / float(n_out) - 0.5, 0.0);
    i0 = min(uint(s), n_in - 1u);
    i1 = min(i0 + 1u, n_in - 1u);
    return s - float(i0);
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint hw = pc.dst_w * pc.dst_h;
    if (i >= hw * pc.c4) return;
    uint c = i / hw, xy = i % hw, dx = xy % pc.dst_w, dy = xy / pc.dst_w;
    uint x0, x1, y0, y1;
    float fx = src_coord(dx, pc.src_w, pc.dst_w, x0, x1);
    float fy = src_coord(dy, pc.src_h, pc.dst_h, y0, y1);
    uint b = c * pc.src_h;
    vec4 top = mix(vec4(src[(b + y0) * pc.src_w + x0]), vec4(src[(b + y0) * pc.src_w + x1]), fx);
    vec4 bot = mix(vec4(src[(b + y1) * pc.src_w + x0]), vec4(src[(b + y1) * pc.src_w + x1]), fx);
    dst[i] = ACT4(vec4(dst[i]) + mix(top, bot, fy));
}
