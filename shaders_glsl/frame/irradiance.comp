#version 460
// Irradiance composites (§4.3.3): E_src and E_add are averages over the active views that see
// the surface point (depth test), weighted by the inverse distance between each view's camera
// and the novel camera; E_add mixes the added lights by their current intensities, and
// E_rem = α_dim · E_src, plus, when some original light has a factor of its own (per_light),
// (1 − α_dim) times the blend of each view's E_src · removed_share (originals.glsl).
// Live lights (frame/live.glsl) add their E_add at the point itself.
// Output: 3 planes of vec4 per pixel (E_src, E_add, E_rem).
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#include "frame.glsl"
#include "emitters.glsl"
#include "originals.glsl"

layout(set = 0, binding = 6) readonly buffer Active { uint active_views[]; };
layout(set = 0, binding = 9) uniform sampler2DArray tex_esrc;
layout(set = 0, binding = 10) uniform sampler2DArray tex_eadd;
layout(set = 0, binding = 12) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 20, r32ui) readonly uniform uimage2D g_tri;
#include "live.glsl"
layout(set = 0, binding = 13) writeonly buffer Irr { vec4 irr[]; };

#include "frame_constants.glsl"

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    for (uint k = 0u; k < 3u; ++k) irr[k * npix + p] = vec4(0.0);
    vec3 x, n;
    float depth;
    vec3 eye = pc.eye.xyz;
    if (!surface(p, pc.width, eye, x, n, depth)) return;
    vec3 es = vec3(0.0), ea = vec3(0.0), er = vec3(0.0);
    float sw = 0.0;
    for (uint a = 0u; a < pc.nactive; ++a) {
        uint j = active_views[a];
        if (visible_pixel(j, x, pc.view_w, pc.view_h) < 0) continue;
        vec2 px = project_px(j, x);
        float w = 1.0 / max(distance(cam_center(cams[j]), eye), 1e-3);
        vec3 esj = sample_map(tex_esrc, px, j);
        es += w * esj;
        if (pc.per_light != 0u)
            er += w * esj * removed_share(tex_eadd, px, j, pc.nviews, pc.norig, pc.nsplit, pc.split_layer);
        vec3 add = vec3(0.0);
        for (uint l = 0u; l < pc.nlights; ++l) {
            if (intensity[l] != 0.0 && !is_live(l, pc.live_mask))
                add += intensity[l] * sample_map(tex_eadd, px, l * pc.nviews + j);
        }
        ea += w * add;
        sw += w;
    }
    if (sw <= 0.0) return;
    vec3 live = vec3(0.0);
    uint tri = imageLoad(g_tri, ivec2(p % pc.width, p / pc.width)).x;
    for (uint i = 0u; i < pc.nlive && tri > 0u; ++i) {
        float s = intensity[lives[i].layer];
        if (s != 0.0) live += s * live_eadd(i, x, n, tri - 1u, p);
    }
    irr[p] = vec4(es / sw, 1.0);
    irr[npix + p] = vec4(ea / sw + live, 1.0);
    vec3 rem = pc.alpha_dim * es / sw;
    if (pc.per_light != 0u) rem += (1.0 - pc.alpha_dim) * er / sw;
    irr[2u * npix + p] = vec4(rem, 1.0);
}
