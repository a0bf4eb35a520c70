#version 460
// Source irradiance E_src of one input view (§4.1.1, Fig. 3). For each pixel's point x on the
// proxy mesh, SAMPLES cosine-weighted rays; each hit y takes its radiance from the input view
// (other than this one) whose camera→y direction is closest to the ray, among the views that see
// y. Rays without such a view are dropped and the estimate renormalized: E = π · mean(L).
//
// Declared original lights (scene.json, in the spirit of Appendix A) are not left to the views:
// few views may see a ceiling panel, and a ray towards it that finds no view would lose the
// direct light. Their direct part comes from next-event estimation (SAMPLES shadow rays, taken
// round-robin over the lights); a cosine ray that meets a declared light counts as a ray of zero
// indirect radiance, so no light is counted twice:
//   E = Σ_l E_dir,l + π · mean(L over rays with a view) · (rays not on a light) / SAMPLES.
// A view pixel on or beside a declared light (within LEAK_PX pixels: the image's pixel filter
// spreads the emitter into its neighbours) is no radiance sample of the surface: dropped.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 1
#include "views.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
#include "nee.glsl"
layout(set = 0, binding = 5) writeonly buffer Out { vec4 e_src[]; };   // rgb, w = valid rays
layout(set = 0, binding = 6, scalar) readonly buffer Lights { Light lights[]; };

layout(push_constant) uniform Push {
    uint view; uint width; uint height; uint nviews; uint samples; uint seed; uint nlights;
} pc;

// A declared light sits on or just off the proxy (ceiling, wall): a hit within this distance of
// its plane, where the ray also crosses the light, is the light.
const float LIGHT_SKIN = 0.03;
const float LEAK_PX = 2.0;

// Whether the view pixel q (global index) shows, or bleeds from, a declared light.
bool near_light(int q) {
    vec4 g = gpos[q];
    uint j = uint(q) / (pc.width * pc.height);
    float margin = LEAK_PX * g.w / cams[j].intrinsics.x;
    for (uint l = 0u; l < pc.nlights; ++l) {
        if (light_near(lights[l], g.xyz, LIGHT_SKIN + margin, margin)) return true;
    }
    return false;
}

// Whether the ray (o, d) whose proxy hit is y at distance t (t < 0: no hit) meets a light first.
bool meets_light(vec3 o, vec3 d, float t, vec3 y) {
    for (uint l = 0u; l < pc.nlights; ++l) {
        float tl = light_hit(lights[l], o, d);
        if (tl < 0.0) continue;
        if (t < 0.0 || tl <= t || abs(dot(y - lights[l].p0.xyz, light_normal(lights[l]))) < LIGHT_SKIN) return true;
    }
    return false;
}

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    uint gi = pc.view * npix + p;
    vec4 xp = gpos[gi];
    if (xp.w <= 0.0) { e_src[p] = vec4(0.0); return; }
    vec3 x = xp.xyz;
    vec3 n = gnrm[gi].xyz;
    vec3 eye = cam_center(cams[pc.view]);
    if (dot(n, eye - x) < 0.0) n = -n;   // the side the camera sees
    vec3 sum = vec3(0.0), direct = vec3(0.0);
    uint valid = 0u, on_light = 0u;
    for (uint s = 0u; s < pc.samples; ++s) {
        if (pc.nlights > 0u) {
            uint l = s % pc.nlights;
            float per_light = float((pc.samples - l + pc.nlights - 1u) / pc.nlights);
            direct += light_direct(lights[l], x, n, rand2(uvec3(gi, s, ~pc.seed)), LIGHT_SKIN) / per_light;
        }
        vec3 d = cosine_dir(n, rand2(uvec3(gi, s, pc.seed)));
        vec3 o = x + n * 1e-3;
        rayQueryEXT rq;
        rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFF, o, 1e-3, d, 1e4);
        while (rayQueryProceedEXT(rq)) {}
        bool hit = rayQueryGetIntersectionTypeEXT(rq, true) == gl_RayQueryCommittedIntersectionTriangleEXT;
        float t = hit ? rayQueryGetIntersectionTEXT(rq, true) : -1.0;
        vec3 y = o + d * t;
        if (meets_light(o, d, t, y)) { on_light += 1u; continue; }
        if (!hit) continue;
        int best_px = best_view(y, d, pc.view, pc.nviews, pc.width, pc.height);
        if (best_px < 0 || near_light(best_px)) continue;
        sum += images[best_px].rgb;
        valid += 1u;
    }
    float n_s = float(pc.samples);
    vec3 e = valid > 0u ? 3.14159265359 * sum / float(valid) * (n_s - float(on_light)) / n_s : vec3(0.0);
    e += direct;
    e_src[p] = vec4(e, float(valid + on_light));
}
