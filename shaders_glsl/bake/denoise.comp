#version 460
// Edge-aware denoising of a per-view irradiance map (§4.1.1; the paper used OptiX's denoiser):
// a cross-bilateral filter guided by the view's G-buffer, each neighbour weighted also by the
// number of rays behind its estimate. Weights: Gaussian in pixel distance,
// Gaussian in the distance of the neighbour to this pixel's tangent plane (relative to depth, so
// slanted surfaces are not cut), and a power of the normals' agreement: the filter averages
// along surfaces and stops at their edges.
// With `with_base`, the input is one noisy part of a map `base` (E_add's indirect light, whose
// direct part keeps its sharp shadows): out = base − input + filtered input.
#extension GL_EXT_scalar_block_layout : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

// The views' G-buffers (gpos, gnrm: all views) through their device addresses: no binding
// holds every view's maps (300 views at 256×192 pass maxStorageBufferRange).
#define VIEWS_BINDING 0
#include "views.glsl"
layout(set = 0, binding = 2) readonly buffer In { vec4 e_in[]; };     // this view
layout(set = 0, binding = 3) writeonly buffer Out { vec4 e_out[]; };
layout(set = 0, binding = 4) readonly buffer Base { vec4 e_base[]; };  // read when with_base

layout(push_constant) uniform Push {
    uint view; uint width; uint height; int radius;
    float sigma_px; float sigma_depth; float normal_power; uint with_base;
} pc;

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    uint base = pc.view * npix;
    vec4 c = gpos[base + p];
    // Pixels whose rays all missed a view get their estimate from the neighbours.
    vec4 whole = pc.with_base != 0u ? e_base[p] : vec4(0.0);
    vec4 unfiltered = pc.with_base != 0u ? whole : e_in[p];
    if (c.w <= 0.0) { e_out[p] = unfiltered; return; }
    vec3 n = gnrm[base + p].xyz;
    ivec2 xy = ivec2(p % pc.width, p / pc.width);
    vec3 sum = vec3(0.0);
    float wsum = 0.0;
    for (int dy = -pc.radius; dy <= pc.radius; ++dy) {
        for (int dx = -pc.radius; dx <= pc.radius; ++dx) {
            ivec2 q = xy + ivec2(dx, dy);
            if (q.x < 0 || q.y < 0 || q.x >= int(pc.width) || q.y >= int(pc.height)) continue;
            uint qi = uint(q.y) * pc.width + uint(q.x);
            vec4 g = gpos[base + qi];
            vec4 e = e_in[qi];
            if (g.w <= 0.0 || e.w <= 0.0) continue;
            float rz = dot(n, g.xyz - c.xyz) / (pc.sigma_depth * c.w);
            float cn = max(dot(n, gnrm[base + qi].xyz), 0.0);
            float w = exp(-0.5 * float(dx * dx + dy * dy) / (pc.sigma_px * pc.sigma_px) - 0.5 * rz * rz)
                    * pow(cn, pc.normal_power) * e.w;   // e.w: rays behind the estimate
            sum += w * e.rgb;
            wsum += w;
        }
    }
    if (wsum <= 0.0) { e_out[p] = unfiltered; return; }
    vec3 f = sum / wsum;
    e_out[p] = pc.with_base != 0u ? vec4(whole.rgb - e_in[p].rgb + f, max(whole.w, 1.0))
                                  : vec4(f, max(e_in[p].w, 1.0));
}
