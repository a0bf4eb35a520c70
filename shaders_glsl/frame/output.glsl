// The frame's output (§5.2): in network mode O = O_diffuse + O_vdep from the network's 6
// channels (tonemapped space), inverted to linear HDR: x = ((1 + μ)^O − 1) / μ, μ = 64; in ULR
// mode the I_1 composite (already linear); in ratio mode the I_1 composite relit by the
// pseudo-albedo rule of eq. 5, I_1 / E_src · (E_add + E_src − E_rem) (E_src floored at 1e-4):
// a diffuse relighting baseline that needs no network. Writes linear RGBA32F (EXR) and a display image:
// exposure (a linear scale) then the sRGB transfer function, 8 bits (screen, PNG).
// In every mode a lit added light in front of the surface is drawn with its radiance.
#extension GL_EXT_scalar_block_layout : require
#include "act_storage.glsl"
#include "camera.glsl"
#include "emitters.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 4, rgba32f) readonly uniform image2D g_pos;
layout(set = 0, binding = 13) readonly buffer Comp { f16vec4 comp[]; };
layout(set = 0, binding = 14) readonly buffer Irr { vec4 irr[]; };     // E_src, E_add, E_rem
layout(set = 0, binding = 16) readonly buffer Net { ACT4 o[]; };   // 6 channels, pack4
layout(set = 0, binding = 17) writeonly buffer Hdr { vec4 hdr[]; };
layout(set = 0, binding = 18) writeonly buffer Ldr { uint ldr[]; };

layout(push_constant, scalar) uniform Push {
    uint width; uint height; uint mode; float exposure;
    Camera cam;      // the novel camera (for the rays towards the added lights)
    uint nlights;
} pc;

const uint MODE_NETWORK = 0u;
const uint MODE_ULR = 1u;

float srgb(float x) {
    x = clamp(x, 0.0, 1.0);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint npix = pc.width * pc.height;
    if (p >= npix) return;
    vec3 c = vec3(0.0);
    ivec2 xy = ivec2(p % pc.width, p / pc.width);
    vec4 xp = imageLoad(g_pos, xy);
    if (xp.w > 0.0) {
        if (pc.mode == MODE_NETWORK) {
            vec4 a = vec4(o[p]), b = vec4(o[npix + p]);
            vec3 tmo = max(a.xyz + vec3(a.w, b.x, b.y), vec3(0.0));
            c = (pow(vec3(65.0), tmo) - 1.0) / 64.0;
        } else if (pc.mode == MODE_ULR) {
            c = vec3(comp[p].rgb);
        } else {
            vec3 es = irr[p].rgb;
            c = vec3(comp[p].rgb) / max(es, vec3(1e-4)) * (irr[npix + p].rgb + es - irr[2u * npix + p].rgb);
        }
    }
    vec3 eye = cam_center(pc.cam);
    vec3 ray = normalize(cam_ray_dir(pc.cam, vec2(xy) + 0.5));
    float t = xp.w > 0.0 ? distance(xp.xyz, eye) : 1e30;
    vec3 le;
    if (nearest_emitter(eye, ray, pc.nlights, t, le)) c = le;
    hdr[p] = vec4(c, 1.0);
    vec3 d = c * pc.exposure;
    uvec3 q = uvec3(round(vec3(srgb(d.r), srgb(d.g), srgb(d.b)) * 255.0));
    ldr[p] = q.r | (q.g << 8) | (q.b << 16) | (255u << 24);
}
