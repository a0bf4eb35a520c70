// Next-event estimation towards an area light: one light sample, one shadow ray. The includer
// declares `tlas` (the proxy mesh) before including this.
#ifndef RELIT_NEE_GLSL
#define RELIT_NEE_GLSL
#include "lights.glsl"

bool occluded(vec3 o, vec3 d, float tmax) {
    rayQueryEXT rq;
    rayQueryInitializeEXT(rq, tlas, gl_RayFlagsOpaqueEXT | gl_RayFlagsTerminateOnFirstHitEXT, 0xFF, o, 1e-3, d, tmax);
    while (rayQueryProceedEXT(rq)) {}
    return rayQueryGetIntersectionTypeEXT(rq, true) == gl_RayQueryCommittedIntersectionTriangleEXT;
}

// Direct irradiance at x (normal n) from light l, one sample u. The shadow ray ends `lift`
// metres in front of the light: an original light sits on the proxy's (noisy) ceiling or wall,
// which must not shadow it; an added light floats free (lift 0).
vec3 light_direct(Light l, vec3 x, vec3 n, vec2 u, float lift) {
    vec3 lp, ln;
    float area;
    light_sample(l, u, lp, ln, area);
    vec3 w = lp - x;
    float d2 = dot(w, w);
    w *= inversesqrt(d2);
    float cx = dot(n, w), cl = -dot(ln, w);
    if (cx <= 0.0 || cl <= 0.0) return vec3(0.0);
    vec3 o = x + n * 1e-3;
    vec3 e = lp + ln * lift - o;
    float de = length(e);
    if (occluded(o, e / de, de - 2e-3)) return vec3(0.0);
    return l.radiance.rgb * (cx * cl * area / d2);
}

#endif
