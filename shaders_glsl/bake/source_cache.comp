#version 460
// Source irradiance E_src of one input view (§4.1.1) from its two parts, each computed where it
// is cheapest: the declared original lights' direct part by next-event estimation at every pixel
// (their shadows stay as sharp as the per-pixel estimator had them), plus the views' indirect
// part read from the source cache at the pixel's point: the texels at the corners of its
// triangle, interpolated barycentrically (source_cache.rs traced them with
// source_irradiance_vertices.comp). Light is counted once as in source_irradiance.glsl: the
// texels' cosine rays that meet a declared light carry no radiance. w = 1 where a corner has an
// estimate (the denoiser's weight), else 0.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 1
#include "source_irradiance.glsl"
#include "barycentric.glsl"

layout(set = 0, binding = 9, scalar) readonly buffer Verts { vec3 verts[]; };
layout(set = 0, binding = 10) readonly buffer Cache { vec4 cache[]; };
layout(set = 0, binding = 11) readonly buffer Corners { uint corner_texel[]; };

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    uint gi = pc.view * npix + p;
    vec4 xp = gpos[gi];
    uint tri = pixel_tri[gi];
    if (xp.w <= 0.0 || tri == 0u) { e_src[p] = vec4(0.0); return; }
    tri -= 1u;
    vec3 n = gnrm[gi].xyz;
    if (dot(n, cam_center(cams[pc.view]) - xp.xyz) < 0.0) n = -n;   // the side the camera sees
    vec3 direct = source_irradiance(xp.xyz, n, pc.view, gi).rgb;
    uvec3 v = uvec3(indices[3u * tri], indices[3u * tri + 1u], indices[3u * tri + 2u]);
    vec3 l = barycentrics(xp.xyz, verts[v.x], verts[v.y], verts[v.z]);
    uvec3 c = uvec3(corner_texel[3u * tri], corner_texel[3u * tri + 1u], corner_texel[3u * tri + 2u]);
    vec4 ind = l.x * cache[c.x] + l.y * cache[c.y] + l.z * cache[c.z];
    // A corner without an estimate (w = 0) leaves the others' weights.
    e_src[p] = ind.w > 0.0 ? vec4(direct + ind.rgb / ind.w, 1.0) : vec4(direct, 0.0);
}
