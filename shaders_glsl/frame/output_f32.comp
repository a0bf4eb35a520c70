#version 460
// Frame output, fp32 network storage (see output.glsl).
#extension GL_GOOGLE_include_directive : require
#define STORE_F32
#include "output.glsl"
