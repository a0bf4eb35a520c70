#version 460
// Cooperative-matrix GEMM (VK_KHR_cooperative_matrix): one subgroup per tile, fp16 A/B, fp32
// accumulators. Same bindings, push block and tiling as gemm.comp, whose reflected layout this
// module uses. Needs a device with a 16x16x16 fp16 subgroup shape and a subgroup size of 32.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_cooperative_matrix : require
#extension GL_KHR_memory_scope_semantics : require
#include "gemm_tile.glsl"

layout(local_size_x = 32) in;

void main() {
    uvec2 o = tile_origin();
    coopmat<float, gl_ScopeSubgroup, TILE, TILE, gl_MatrixUseAccumulator> acc =
        coopmat<float, gl_ScopeSubgroup, TILE, TILE, gl_MatrixUseAccumulator>(0.0);
    for (uint k = 0u; k < pc.K; k += TILE) {
        coopmat<float16_t, gl_ScopeSubgroup, TILE, TILE, gl_MatrixUseA> ma;
        coopmat<float16_t, gl_ScopeSubgroup, TILE, TILE, gl_MatrixUseB> mb;
        coopMatLoad(ma, a, o.x * pc.K + k, pc.K, gl_CooperativeMatrixLayoutRowMajor);
        coopMatLoad(mb, b, k * pc.N + o.y, pc.N, gl_CooperativeMatrixLayoutRowMajor);
        acc = coopMatMulAdd(ma, mb, acc);
    }
    coopMatStore(acc, c, o.x * pc.N + o.y, pc.N, gl_CooperativeMatrixLayoutRowMajor);
}
