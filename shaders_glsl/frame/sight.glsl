// Shadow rays shared between neighbouring pixels (frame/glossy.comp; CPU twin: frame/glossy.rs
// `shared_sight`). A light's visibility changes little from one pixel to the next on one
// surface, and a ray query costs a whole SIMD vector of pixels on a CPU device (and a warp on a
// GPU) whether one lane traces or all: so the lights are dealt out, pixel i of the workgroup
// tracing slot r·m + i mod m in round r (m = min(slots, GLOSSY_SIGHT_SPAN)), and each pixel
// takes a slot's answer from the two nearest pixels that traced it, one on each side, that lie
// on its surface (within GLOSSY_SIGHT_DIST, normals within ~25°); where they disagree (a
// shadow's edge) or none may answer, it traces its own ray.
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

// Round r's answer of pixel j for a pixel at x, normal n: 1 seen, 0 not, −1 none it may take
// (j outside the workgroup, another surface, or j did not trace).
int answer(int j, uint r, vec3 x, vec3 n) {
    if (j < 0 || j >= int(SIGHT_GROUP)) return -1;
    uint b = (sight_bits[j] >> (2u * r)) & 3u;
    bool near = distance(sight_x[j], x) <= GLOSSY_SIGHT_DIST && dot(sight_n[j], n) >= 0.9;
    return (b & 1u) != 0u && near ? int(b >> 1u) : -1;
}

// Slot k's answer at this pixel (li in the workgroup): its own where it traced k; else that of
// the two nearest pixels that traced it, one on each side, where they agree, or of the one it
// may take (the other outside the workgroup or on another surface); a ray of its own where
// they disagree (a shadow's edge) or neither may answer.
bool slot_seen(uint k, uint m, uint li, vec3 x, vec3 n, Light l) {
    if (!faces_light(x, n, l)) return false;
    uint r = k / m, c = k % m;
    int j0 = int(li) - int((li + m - c) % m);
    int a0 = answer(j0, r, x, n);
    if (j0 == int(li) && a0 >= 0) return a0 == 1;
    int a1 = j0 == int(li) ? -1 : answer(j0 + int(m), r, x, n);
    if (a0 >= 0 && a1 >= 0 && a0 != a1) return sees_light(x, n, l);
    if (max(a0, a1) >= 0) return max(a0, a1) == 1;
    return sees_light(x, n, l);
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
