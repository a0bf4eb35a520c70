// Area lights for the bake and frame passes: a quad (corner, edge_u, edge_v; emits on the side
// of edge_u × edge_v) or a disk (centre, normal, radius), constant radiance, one-sided.
#ifndef RELIT_LIGHTS_GLSL
#define RELIT_LIGHTS_GLSL
#include "random.glsl"

struct Light {
    vec4 p0;        // quad: corner; disk: centre          (w: 0 = quad, 1 = disk)
    vec4 p1;        // quad: edge_u; disk: normal
    vec4 p2;        // quad: edge_v; disk: (radius, -, -)
    vec4 radiance;  // rgb; w: how far in front of the light shadow rays end (GpuLight::traced)
};

// A point on the light for u in [0,1)^2, its normal, and the light's area.
void light_sample(Light l, vec2 u, out vec3 p, out vec3 n, out float area) {
    if (l.p0.w < 0.5) {
        vec3 c = cross(l.p1.xyz, l.p2.xyz);
        area = length(c);
        n = c / area;
        p = l.p0.xyz + u.x * l.p1.xyz + u.y * l.p2.xyz;
    } else {
        n = normalize(l.p1.xyz);
        float r = l.p2.x;
        vec3 t, b;
        onb(n, t, b);
        float rr = r * sqrt(u.x);
        float phi = 6.28318530718 * u.y;
        p = l.p0.xyz + t * (rr * cos(phi)) + b * (rr * sin(phi));
        area = 3.14159265359 * r * r;
    }
}

// The unit normal of the emitting side.
vec3 light_normal(Light l) {
    return l.p0.w < 0.5 ? normalize(cross(l.p1.xyz, l.p2.xyz)) : normalize(l.p1.xyz);
}

// Whether q (from the corner or centre, in the light's plane) lies inside the outline grown by
// `margin` metres. A quad may be any parallelogram: q is solved in (edge_u, edge_v).
bool within_outline(Light l, vec3 q, float margin) {
    if (l.p0.w >= 0.5) return length(q) <= l.p2.x + margin;
    vec3 u = l.p1.xyz, v = l.p2.xyz;
    float uu = dot(u, u), uv = dot(u, v), vv = dot(v, v), qu = dot(q, u), qv = dot(q, v);
    float det = uu * vv - uv * uv;
    float a = (qu * vv - qv * uv) / det, b = (qv * uu - qu * uv) / det;
    float mu = margin / sqrt(uu), mv = margin / sqrt(vv);
    return a >= -mu && a <= 1.0 + mu && b >= -mv && b <= 1.0 + mv;
}

// Distance along the ray (o, unit d) to the light's emitting side, or -1 when the ray misses it
// or meets its back.
float light_hit(Light l, vec3 o, vec3 d) {
    vec3 n = light_normal(l);
    float dn = dot(d, n);
    if (dn >= 0.0) return -1.0;
    float t = dot(l.p0.xyz - o, n) / dn;
    if (t <= 0.0) return -1.0;
    return within_outline(l, o + t * d - l.p0.xyz, 0.0) ? t : -1.0;
}

// Whether p lies on the light's outline grown by `margin` (metres), within `skin` of its plane.
bool light_near(Light l, vec3 p, float skin, float margin) {
    vec3 n = light_normal(l);
    vec3 q = p - l.p0.xyz;
    float h = dot(q, n);
    return abs(h) <= skin && within_outline(l, q - h * n, margin);
}

#endif
