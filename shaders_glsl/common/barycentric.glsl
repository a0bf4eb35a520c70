// Barycentric weights of p (projected onto the plane of triangle a, b, c), clamped into the
// triangle: how the surface cache is read at a point of a triangle.
#ifndef RELIT_BARYCENTRIC_GLSL
#define RELIT_BARYCENTRIC_GLSL

vec3 barycentrics(vec3 p, vec3 a, vec3 b, vec3 c) {
    vec3 e0 = b - a, e1 = c - a, q = p - a;
    float d00 = dot(e0, e0), d01 = dot(e0, e1), d11 = dot(e1, e1);
    float d20 = dot(q, e0), d21 = dot(q, e1);
    float den = max(d00 * d11 - d01 * d01, 1e-20);
    float v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
    vec3 l = max(vec3(1.0 - v - w, v, w), vec3(0.0));
    return l / max(l.x + l.y + l.z, 1e-20);
}

#endif
