// Element type of the network's tensors in memory: fp16 by default, fp32 when the including
// module defines STORE_F32 (the `*_f32.comp` variants). Arithmetic is fp32 either way.
#ifndef RELIT_ACT_STORAGE_GLSL
#define RELIT_ACT_STORAGE_GLSL
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_shader_16bit_storage : require
#ifdef STORE_F32
#define ACT4 vec4
#else
#define ACT4 f16vec4
#endif
#endif
