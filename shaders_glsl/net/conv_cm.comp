#version 460
// Convolution, cooperative-matrix backend (VK_KHR_cooperative_matrix), fp16 storage: an implicit
// GEMM. One 32-wide subgroup computes 16 output pixels of a row x the 16 output channels of one
// block: for every tap and every 16 input channels, the 16x16 input tile (pixels x channels, with
// bias and zero padding applied as in the portable body) is staged in shared memory and
// multiplied with the 16x16 weight tile read straight from the packed weights. Same bindings,
// push block, packing and epilogue as conv.comp, whose reflected layout this module uses.
// Dispatch grid: (ceil(out_w / 16), out_h, output blocks).
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_cooperative_matrix : require
#extension GL_KHR_memory_scope_semantics : require
#include "conv.glsl"

layout(local_size_x = 32) in;

// The weights as fp16 scalars for coopMatLoad (same buffer as w4).
layout(set = 0, binding = 1) readonly buffer WtS { float16_t ws[]; };

shared float16_t a_tile[16 * 16];
shared float c_tile[16 * 16];

void main() {
    uint ox0 = gl_WorkGroupID.x * 16u;
    uint oy = gl_WorkGroupID.y;
    uint ocb = pc.ocb_base + gl_WorkGroupID.z;
    uint lid = gl_LocalInvocationID.x;
    coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator> acc =
        coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator>(0.0);
    uint taps = pc.ksize * pc.ksize;
    for (uint tap = 0u; tap < taps; ++tap) {
        uint ky = tap / pc.ksize, kx = tap % pc.ksize;
        int iy = int(oy * pc.stride + ky) - int(pc.pad);
        for (uint icb = 0u; icb < pc.icp; icb += 16u) {
            for (uint e = lid; e < 256u; e += 32u) {
                uint p = e / 16u, ic = icb + e % 16u;
                float v = 0.0;
                if (ic < pc.in_c4 * 4u) {
                    int ix = int((ox0 + p) * pc.stride + kx) - int(pc.pad);
                    v = sample_in(ic / 4u, ix, iy)[ic % 4u];
                }
                a_tile[e] = float16_t(v);
            }
            barrier();
            coopmat<float16_t, gl_ScopeSubgroup, 16, 16, gl_MatrixUseA> ma;
            coopmat<float16_t, gl_ScopeSubgroup, 16, 16, gl_MatrixUseB> mb;
            coopMatLoad(ma, a_tile, 0, 16, gl_CooperativeMatrixLayoutRowMajor);
            coopMatLoad(mb, ws, weight_index(ocb, tap, icb) * 4u, OCB, gl_CooperativeMatrixLayoutRowMajor);
            acc = coopMatMulAdd(ma, mb, acc);
            barrier();
        }
    }
    coopMatStore(acc, c_tile, 0, 16, gl_CooperativeMatrixLayoutRowMajor);
    barrier();
    uint oc4_end = (pc.out_c + 3u) / 4u;
    for (uint e = lid; e < 64u; e += 32u) {
        uint p = e / 4u, j = e % 4u, oc4 = ocb * 4u + j;
        if (ox0 + p >= pc.out_w || oc4 >= oc4_end) continue;
        uint c = p * 16u + j * 4u;
        store(oc4, ox0 + p, oy, vec4(c_tile[c], c_tile[c + 1u], c_tile[c + 2u], c_tile[c + 3u]));
    }
}
