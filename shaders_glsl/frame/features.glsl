// The network input (§4.4, §5.2): IN_CHANNELS channels per pixel, written as a pack4 tensor
// (net/conv.glsl layout) in the storage type of the network, in the order of the CH_* rows of
// engine/constants.table (the contract with the trainer). Tonemap: log(1 + μx) / log(1 + μ).
// Pixels without a surface are all zero.
#include "act_storage.glsl"
#include "constants.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 4, rgba32f) readonly uniform image2D g_pos;
layout(set = 0, binding = 5, rgba32f) readonly uniform image2D g_nrm;
layout(set = 0, binding = 13) readonly buffer Comp { f16vec4 comp[]; };     // 16 planes
layout(set = 0, binding = 14) readonly buffer Irr { vec4 irr[]; };       // 3 planes
layout(set = 0, binding = 15) readonly buffer Mirror { vec4 mirror[]; }; // 1 plane
layout(set = 0, binding = 16) writeonly buffer NetIn { ACT4 t[]; };

#include "frame_constants.glsl"

const uint GROUPS = (IN_CHANNELS + 3u) / 4u;  // padded to a multiple of 4
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
        // I_1..8 then M_src_1..8: the 16 composite planes in order
        for (uint k = 0u; k < 16u; ++k) {
            vec3 c = tm(vec3(comp[k * npix + p].rgb));
            v[CH_I + 3u * k] = c.r; v[CH_I + 3u * k + 1u] = c.g; v[CH_I + 3u * k + 2u] = c.b;
        }
        vec4 m = mirror[p];
        vec3 c = tm(m.rgb);
        v[CH_M_TGT] = c.r; v[CH_M_TGT + 1u] = c.g; v[CH_M_TGT + 2u] = c.b;
        // E_src, E_add, E_rem: the 3 irradiance planes in order
        for (uint k = 0u; k < 3u; ++k) {
            c = tm(irr[k * npix + p].rgb / PI);
            uint e = CH_E_SRC + 3u * k;
            v[e] = c.r; v[e + 1u] = c.g; v[e + 2u] = c.b;
        }
        float dist = distance(x, eye);
        v[CH_DISPARITY] = min(1.0, 0.5 / xp.w);
        v[CH_NORMAL] = n.x; v[CH_NORMAL + 1u] = n.y; v[CH_NORMAL + 2u] = n.z;
        v[CH_VIEW_ANGLE] = acos(clamp(dot(n, (eye - x) / dist), 0.0, 1.0)) / (0.5 * PI);
        v[CH_MIRROR_DIST] = m.w / dist;
    }
    for (uint g = 0u; g < GROUPS; ++g)
        t[g * npix + p] = ACT4(vec4(v[4u * g], v[4u * g + 1u], v[4u * g + 2u], v[4u * g + 3u]));
}
