#version 460
// Network input features, fp32 storage (see features.glsl).
#extension GL_GOOGLE_include_directive : require
#define STORE_F32
#include "features.glsl"
