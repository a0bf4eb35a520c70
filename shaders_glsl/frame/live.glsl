// Live lights: added lights being placed or moved in the viewer. Their E_add is evaluated at
// the surface point every frame instead of read from per-view maps (which they do not have
// yet): the direct part by next-event estimation, plus the light's surface cache, which the
// viewer refines a few paths per texel at a time while nothing moves. Same quantity as a baked
// E_add map holds (§4.1.3), at the point itself. The includer declares `tlas` (binding 12).
#ifndef RELIT_LIVE_GLSL
#define RELIT_LIVE_GLSL
#include "nee.glsl"
#include "barycentric.glsl"

struct LiveLight {
    Light light;
    uint layer;     // the added light's index (its intensity, its E_add layers when baked)
    uint samples;   // shadow rays per point
    uint texels;    // cache i holds texels [i * texels, (i + 1) * texels)
    uint pad;
};

#include "frame_mesh.glsl"
layout(set = 0, binding = 23) readonly buffer LiveCaches { vec4 live_cache[]; };
layout(set = 0, binding = 24) readonly buffer LiveCorners { uint live_corners[]; };
layout(set = 0, binding = 25, scalar) readonly buffer Lives { LiveLight lives[]; };

// Whether added light l is live (its per-view layers are not read). Lights past 31 cannot be.
bool is_live(uint l, uint mask) { return l < 32u && (mask & (1u << l)) != 0u; }

// The geometric normal of bake-mesh triangle `tri`, facing `toward`.
vec3 live_normal(uint tri, vec3 toward) {
    uvec3 v = uvec3(live_indices[3u * tri], live_indices[3u * tri + 1u], live_indices[3u * tri + 2u]);
    vec3 n = normalize(cross(live_verts[v.y] - live_verts[v.x], live_verts[v.z] - live_verts[v.x]));
    return dot(n, toward) < 0.0 ? -n : n;
}

// E_add of live light i at x (normal n) on bake-mesh triangle `tri`; `key` seeds the samples.
vec3 live_eadd(uint i, vec3 x, vec3 n, uint tri, uint key) {
    LiveLight L = lives[i];
    vec3 dir = vec3(0.0);
    for (uint s = 0u; s < L.samples; ++s)
        dir += light_direct(L.light, x, n, rand2(uvec3(key, s, i)), 0.0);
    uvec3 v = uvec3(live_indices[3u * tri], live_indices[3u * tri + 1u], live_indices[3u * tri + 2u]);
    vec3 l = barycentrics(x, live_verts[v.x], live_verts[v.y], live_verts[v.z]);
    uint base = i * L.texels;
    uvec3 c = uvec3(live_corners[3u * tri], live_corners[3u * tri + 1u], live_corners[3u * tri + 2u]) + base;
    vec3 ind = l.x * live_cache[c.x].rgb + l.y * live_cache[c.y].rgb + l.z * live_cache[c.z].rgb;
    return dir / float(max(L.samples, 1u)) + ind;
}

#endif
