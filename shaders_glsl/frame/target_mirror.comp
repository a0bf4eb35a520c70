#version 460
// Target mirror image M_tgt (§4.2.2, eq. 5): one ray query per pixel in the mirror direction of
// the novel view at the first surface; its hit y takes its value from the input view whose
// viewing direction onto y is best aligned with the reflected ray (among all views that see y):
//   I_i / E_src_i · (E_add_i + E_src_i − E_rem_i),  E_rem_i = α_dim · E_src_i (plus, when some
//   original light has a factor of its own, (1 − α_dim) · E_src_i · removed_share: originals.glsl),
// read at y's pixel in view i (nearest texel, as the depth test). E_src is floored at E_FLOOR
// (W/m², constants.table) in the ratio. A lit added light met before y is seen in the mirror: its radiance;
// a declared original light at y shows its dimmed glow (emitters.glsl).
// A live light (frame/live.glsl) adds its E_add evaluated at y itself.
// Output vec4: rgb, w = reflected distance |y − x| (0: no hit, no view).
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#include "frame.glsl"
#include "emitters.glsl"
#include "originals.glsl"

layout(set = 0, binding = 7) uniform sampler2DArray tex_img;
layout(set = 0, binding = 9) uniform sampler2DArray tex_esrc;
layout(set = 0, binding = 10) uniform sampler2DArray tex_eadd;
layout(set = 0, binding = 12) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 13) writeonly buffer Mirror { vec4 mirror[]; };
#include "live.glsl"

#include "frame_constants.glsl"

void main() {
    uint p = gl_GlobalInvocationID.x;
    if (p >= pc.width * pc.height) return;
    mirror[p] = vec4(0.0);
    vec3 x, n;
    float depth;
    vec3 eye = pc.eye.xyz;
    if (!surface(p, pc.width, eye, x, n, depth)) return;
    vec3 r = reflect(normalize(x - eye), n);
    vec3 o = x + n * 1e-3;
    rayQueryEXT rq;
    rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFF, o, 1e-3, r, 1e4);
    while (rayQueryProceedEXT(rq)) {}
    bool hit = rayQueryGetIntersectionTypeEXT(rq, true) == gl_RayQueryCommittedIntersectionTriangleEXT;
    float t = hit ? rayQueryGetIntersectionTEXT(rq, true) : 1e30;
    vec3 le;
    if (nearest_emitter(o, r, pc.nlights, t, le)) { mirror[p] = vec4(le, t); return; }
    if (!hit) return;
    vec3 y = o + r * t;
    int q = best_view(y, r, pc.exclude, pc.nviews, pc.view_w, pc.view_h);
    uint npv = pc.view_w * pc.view_h;
    uint j = uint(max(q, 0)) / npv, qp = uint(max(q, 0)) % npv;
    ivec2 xy = ivec2(qp % pc.view_w, qp / pc.view_w);
    vec3 ea = vec3(0.0);
    for (uint l = 0u; q >= 0 && l < pc.nlights; ++l) {
        if (intensity[l] != 0.0 && !is_live(l, pc.live_mask))
            ea += intensity[l] * texelFetch(tex_eadd, ivec3(xy, l * pc.nviews + j), 0).rgb;
    }
    uint tri = uint(rayQueryGetIntersectionPrimitiveIndexEXT(rq, true));
    for (uint i = 0u; i < pc.nlive; ++i) {
        float s = intensity[lives[i].layer];
        if (s != 0.0) ea += s * live_eadd(i, y, live_normal(tri, -r), tri, p);
    }
    vec3 col = q >= 0 ? texelFetch(tex_img, ivec3(xy, j), 0).rgb : vec3(0.0);
    if (original_light(y, r, pc.norig, pc.alpha_dim, col, ea, 0.0, le)) { mirror[p] = vec4(le, distance(y, x)); return; }
    if (q < 0) return;
    vec3 es = texelFetch(tex_esrc, ivec3(xy, j), 0).rgb;
    vec3 rem = pc.alpha_dim * es;
    if (pc.per_light != 0u)
        rem += (1.0 - pc.alpha_dim) * es * removed_share(tex_eadd, vec2(xy) + 0.5, j, pc.nviews, pc.norig, pc.nsplit, pc.split_layer);
    vec3 modified = ea + es - rem;
    mirror[p] = vec4(col / max(es, vec3(E_FLOOR)) * modified, distance(y, x));
}
