// Lights seen through a glossy lobe (frame/glossy_sums.comp, frame/glossy.comp): a surface point's
// shadow ray to a light and the light's radiance through a GGX microfacet lobe.
// Needs: tlas, the Originals, Emitters and Intensity buffers (emitters.glsl) and the push
// constants norig, nlights, alpha_dim.
#ifndef RELIT_LOBE_GLSL
#define RELIT_LOBE_GLSL
#include "nee.glsl"

const uint LOBES = 3u;     // regressors: the original lights through three lobe widths
const uint MAX_ORIG = 8u;  // original lights that take part in the fit (shadow rays per pixel)

float lobe_width(uint c) {
    return c == 0u ? GLOSSY_LOBE_1 : (c == 1u ? GLOSSY_LOBE_2 : GLOSSY_LOBE_3);
}

// A light's centre, unit emitting normal and area.
void light_frame(Light l, out vec3 c, out vec3 nl, out float area) {
    if (l.p0.w < 0.5) {
        vec3 cr = cross(l.p1.xyz, l.p2.xyz);
        area = length(cr);
        nl = cr / area;
        c = l.p0.xyz + 0.5 * (l.p1.xyz + l.p2.xyz);
    } else {
        nl = normalize(l.p1.xyz);
        area = 3.14159265358979 * l.p2.x * l.p2.x;
        c = l.p0.xyz;
    }
}

// Whether x (normal n) sees light l's centre: one ray, from SIGHT_LIFT off the surface (n is
// a smoothed or a plane's normal: a ray 1 mm off a proxy from photos hit the proxy's own bumps
// and speckled highlights) to 5 cm short of the light (a declared light sits on the proxy).
bool sees_light(vec3 x, vec3 n, Light l) {
    vec3 c, nl;
    float area;
    light_frame(l, c, nl, area);
    vec3 d = c - x;
    float dist = length(d);
    if (dot(d, n) <= 0.0 || dist < 0.06) return false;
    return !occluded(x + n * SIGHT_LIFT, d / dist, dist - 0.05);
}

// Light l as seen from x: its solid angle Ω (0 from behind) and the unit direction w to its
// centre.
void light_seen(vec3 x, Light l, out float omega, out vec3 w) {
    vec3 c, nl;
    float area;
    light_frame(l, c, nl, area);
    vec3 d = c - x;
    float d2 = max(dot(d, d), 1e-6);
    w = d * inversesqrt(d2);
    float cosl = -dot(nl, w);
    omega = cosl > 0.0 ? min(area * cosl / d2, 2.0 * 3.14159265358979) : 0.0;
}

// A microfacet lobe of GGX roughness α lit by a light of solid angle Ω in unit direction w,
// seen from unit direction v over normal n: Ω·D(n·h)·F(v·h)·G1(n·v)·G1(n·w)/(4·n·v·F0), h the
// half vector, D the GGX distribution with α widened by the light's size (α'² = α² + Ω/8π: the
// light's disk, of radius √(Ω/π), halves in half-vector space), F Schlick's Fresnel of a
// dielectric (F0 = GLOSSY_F0, 0.04; divided by it, the fitted strength s reads as the
// surface's F0: 0.04 for plastic, lacquer, a TV; hand_room's table top fits 0.041), G1 Smith's
// masking of lobe α (without it a lamp at grazing incidence lit a rough table top with
// Fresnel's full 25×: sg700004). Zero from views more grazing than GLOSSY_COS_MIN (the sums
// pass skips them).
// Smith's GGX masking of one direction at cosine c to the normal.
float smith_g1(float alpha, float c) {
    float a2 = alpha * alpha;
    return 2.0 * c / (c + sqrt(a2 + (1.0 - a2) * c * c));
}

