#version 460
// Convolution, cooperative-matrix backend (VK_KHR_cooperative_matrix), fp16 storage: an implicit
// GEMM. A workgroup (one subgroup) computes 16 output pixels of a row x the 16 output channels of
// one block, as MT x NT tiles of the device's shape (coop_shape.glsl). For every tap and every 16
// input channels, the 16 x 16 input block (pixels x channels, with bias and zero padding applied
// as in the portable body) is staged in shared memory once; the B tiles are read straight from
// the packed weights, each one reused by the MT pixel tiles. Same bindings, push block, packing
// and epilogue as conv.comp, whose reflected layout this module uses.
// Dispatch grid: (ceil(out_w / 16), out_h, output blocks).
#extension GL_GOOGLE_include_directive : require
#include "conv.glsl"
#include "coop_shape.glsl"

// The weights as fp16 scalars for coopMatLoad (same buffer as w4).
layout(set = 0, binding = 1) readonly buffer WtS { float16_t ws[]; };

shared float16_t a_tile[16 * 16];
shared float c_tile[16 * 16];

// Stages input channels icb..icb+15 of 16 pixels for one tap, in pixel-major rows.
void stage_input(uint ox0, uint oy, uint kx, uint ky, uint icb) {
    int iy = int(oy * pc.stride + ky) - int(pc.pad);
    for (uint e = gl_LocalInvocationID.x; e < 256u; e += SG) {
        uint p = e / 16u, ic = icb + e % 16u;
        float v = 0.0;
        if (ic < pc.in_c4 * 4u) {
            int ix = int((ox0 + p) * pc.stride + kx) - int(pc.pad);
            v = sample_in(ic / 4u, ix, iy)[ic % 4u];
        }
        a_tile[e] = float16_t(v);
    }
}

void main() {
    uint ox0 = gl_WorkGroupID.x * 16u;
    uint oy = gl_WorkGroupID.y;
    uint ocb = pc.ocb_base + gl_WorkGroupID.z;
    COOP_C acc[MT][NT];
    for (uint m = 0u; m < MT; ++m)
        for (uint n = 0u; n < NT; ++n) acc[m][n] = COOP_C(0.0);
    uint taps = pc.ksize * pc.ksize;
    for (uint tap = 0u; tap < taps; ++tap) {
        for (uint icb = 0u; icb < pc.icp; icb += 16u) {
            stage_input(ox0, oy, tap % pc.ksize, tap / pc.ksize, icb);
            barrier();
            for (uint kk = 0u; kk < 16u; kk += TK) {
                COOP_A ma[MT];
                for (uint m = 0u; m < MT; ++m)
                    coopMatLoad(ma[m], a_tile, m * TM * 16u + kk, 16, gl_CooperativeMatrixLayoutRowMajor);
                uint wi = weight_index(ocb, tap, icb + kk) * 4u;
                for (uint n = 0u; n < NT; ++n) {
                    COOP_B mb;
                    coopMatLoad(mb, ws, wi + n * TN, OCB, gl_CooperativeMatrixLayoutRowMajor);
                    for (uint m = 0u; m < MT; ++m) acc[m][n] = coopMatMulAdd(ma[m], mb, acc[m][n]);
                }
            }
            barrier();
        }
    }
    for (uint m = 0u; m < MT; ++m)
        for (uint n = 0u; n < NT; ++n)
            coopMatStore(acc[m][n], c_tile, m * TM * 16u + n * TN, 16, gl_CooperativeMatrixLayoutRowMajor);
    barrier();
    uint oc4_end = (pc.out_c + 3u) / 4u;
    for (uint e = gl_LocalInvocationID.x; e < 64u; e += SG) {
        uint p = e / 4u, j = e % 4u, oc4 = ocb * 4u + j;
        if (ox0 + p >= pc.out_w || oc4 >= oc4_end) continue;
        uint c = p * 16u + j * 4u;
        store(oc4, ox0 + p, oy, vec4(c_tile[c], c_tile[c + 1u], c_tile[c + 2u], c_tile[c + 3u]));
    }
}
