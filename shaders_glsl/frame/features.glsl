// The network input (§4.4, §5.2): 66 channels per pixel, written as a pack4 tensor
// (net/conv.glsl layout) in the storage type of the network. Channel order (the contract with
// the trainer, also in engine/src/frame/features.rs):
//    0–23  I_1..8 (RGB each)                tonemapped
//   24–47  M_src_1..8 (RGB each)            tonemapped
//   48–50  M_tgt                            tonemapped
//   51–53  E_src / π                        tonemapped
//   54–56  E_add / π                        tonemapped
//   57–59  E_rem / π                        tonemapped
//   60     disparity: min(1, 0.5 m / depth)
//   61–63  normal (world, facing the camera)
//   64     angle between normal and view vector / (π/2)
//   65     reflected / observed distance: |y − x| / |x − c| (0 without a mirror hit)
// Tonemap: log(1 + μx) / log(1 + μ), μ = 64. Pixels without a surface are all zero.
#include "act_storage.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 4, rgba32f) readonly uniform image2D g_pos;
layout(set = 0, binding = 5, rgba32f) readonly uniform image2D g_nrm;
layout(set = 0, binding = 13) readonly buffer Comp { f16vec4 comp[]; };     // 16 planes
layout(set = 0, binding = 14) readonly buffer Irr { vec4 irr[]; };       // 3 planes
layout(set = 0, binding = 15) readonly buffer Mirror { vec4 mirror[]; }; // 1 plane
layout(set = 0, binding = 16) writeonly buffer NetIn { ACT4 t[]; };

layout(push_constant) uniform Push { vec4 eye; uint width; uint height; } pc;

const uint GROUPS = 17u;  // 66 channels padded to 68
const float PI = 3.14159265358979;

#include "tonemap.glsl"

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    float v[GROUPS * 4u];
    for (uint c = 0u; c < GROUPS * 4u; ++c) v[c] = 0.0;
    ivec2 xy = ivec2(p % pc.width, p / pc.width);
    vec4 xp = imageLoad(g_pos, xy);
    if (xp.w > 0.0) {
        vec3 x = xp.xyz, eye = pc.eye.xyz;
        vec3 n = imageLoad(g_nrm, xy).xyz;
        if (dot(n, eye - x) < 0.0) n = -n;
        for (uint k = 0u; k < 16u; ++k) {
            vec3 c = tm(vec3(comp[k * npix + p].rgb));
            v[3u * k] = c.r; v[3u * k + 1u] = c.g; v[3u * k + 2u] = c.b;
        }
        vec4 m = mirror[p];
        vec3 c = tm(m.rgb);
        v[48] = c.r; v[49] = c.g; v[50] = c.b;
        for (uint k = 0u; k < 3u; ++k) {
            c = tm(irr[k * npix + p].rgb / PI);
            v[51u + 3u * k] = c.r; v[52u + 3u * k] = c.g; v[53u + 3u * k] = c.b;
        }
        float dist = distance(x, eye);
        v[60] = min(1.0, 0.5 / xp.w);
        v[61] = n.x; v[62] = n.y; v[63] = n.z;
        v[64] = acos(clamp(dot(n, (eye - x) / dist), 0.0, 1.0)) / (0.5 * PI);
        v[65] = m.w / dist;
    }
    for (uint g = 0u; g < GROUPS; ++g)
        t[g * npix + p] = ACT4(vec4(v[4u * g], v[4u * g + 1u], v[4u * g + 2u], v[4u * g + 3u]));
}
