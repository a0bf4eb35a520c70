// Source irradiance estimator (§4.1.1, Fig. 3), shared by the per-pixel pass
// (source_irradiance.comp) and the per-vertex one (source_irradiance_vertices.comp).
//
// At a point x (normal n), SAMPLES cosine-weighted rays; each hit y takes its radiance from the
// input view (other than `exclude`) whose camera→y direction is closest to the ray, among the
// views that see y. A hit that no view sees (or only through a pixel beside a light, see
// near_light.glsl) takes the radiance mesh's value there, when its triangle's corners have one
// (radiance_mesh.rs). Rays that leave the proxy, or find no radiance, are dropped and the
// estimate renormalized: E = π · mean(L).
//
// Declared original lights (scene.json, in the spirit of Appendix A) are not left to the views:
// few views may see a ceiling panel, and a ray towards it that finds no view would lose the
// direct light. Their direct part comes from next-event estimation (SAMPLES shadow rays, taken
// round-robin over the lights); a cosine ray that meets a declared light counts as a ray of zero
// indirect radiance, so no light is counted twice:
//   E = Σ_l E_dir,l + π · mean(L over rays with a radiance) · (rays not on a light) / SAMPLES.
// `parts` chooses the terms: the source cache (source_cache.rs) traces the indirect one at
// texels and the direct one at pixels.
//
// The includer defines VIEWS_BINDING (1) and includes this after its #extension lines.
#ifndef RELIT_SOURCE_IRRADIANCE_GLSL
#define RELIT_SOURCE_IRRADIANCE_GLSL
#include "views.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
#include "nee.glsl"
layout(set = 0, binding = 5) writeonly buffer Out { vec4 e_src[]; };   // rgb, w = rays used
layout(set = 0, binding = 6, scalar) readonly buffer Lights { Light lights[]; };
layout(set = 0, binding = 7) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 8) readonly buffer Radiance { vec4 radiance[]; };   // per vertex; w > 0: known
#include "near_light.glsl"

// `view`: the view whose pixels are estimated (excluded as a radiance source), or the first
// vertex of this dispatch; `count`: vertices in the dispatch (the per-pixel pass ignores it).
layout(push_constant) uniform Push {
    uint view; uint width; uint height; uint nviews; uint samples; uint seed; uint nlights; uint count;
    uint parts;
} pc;

const uint PART_DIRECT = 1u;     // the declared lights' next-event estimation
const uint PART_INDIRECT = 2u;   // the cosine rays gathering the views' radiance

// Whether the ray (o, d) whose proxy hit is y at distance t (t < 0: no hit) meets a light first.
bool meets_light(vec3 o, vec3 d, float t, vec3 y) {
    for (uint l = 0u; l < pc.nlights; ++l) {
        float tl = light_hit(lights[l], o, d);
        if (tl < 0.0) continue;
        if (t < 0.0 || tl <= t || abs(dot(y - lights[l].p0.xyz, light_normal(lights[l]))) < LIGHT_SKIN) return true;
    }
    return false;
}

// The radiance mesh at barycentrics bc of triangle tri; w > 0 when all three corners have one.
vec4 mesh_radiance(uint tri, vec2 bc) {
    vec3 b = vec3(1.0 - bc.x - bc.y, bc);
    vec3 r = vec3(0.0);
    bool known = true;
    for (uint k = 0u; k < 3u; ++k) {
        vec4 v = radiance[indices[3u * tri + k]];
        r += b[k] * v.rgb;
        known = known && v.w > 0.0;
    }
    return vec4(r, known ? 1.0 : 0.0);
}

// E_src at x (normal n facing the side wanted), random stream `key`; w = rays used.
vec4 source_irradiance(vec3 x, vec3 n, uint exclude, uint key) {
    vec3 sum = vec3(0.0), direct = vec3(0.0);
    uint valid = 0u, on_light = 0u;
    for (uint s = 0u; s < pc.samples; ++s) {
        if (pc.nlights > 0u && (pc.parts & PART_DIRECT) != 0u) {
            uint l = s % pc.nlights;
            float per_light = float((pc.samples - l + pc.nlights - 1u) / pc.nlights);
            direct += light_direct(lights[l], x, n, rand2(uvec3(key, s, ~pc.seed)), LIGHT_SKIN) / per_light;
        }
        if ((pc.parts & PART_INDIRECT) == 0u) continue;
        vec3 d = cosine_dir(n, rand2(uvec3(key, s, pc.seed)));
        vec3 o = x + n * 1e-3;
        rayQueryEXT rq;
        rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFF, o, 1e-3, d, 1e4);
        while (rayQueryProceedEXT(rq)) {}
        bool hit = rayQueryGetIntersectionTypeEXT(rq, true) == gl_RayQueryCommittedIntersectionTriangleEXT;
        float t = hit ? rayQueryGetIntersectionTEXT(rq, true) : -1.0;
        vec3 y = o + d * t;
        if (meets_light(o, d, t, y)) { on_light += 1u; continue; }
        if (!hit) continue;
        int best_px = best_view(y, d, exclude, pc.nviews, pc.width, pc.height);
        if (best_px >= 0 && !clipped(best_px) && !near_light(best_px, pc.width, pc.height, pc.nlights)) {
            sum += images[best_px].rgb;
            valid += 1u;
            continue;
        }
        vec4 l = mesh_radiance(uint(rayQueryGetIntersectionPrimitiveIndexEXT(rq, true)),
                               rayQueryGetIntersectionBarycentricsEXT(rq, true));
        if (l.w <= 0.0) continue;
        sum += l.rgb;
        valid += 1u;
    }
    float n_s = float(pc.samples);
    vec3 e = valid > 0u ? 3.14159265359 * sum / float(valid) * (n_s - float(on_light)) / n_s : vec3(0.0);
    return vec4(e + direct, float(valid + on_light));
}

#endif
