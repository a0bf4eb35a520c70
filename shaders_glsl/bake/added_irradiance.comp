#version 460
// Added irradiance E_add of one view for one user light (§4.1.3): the direct part by
// next-event estimation at every pixel (shadow rays; small lights keep sharp shadows), plus the
// indirect part read from the light's surface cache (surface_cache.comp) at the pixel's point:
// the texels at the corners of its triangle, interpolated barycentrically.
// The light is not in the mesh, so rays never hit it: its light arrives by the NEE only.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 1
#include "views.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
#include "nee.glsl"
#include "barycentric.glsl"
layout(set = 0, binding = 5, scalar) readonly buffer Verts { vec3 verts[]; };
layout(set = 0, binding = 6) readonly buffer Indices { uint indices[]; };
// The cache: indirect E_add per texel, and the texel at each triangle corner.
layout(set = 0, binding = 8) readonly buffer Cache { vec4 cache[]; };
layout(set = 0, binding = 9) readonly buffer Corners { uint corner_texel[]; };
layout(set = 0, binding = 10) writeonly buffer Out { vec4 e_add[]; };

layout(push_constant, scalar) uniform Push {
    uint view; uint width; uint height; uint samples; uint seed; uvec3 pad;  // Light starts 16-byte aligned, as in Rust
    Light light;
} pc;

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    uint gi = pc.view * npix + p;
    vec4 xp = gpos[gi];
    uint tri = pixel_tri[gi];
    if (xp.w <= 0.0 || tri == 0u) { e_add[p] = vec4(0.0); return; }
    tri -= 1u;
    vec3 eye = cam_center(cams[pc.view]);
    vec3 n = gnrm[gi].xyz;
    if (dot(n, eye - xp.xyz) < 0.0) n = -n;
    vec3 dir = vec3(0.0);
    for (uint s = 0u; s < pc.samples; ++s)
        dir += light_direct(pc.light, xp.xyz, n, rand2(uvec3(gi, s * 64u, pc.seed)), pc.light.radiance.w);
    uvec3 v = uvec3(indices[3u * tri], indices[3u * tri + 1u], indices[3u * tri + 2u]);
    vec3 l = barycentrics(xp.xyz, verts[v.x], verts[v.y], verts[v.z]);
    uvec3 c = uvec3(corner_texel[3u * tri], corner_texel[3u * tri + 1u], corner_texel[3u * tri + 2u]);
    vec3 ind = l.x * cache[c.x].rgb + l.y * cache[c.y].rgb + l.z * cache[c.z].rgb;
    e_add[p] = vec4(dir / float(pc.samples) + ind, 1.0);
}
