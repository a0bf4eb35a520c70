// Shared by gemm.comp (portable) and gemm_cm.comp (cooperative matrix): the bindings, the push
// block and the tiling. One workgroup computes one TILE x TILE block of C = A * B; the dispatch
// grid is (N / TILE, M / TILE) for both backends. A is M x K and B is K x N, row-major fp16;
// C is M x N, row-major fp32. M, N and K are multiples of TILE (callers pad).
#ifndef RELIT_GEMM_TILE_GLSL
#define RELIT_GEMM_TILE_GLSL

#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_shader_16bit_storage : require

const uint TILE = 16;

layout(set = 0, binding = 0) readonly buffer MatA { float16_t a[]; };
layout(set = 0, binding = 1) readonly buffer MatB { float16_t b[]; };
layout(set = 0, binding = 2) writeonly buffer MatC { float c[]; };

layout(push_constant) uniform Push { uint M; uint N; uint K; } pc;

// Row and column of this workgroup's tile's first element.
uvec2 tile_origin() { return uvec2(gl_WorkGroupID.y * TILE, gl_WorkGroupID.x * TILE); }

#endif
