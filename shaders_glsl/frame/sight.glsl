// Shadow rays shared between neighbouring pixels (frame/glossy.comp; CPU twin: frame/sight.rs).
// A light's visibility changes little from one pixel to the next on one surface, and a ray query
// costs a whole SIMD vector of pixels on a CPU device (and a warp on a GPU) whether one lane
// traces or all: so a workgroup is a tile of SIGHT_TILE² pixels whose rows are vectors on
// llvmpipe, only every GLOSSY_SIGHT_ROWS-th row traces (`traces`), and the lights are dealt out
// along it, pixel (tx, ty) tracing slot r·m + c in round r, c = tx mod m mirrored every other
// tracing row (`slot_column`; m = min(slots, GLOSSY_SIGHT_SPAN)). A pixel takes a slot's answer
// from the nearest pixels that traced it (the columns with that slot on either side, in its
// own row and the tracing rows before and after where it traces, else in the tracing rows
// above and below) that lie on its plane (within GLOSSY_SIGHT_DIST of it and GLOSSY_SIGHT_REACH
// away, normals within ~25°) where all of them agree; where they disagree (a shadow's edge) or
// none may answer, it traces its own ray.
// Slots: the original lights (at most MAX_ORIG), then the lit added lights in order, at most
// SIGHT_MAX in all. A slot whose light is still has a column in the sight cache
// (sight_cache.glsl) and is read there; only the others (lights being moved) are dealt out as
// above, in their order, as if they were all the slots. The includer includes lobe.glsl, dispatches one workgroup of SIGHT_GROUP
// invocations per tile (`tile_pixel`) and reaches `shared_sight` in uniform control flow.
#ifndef RELIT_SIGHT_GLSL
#define RELIT_SIGHT_GLSL

const uint SIGHT_MAX = 32u;
const uint SIGHT_TILE = 8u;
const uint SIGHT_GROUP = SIGHT_TILE * SIGHT_TILE;

shared vec3 sight_x[SIGHT_GROUP];
shared vec3 sight_n[SIGHT_GROUP];
shared uint sight_bits[SIGHT_GROUP];

// Whether x (normal n) faces light l near enough to trace (sees_light's own tests).
bool faces_light(vec3 x, vec3 n, Light l) {
    vec3 c, nl;
    float area;
    light_frame(l, c, nl, area);
    vec3 d = c - x;
    return dot(d, n) > 0.0 && length(d) >= 0.06;
}

// The original lights that take part, and the slots in all.
uint sight_slots(out uint no) {
    no = min(pc.norig, MAX_ORIG);
    uint k = no;
    for (uint l = 0u; l < pc.nlights; ++l)
        if (intensity[l] > 0.0) ++k;
    return min(k, SIGHT_MAX);
}

// The light of slot k: original k, or the (k − no)-th lit added light.
Light sight_light(uint k, uint no) {
    if (k < no) return originals[k].light;
    uint seen = no;
    for (uint l = 0u; l < pc.nlights; ++l) {
        if (intensity[l] <= 0.0) continue;
        if (seen == k) return emitters[l];
        ++seen;
    }
    return emitters[0];
}

#include "sight_cache.glsl"

// This invocation's pixel (x, y): tile gl_WorkGroupID.x of the image's rows of tiles.
uvec2 tile_pixel() {
    uint tiles_x = (pc.width + SIGHT_TILE - 1u) / SIGHT_TILE;
    uint t = gl_WorkGroupID.x, li = gl_LocalInvocationIndex;
    return uvec2(t % tiles_x, t / tiles_x) * SIGHT_TILE + uvec2(li % SIGHT_TILE, li / SIGHT_TILE);
}

// The tracing rows: every GLOSSY_SIGHT_ROWS-th, and the tile's last where the rows after the
// last of those would be more than one (so that the rows between have one above and one below).
const bool SIGHT_LAST_ROW = (SIGHT_TILE - 1u) % GLOSSY_SIGHT_ROWS > 1u;
bool traces(uint ty) {
    return ty % GLOSSY_SIGHT_ROWS == 0u || (SIGHT_LAST_ROW && ty == SIGHT_TILE - 1u);
}

// The tracing rows before and after tracing row y (either may lie outside the tile).
int row_before(int y) {
    return SIGHT_LAST_ROW && y == int(SIGHT_TILE) - 1 ? y - y % int(GLOSSY_SIGHT_ROWS)
                                                       : y - int(GLOSSY_SIGHT_ROWS);
}
int row_after(int y) {
    int next = y + int(GLOSSY_SIGHT_ROWS);
    return SIGHT_LAST_ROW && y < int(SIGHT_TILE) - 1 ? min(next, int(SIGHT_TILE) - 1) : next;
}

// The column (mod m) where tracing row y traces slot column c: mirrored every other tracing
// row, so that a pixel near a tile's side finds the slot on its far side in a row nearby.
uint slot_column(uint c, uint m, int y) {
    return ((uint(y) + GLOSSY_SIGHT_ROWS - 1u) / GLOSSY_SIGHT_ROWS) % 2u == 0u ? c : m - 1u - c;
}

