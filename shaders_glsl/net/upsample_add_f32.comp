#version 460
// Upsample-and-add, fp32 storage (see upsample_add.glsl).
#extension GL_GOOGLE_include_directive : require
#define STORE_F32
#include "upsample_add.glsl"
