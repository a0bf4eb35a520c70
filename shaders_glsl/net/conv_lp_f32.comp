#version 460
// Convolution shaped for CPU drivers (llvmpipe), fp32 storage. llvmpipe runs 8 invocations as
// the lanes of one SIMD vector, so here the lanes are 8 consecutive output pixels of a row and
// each invocation holds OCN output channels in registers (OCN accumulators: ≤ ~10 fit AVX2's 16
// registers, ≤ ~24 AVX-512's 32). What Mesa 25.0 compiles well decides the rest:
// - weights are read at constant addresses, which llvmpipe
//   turns into one scalar load and a broadcast: see Wt below. So the loops over taps and input
//   channels are unrolled (K, CI4 are specialization constants) and each dispatch covers CI4
//   input channel groups of OCN output channels, whose weights are bound for it; the partial
//   sums stay in the output tensor between dispatches and the last one applies the epilogue
//   (conv.glsl's).
// - activations are read through buffer-device-address pointers: one masked gather per
//   component, instead of a per-lane loop with bounds checks.
// Each invocation computes ROWS rows, so each weight it loads serves ROWS · 4 multiply-adds.
// Dispatch grid: (ceil(out_w / 8), ceil(out_h / (4 · ROWS)), 1) per (output group, input chunk).
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_control_flow_attributes : require

layout(local_size_x = 8, local_size_y = 4) in;

layout(constant_id = 0) const uint K = 3;       // kernel size
layout(constant_id = 1) const uint STRIDE = 1;
layout(constant_id = 2) const uint OCN = 8;     // output channels per invocation (multiple of 4)
layout(constant_id = 3) const uint CI4 = 1;     // input channel groups of 4 per dispatch
layout(constant_id = 4) const uint ROWS = 1;    // output rows per invocation (weight reuse)

layout(buffer_reference, scalar, buffer_reference_align = 16) readonly buffer Act { vec4 v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 16) buffer Sums { vec4 v[]; };

// Weights pre-packed in the order this kernel reads them (conv.rs, `pack_lanes`): the window
// of one (output group, input chunk) is [tap][input channel of the chunk][OCN], bound as a
// uniform buffer at that window's offset. Every index below is then a constant, which is what
// llvmpipe needs to read a weight with one scalar load and a broadcast: it treats an address
// built from a push constant or a loop counter, or a pointer, as varying (a gather or a
// per-lane loop).
layout(set = 0, binding = 0) uniform Wt { vec4 w4[K * K * CI4 * OCN]; };
layout(set = 0, binding = 1) uniform Bias { vec4 bias4[OCN / 4]; };   // this group's

const uint FIRST = 1u;    // phase: start the sums from zero
const uint LAST = 2u;     // phase: apply the epilogue
const uint RELU = 1u;     // flags, as conv.glsl's
const uint RESIDUAL = 2u;

layout(push_constant, scalar) uniform Push {
    // Device addresses as (low, high) words: no 64-bit integers needed.
    uvec2 in_addr;        // input tensor (pack4, fp32)
    uvec2 out_addr;       // output tensor: the partial sums, then the result
    uvec2 res_addr;       // residual tensor (output shape) when flags has RESIDUAL
    uint in_w; uint in_h; uint in_c4;
    uint out_w; uint out_h; uint out_c;
    uint pad;
    uint c4;              // first input group of this dispatch
    uint oc4;             // first output group of this dispatch
    uint phase;
    uint flags;
    float in_bias; float out_bias; float scale;
} pc;

void main() {
    const uint G = OCN / 4u;
    uint ox = gl_GlobalInvocationID.x, oy0 = gl_GlobalInvocationID.y * ROWS;
    bool live_x = ox < pc.out_w;
    ox = min(ox, pc.out_w - 1u);
    uint oy[ROWS];
    [[unroll]] for (uint r = 0u; r < ROWS; ++r) oy[r] = min(oy0 + r, pc.out_h - 1u);
    Sums sums = Sums(pc.out_addr);
    uint out_c4 = (pc.out_c + 3u) / 4u;
    vec4 acc[ROWS * G];
    [[unroll]] for (uint r = 0u; r < ROWS; ++r) {
        [[unroll]] for (uint g = 0u; g < G; ++g) {
            acc[r * G + g] = vec4(0.0);
            if ((pc.phase & FIRST) == 0u && pc.oc4 + g < out_c4)
                acc[r * G + g] = sums.v[((pc.oc4 + g) * pc.out_h + oy[r]) * pc.out_w + ox];
        }
    }
    Act src = Act(pc.in_addr);
    [[unroll]] for (uint ci = 0u; ci < CI4; ++ci) {
        if (pc.c4 + ci >= pc.in_c4) break;   // uniform: the last chunk of an odd channel count
        uint plane = (pc.c4 + ci) * pc.in_h;
        [[unroll]] for (uint ky = 0u; ky < K; ++ky) {
            [[unroll]] for (uint kx = 0u; kx < K; ++kx) {
                int ix = int(ox * STRIDE + kx) - int(pc.pad);
                bool col_in = ix >= 0 && ix < int(pc.in_w);
                uint col = uint(clamp(ix, 0, int(pc.in_w) - 1));
                vec4 v[ROWS];
                [[unroll]] for (uint r = 0u; r < ROWS; ++r) {
                    int iy = int(oy[r] * STRIDE + ky) - int(pc.pad);
                    bool inside = col_in && iy >= 0 && iy < int(pc.in_h);
                    uint at = (plane + uint(clamp(iy, 0, int(pc.in_h) - 1))) * pc.in_w + col;
                    v[r] = inside ? src.v[at] + pc.in_bias : vec4(0.0);
                }
                // Each weight: one scalar load, used by every row.
                [[unroll]] for (uint i = 0u; i < 4u; ++i) {
                    [[unroll]] for (uint g = 0u; g < G; ++g) {
                        vec4 w = w4[((ky * K + kx) * 4u * CI4 + ci * 4u + i) * G + g];
                        [[unroll]] for (uint r = 0u; r < ROWS; ++r) acc[r * G + g] += v[r][i] * w;
                    }
                }
            }
        }
    }
    if (!live_x) return;
    [[unroll]] for (uint r = 0u; r < ROWS; ++r) {
        if (oy0 + r >= pc.out_h) break;
        [[unroll]] for (uint g = 0u; g < G; ++g) {
            uint oc4 = pc.oc4 + g;
            if (oc4 >= out_c4) break;   // uniform: the groups past the tensor's last
            uint o = (oc4 * pc.out_h + oy[r]) * pc.out_w + ox;
            vec4 a = acc[r * G + g];
            if ((pc.phase & LAST) != 0u) {
                a = (a + bias4[g]) * pc.scale + pc.out_bias;
                if ((pc.flags & RESIDUAL) != 0u) a += Act(pc.res_addr).v[o];
                if ((pc.flags & RELU) != 0u) a = max(a, vec4(0.0));
                uvec4 c = uvec4(0u, 1u, 2u, 3u) + oc4 * 4u;
                a = mix(vec4(0.0), a, lessThan(c, uvec4(pc.out_c)));
            }
            sums.v[o] = a;
        }
    }
}