float lobe_weight(float alpha, float omega, vec3 w, vec3 v, vec3 n) {
    const float PI = 3.14159265358979;
    float cv = dot(n, v);
    if (cv < GLOSSY_COS_MIN || dot(n, w) <= 0.0) return 0.0;
    float a2 = alpha * alpha + omega / (8.0 * PI);
    vec3 h = normalize(w + v);
    float ch = max(dot(n, h), 0.0);
    float t = ch * ch * (a2 - 1.0) + 1.0;
    float f = 1.0 + (1.0 / GLOSSY_F0 - 1.0) * pow(1.0 - clamp(dot(v, h), 0.0, 1.0), 5.0);
    return omega * a2 / (PI * t * t) * f * smith_g1(alpha, cv) * smith_g1(alpha, dot(n, w)) / (4.0 * cv);
}

// Light l's radiance seen from x (normal n) from unit direction v through lobe α.
vec3 lobe_light(vec3 x, vec3 v, vec3 n, float alpha, Light l) {
    float omega;
    vec3 w;
    light_seen(x, l, omega, w);
    return omega > 0.0 ? l.radiance.rgb * lobe_weight(alpha, omega, w, v, n) : vec3(0.0);
}

// The surface normal a mirror direction takes at pixel xy: the mean of the G-buffer normals
// (facing n) over the (2·NORMAL_RADIUS + 1)² pixels on the same surface (normals within ~25°,
// depth within 5 %). A proxy from photos has noisy normals, and a 10° tilt moves a highlight
// by more than a lobe's width.
const int NORMAL_RADIUS = 3;
vec3 smooth_normal(ivec2 xy, vec3 n, float depth) {
    vec3 s = vec3(0.0);
    for (int dy = -NORMAL_RADIUS; dy <= NORMAL_RADIUS; ++dy) {
        for (int dx = -NORMAL_RADIUS; dx <= NORMAL_RADIUS; ++dx) {
            ivec2 q = xy + ivec2(dx, dy);
            if (any(lessThan(q, ivec2(0))) || q.x >= int(pc.width) || q.y >= int(pc.height)) continue;
            vec4 g = imageLoad(g_pos, q);
            vec3 nq = imageLoad(g_nrm, q).xyz;
            float c = dot(nq, n);
            if (g.w <= 0.0 || abs(g.w - depth) > 0.05 * depth || abs(c) < 0.9) continue;
            s += c < 0.0 ? -nq : nq;
        }
    }
    return normalize(s);
}

// The original lights x (normal n) sees (bit l of `seen`), through each lobe from unit view
// direction v, as photographed: each light's geometry once, then one GGX term per lobe.
void lobe_originals(vec3 x, vec3 v, vec3 n, uint seen, out vec3 xs[LOBES]) {
    for (uint c = 0u; c < LOBES; ++c) xs[c] = vec3(0.0);
    for (uint l = 0u; l < min(pc.norig, MAX_ORIG); ++l) {
        if ((seen & (1u << l)) == 0u) continue;
        Light o = originals[l].light;
        float omega;
        vec3 w;
        light_seen(x, o, omega, w);
        if (omega <= 0.0) continue;
        for (uint c = 0u; c < LOBES; ++c) xs[c] += o.radiance.rgb * lobe_weight(lobe_width(c), omega, w, v, n);
    }
}

// Σ_c w_c·X_c: the original lights x (normal n) sees (bit l of `seen`) through the lobes of
// strength w from unit view direction v (lobes of no strength skipped).
vec3 lobes_originals(vec3 x, vec3 v, vec3 n, uint seen, vec3 w) {
    vec3 s = vec3(0.0);
    for (uint l = 0u; l < min(pc.norig, MAX_ORIG); ++l) {
        if ((seen & (1u << l)) == 0u) continue;
        Light o = originals[l].light;
        float omega;
        vec3 wl;
        light_seen(x, o, omega, wl);
        if (omega <= 0.0) continue;
        float k = 0.0;
        for (uint c = 0u; c < LOBES; ++c)
            if (w[c] > 0.0) k += w[c] * lobe_weight(lobe_width(c), omega, wl, v, n);
        s += o.radiance.rgb * k;
    }
    return s;
}

#endif
