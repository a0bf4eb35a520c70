#version 460
// Added irradiance E_add of one view for one user light (§4.1.3), path traced on the albedo
// mesh: at each bounce, next-event estimation towards the light (shadow ray), then a
// cosine-sampled continuation whose throughput is the interpolated vertex albedo. With cosine
// sampling the π of E = π·L cancels the 1/π of Lambertian reflection:
//   E(x) ≈ E_dir(x) + Σ_k (Π_{m≤k} ρ(y_m)) E_dir(y_k).
// The light is not in the mesh, so rays never hit it: its light arrives by the NEE only.
// `bounces` caps the path (the ground truth's path tracer stops at depth 8, i.e. 6 bounces
// after the first indirect ray); past RR_START bounces Russian roulette ends most paths early.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 1
#include "views.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
#include "nee.glsl"
layout(set = 0, binding = 5, scalar) readonly buffer Verts { vec3 verts[]; };
layout(set = 0, binding = 6) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 7) readonly buffer Albedo { vec4 albedo[]; };
layout(set = 0, binding = 8) writeonly buffer Out { vec4 e_add[]; };
// The indirect part alone (bounces ≥ 1): the bake filters it and keeps the direct part sharp.
layout(set = 0, binding = 9) writeonly buffer Indirect { vec4 e_ind[]; };

layout(push_constant, scalar) uniform Push {
    uint view; uint width; uint height; uint samples; uint seed; uint bounces; uint pad0; uint pad1;
    Light light;
} pc;

const uint RR_START = 2u;
const uint MISS_RETRIES = 4u;

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    uint gi = pc.view * npix + p;
    vec4 xp = gpos[gi];
    if (xp.w <= 0.0) { e_add[p] = vec4(0.0); e_ind[p] = vec4(0.0); return; }
    vec3 eye = cam_center(cams[pc.view]);
    vec3 n0 = gnrm[gi].xyz;
    if (dot(n0, eye - xp.xyz) < 0.0) n0 = -n0;
    vec3 sum = vec3(0.0), dir = vec3(0.0);
    for (uint s = 0u; s < pc.samples; ++s) {
        vec3 x = xp.xyz, n = n0, thr = vec3(1.0);
        for (uint b = 0u; b <= pc.bounces; ++b) {
            uint k = s * 64u + 2u * b;
            vec3 e = thr * light_direct(pc.light, x, n, rand2(uvec3(gi, k, pc.seed)), 0.0);
            if (b == 0u) dir += e; else sum += e;
            if (b == pc.bounces) break;
            // A ray that leaves the proxy went through a hole of the MVS mesh (the room is
            // closed): as E_src drops such rays, draw the direction again.
            vec3 d;
            rayQueryEXT rq;
            bool hit = false;
            for (uint r = 0u; r < MISS_RETRIES && !hit; ++r) {
                d = cosine_dir(n, rand2(uvec3(gi, k + 1u, pc.seed + r * 0x9E3779B9u)));
                rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFF, x + n * 1e-3, 1e-3, d, 1e4);
                while (rayQueryProceedEXT(rq)) {}
                hit = rayQueryGetIntersectionTypeEXT(rq, true) == gl_RayQueryCommittedIntersectionTriangleEXT;
            }
            if (!hit) break;
            uint tri = uint(rayQueryGetIntersectionPrimitiveIndexEXT(rq, true));
            vec2 bc = rayQueryGetIntersectionBarycentricsEXT(rq, true);
            uvec3 t = uvec3(indices[3u * tri], indices[3u * tri + 1u], indices[3u * tri + 2u]);
            vec3 a = verts[t.x], bb = verts[t.y], c = verts[t.z];
            x = x + n * 1e-3 + d * rayQueryGetIntersectionTEXT(rq, true);
            n = normalize(cross(bb - a, c - a));
            if (dot(n, d) > 0.0) n = -n;
            vec3 rho = (1.0 - bc.x - bc.y) * albedo[t.x].rgb + bc.x * albedo[t.y].rgb + bc.y * albedo[t.z].rgb;
            thr *= clamp(rho, vec3(0.0), vec3(1.0));
            // Russian roulette past RR_START bounces: unbiased, and most paths stop early.
            if (b + 1u >= RR_START) {
                float q = min(max(thr.r, max(thr.g, thr.b)), 0.95);
                if (rand2(uvec3(gi, k + 1u, ~pc.seed)).x >= q) break;
                thr /= q;
            }
        }
    }
    e_add[p] = vec4((dir + sum) / float(pc.samples), 1.0);
    e_ind[p] = vec4(sum / float(pc.samples), 1.0);
}
