#version 460
// The view-dependent layer's sums (§3: L = a·E + S), which the fit per surface pools
// (frame/glossy_fit/ renders them from the input cameras). At each pixel the input views j that see the surface point x give a
// photo value I_j and three regressors X_j,c: the declared original lights x sees, through a
// GGX lobe of roughness GLOSSY_LOBE_1..3 seen from view j (lobe.glsl; the normal smoothed over
// the surface around x, `smooth_normal`); views more grazing than GLOSSY_COS_MIN are skipped.
// The model is a coated surface's: I_j = D·(1 − F_j) + s·X_j (RGB D, grey s, the F0 of
// Schlick's F_j = s·(1 + K·(1 − n·v_j)⁵), K = 1/GLOSSY_F0 − 1): its diffuse part darkens towards
// grazing views by the coat's transmittance, as much as s says. With D ≈ Ī it is linear in s:
// I_j = D + s·X'_j, X'_j = X_j − K·Ī·(1 − n·v_j)⁵. Views nearer a light's mirror direction are
// often the steeper ones, so with X alone that darkening passed for a highlight where no photo
// shows one (hand_room's floor fitted 0.27 for its F0 of 0.04), and a surface's real highlights
// were fitted against a diffuse part that was not constant. It writes the centred sums a
// surface pools:
//   plane 0: Σ|X' − X̄'|² per lobe;  plane 1: Σ(X' − X̄')·(I − Ī) per lobe;
//   plane 2: (Σ|I − Ī|², views, original lights seen (bits), 0).
// All zero where fewer than GLOSSY_MIN_VIEWS views see x or I_1 is black.
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

layout(set = 0, binding = 6) readonly buffer Active { uint active_views[]; };
layout(set = 0, binding = 7) uniform sampler2DArray tex_img;
layout(set = 0, binding = 12) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 13) readonly buffer Comp { f16vec4 comp[]; };
layout(set = 0, binding = 31) writeonly buffer GlossySums { vec4 sums[]; };

#include "frame_constants.glsl"

#include "lobe.glsl"

const uint PLANES = 3u;

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    for (uint k = 0u; k < PLANES; ++k) sums[k * npix + p] = vec4(0.0);
    vec3 x, n;
    float depth;
    if (pc.norig == 0u || !surface(p, pc.width, pc.eye.xyz, x, n, depth)
        || all(equal(vec3(comp[p].rgb), vec3(0.0)))) return;
    n = smooth_normal(ivec2(p % pc.width, p / pc.width), n, depth);
    uint seen = 0u;
    for (uint l = 0u; l < min(pc.norig, MAX_ORIG); ++l)
        if (sees_light(x, n, originals[l].light)) seen |= 1u << l;
    if (seen == 0u) return;
    vec3 sx[LOBES];
    float sxx[LOBES], sxi[LOBES];
    for (uint c = 0u; c < LOBES; ++c) { sx[c] = vec3(0.0); sxx[c] = 0.0; sxi[c] = 0.0; }
    vec3 sgx[LOBES];
    for (uint c = 0u; c < LOBES; ++c) sgx[c] = vec3(0.0);
    vec3 si = vec3(0.0), sgi = vec3(0.0);
    float sii = 0.0, cnt = 0.0, sg = 0.0, sgg = 0.0;
    for (uint a = 0u; a < pc.nactive; ++a) {
        uint j = active_views[a];
        if (visible_pixel(j, x, pc.view_w, pc.view_h) < 0) continue;
        vec3 v = normalize(cam_center(cams[j]) - x);
        // Grazing views: the proxy's errors grow and Schlick's Fresnel is least sure.
        if (dot(n, v) < GLOSSY_COS_MIN) continue;
        vec3 col = sample_map(tex_img, project_px(j, x), j);
        vec3 xs[LOBES];
        lobe_originals(x, v, n, seen, xs);
        float g = pow(1.0 - dot(n, v), 5.0);
        for (uint c = 0u; c < LOBES; ++c) {
            sx[c] += xs[c]; sxx[c] += dot(xs[c], xs[c]); sxi[c] += dot(xs[c], col);
            sgx[c] += g * xs[c];
        }
        si += col; sii += dot(col, col); cnt += 1.0;
        sg += g; sgg += g * g; sgi += g * col;
    }
    if (cnt < float(GLOSSY_MIN_VIEWS)) return;
    vec3 im = si / cnt;
    // Centred sums of Z_j = Ī·(1 − n·v_j)⁵; X' = X − K·Z.
    const float K = 1.0 / GLOSSY_F0 - 1.0;
    float gm = sg / cnt;
    float czz = dot(im, im) * (sgg - cnt * gm * gm);
    float czi = dot(im, sgi - cnt * gm * im);
    vec4 cxx = vec4(0.0), cxi = vec4(0.0);
    for (uint c = 0u; c < LOBES; ++c) {
        vec3 xm = sx[c] / cnt;
        float czx = dot(im, sgx[c] - cnt * gm * xm);
        cxx[c] = max(sxx[c] - cnt * dot(xm, xm) - 2.0 * K * czx + K * K * czz, 0.0);
        cxi[c] = sxi[c] - cnt * dot(xm, im) - K * czi;
    }
    sums[p] = cxx;
    sums[npix + p] = cxi;
    sums[2u * npix + p] = vec4(sii - cnt * dot(im, im), cnt, float(seen), 0.0);
}
