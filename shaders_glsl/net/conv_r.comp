#version 460
// Convolution remainder (first 4 channels of a block), portable, fp16 storage (see
// conv_portable.glsl).
#extension GL_GOOGLE_include_directive : require
#define OCG 1
#include "conv_portable.glsl"
