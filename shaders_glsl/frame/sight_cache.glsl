// The sight cache's lookup (frame/sight_cache.rs; the cache: sight_cache.comp): which still
// lights a pixel's point sees, interpolated from its triangle's points instead of traced. The
// includer includes frame.glsl, emitters.glsl and lobe.glsl, and enables scalar layout.
#ifndef RELIT_SIGHT_CACHE_GLSL
#define RELIT_SIGHT_CACHE_GLSL
#include "barycentric.glsl"
#include "frame_mesh.glsl"

// Per triangle: its corners' texels and 1, or (its grid's first point, 0, 0, resolution r).
layout(set = 0, binding = 36) readonly buffer SightTris { uvec4 sight_tris[]; };
// Per point, 8 words: four 8-bit counts of SIGHT_CACHE_SAMPLES rays each.
layout(set = 0, binding = 37) readonly buffer SightVis { uint sight_vis[]; };
// Per slot (sight.glsl): its light's column, plus SIGHT_SHARP for a light of at most
// SIGHT_SHARP_AREA; or SIGHT_NO_COLUMN (it traces).
layout(set = 0, binding = 38) readonly buffer SightCols { uint sight_cols[]; };

const uint SIGHT_WORDS = 8u;
const uint SIGHT_NO_COLUMN = 0xFFFFFFFFu;
const uint SIGHT_SHARP = 0x100u;

// The slots (of nk) whose lights have a column: the same in every invocation.
uint sight_cached(uint nk) {
    uint m = 0u;
    for (uint k = 0u; k < nk; ++k)
        if (sight_cols[k] != SIGHT_NO_COLUMN) m |= 1u << k;
    return m;
}

// Grid point (i, j) of triangle entry e: a corner's texel, or row j (of r + 1 − j points).
uint sight_point(uvec4 e, uint i, uint j) {
    if (e.w == 1u) return i == 1u ? e.y : (j == 1u ? e.z : e.x);
    return e.x + j * (2u * e.w + 3u - j) / 2u + i;
}

// The points around x on triangle tri and their weights: the grid cell holding x's
// barycentrics, split into its two triangles.
void sight_weights(uint tri, vec3 x, out uvec3 pts, out vec3 w) {
    uvec3 v = uvec3(live_indices[3u * tri], live_indices[3u * tri + 1u], live_indices[3u * tri + 2u]);
    vec3 l = barycentrics(x, live_verts[v.x], live_verts[v.y], live_verts[v.z]);
    uvec4 e = sight_tris[tri];
    uint r = e.w;
    float fi = l.y * float(r), fj = l.z * float(r);
    uint i0 = min(uint(fi), r);
    uint j0 = min(uint(fj), r - i0);
    float u = fi - float(i0), t = fj - float(j0);
    if (i0 + j0 == r) {
        pts = uvec3(sight_point(e, i0, j0));
        w = vec3(1.0, 0.0, 0.0);
    } else if (u + t <= 1.0 || i0 + j0 + 2u > r) {
        pts = uvec3(sight_point(e, i0, j0), sight_point(e, i0 + 1u, j0), sight_point(e, i0, j0 + 1u));
        w = max(vec3(1.0 - u - t, u, t), vec3(0.0));
        w /= max(w.x + w.y + w.z, 1e-20);
    } else {
        pts = uvec3(sight_point(e, i0 + 1u, j0 + 1u), sight_point(e, i0, j0 + 1u),
                    sight_point(e, i0 + 1u, j0));
        w = vec3(u + t - 1.0, 1.0 - u, 1.0 - t);
    }
}

float sight_count(uint p, uint col) {
    return float((sight_vis[p * SIGHT_WORDS + col / 4u] >> (8u * (col % 4u))) & 255u);
}

// Bit k for each slot k in `cached`: whether x (normal n) on triangle tri faces its light and
// sees at least half of it, its points' counts interpolated. Bit k of `unsure`: a small light's
// hard shadow edge crosses the cell (its points straddle half and differ by half of the rays or
// more): the pixel traces its own ray there, which keeps the edge where a ray puts it and the
// shadows narrower than the points' spacing. A large light's penumbra is soft and interpolates
// (tracing its edges too took the demo room's layer from 11 to 26 ms on lavapipe).
uint cache_sight(uint cached, uint tri, vec3 x, vec3 n, uint no, out uint unsure) {
    unsure = 0u;
    if (cached == 0u) return 0u;
    uvec3 pts;
    vec3 w;
    sight_weights(tri, x, pts, w);
    uint seen = 0u;
    float half_count = 0.5 * float(SIGHT_CACHE_SAMPLES);
    for (uint m = cached; m != 0u; m &= m - 1u) {
        uint k = uint(findLSB(m)), c = sight_cols[k] & 0xFFu;
        bool sharp = (sight_cols[k] & SIGHT_SHARP) != 0u;
        if (!faces_light(x, n, sight_light(k, no))) continue;
        vec3 cnt = vec3(sight_count(pts.x, c), sight_count(pts.y, c), sight_count(pts.z, c));
        // A point of weight zero (x on its cell's far side) has no say.
        bvec3 say = greaterThan(w, vec3(0.0));
        vec3 hi = mix(vec3(-1.0), cnt, say), lo = mix(vec3(1e9), cnt, say);
        float top = max(hi.x, max(hi.y, hi.z)), bottom = min(lo.x, min(lo.y, lo.z));
        if (sharp && top >= half_count && bottom < half_count && top - bottom >= half_count)
            unsure |= 1u << k;
        else if (dot(w, cnt) >= half_count)
            seen |= 1u << k;
    }
    return seen;
}

#endif
