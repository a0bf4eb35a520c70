#version 460
// The view-dependent layer (§3: L = a·E + S). A pixel takes the lobes' strengths w_c of its
// surface (`surface_fit`, per triangle through g_tri: frame/glossy_fit/ pooled every photo of
// that surface and material once per scene); where the surface has none the layer is today's
// image (D = I_1, S = 0: ratio's).
// The photos' view-dependent part in I_1 is Σ_c w_c·X̄_c: the original lights x sees through
// lobe c (lobe.glsl) from each input view that sees x, averaged under I_1's own view weights
// (`photos_part`); it is lowered where it would exceed GLOSSY_SHARE of I_1, and D = I_1 minus
// it, but never below the darkest photo of x (I_8: every photo holds D plus a non-negative
// view-dependent part).
// S = k·max(I_1 − D + Σ_c w_c·X_c − Σ_c w_c·X̄_c, 0) + Σ_L i_L Σ_c w_c·X_L,c: the photos' own
// highlights moved to the novel view (X_c: the original lights through the lobes seen from the
// novel view), dimmed with their lights (eq. 5 would scale them by the diffuse ratio; k =
// 1 − α_dim, or with per-light factors what remains of E_src, 1 − E_rem / E_src: a highlight
// is taken to come from the original lights in the shares their diffuse light does), plus
// each lit lamp x sees through the lobes seen from the novel view (the normal smoothed,
// lobe.glsl). Under the original lighting the layer is I_1 where there is no fit: ratio's.
// Which original lights and lit lamps x sees comes from the sight cache where the light is
// still (sight_cache.glsl), else from shadow rays shared between neighbouring pixels of one
// surface (sight.glsl): on lavapipe the rays were three quarters of the layer.
// Output: plane 0 (D, Σ w_c), plane 1 (S, the leading lobe + 1; 0: no fit). Holes (no view)
// are all zero.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_shader_16bit_storage : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;  // SIGHT_GROUP (sight.glsl): one tile of 8×8 pixels

#include "frame.glsl"
#include "emitters.glsl"

layout(set = 0, binding = 6) readonly buffer Active { uint active_views[]; };
layout(set = 0, binding = 12) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 13) readonly buffer Comp { f16vec4 comp[]; };
layout(set = 0, binding = 14) readonly buffer Irr { vec4 irr[]; };   // E_src, E_add, E_rem
layout(set = 0, binding = 30) writeonly buffer Glossy { vec4 glossy[]; };
layout(set = 0, binding = 20, r32ui) readonly uniform uimage2D g_tri;
// Per triangle: the fits (w_1..3, t), then the surface normals (frame/glossy_fit/).
layout(set = 0, binding = 33) readonly buffer GlossyFit { vec4 surface_fit[]; };
// Bit a: whether active view a sees the pixel's point (reproject.comp).
layout(set = 0, binding = 35) readonly buffer ViewsSeen { uvec2 views_seen[]; };

#include "frame_constants.glsl"

#include "lobe.glsl"
#include "sight.glsl"

// Σ_L i_L Σ_c w_c·X_L,c: the lit lamps x (normal n) sees (slot bits `seen` of sight.glsl;
// lamps past its slots trace their own ray), through the lobes of strength w seen from unit v.
vec3 lamps(vec3 x, vec3 n, vec3 v, vec3 w, uint seen) {
    vec3 s = vec3(0.0);
    uint k = min(pc.norig, MAX_ORIG);
    for (uint l = 0u; l < pc.nlights; ++l) {
        if (intensity[l] <= 0.0) continue;
        bool sees = k < SIGHT_MAX ? (seen & (1u << k)) != 0u : sees_light(x, n, emitters[l]);
        ++k;
        if (!sees) continue;
        float omega;
        vec3 wl;
        light_seen(x, emitters[l], omega, wl);
        if (omega <= 0.0) continue;
        float c = 0.0;
        for (uint b = 0u; b < LOBES; ++b)
            if (w[b] > 0.0) c += w[b] * lobe_weight(lobe_width(b), omega, wl, v, n);
        s += intensity[l] * emitters[l].radiance.rgb * c;
    }
    return s;
}

