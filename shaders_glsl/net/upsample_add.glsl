// Bilinear upsampling of a pyramid level to full size, added into the running sum (§5.1):
// dst += up(src). Sampling matches PyTorch's interpolate(mode="bilinear", align_corners=False):
// source coordinate (d + 0.5) * in/out - 0.5, clamped at 0, neighbours clamped to the edge.
// Tensors in pack4 layout (conv.glsl). One invocation per destination pixel and channel group.
// UP_POINTERS (upsample_add_lp_f32.comp, CPU devices): the tensors through buffer-device-address
// pointers, whose addresses lead the push block. On Mesa 25.0 a storage binding read at a
// per-invocation index is a loop over the lanes with a bounds check each; a pointer read is one
// masked gather (see conv_lp_f32.comp).
#include "act_storage.glsl"
#ifdef UP_POINTERS
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference_uvec2 : require
#endif

layout(local_size_x = 64) in;

#ifdef UP_POINTERS
layout(buffer_reference, scalar, buffer_reference_align = 16) readonly buffer Src { ACT4 v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 16) buffer Dst { ACT4 v[]; };
layout(push_constant, scalar) uniform Push {
    uvec2 src_addr; uvec2 dst_addr;   // (low, high) words
    uint src_w; uint src_h; uint dst_w; uint dst_h; uint c4;
} pc;
#define SRC(i) Src(pc.src_addr).v[i]
#define DST(i) Dst(pc.dst_addr).v[i]
#else
layout(set = 0, binding = 0) readonly buffer Src { ACT4 src[]; };
layout(set = 0, binding = 1) buffer Dst { ACT4 dst[]; };
layout(push_constant) uniform Push { uint src_w; uint src_h; uint dst_w; uint dst_h; uint c4; } pc;
#define SRC(i) src[i]
#define DST(i) dst[i]
#endif

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
    vec4 top = mix(vec4(SRC((b + y0) * pc.src_w + x0)), vec4(SRC((b + y0) * pc.src_w + x1)), fx);
    vec4 bot = mix(vec4(SRC((b + y1) * pc.src_w + x0)), vec4(SRC((b + y1) * pc.src_w + x1)), fx);
    DST(i) = ACT4(vec4(DST(i)) + mix(top, bot, fy));
}
