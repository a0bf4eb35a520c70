// The cooperative-matrix shape a kernel runs with, chosen by the engine from what the device
// reports (net::CoopTile) and passed as specialization constants: one subgroup of SG lanes per
// workgroup, fp16 A (TM x TK) and B (TK x TN) tiles, fp32 accumulators (TM x TN). A workgroup
// always covers a 16 x 16 block of the output, as MT x NT accumulator tiles, so the packing,
// the padding and the dispatch grid are those of the portable kernels for every shape; the
// engine only picks shapes whose sides divide 16.
#ifndef RELIT_COOP_SHAPE_GLSL
#define RELIT_COOP_SHAPE_GLSL

#extension GL_KHR_cooperative_matrix : require
#extension GL_KHR_memory_scope_semantics : require

layout(local_size_x_id = 0) in;
layout(constant_id = 0) const uint SG = 32;
layout(constant_id = 1) const uint TM = 16;
layout(constant_id = 2) const uint TN = 16;
layout(constant_id = 3) const uint TK = 16;
const uint MT = 16 / TM;
const uint NT = 16 / TN;

#define COOP_A coopmat<float16_t, gl_ScopeSubgroup, TM, TK, gl_MatrixUseA>
#define COOP_B coopmat<float16_t, gl_ScopeSubgroup, TK, TN, gl_MatrixUseB>
#define COOP_C coopmat<float, gl_ScopeSubgroup, TM, TN, gl_MatrixUseAccumulator>

#endif
