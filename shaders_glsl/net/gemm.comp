#version 460
// Portable GEMM: 64 invocations per tile, each computing 4 outputs of one row, with fp32
// arithmetic (faster than fp16 on CPUs without native half) over fp16 storage.
#extension GL_GOOGLE_include_directive : require
#include "gemm_tile.glsl"

layout(local_size_x = 64) in;

void main() {
    uvec2 o = tile_origin();
    uint row = o.x + gl_LocalInvocationID.x / 4u;
    uint col = o.y + (gl_LocalInvocationID.x % 4u) * 4u;
    vec4 acc = vec4(0.0);
    for (uint k = 0u; k < pc.K; ++k) {
        float av = float(a[row * pc.K + k]);
        uint bk = k * pc.N + col;
        acc += av * vec4(float(b[bk]), float(b[bk + 1u]), float(b[bk + 2u]), float(b[bk + 3u]));
    }
    uint ci = row * pc.N + col;
    c[ci] = acc.x; c[ci + 1u] = acc.y; c[ci + 2u] = acc.z; c[ci + 3u] = acc.w;
}
