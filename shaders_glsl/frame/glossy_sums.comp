#version 460
// The view-dependent layer's sums (§3: L = a·E + S), which the fit per surface pools
// (frame/glossy_fit/ renders them from the input cameras). At each pixel the input views j that see the surface point x give a
// photo value I_j and three regressors X_j,c: the declared original lights x sees, through a
// GGX lobe of roughness GLOSSY_LOBE_1..3 seen from view j (lobe.glsl; the normal smoothed over
// the surface around x, `smooth_normal`); views more grazing than GLOSSY_COS_MIN are skipped.
// For the model I_j = D + s·X_j (RGB D, grey s) it writes the centred sums a surface pools:
//   plane 0: Σ|X − X̄|² per lobe;  plane 1: Σ(X − X̄)·(I − Ī) per lobe;
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
    vec3 si = vec3(0.0);
    float sii = 0.0, cnt = 0.0;
    for (uint a = 0u; a < pc.nactive; ++a) {
        uint j = active_views[a];
        if (visible_pixel(j, x, pc.view_w, pc.view_h) < 0) continue;
        vec3 ci = cam_center(cams[j]);
        // Grazing views: the proxy's errors grow and Schlick's Fresnel is least sure.
        if (dot(n, normalize(ci - x)) < GLOSSY_COS_MIN) continue;
        vec3 col = sample_map(tex_img, project_px(j, x), j);
        vec3 xs[LOBES];
        lobe_originals(x, normalize(ci - x), n, seen, xs);
        for (uint c = 0u; c < LOBES; ++c) {
            sx[c] += xs[c]; sxx[c] += dot(xs[c], xs[c]); sxi[c] += dot(xs[c], col);
        }
        si += col; sii += dot(col, col); cnt += 1.0;
    }
    if (cnt < float(GLOSSY_MIN_VIEWS)) return;
    vec3 im = si / cnt;
    vec4 cxx = vec4(0.0), cxi = vec4(0.0);
    for (uint c = 0u; c < LOBES; ++c) {
        vec3 xm = sx[c] / cnt;
        cxx[c] = sxx[c] - cnt * dot(xm, xm);
        cxi[c] = sxi[c] - cnt * dot(xm, im);
    }
    sums[p] = cxx;
    sums[npix + p] = cxi;
    sums[2u * npix + p] = vec4(sii - cnt * dot(im, im), cnt, float(seen), 0.0);
}
