#version 460
// Upsample-and-add for CPU drivers, fp32 storage: upsample_add.glsl's arithmetic, with the
// tensors read and written through buffer-device-address pointers. On Mesa 25.0 a storage
// binding read at a per-invocation index is a loop over the lanes with a bounds check each; a
// pointer read is one masked gather (see conv_lp_f32.comp).
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference_uvec2 : require

layout(local_size_x = 64) in;

layout(buffer_reference, scalar, buffer_reference_align = 16) readonly buffer Src { vec4 v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 16) buffer Dst { vec4 v[]; };

layout(push_constant, scalar) uniform Push {
    uvec2 src_addr; uvec2 dst_addr;   // device addresses as (low, high) words
    uint src_w; uint src_h; uint dst_w; uint dst_h; uint c4;
} pc;

// PyTorch's bilinear source coordinate (align_corners=False), as upsample_add.glsl.
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
    Src src = Src(pc.src_addr);
    vec4 top = mix(src.v[(b + y0) * pc.src_w + x0], src.v[(b + y0) * pc.src_w + x1], fx);
    vec4 bot = mix(src.v[(b + y1) * pc.src_w + x0], src.v[(b + y1) * pc.src_w + x1], fx);
    Dst dst = Dst(pc.dst_addr);
    dst.v[i] += mix(top, bot, fy);
}
