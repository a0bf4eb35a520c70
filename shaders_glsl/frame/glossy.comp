#version 460
// The view-dependent layer (§3: L = a·E + S), second half. A pixel takes the lobes' strengths
// of its surface (`surface_fit`, per triangle through g_tri: frame/glossy_fit.rs pooled every
// photo of that surface and material once per scene). Where the surface has none, it pools the
// centred sums of frame/glossy_sums.comp over its 5×5 neighbours on the same surface (normals
// within ~25°, depth within 5 %); each lobe c takes a strength w_c from how much of the pooled
// variance it explains (`lobe_strengths`); none where the photos differ by less than
// GLOSSY_SPREAD (relative RMS) or no lobe explains GLOSSY_FIT: there the layer is today's image
// (D = I_1, S = 0: ratio's).
// The photos' view-dependent part in I_1 is Σ w_c·X̄_c (X̄ under I_1's own view weights), lowered
// together where it would exceed GLOSSY_SHARE of I_1, and D = I_1 minus it, but never below the
// darkest photo of x (I_8: every photo holds D plus a non-negative view-dependent part).
// S = k·(I_1 − D) + Σ_L i_L Σ_c w_c·X_L,c: the photos' own highlights as they are, dimmed with
// their lights (eq. 5 would scale them by the diffuse ratio; k = 1 − α_dim, or with per-light
// factors what remains of E_src, 1 − E_rem / E_src: a highlight is taken to come from the
// original lights in the shares their diffuse light does), plus each lit lamp x sees through
// the lobes seen from the novel view (the normal smoothed, lobe.glsl). Under the original
// lighting the layer gives I_1 back: ratio's image.
// Output: plane 0 (D, Σ w_c), plane 1 (S, the leading lobe + 1; 0: no fit). Holes (no view)
// are all zero.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_shader_16bit_storage : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#include "frame.glsl"
#include "emitters.glsl"

layout(set = 0, binding = 12) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 13) readonly buffer Comp { f16vec4 comp[]; };
layout(set = 0, binding = 14) readonly buffer Irr { vec4 irr[]; };   // E_src, E_add, E_rem
layout(set = 0, binding = 30) writeonly buffer Glossy { vec4 glossy[]; };
layout(set = 0, binding = 31) readonly buffer GlossySums { vec4 sums[]; };
layout(set = 0, binding = 20, r32ui) readonly uniform uimage2D g_tri;
layout(set = 0, binding = 33) readonly buffer GlossyFit { vec4 surface_fit[]; };  // per triangle

layout(push_constant) uniform Push {
    vec4 eye;
    uint width; uint height; uint nactive; uint view_w; uint view_h;
    uint nlights; uint norig; float alpha_dim; uint per_light;
} pc;

#include "lobe.glsl"

const int RADIUS = 2;

// Σ_L i_L Σ_c w_c·X_L,c: the lit lamps x (normal n) sees, through the lobes seen from unit v.
vec3 lamps(vec3 x, vec3 n, vec3 v, vec3 w) {
    vec3 s = vec3(0.0);
    for (uint l = 0u; l < pc.nlights; ++l) {
        if (intensity[l] <= 0.0 || !sees_light(x, n, emitters[l])) continue;
        float omega;
        vec3 wl;
        light_seen(x, emitters[l], omega, wl);
        if (omega <= 0.0) continue;
        float k = 0.0;
        for (uint c = 0u; c < LOBES; ++c) k += w[c] * lobe_weight(lobe_width(c), omega, wl, v, n);
        s += intensity[l] * emitters[l].radiance.rgb * k;
    }
    return s;
}

