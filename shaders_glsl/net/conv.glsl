// Shared by every convolution backend (conv.comp portable fp16, conv_f32.comp portable fp32,
// conv_cm.comp cooperative matrix): bindings, push block, tensor layout, weight packing and the
// fused epilogue. Used for the 3x3 convs of the fixup blocks, the 4x4 stride-2 downsampling convs
// and the output conv (§5.1).
//
// Tensors are "pack4": channel groups of 4, one vec4 per pixel, index (c4 * H + y) * W + x.
// Weights are packed by tools at load time in the order the kernels read them:
//   [ocb][tap = ky * K + kx][ic (padded to 16)][16 output channels of block ocb]
// so one input channel's 16 output weights are contiguous (4 vec4 for the portable loop, one row
// of the 16x16 B tile for the cooperative-matrix loop). Padding weights are zero, so padded
// input channels never reach a real output.
#ifndef RELIT_CONV_GLSL
#define RELIT_CONV_GLSL

#include "act_storage.glsl"
#ifdef STORE_F32
#define WVEC4 vec4
#else
#define WVEC4 f16vec4
#endif

layout(set = 0, binding = 0) readonly buffer In { ACT4 x[]; };
layout(set = 0, binding = 1) readonly buffer Wt { WVEC4 w4[]; };
layout(set = 0, binding = 2) readonly buffer Bias { vec4 bias4[]; };   // per output channel
layout(set = 0, binding = 3) readonly buffer Res { ACT4 res[]; };      // residual, output shape
layout(set = 0, binding = 4) writeonly buffer Out { ACT4 y[]; };

const uint RELU = 1u;
const uint RESIDUAL = 2u;
// Output channels per block (and per portable invocation).
const uint OCB = 16u;

layout(push_constant) uniform Push {
    uint in_w; uint in_h; uint in_c4;
    uint out_w; uint out_h; uint out_c;     // out_c: real channels (padding is written as 0)
    uint ksize; uint stride; uint pad;
    uint icp;                              // input channels padded to 16: the weights' K stride
    float in_bias;                         // added to every input sample inside the image
    float out_bias;                        // added after the scale
    float scale;
    uint flags;
    uint ocb_base;                         // first output block of this dispatch
} pc;

// Vec4 index of the weights of (ocb, tap, ic), output channels 4j..4j+3 of the block at + j.
uint weight_index(uint ocb, uint tap, uint ic) {
    return ((ocb * pc.ksize * pc.ksize + tap) * pc.icp + ic) * (OCB / 4u);
}

// y = relu?((acc + bias) * scale + out_bias + residual?), zero on padding channels.
void store(uint oc4, uint ox, uint oy, vec4 acc) {
    uint o = (oc4 * pc.out_h + oy) * pc.out_w + ox;
    vec4 v = (acc + bias4[oc4]) * pc.scale + pc.out_bias;
    if ((pc.flags & RESIDUAL) != 0u) v += vec4(res[o]);
    if ((pc.flags & RELU) != 0u) v = max(v, vec4(0.0));
    uvec4 c = uvec4(0u, 1u, 2u, 3u) + oc4 * 4u;
    v = mix(vec4(0.0), v, lessThan(c, uvec4(pc.out_c)));
    y[o] = ACT4(v);
}

// The input sample (4 channels) at (ix, iy) with the input bias; zero padding outside.
vec4 sample_in(uint c4, int ix, int iy) {
    if (ix < 0 || iy < 0 || ix >= int(pc.in_w) || iy >= int(pc.in_h)) return vec4(0.0);
    return vec4(x[(c4 * pc.in_h + uint(iy)) * pc.in_w + uint(ix)]) + pc.in_bias;
}

#endif
