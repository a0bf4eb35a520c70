#version 460
// Convolution, portable backend, fp32 storage (see conv_portable.glsl).
#extension GL_GOOGLE_include_directive : require
#define STORE_F32
#include "conv_portable.glsl"
