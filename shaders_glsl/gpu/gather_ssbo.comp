#version 460
// The storage-access probe reading its table through a storage-buffer binding (gather.glsl).
#extension GL_GOOGLE_include_directive : require
#include "gather.glsl"

layout(set = 0, binding = 0) readonly buffer Table { vec4 table[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) return;
    vec4 s = vec4(0.0);
    for (uint k = 0u; k < LOADS; ++k) s += table[gather_index(i, k)];
    sums[i] = s;
}
