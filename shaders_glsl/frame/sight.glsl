// Shadow rays shared between neighbouring pixels (frame/glossy.comp; CPU twin: frame/glossy.rs
// `shared_sight`). A light's visibility changes little from one pixel to the next on one
// surface, and a ray query costs a whole SIMD vector of pixels on a CPU device (and a warp on a
// GPU) whether one lane traces or all: so the lights are dealt out, pixel i of the workgroup
// tracing slot r·m + i mod m in round r (m = min(slots, GLOSSY_SIGHT_SPAN)), and each pixel
// takes a slot's answer from the nearest pixel that traced it, where that pixel lies on the
// same surface (within GLOSSY_SIGHT_DIST, normals within ~25°) and traced it; else it traces
// its own ray.
// Slots: the original lights (at most MAX_ORIG), then the lit added lights in order, at most
// SIGHT_MAX in all. The includer includes lobe.glsl and runs in workgroups of SIGHT_GROUP
// invocations over consecutive pixels, reaching `shared_sight` in uniform control flow.
#ifndef RELIT_SIGHT_GLSL
#define RELIT_SIGHT_GLSL

const uint SIGHT_MAX = 32u;
const uint SIGHT_GROUP = 64u;

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

// Slot k's answer at this pixel (li in the workgroup), from the pixel that traced it when it
// may stand in for this one, else from a ray of its own.
bool slot_seen(uint k, uint m, uint li, vec3 x, vec3 n, Light l) {
    if (!faces_light(x, n, l)) return false;
    uint j = li - li % m + k % m;
    if (j >= SIGHT_GROUP) j -= m;
    uint b = (sight_bits[j] >> (2u * (k / m))) & 3u;
    bool near = j == li || (distance(sight_x[j], x) <= GLOSSY_SIGHT_DIST && dot(sight_n[j], n) >= 0.9);
    return near && (b & 1u) != 0u ? (b & 2u) != 0u : sees_light(x, n, l);
}

// Bit k: whether this pixel (`on`: it needs the answers) at x, normal n, sees slot k's light.
uint shared_sight(bool on, vec3 x, vec3 n) {
    uint li = gl_LocalInvocationIndex;
    uint no;
    uint nk = sight_slots(no);
    uint m = max(min(nk, GLOSSY_SIGHT_SPAN), 1u);
    uint mine = 0u;
    for (uint r = 0u; r * m < nk; ++r) {
        uint k = r * m + li % m;
        if (!on || k >= nk) continue;
        Light l = sight_light(k, no);
        if (faces_light(x, n, l)) mine |= (sees_light(x, n, l) ? 3u : 1u) << (2u * r);
    }
    sight_x[li] = x;
    sight_n[li] = n;
    sight_bits[li] = mine;
    barrier();
    uint seen = 0u;
    if (!on) return seen;
    for (uint k = 0u; k < nk; ++k)
        if (slot_seen(k, m, li, x, n, sight_light(k, no))) seen |= 1u << k;
    return seen;
}

#endif
