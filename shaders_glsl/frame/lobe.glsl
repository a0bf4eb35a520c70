// Lights seen through a glossy lobe (frame/glossy_sums.comp, frame/glossy.comp): a surface point's
// shadow ray to a light and the light's radiance through a normalized Gaussian lobe.
// Needs: tlas, the Originals, Emitters and Intensity buffers (emitters.glsl) and the push
// constants norig, nlights, alpha_dim.
#ifndef RELIT_LOBE_GLSL
#define RELIT_LOBE_GLSL

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

// Whether x (normal n) sees light l's centre: one ray, stopped 5 cm short of the light (a
// declared light sits on the proxy surface).
bool sees_light(vec3 x, vec3 n, Light l) {
    vec3 c, nl;
    float area;
    light_frame(l, c, nl, area);
    vec3 d = c - x;
    float dist = length(d);
    if (dot(d, n) <= 0.0 || dist < 0.06) return false;
    rayQueryEXT rq;
    rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT | gl_RayFlagsTerminateOnFirstHitEXT, 0xFF,
                          x + n * 1e-3, 1e-3, d / dist, dist - 0.05);
    while (rayQueryProceedEXT(rq)) {}
    return rayQueryGetIntersectionTypeEXT(rq, true) == gl_RayQueryCommittedIntersectionNoneEXT;
}

// Light l as seen from x against unit r: its solid angle Ω (0 from behind) and the squared
// angle θ² between r and the direction to its centre.
void light_seen(vec3 x, vec3 r, Light l, out float omega, out float th2) {
    vec3 c, nl;
    float area;
    light_frame(l, c, nl, area);
    vec3 d = c - x;
    float d2 = max(dot(d, d), 1e-6);
    vec3 w = d * inversesqrt(d2);
    float cosl = -dot(nl, w);
    omega = cosl > 0.0 ? min(area * cosl / d2, 2.0 * 3.14159265358979) : 0.0;
    float th = acos(clamp(dot(w, r), -1.0, 1.0));
    th2 = th * th;
}

// The normalized Gaussian lobe of width σ applied to a light of solid angle Ω at angle θ:
// Ω·exp(−θ²/2v)/(2πv), v = σ² + Ω/4π (the light as a Gaussian of its own solid angle).
float lobe_weight(float sigma, float omega, float th2) {
    const float PI = 3.14159265358979;
    float v = sigma * sigma + omega / (4.0 * PI);
    return omega * exp(-th2 / (2.0 * v)) / (2.0 * PI * v);
}

// Light l's radiance seen from x through the lobe of width σ around unit r.
vec3 lobe_light(vec3 x, vec3 r, float sigma, Light l) {
    float omega, th2;
    light_seen(x, r, l, omega, th2);
    return omega > 0.0 ? l.radiance.rgb * lobe_weight(sigma, omega, th2) : vec3(0.0);
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

// The original lights x sees (bit l of `seen`), through each lobe around r, as photographed:
// each light's geometry once, then one exponential per lobe.
void lobe_originals(vec3 x, vec3 r, uint seen, out vec3 xs[LOBES]) {
    for (uint c = 0u; c < LOBES; ++c) xs[c] = vec3(0.0);
    for (uint l = 0u; l < min(pc.norig, MAX_ORIG); ++l) {
        if ((seen & (1u << l)) == 0u) continue;
        Light o = originals[l].light;
        float omega, th2;
        light_seen(x, r, o, omega, th2);
        if (omega <= 0.0) continue;
        for (uint c = 0u; c < LOBES; ++c) xs[c] += o.radiance.rgb * lobe_weight(lobe_width(c), omega, th2);
    }
}

#endif