// Each lobe's strength w_c = κ·ω_c·s_c from the pooled sums: s_c the lobe's least-squares
// slope (≥ 0; a lobe whose slope exceeds lobe_s_max takes none), e_c the share of the variance it explains, ω_c ∝
// max(e_c − GLOSSY_FIT, 0)⁴ (normalized: the best lobe leads, close ones mix, as a GGX lobe's
// tail mixes widths), κ = clamp((max e − GLOSSY_FIT) / GLOSSY_FIT_RAMP, 0, 1); a lobe whose
// explained variance is within the spread threshold takes none. Continuous in the sums, so the
// layer fades in and out instead of switching lobes patch by patch.
vec3 lobe_strengths(vec4 cxx, vec4 cxi, float cii, float spread) {
    vec3 s = vec3(0.0), om = vec3(0.0);
    float best = 0.0;
    for (uint c = 0u; c < LOBES; ++c) {
        if (cxx[c] <= 1e-8) continue;
        s[c] = max(cxi[c] / cxx[c], 0.0);
        if (s[c] > lobe_s_max(c)) { s[c] = 0.0; continue; }
        float e = (2.0 * s[c] * cxi[c] - s[c] * s[c] * cxx[c]) / cii;
        // What the lobe explains must itself exceed GLOSSY_SPREAD: chance correlations with
        // resampling noise explain a share of a small variance.
        if (s[c] <= 0.0 || e * cii <= spread) continue;
        float m = max(e - GLOSSY_FIT, 0.0);
        om[c] = m * m * m * m;
        best = max(best, e);
    }
    float total = om.x + om.y + om.z;
    if (total <= 0.0) return vec3(0.0);
    float kappa = clamp((best - GLOSSY_FIT) / GLOSSY_FIT_RAMP, 0.0, 1.0);
    return kappa * s * om / total;
}

// The lobes' strengths from the sums pooled over pixel p's 5×5 neighbours on its surface (none:
// zero).
vec3 local_fit(ivec2 xy, uint p, uint npix, vec3 n, float depth) {
    vec4 cxx = vec4(0.0), cxi = vec4(0.0);
    float cii = 0.0, spread = 0.0;
    for (int dy = -RADIUS; dy <= RADIUS; ++dy) {
        for (int dx = -RADIUS; dx <= RADIUS; ++dx) {
            ivec2 q2 = xy + ivec2(dx, dy);
            if (any(lessThan(q2, ivec2(0))) || q2.x >= int(pc.width) || q2.y >= int(pc.height)) continue;
            uint q = uint(q2.y) * pc.width + uint(q2.x);
            vec4 s2 = sums[2u * npix + q];
            vec4 gq = imageLoad(g_pos, q2);
            if (s2.y == 0.0 || abs(gq.w - depth) > 0.05 * depth) continue;
            if (abs(dot(imageLoad(g_nrm, q2).xyz, n)) < 0.9) continue;
            cxx += sums[q]; cxi += sums[npix + q]; cii += s2.x; spread += s2.w;
        }
    }
    if (cii <= max(spread, 1e-8)) return vec3(0.0);
    return lobe_strengths(cxx, cxi, cii, spread);
}

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    glossy[p] = vec4(0.0);
    glossy[npix + p] = vec4(0.0);
    vec3 x, n;
    float depth;
    vec3 eye = pc.eye.xyz;
    vec3 i1 = vec3(comp[p].rgb);
    if (!surface(p, pc.width, eye, x, n, depth) || all(equal(i1, vec3(0.0)))) return;
    glossy[p] = vec4(i1, 0.0);
    ivec2 xy = ivec2(p % pc.width, p / pc.width);
    uint tri = imageLoad(g_tri, xy).x;
    vec3 w = tri > 0u ? surface_fit[tri - 1u].xyz : vec3(0.0);
    if (w == vec3(0.0) && sums[2u * npix + p].y != 0.0) w = local_fit(xy, p, npix, n, depth);
    if (w == vec3(0.0)) return;
    vec3 xm = vec3(0.0);
    for (uint c = 0u; c < LOBES; ++c) xm += w[c] * sums[(3u + c) * npix + p].rgb;
    float cap = min(1.0, GLOSSY_SHARE * luminance(i1) / max(luminance(xm), 1e-8));
    w *= cap;
    vec3 i8 = vec3(comp[7u * npix + p].rgb);
    vec3 d = max(max(i1 - cap * xm, min(i8, i1)), vec3(0.0));
    n = smooth_normal(xy, n, depth);
    uint lead = w.y > w.x ? (w.z > w.y ? 2u : 1u) : (w.z > w.x ? 2u : 0u);
    glossy[p] = vec4(d, w.x + w.y + w.z);
    vec3 kept = vec3(1.0 - pc.alpha_dim);
    if (pc.per_light != 0u)
        kept = max(vec3(1.0) - irr[2u * npix + p].rgb / max(irr[p].rgb, vec3(E_FLOOR)), vec3(0.0));
    glossy[npix + p] = vec4(kept * (i1 - d) + lamps(x, n, normalize(eye - x), w), float(lead + 1u));
}