// Σ_c w_c·X̄_c at pixel p: the original lights x (normal n) sees (bits `seen`), through the
// fitted lobes from each input view that sees x (`views_seen`) and is not grazing (as the sums
// pass takes them), averaged under I_1's view weights 1/|eye − c_j|². Zero where fewer than
// GLOSSY_MIN_VIEWS views see x.
vec3 photos_part(uint p, vec3 x, vec3 n, vec3 w, uint seen) {
    if (seen == 0u) return vec3(0.0);
    vec3 sx = vec3(0.0);
    float sw = 0.0, cnt = 0.0;
    uvec2 vs = views_seen[p];
    for (uint a = 0u; a < pc.nactive; ++a) {
        if (((vs[a >> 5u] >> (a & 31u)) & 1u) == 0u) continue;
        vec3 ci = cam_center(cams[active_views[a]]);
        vec3 v = normalize(ci - x);
        if (dot(n, v) < GLOSSY_COS_MIN) continue;
        vec3 e = pc.eye.xyz - ci;
        float w1 = 1.0 / max(dot(e, e), 1e-8);
        sx += w1 * lobes_originals(x, v, n, seen, w);
        sw += w1;
        cnt += 1.0;
    }
    return cnt < float(GLOSSY_MIN_VIEWS) ? vec3(0.0) : sx / sw;
}

// A pixel's surface (x, smoothed normal n, triangle id + 1 tri), I_1 (zero where it has no
// surface) and its surface's lobe strengths w; false where it has no surface, no photo or no fit.
bool fitted_pixel(uint p, uvec2 xy, out vec3 x, out vec3 n, out vec3 i1, out vec3 w, out uint tri) {
    x = vec3(0.0);
    tri = 0u;
    n = vec3(0.0, 0.0, 1.0);
    w = vec3(0.0);
    i1 = vec3(comp[p].rgb);
    float depth;
    if (!surface(p, pc.width, pc.eye.xyz, x, n, depth)) i1 = vec3(0.0);
    if (all(equal(i1, vec3(0.0)))) return false;
    tri = imageLoad(g_tri, ivec2(xy)).x;
    w = tri > 0u ? surface_fit[tri - 1u].xyz : vec3(0.0);
    if (w == vec3(0.0)) return false;
    // The surface's normal where the fit has one (a flat surface), facing the G-buffer's.
    vec3 ns = surface_fit[uint(surface_fit.length()) / 2u + tri - 1u].xyz;
    n = ns != vec3(0.0) ? (dot(ns, n) < 0.0 ? -ns : ns) : smooth_normal(ivec2(xy), n, depth);
    return true;
}

void main() {
    uvec2 xy = tile_pixel();
    uint p = xy.y * pc.width + xy.x;
    uint npix = pc.width * pc.height;
    vec3 x, n, i1, w;
    uint tri = 0u;
    bool inside = xy.x < pc.width && xy.y < pc.height;
    bool on = inside && fitted_pixel(p, xy, x, n, i1, w, tri);
    // Every invocation reaches the shared rays (they hold a workgroup barrier).
    uint seen = shared_sight(on, x, n, tri - 1u);
    if (!on) {
        // No fit: today's image (D = I_1, S = 0); holes all zero.
        if (inside) {
            glossy[p] = vec4(i1, 0.0);
            glossy[npix + p] = vec4(0.0);
        }
        return;
    }
    uint no = min(pc.norig, MAX_ORIG);
    vec3 xm = photos_part(p, x, n, w, seen & ((1u << no) - 1u));
    float cap = min(1.0, GLOSSY_SHARE * luminance(i1) / max(luminance(xm), 1e-8));
    w *= cap;
    vec3 i8 = vec3(comp[7u * npix + p].rgb);
    vec3 d = max(max(i1 - cap * xm, min(i8, i1)), vec3(0.0));
    uint lead = w.y > w.x ? (w.z > w.y ? 2u : 1u) : (w.z > w.x ? 2u : 0u);
    glossy[p] = vec4(d, w.x + w.y + w.z);
    vec3 kept = vec3(1.0 - pc.alpha_dim);
    if (pc.per_light != 0u)
        kept = max(vec3(1.0) - irr[2u * npix + p].rgb / max(irr[p].rgb, vec3(E_FLOOR)), vec3(0.0));
    vec3 v = normalize(pc.eye.xyz - x);
    // The photos' highlights moved to the novel view: what the lobes give there less what they
    // gave the photos (w carries the cap: cap·X̄ is what D lost).
    vec3 own = max(i1 - d + lobes_originals(x, v, n, seen & ((1u << no) - 1u), w) - cap * xm,
                   vec3(0.0));
    glossy[npix + p] = vec4(kept * own + lamps(x, n, v, w, seen), float(lead + 1u));
}
