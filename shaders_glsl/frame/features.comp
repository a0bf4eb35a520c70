#version 460
// Network input features, fp16 storage (see features.glsl).
#extension GL_GOOGLE_include_directive : require
#include "features.glsl"
