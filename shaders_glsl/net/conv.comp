#version 460
// Convolution, portable backend, fp16 storage (see conv_portable.glsl).
#extension GL_GOOGLE_include_directive : require
#include "conv_portable.glsl"
