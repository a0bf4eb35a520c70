#version 460
// Albedo mesh (§4.1.2): each proxy-mesh vertex averages π·I_j / E_src_j over the views j that
// see it (depth test), weighted by the inverse distance to camera j. E_src is irradiance (W/m²)
// and a Lambertian surface has I = ρ/π·E, hence the π: the result is the reflectance ρ that
// the added-irradiance path tracer multiplies by at each bounce. Pixels on or beside a declared
// original light are emission, not reflection: no samples (the vertices there take their
// neighbours' albedo, albedo_mesh.rs).
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

#define VIEWS_BINDING 0
#include "views.glsl"
#include "lights.glsl"

layout(set = 0, binding = 4, scalar) readonly buffer Verts { vec3 verts[]; };
layout(set = 0, binding = 6) writeonly buffer Out { vec4 albedo[]; };     // rgb, w = weight sum
layout(set = 0, binding = 7, scalar) readonly buffer Lights { Light lights[]; };

#include "near_light.glsl"

// e_src: E_src of all views, view-major, through its device address (no binding would hold
// 300 views' maps: maxStorageBufferRange).
layout(push_constant) uniform Push {
    uint nverts; uint width; uint height; uint nviews; uint nlights; uint pad; uvec2 e_src_addr;
} pc;
#define e_src (Vec4Ref(pc.e_src_addr).v)

void main() {
    uint v = gl_GlobalInvocationID.x;
    if (v >= pc.nverts) return;
    vec3 p = verts[v];
    vec3 sum = vec3(0.0);
    float wsum = 0.0;
    for (uint j = 0u; j < pc.nviews; ++j) {
        int q = visible_pixel(j, p, pc.width, pc.height);
        if (q < 0 || clipped(q) || near_light(q, pc.width, pc.height, pc.nlights)) continue;
        vec4 e = e_src[q];
        // Pixels without an irradiance estimate (no ray found a view) carry no albedo.
        if (e.w <= 0.0 || max(e.r, max(e.g, e.b)) <= 1e-6) continue;
        float w = 1.0 / max(distance(cam_center(cams[j]), p), 1e-3);
        sum += w * 3.14159265359 * images[q].rgb / max(e.rgb, vec3(1e-6));
        wsum += w;
    }
    albedo[v] = vec4(wsum > 0.0 ? sum / wsum : vec3(0.0), wsum);
}
