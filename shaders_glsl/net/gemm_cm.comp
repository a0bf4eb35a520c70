#version 460
// Cooperative-matrix GEMM (VK_KHR_cooperative_matrix): one subgroup per 16 x 16 tile of C, as
// MT x NT tiles of the device's shape (coop_shape.glsl), fp16 A/B, fp32 accumulators. Same
// bindings, push block and tiling as gemm.comp, whose reflected layout this module uses.
#extension GL_GOOGLE_include_directive : require
#include "gemm_tile.glsl"
#include "coop_shape.glsl"

void main() {
    uvec2 o = tile_origin();
    COOP_C acc[MT][NT];
    for (uint m = 0u; m < MT; ++m)
        for (uint n = 0u; n < NT; ++n) acc[m][n] = COOP_C(0.0);
    for (uint k = 0u; k < pc.K; k += TK) {
        COOP_A ma[MT];
        for (uint m = 0u; m < MT; ++m)
            coopMatLoad(ma[m], a, (o.x + m * TM) * pc.K + k, pc.K, gl_CooperativeMatrixLayoutRowMajor);
        for (uint n = 0u; n < NT; ++n) {
            COOP_B mb;
            coopMatLoad(mb, b, k * pc.N + o.y + n * TN, pc.N, gl_CooperativeMatrixLayoutRowMajor);
            for (uint m = 0u; m < MT; ++m) acc[m][n] = coopMatMulAdd(ma[m], mb, acc[m][n]);
        }
    }
    for (uint m = 0u; m < MT; ++m)
        for (uint n = 0u; n < NT; ++n)
            coopMatStore(acc[m][n], c, (o.x + m * TM) * pc.N + o.y + n * TN, pc.N,
                         gl_CooperativeMatrixLayoutRowMajor);
}
