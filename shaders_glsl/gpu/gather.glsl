// Storage-access probe (`relit bench gather`): each invocation reads LOADS vec4s of a table at
// indices that differ per invocation (a hash of the invocation and the load) and writes their
// sum. The two kernels differ only in how the table is read — a storage-buffer binding
// (gather_ssbo.comp) or a buffer-device-address pointer (gather_bda.comp) — which is what Mesa
// 25.0's llvmpipe compiles so differently (a per-lane loop with bounds checks, or one masked
// gather); see the README's "Storage access on lavapipe".
#ifndef RELIT_GATHER_GLSL
#define RELIT_GATHER_GLSL

layout(local_size_x = 64) in;

const uint LOADS = 16u;

layout(set = 0, binding = 1) writeonly buffer Out { vec4 sums[]; };

layout(push_constant) uniform Push {
    uvec2 table_addr;   // gather_bda.comp only
    uint count;         // invocations
    uint mask;          // table length - 1 (a power of two)
} pc;

// The table index of load k of invocation i (the same hash as gpu::gather::index).
uint gather_index(uint i, uint k) {
    uint h = (i * 2654435761u) ^ (k * 40503u + 0x9e3779b9u);
    h ^= h >> 15;
    h *= 2246822519u;
    h ^= h >> 13;
    return h & pc.mask;
}

#endif
