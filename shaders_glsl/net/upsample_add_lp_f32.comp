#version 460
// Upsample-and-add for CPU devices, fp32 storage, tensors by pointer (see upsample_add.glsl).
#extension GL_GOOGLE_include_directive : require
#define STORE_F32
#define UP_POINTERS
#include "upsample_add.glsl"
