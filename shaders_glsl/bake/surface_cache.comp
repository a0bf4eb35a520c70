#version 460
// The surface cache of one added light (§4.1.3, computed once per surface point instead of once
// per pixel of every view): the indirect part of E_add at each texel — a vertex of the bake
// mesh, once per crease side — path traced on the albedo mesh. The direct part stays per pixel
// (added_irradiance.comp), so small lights keep sharp shadows; the indirect part is smooth and
// a texel every few centimetres holds it. Each path: a cosine-sampled ray from the texel, the
// interpolated vertex albedo as throughput, next-event estimation at every hit:
//   E_ind(x) ≈ Σ_{k≥1} (Π_{m≤k} ρ(y_m)) E_dir(y_k).
// `bounces` caps the path (6: the ground truth's path depth); past RR_START bounces Russian
// roulette ends most paths early. A ray that leaves the proxy went through a hole of the MVS
// mesh (the room is closed), so its direction is drawn again, up to MISS_RETRIES times.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
#include "nee.glsl"
#include "random.glsl"
layout(set = 0, binding = 1, scalar) readonly buffer Verts { vec3 verts[]; };
layout(set = 0, binding = 2) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 3) readonly buffer Albedo { vec4 albedo[]; };
layout(set = 0, binding = 4) readonly buffer Texels { vec4 texel_pos[]; };
layout(set = 0, binding = 5) readonly buffer Normals { vec4 texel_nrm[]; };
layout(set = 0, binding = 6) writeonly buffer Out { vec4 e_ind[]; };
// With `use_list`, invocation i traces texel texel_list[first + i] (the live lights refine the
// texels the frame shows first); otherwise texel first + i. Either way the result goes to e_ind
// at the texel's index.
layout(set = 0, binding = 7) readonly buffer List { uint texel_list[]; };

layout(push_constant, scalar) uniform Push {
    uint first; uint count; uint samples; uint seed; uint bounces; uint use_list; uvec2 pad;  // Light starts 16-byte aligned, as in Rust
    Light light;
} pc;

const uint RR_START = 2u;
const uint MISS_RETRIES = 4u;

void main() {
    if (gl_GlobalInvocationID.x >= pc.count) return;
    uint t = pc.use_list != 0u ? texel_list[pc.first + gl_GlobalInvocationID.x]
                               : pc.first + gl_GlobalInvocationID.x;
    vec3 x0 = texel_pos[t].xyz, n0 = texel_nrm[t].xyz;
    vec3 sum = vec3(0.0);
    for (uint s = 0u; s < pc.samples; ++s) {
        vec3 x = x0, n = n0, thr = vec3(1.0);
        for (uint b = 1u; b <= pc.bounces; ++b) {
            uint k = s * 64u + 2u * b;
            vec3 d;
            rayQueryEXT rq;
            bool hit = false;
            for (uint r = 0u; r < MISS_RETRIES && !hit; ++r) {
                d = cosine_dir(n, rand2(uvec3(t, k + 1u, pc.seed + r * 0x9E3779B9u)));
                rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT, 0xFF, x + n * 1e-3, 1e-3, d, 1e4);
                while (rayQueryProceedEXT(rq)) {}
                hit = rayQueryGetIntersectionTypeEXT(rq, true) == gl_RayQueryCommittedIntersectionTriangleEXT;
            }
            if (!hit) break;
            uint tri = uint(rayQueryGetIntersectionPrimitiveIndexEXT(rq, true));
            vec2 bc = rayQueryGetIntersectionBarycentricsEXT(rq, true);
            uvec3 v = uvec3(indices[3u * tri], indices[3u * tri + 1u], indices[3u * tri + 2u]);
            vec3 a = verts[v.x], bb = verts[v.y], c = verts[v.z];
            x = x + n * 1e-3 + d * rayQueryGetIntersectionTEXT(rq, true);
            n = normalize(cross(bb - a, c - a));
            if (dot(n, d) > 0.0) n = -n;
            vec3 rho = (1.0 - bc.x - bc.y) * albedo[v.x].rgb + bc.x * albedo[v.y].rgb + bc.y * albedo[v.z].rgb;
            thr *= clamp(rho, vec3(0.0), vec3(1.0));
            if (b >= RR_START) {
                float q = min(max(thr.r, max(thr.g, thr.b)), 0.95);
                if (rand2(uvec3(t, k + 1u, ~pc.seed)).x >= q) break;
                thr /= q;
            }
            sum += thr * light_direct(pc.light, x, n, rand2(uvec3(t, k, pc.seed)), pc.light.radiance.w);
        }
    }
    e_ind[t] = vec4(sum / float(pc.samples), 1.0);
}
