#version 460
// Reprojected composites (§4.3.1–4.3.2). For each novel-view pixel, every active input view
// that sees the surface point x (depth test against its depth map) contributes its colour I and
// source mirror value M_src, sampled bilinearly where x projects:
//   I_1..4, M_1..4: weighted averages with Buehler-style weights, exactly as in §4.3.1
//     w1 = 1/|c_new - c_i|^2, w2 = (unit(c_new - x) . unit(c_i - x))^2,
//     w3 = 1/|c_i - x|^2,     w4 = exp((c_i - x) . n / (0.1 |c_i - x|)) - 1;
//   I_5..8, M_5..8: the view with the highest, 2nd highest, median (lower median, index
//     (k-1)/2 of k sorted ascending) and lowest luminance of I, over all active views that see
//     x (ties broken by view index).
// Output: 16 planes of f16vec4 per pixel (I_1..8 then M_1..8), w = 1 where defined; half
// precision keeps the buffer within maxStorageBufferRange up to 1024x768.
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_shader_16bit_storage : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#include "frame.glsl"

layout(set = 0, binding = 6) readonly buffer Active { uint active_views[]; };
layout(set = 0, binding = 7) uniform sampler2DArray tex_img;
layout(set = 0, binding = 8) uniform sampler2DArray tex_msrc;
layout(set = 0, binding = 13) writeonly buffer Comp { f16vec4 comp[]; };
// Bit a: whether active view a sees the pixel's point (the glossy layer's photos' part reads
// them rather than testing every view's depth map again).
layout(set = 0, binding = 35) writeonly buffer ViewsSeen { uvec2 views_seen[]; };

#include "frame_constants.glsl"

void put(uint i, vec4 v) { comp[i] = f16vec4(clamp(v, -65000.0, 65000.0)); }

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    for (uint k = 0u; k < 16u; ++k) put(k * npix + p, vec4(0.0));
    views_seen[p] = uvec2(0u);
    vec3 x, n;
    float depth;
    vec3 eye = pc.eye.xyz;
    if (!surface(p, pc.width, eye, x, n, depth)) return;
    vec3 dn = normalize(eye - x);
    vec3 si[4] = vec3[4](vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0));
    vec3 sm[4] = vec3[4](vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0));
    float sw[4] = float[4](0.0, 0.0, 0.0, 0.0);
    float lum[MAX_ACTIVE];
    uint vid[MAX_ACTIVE];
    uint cnt = 0u;
    uvec2 seen = uvec2(0u);
    for (uint a = 0u; a < pc.nactive; ++a) {
        uint j = active_views[a];
        if (visible_pixel(j, x, pc.view_w, pc.view_h) < 0) continue;
        seen[a >> 5u] |= 1u << (a & 31u);
        vec2 px = project_px(j, x);
        vec3 col = sample_map(tex_img, px, j);
        vec3 mir = sample_map(tex_msrc, px, j);
        vec3 ci = cam_center(cams[j]);
        vec3 d = ci - x;
        float dl = length(d);
        vec3 e = eye - ci;
        float cw = dot(dn, d / dl);
        float w[4] = float[4](1.0 / max(dot(e, e), 1e-8), cw * cw, 1.0 / max(dl * dl, 1e-8),
                             exp(dot(d, n) / (0.1 * dl)) - 1.0);
        for (uint k = 0u; k < 4u; ++k) {
            si[k] += w[k] * col;
            sm[k] += w[k] * mir;
            sw[k] += w[k];
        }
        // Insertion into the ascending (luminance, view) list.
        float l = luminance(col);
        uint i = cnt;
        while (i > 0u && (lum[i - 1u] > l || (lum[i - 1u] == l && vid[i - 1u] > j))) {
            lum[i] = lum[i - 1u];
            vid[i] = vid[i - 1u];
            --i;
        }
        lum[i] = l;
        vid[i] = j;
        ++cnt;
    }
    for (uint k = 0u; k < 4u; ++k) {
        if (sw[k] > 0.0) {
            put(k * npix + p, vec4(si[k] / sw[k], 1.0));
            put((8u + k) * npix + p, vec4(sm[k] / sw[k], 1.0));
        }
    }
    views_seen[p] = seen;
    if (cnt == 0u) return;
    uint pick[4] = uint[4](cnt - 1u, cnt >= 2u ? cnt - 2u : 0u, (cnt - 1u) / 2u, 0u);
    for (uint k = 0u; k < 4u; ++k) {
        uint j = vid[pick[k]];
        vec2 px = project_px(j, x);
        put((4u + k) * npix + p, vec4(sample_map(tex_img, px, j), 1.0));
        put((12u + k) * npix + p, vec4(sample_map(tex_msrc, px, j), 1.0));
    }
}