// Round r's answer of the pixel at t in the tile for a pixel at x, normal n: 1 seen, 0 not,
// −1 none it may take (outside the tile, a hole, not on x's plane, or it did not trace).
int answer(ivec2 t, uint r, vec3 x, vec3 n) {
    if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, ivec2(SIGHT_TILE)))) return -1;
    uint j = uint(t.y) * SIGHT_TILE + uint(t.x);
    uint b = (sight_bits[j] >> (2u * r)) & 3u;
    vec3 d = sight_x[j] - x;
    bool near = abs(dot(d, n)) <= GLOSSY_SIGHT_DIST
        && dot(d, d) <= GLOSSY_SIGHT_REACH * GLOSSY_SIGHT_REACH && dot(sight_n[j], n) >= 0.9;
    return (b & 1u) != 0u && near ? int(b >> 1u) : -1;
}

// Slot k's answer at this pixel (tx, ty in the tile): 1 seen, 0 not. Its own where it traced
// k; else that of the pixels that traced k around it (the tracing rows around, the columns
// with k on either side) where all that may answer agree; −1 (a ray of its own) where they
// disagree (a shadow's edge) or none may answer.
int slot_answer(uint k, uint m, uvec2 t, vec3 x, vec3 n, Light l) {
    if (!faces_light(x, n, l)) return 0;
    uint r = k / m, c = k % m;
    int ty = int(t.y), rows = int(GLOSSY_SIGHT_ROWS);
    if (traces(t.y) && t.x % m == slot_column(c, m, ty)) {
        int a = answer(ivec2(t), r, x, n);
        if (a >= 0) return a;
    }
    // The tracing rows around: before, its own and after where it traces, else the nearest
    // above and below.
    int y0 = traces(t.y) ? row_before(ty) : ty - ty % rows;
    int y1 = traces(t.y) ? ty : row_after(y0);
    int y2 = traces(t.y) ? row_after(ty) : y1;
    uint said = 0u;  // bit 0: some pixel saw it, bit 1: some did not
    for (uint i = 0u; i < 3u; ++i) {
        int y = i == 0u ? y0 : (i == 1u ? y1 : y2);
        if (y < 0 || y >= int(SIGHT_TILE) || (i == 2u && y2 == y1)) continue;
        int x0 = int(t.x) - int((t.x + m - slot_column(c, m, y)) % m);
        for (int dx = 0; dx < (x0 == int(t.x) ? 1 : 2); ++dx) {
            int a = answer(ivec2(x0 + dx * int(m), y), r, x, n);
            if (a >= 0) said |= a == 1 ? 1u : 2u;
        }
    }
    return said == 1u ? 1 : (said == 2u ? 0 : -1);
}

// The j-th slot (of nk) that traces: not in `cached`.
uint traced_slot(uint j, uint cached, uint nk) {
    for (uint k = 0u; k < nk; ++k) {
        if (((cached >> k) & 1u) != 0u) continue;
        if (j == 0u) return k;
        --j;
    }
    return nk;
}

// Bit k: whether this pixel (`on`: it needs the answers) at x, normal n, on triangle tri sees
// slot k's light. Slots with a column in the sight cache (sight_cache.glsl: still lights) read
// it; the others are dealt out as the header says, the j-th of them in place j. The rays of
// its own go last, one per pass of a loop whose lanes each take their next slot: a vector then
// pays for its pixels' largest count of such rays, not for every slot that one of its pixels
// needs.
uint shared_sight(bool on, vec3 x, vec3 n, uint tri) {
    uint li = gl_LocalInvocationIndex;
    uvec2 t = uvec2(li % SIGHT_TILE, li / SIGHT_TILE);
    uint no;
    uint nk = sight_slots(no);
    uint cached = sight_cached(nk);
    uint nt = nk - uint(bitCount(cached));
    uint m = max(min(nt, GLOSSY_SIGHT_SPAN), 1u);
    uint mine = 0u;
    for (uint r = 0u; r * m < nt; ++r) {
        if (!on || !traces(t.y)) continue;
        uint j = r * m + slot_column(t.x % m, m, int(t.y));
        if (j >= nt) continue;
        Light l = sight_light(traced_slot(j, cached, nk), no);
        if (faces_light(x, n, l)) mine |= (sees_light(x, n, l) ? 3u : 1u) << (2u * r);
    }
    sight_x[li] = x;
    sight_n[li] = n;
    sight_bits[li] = mine;
    barrier();
    if (!on) return 0u;
    uint own;
    uint seen = cache_sight(cached, tri, x, n, no, own);
    uint j = 0u;
    for (uint k = 0u; k < nk; ++k) {
        if (((cached >> k) & 1u) != 0u) continue;
        int a = slot_answer(j++, m, t, x, n, sight_light(k, no));
        if (a == 1) seen |= 1u << k;
        if (a < 0) own |= 1u << k;
    }
    while (own != 0u) {
        uint k = uint(findLSB(own));
        own &= own - 1u;
        if (sees_light(x, n, sight_light(k, no))) seen |= 1u << k;
    }
    return seen;
}

#endif
