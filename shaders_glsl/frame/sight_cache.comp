#version 460
// The sight cache (frame/sight_cache.rs): at each of its points, for each column's light, how
// many of SIGHT_CACHE_SAMPLES rays to points of the light's area arrive, 8 bits a column, four
// columns a word (a light's samples are keyed by its column). A ray starts SIGHT_LIFT off the
// surface on the light point's side (a point's normal may face either way; the glossy layer
// tests facing with its own) and ends 5 cm short of the light, as lobe.glsl's `sees_light`.
#extension GL_EXT_ray_query : require
#extension GL_EXT_scalar_block_layout : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#include "constants.glsl"
#include "lights.glsl"

layout(set = 0, binding = 0) uniform accelerationStructureEXT tlas;
layout(set = 0, binding = 1) readonly buffer SightPoints { vec4 points[]; };
layout(set = 0, binding = 2) readonly buffer SightNormals { vec4 normals[]; };
layout(set = 0, binding = 3, scalar) readonly buffer SightLights { Light lights[]; };
layout(set = 0, binding = 4) buffer SightOut { uint vis[]; };

#include "nee.glsl"

// Columns col0 .. col0 + ncols − 1 are traced; the point's other columns are kept (a cache grows
// a column per newly lit light), and with col0 = 0 its words start from zero.
layout(push_constant) uniform Push { uint first; uint count; uint col0; uint ncols; } pc;

const uint WORDS = 8u;  // sight_cache.rs: 32 columns, four a word

bool reaches(vec3 x, vec3 n, vec3 q) {
    vec3 d = q - x;
    float dist = length(d);
    if (dist < 0.06) return false;
    vec3 o = x + (dot(d, n) >= 0.0 ? n : -n) * SIGHT_LIFT;
    return !occluded(o, d / dist, dist - 0.05);
}

void main() {
    if (gl_GlobalInvocationID.x >= pc.count) return;
    uint p = pc.first + gl_GlobalInvocationID.x;
    vec3 x = points[p].xyz, n = normals[p].xyz;
    if (pc.col0 == 0u)
        for (uint w = 0u; w < WORDS; ++w) vis[p * WORDS + w] = 0u;
    for (uint c = pc.col0; c < min(pc.col0 + pc.ncols, 4u * WORDS); ++c) {
        uint count = 0u;
        for (uint s = 0u; s < SIGHT_CACHE_SAMPLES; ++s) {
            vec3 q, nl;
            float area;
            light_sample(lights[c - pc.col0], rand2(uvec3(p, s, c)), q, nl, area);
            if (reaches(x, n, q)) ++count;
        }
        uint i = p * WORDS + c / 4u, shift = 8u * (c % 4u);
        vis[i] = (vis[i] & ~(255u << shift)) | (count << shift);
    }
}
