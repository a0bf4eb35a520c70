#version 460
// The storage-access probe reading its table through a buffer-device-address pointer
// (gather.glsl).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#include "gather.glsl"

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer TableRef { vec4 v[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) return;
    TableRef table = TableRef(pc.table_addr);
    vec4 s = vec4(0.0);
    for (uint k = 0u; k < LOADS; ++k) s += table.v[gather_index(i, k)];
    sums[i] = s;
}
