#version 460
// Frame output, fp16 network storage (see output.glsl).
#extension GL_GOOGLE_include_directive : require
#include "output.glsl"
