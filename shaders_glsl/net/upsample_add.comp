#version 460
// Upsample-and-add, fp16 storage (see upsample_add.glsl).
#extension GL_GOOGLE_include_directive : require
#include "upsample_add.glsl"
