#version 460
// Convolution shaped for CPU drivers (llvmpipe), fp32 storage. llvmpipe runs 8 invocations as
// the lanes of one SIMD vector: here the lanes are 8 consecutive output pixels of a row, and
// each invocation computes OCN output channels × ROWS rows. What Mesa 25.0 compiles well decides
// the rest (read from GALLIVM_DEBUG=asm):
// - weights: the 8 lanes load 8 output channels' weights of one (tap, input channel) with one
//   masked gather, and subgroupBroadcast(w, j) hands weight j to every lane as one register
//   permute (a weight read from a uniform buffer cost a bounds check, a scalar load, a spill
//   and a broadcast, and needed every index constant: one dispatch per input chunk). So the
//   loop over input channels is a plain loop and a layer is one dispatch.
// - activations: read through buffer-device-address pointers (one masked gather per component,
//   not a per-lane loop with bounds checks), unconditionally at a clamped address and then
//   selected (a conditional load becomes a branch and mask bookkeeping). The ROWS output rows
//   share input rows between the vertical taps: each input row is gathered once per column tap.
// - the OCN × ROWS accumulators spill (LANES_BLOCKING in conv/lanes.rs has the measurements);
//   the spill traffic costs less than the gathers that more rows save.
// Dispatch grid: (ceil(out_w / 8), ceil(out_h / (4 · ROWS)), ceil(out_c / OCN)).
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_KHR_shader_subgroup_ballot : require

layout(local_size_x = 8, local_size_y = 4) in;

layout(constant_id = 0) const uint K = 3;       // kernel size
layout(constant_id = 1) const uint STRIDE = 1;
layout(constant_id = 2) const uint OCN = 8;     // output channels per invocation (multiple of 8)
layout(constant_id = 3) const uint ROWS = 2;    // output rows per invocation (weight reuse)

layout(buffer_reference, scalar, buffer_reference_align = 16) readonly buffer Act { vec4 v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 16) writeonly buffer Out { vec4 v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 4) readonly buffer Wts { float v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 16) readonly buffer Bias { vec4 v[]; };

const uint RELU = 1u;     // flags, as conv.glsl's
const uint RESIDUAL = 2u;

layout(push_constant, scalar) uniform Push {
    // Device addresses as (low, high) words: no 64-bit integers needed.
    uvec2 in_addr;        // input tensor (pack4, fp32)
    uvec2 out_addr;       // output tensor (pack4, fp32)
    uvec2 res_addr;       // residual tensor (output shape) when flags has RESIDUAL
    uvec2 w_addr;         // weights, [OCN group][c4][tap][4 input channels][OCN] (conv/mod.rs)
    uvec2 bias_addr;      // bias per output channel, padded to OCN
    uint in_w; uint in_h; uint in_c4;
    uint out_w; uint out_h; uint out_c;
    uint pad;
    uint flags;
    float in_bias; float out_bias; float scale;
} pc;

void main() {
    const uint G = OCN / 4u;      // vec4 accumulators per row
    const uint TAPS = K * K;
    uint ox = gl_GlobalInvocationID.x, oy0 = gl_GlobalInvocationID.y * ROWS;
    uint og = gl_WorkGroupID.z;   // output channel group of OCN
    bool live_x = ox < pc.out_w;
    ox = min(ox, pc.out_w - 1u);
    vec4 acc[ROWS * G];
    [[unroll]] for (uint a = 0u; a < ROWS * G; ++a) acc[a] = vec4(0.0);

    Act src = Act(pc.in_addr);
    Wts wts = Wts(pc.w_addr);
    // Lane l of every 8 reads output channel l of each group of 8.
    uint lane = gl_SubgroupInvocationID & 7u;
    uint wi = og * pc.in_c4 * TAPS * 4u * OCN + lane;
    // The input rows the ROWS output rows read: rows overlap between taps, so each is gathered
    // once per column tap. (Also sharing them between column taps, by shifting the kx = 0 row
    // 1 and 2 lanes with subgroupShuffle, was slower: llvmpipe's shuffle costs more than the
    // gather it saves.)
    const uint IN_ROWS = (ROWS - 1u) * STRIDE + K;
    int iy0 = int(oy0 * STRIDE) - int(pc.pad);
    for (uint c = 0u; c < pc.in_c4; ++c) {
        uint plane = c * pc.in_h;
        [[unroll]] for (uint kx = 0u; kx < K; ++kx) {
            int ix = int(ox * STRIDE + kx) - int(pc.pad);
            bool col_in = ix >= 0 && ix < int(pc.in_w);
            uint col = uint(clamp(ix, 0, int(pc.in_w) - 1));
            vec4 v[IN_ROWS];
            [[unroll]] for (uint t = 0u; t < IN_ROWS; ++t) {
                int iy = iy0 + int(t);
                bool inside = col_in && iy >= 0 && iy < int(pc.in_h);
                uint at = (plane + uint(clamp(iy, 0, int(pc.in_h) - 1))) * pc.in_w + col;
                // Loaded unconditionally (the address is clamped) and then selected: a
                // conditional load would become a branch and mask bookkeeping.
                vec4 s = src.v[at] + pc.in_bias;
                v[t] = mix(vec4(0.0), s, bvec4(inside));
            }
            [[unroll]] for (uint ky = 0u; ky < K; ++ky) {
                uint wt = wi + (ky * K + kx) * 4u * OCN;
                [[unroll]] for (uint i = 0u; i < 4u; ++i) {
                    [[unroll]] for (uint h = 0u; h < OCN / 8u; ++h) {
                        float w8 = wts.v[wt + (i * OCN + h * 8u)];
                        [[unroll]] for (uint j = 0u; j < 8u; ++j) {
                            float w = subgroupBroadcast(w8, j);
                            uint a = h * 2u + j / 4u;
                            [[unroll]] for (uint r = 0u; r < ROWS; ++r)
                                acc[r * G + a][j % 4u] += v[r * STRIDE + ky][i] * w;
                        }
                    }
                }
            }
        }
        wi += TAPS * 4u * OCN;
    }
    if (!live_x) return;
    uint out_c4 = (pc.out_c + 3u) / 4u;
    [[unroll]] for (uint r = 0u; r < ROWS; ++r) {
        if (oy0 + r >= pc.out_h) break;
        [[unroll]] for (uint g = 0u; g < G; ++g) {
            uint oc4 = og * G + g;
            if (oc4 >= out_c4) break;
            uint o = (oc4 * pc.out_h + oy0 + r) * pc.out_w + ox;
            vec4 a = (acc[r * G + g] + Bias(pc.bias_addr).v[oc4]) * pc.scale + pc.out_bias;
            if ((pc.flags & RESIDUAL) != 0u) a += Act(pc.res_addr).v[o];
            if ((pc.flags & RELU) != 0u) a = max(a, vec4(0.0));
            uvec4 ch = uvec4(0u, 1u, 2u, 3u) + oc4 * 4u;
            Out(pc.out_addr).v[o] = mix(vec4(0.0), a, lessThan(ch, uvec4(pc.out_c)));
        }
    }
}
