#version 460
// Added irradiance E_add of one view for one user light (§4.1.3), path traced on the albedo
// mesh: at each bounce, next-event estimation towards the light (shadow ray), then a
// cosine-sampled continuation whose throughput is the interpolated vertex albedo. With cosine
// sampling the π of E = π·L cancels the 1/π of Lambertian reflection:
//   E(x) ≈ E_dir(x) + Σ_k (Π_{m≤k} ρ(y_m)) E_dir(y_k).
// The light is not in the mesh, so rays never hit it: its light arrives by the NEE only.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 1
#include "views.glsl"
#include "lights.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 5, scalar) readonly buffer Verts { vec3 verts[]; };
layout(set = 0, binding = 6) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 7) readonly buffer Albedo { vec4 albedo[]; };
layout(set = 0, binding = 8) writeonly buffer Out { vec4 e_add[]; };

layout(push_constant, scalar) uniform Push {
    uint view; uint width; uint height; uint samples; uint seed; uint bounces; uint pad0; uint pad1;
    Light light;
} pc;

bool occluded(vec3 o, vec3 d, float tmax) {
    rayQueryEXT rq;
    rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT | gl_RayFlagsTerminateOnFirstHitEXT, 0xFF, o, 1e-3, d, tmax);
    while (rayQueryProceedEXT(rq)) {}
    return rayQueryGetIntersectionTypeEXT(rq, true) == gl_RayQueryCommittedIntersectionTriangleEXT;
}

// Direct irradiance at x (normal n) from one light sample.
vec3 direct(vec3 x, vec3 n, vec2 u) {
    vec3 lp, ln;
    float area;
    light_sample(pc.light, u, lp, ln, area);
    vec3 w = lp - x;
    float d2 = dot(w, w);
    float d = sqrt(d2);
    w /= d;
    float cx = dot(n, w), cl = -dot(ln, w);
    if (cx <= 0.0 || cl <= 0.0) return vec3(0.0);
    if (occluded(x + n * 1e-3, w, d - 2e-3)) return vec3(0.0);
    return pc.light.radiance.rgb * (cx * cl * area / d2);
}

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    uint gi = pc.view * npix + p;
    vec4 xp = gpos[gi];
    if (xp.w <= 0.0) { e_add[p] = vec4(0.0); return; }
    vec3 eye = cam_center(cams[pc.view]);
    vec3 n0 = gnrm[gi].xyz;
    if (dot(n0, eye - xp.xyz) < 0.0) n0 = -n0;
    vec3 sum = vec3(0.0);
    for (uint s = 0u; s < pc.samples; ++s) {
        vec3 x = xp.xyz, n = n0, thr = vec3(1.0);
        for (uint b = 0u; b <= pc.bounces; ++b) {
            uint k = s * 64u + 2u * b;
            sum += thr * direct(x, n, rand2(uvec3(gi, k, pc.seed)));
            if (b == pc.bounces) break;
            vec3 d = cosine_dir(n, rand2(uvec3(gi, k + 1u, pc.seed)));
            rayQueryEXT rq;
            rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFF, x + n * 1e-3, 1e-3, d, 1e4);
            while (rayQueryProceedEXT(rq)) {}
            if (rayQueryGetIntersectionTypeEXT(rq, true) != gl_RayQueryCommittedIntersectionTriangleEXT) break;
            uint tri = uint(rayQueryGetIntersectionPrimitiveIndexEXT(rq, true));
            vec2 bc = rayQueryGetIntersectionBarycentricsEXT(rq, true);
            uvec3 t = uvec3(indices[3u * tri], indices[3u * tri + 1u], indices[3u * tri + 2u]);
            vec3 a = verts[t.x], bb = verts[t.y], c = verts[t.z];
            x = x + n * 1e-3 + d * rayQueryGetIntersectionTEXT(rq, true);
            n = normalize(cross(bb - a, c - a));
            if (dot(n, d) > 0.0) n = -n;
            vec3 rho = (1.0 - bc.x - bc.y) * albedo[t.x].rgb + bc.x * albedo[t.y].rgb + bc.y * albedo[t.z].rgb;
            thr *= clamp(rho, vec3(0.0), vec3(1.0));
        }
    }
    e_add[p] = vec4(sum / float(pc.samples), 1.0);
}
