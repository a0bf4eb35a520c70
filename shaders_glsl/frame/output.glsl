// The frame's output (§5.2): in network mode O = O_diffuse + O_vdep from the network's 6
// channels (tonemapped space), inverted to linear HDR: x = ((1 + μ)^O − 1) / μ, μ = 64; in ULR
// mode the I_1 composite (already linear); in ratio mode the I_1 composite relit by the
// pseudo-albedo rule of eq. 5, I_1 / E_src · (E_add + E_src − E_rem) (E_src floored at E_FLOOR):
// a diffuse relighting baseline that needs no network. Writes linear RGBA32F (EXR) and a display image:
// exposure (a linear scale) then the sRGB transfer function, 8 bits (screen, PNG).
// Ratio-filled mode shows ratio's image where an input view sees the surface (I_1 not black) and
// the network's in the holes, which ratio leaves black. Glossy mode (§3, L = a·E + S) relights
// the fitted diffuse part D by eq. 5 and adds the view-dependent part S (frame/glossy.comp):
// D / E_src · (E_add + E_src − E_rem) + S; where no fit holds, D = I_1 and S = 0: ratio's image.
// In every mode a lit added light in front of the surface is drawn with its radiance, and a
// declared original light on the surface with its dimmed glow (emitters.glsl).
// A network with base "ratio" (model.py) corrects the ratio image: its diffuse output is added
// to tm(R), R formed from the network's own input channels (I_1, E_src/π, E_add/π, E_rem/π,
// untonemapped), as model.py's ratio_base does, so the trainer and the engine compute the same.
// Its shrink τ soft-thresholds each correction where I_1 (the input's channels 0–2) is not black;
// its gate G then scales it there by min(1, f / G), f = max over RGB of E_add / (E_src − E_rem +
// E_add), the new light's share: where no lamp reaches, the image is ratio's exactly. Its gain
// turns the diffuse correction there into a gain on the base that keeps the base's colour. Its
// agreement A scales each correction there also by min(1, D / A), D the input views'
// disagreement around the pixel (`disagreement` below): where the views agree, ratio's image.
#extension GL_EXT_scalar_block_layout : require
#include "act_storage.glsl"
#include "camera.glsl"
#include "emitters.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 4, rgba32f) readonly uniform image2D g_pos;
layout(set = 0, binding = 13) readonly buffer Comp { f16vec4 comp[]; };
layout(set = 0, binding = 14) readonly buffer Irr { vec4 irr[]; };     // E_src, E_add, E_rem
layout(set = 0, binding = 16) readonly buffer NetOut { ACT4 o[]; };   // 6 channels, pack4
layout(set = 0, binding = 17) writeonly buffer Hdr { vec4 hdr[]; };
layout(set = 0, binding = 18) writeonly buffer Ldr { uint ldr[]; };
layout(set = 0, binding = 26) readonly buffer NetIn { ACT4 x[]; };  // 66 channels, pack4
layout(set = 0, binding = 30) readonly buffer Glossy { vec4 glossy[]; };  // (D, s), (S, lobe)

// The novel camera (for the rays towards the added lights): a buffer, since its 80 bytes do not
// fit in the frame's constants.
layout(set = 0, binding = 34) readonly buffer NovelCamera { Camera novel_cam; };

#include "frame_constants.glsl"

const uint MODE_NETWORK = 0u;
const uint MODE_ULR = 1u;
const uint MODE_RATIO_FILLED = 3u;  // ratio where I_1 is not black, the network in the holes
const uint MODE_GLOSSY = 4u;        // the diffuse part relit by eq. 5 plus the view-dependent layer

#include "tonemap.glsl"

// E_src, E_add, E_rem (/π, untonemapped) from the input tensor: channels 51–59 (pack4 groups
// 12–14), as the ratio base and the gate read them.
struct InputIrr { vec3 es; vec3 ea; vec3 er; };
InputIrr input_irr(uint p, uint npix) {
    vec4 g12 = vec4(x[12u * npix + p]), g13 = vec4(x[13u * npix + p]), g14 = vec4(x[14u * npix + p]);
    return InputIrr(untm(vec3(g12.w, g13.x, g13.y)), untm(vec3(g13.z, g13.w, g14.x)), untm(g14.yzw));
}

// E_src/π floored at E_FLOOR / π, as ratio mode floors E at E_FLOOR.
const float ES_FLOOR = E_FLOOR / 3.14159265358979;

// tm(I_1 / E_src · (E_add + E_src − E_rem)) from the input tensor (I_1: channels 0–2).
vec3 ratio_base(uint p, InputIrr e) {
    vec3 i1 = untm(vec4(x[p]).xyz);
    return tm(i1 / max(e.es, vec3(ES_FLOOR)) * (e.ea + e.es - e.er));
}

// f: the new light's share of the pixel's light, E_add / (E_src − E_rem + E_add), max over RGB.
float new_light_share(InputIrr e) {
    vec3 f = e.ea / max(e.es - e.er + e.ea, vec3(ES_FLOOR));
    return max(f.r, max(f.g, f.b));
}

// Eq. 5's ratio image from the composite and the irradiance planes, as ratio mode shows it.
vec3 ratio_image(uint p, uint npix) {
    vec3 es = irr[p].rgb;
    return vec3(comp[p].rgb) / max(es, vec3(E_FLOOR)) * (irr[npix + p].rgb + es - irr[2u * npix + p].rgb);
}

vec3 soft_threshold(vec3 c, float t) { return sign(c) * max(abs(c) - t, vec3(0.0)); }

// gain's diffuse image: tm(untm(B)·exp(w·g)), g the log ratio of the RGB means of untm(B + d)
// and untm(B), each plus GAIN_EPS (output.rs `gained`, model.py `log_gain`).
vec3 gained(vec3 b, vec3 d, float w) {
    vec3 lb = untm(b), ld = untm(b + d);
    float g = log((ld.r + ld.g + ld.b) / 3.0 + GAIN_EPS) - log((lb.r + lb.g + lb.b) / 3.0 + GAIN_EPS);
    return tm(lb * exp(w * g));
}

// The RGB mean of |I_k − I_1| (input channels 0–23, tonemapped, pack4 groups 0–5) averaged
// over the layers k = 2..8 that cover pixel q together with I_1; 0 where none does.
float pixel_disagreement(uint q, uint npix) {
    float c[24];
    for (uint g = 0u; g < 6u; g++) {
        vec4 v = vec4(x[g * npix + q]);
        c[4u * g] = v.x; c[4u * g + 1u] = v.y; c[4u * g + 2u] = v.z; c[4u * g + 3u] = v.w;
    }
    vec3 i1 = vec3(c[0], c[1], c[2]);
    if (all(equal(i1, vec3(0.0)))) return 0.0;
    float sum = 0.0, n = 0.0;
    for (uint k = 1u; k < 8u; k++) {
        vec3 ik = vec3(c[3u * k], c[3u * k + 1u], c[3u * k + 2u]);
        if (any(notEqual(ik, vec3(0.0)))) {
            vec3 d = abs(ik - i1);
            sum += (d.r + d.g + d.b) / 3.0;
            n += 1.0;
        }
    }
    return n > 0.0 ? sum / n : 0.0;
}

// D of `agree`: pixel_disagreement under the 5×5 binomial filter [1 4 6 4 1]/16 (separable,
// σ = 1 px), edge pixels repeated (model.py `disagreement`, output.rs).
float disagreement(ivec2 xy, uint npix) {
    const float W[5] = float[5](1.0, 4.0, 6.0, 4.0, 1.0);
    float d = 0.0;
    for (int j = 0; j < 5; j++) {
        int cy = clamp(xy.y + j - 2, 0, int(pc.height) - 1);
        for (int i = 0; i < 5; i++) {
            int cx = clamp(xy.x + i - 2, 0, int(pc.width) - 1);
            d += W[i] * W[j] * pixel_disagreement(uint(cy) * pc.width + uint(cx), npix);
        }
    }
    return d / 256.0;
}

// Glossy mode's image: D relit by eq. 5 plus S (black in holes, where both are 0).
vec3 glossy_image(uint p, uint npix) {
    vec3 es = irr[p].rgb;
    vec3 d = glossy[p].rgb / max(es, vec3(E_FLOOR)) * (irr[npix + p].rgb + es - irr[2u * npix + p].rgb);
    return d + glossy[npix + p].rgb;
}

// Network mode's image: O_d + O_v, and with base "ratio" (1) or "glossy" (2) that base plus the
// corrections, soft-thresholded and gated on covered pixels. A closed gate leaves the base's own
// image (not the ratio base's round trip through the input tensor, which fp16 storage rounds),
// so no key removes a highlight the glossy layer draws.
vec3 network_image(uint p, ivec2 xy, uint npix) {
    vec4 a = vec4(o[p]), b = vec4(o[npix + p]);
    vec3 od = a.xyz, ov = vec3(a.w, b.x, b.y);
    if (pc.base != 0u) {
        InputIrr e = input_irr(p, npix);
        bool covered = any(notEqual(vec4(x[p]).xyz, vec3(0.0)));
        float t = covered ? pc.shrink : 0.0;
        float w = covered && pc.gate > 0.0 ? min(new_light_share(e) / pc.gate, 1.0) : 1.0;
        if (covered && pc.agree > 0.0 && w > 0.0) w *= min(disagreement(xy, npix) / pc.agree, 1.0);
        if (w == 0.0) return pc.base == 2u ? glossy_image(p, npix) : ratio_image(p, npix);
        vec3 b = pc.base == 2u ? tm(glossy_image(p, npix)) : ratio_base(p, e);
        od = soft_threshold(od, t);
        od = pc.gain == 1u && covered ? gained(b, od, w) : b + w * od;
        ov = w * soft_threshold(ov, t);
    }
    return untm(max(od + ov, vec3(0.0)));
}

// The image of a mode that leaves holes black (ratio, glossy, ULR) at pixel q.
vec3 plain_image(uint q, uint npix) {
    if (pc.mode == MODE_GLOSSY) return glossy_image(q, npix);
    if (pc.mode == MODE_ULR) return vec3(comp[q].rgb);
    return ratio_image(q, npix);
}

// A hole's fill for the viewer's moving frame (output.rs `fill_holes`): the mean of the image
// at the first covered pixel along each of 8 directions within FILL_RADIUS pixels, so that
// no black speckles show while the user walks or drags a lamp; black where none is found.
const int FILL_RADIUS = 12;
vec3 hole_fill(ivec2 xy, uint npix) {
    const ivec2 DIRS[8] = ivec2[8](ivec2(1, 0), ivec2(-1, 0), ivec2(0, 1), ivec2(0, -1),
                                   ivec2(1, 1), ivec2(-1, 1), ivec2(1, -1), ivec2(-1, -1));
    vec3 sum = vec3(0.0);
    float n = 0.0;
    for (int d = 0; d < 8; d++) {
        for (int k = 1; k <= FILL_RADIUS; k++) {
            ivec2 q = xy + k * DIRS[d];
            if (any(lessThan(q, ivec2(0))) || q.x >= int(pc.width) || q.y >= int(pc.height)) break;
            uint qi = uint(q.y) * pc.width + uint(q.x);
            if (any(notEqual(vec3(comp[qi].rgb), vec3(0.0)))) { sum += plain_image(qi, npix); n += 1.0; break; }
        }
    }
    return n > 0.0 ? sum / n : vec3(0.0);
}

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
    bool hole = all(equal(vec3(comp[p].rgb), vec3(0.0)));
    if (xp.w > 0.0) {
        if (pc.mode == MODE_NETWORK || (pc.mode == MODE_RATIO_FILLED && hole)) {
            c = network_image(p, xy, npix);
        } else if (hole && pc.fill == 1u) {
            c = hole_fill(xy, npix);
        } else {
            c = plain_image(p, npix);
        }
    }
    vec3 eye = cam_center(novel_cam);
    vec3 ray = normalize(cam_ray_dir(novel_cam, vec2(xy) + 0.5));
    float t = xp.w > 0.0 ? distance(xp.xyz, eye) : 1e30;
    vec3 le;
    float leak = LEAK_PX * xp.w / novel_cam.intrinsics.x;  // metres the pixel filter spreads glow
    if (xp.w > 0.0 && original_light(xp.xyz, ray, pc.norig, pc.alpha_dim, vec3(comp[p].rgb),
                                     irr[npix + p].rgb, leak, le)) c = le;
    if (nearest_emitter(eye, ray, pc.nlights, t, le)) c = le;
    hdr[p] = vec4(c, 1.0);
    vec3 d = c * pc.exposure;
    uvec3 q = uvec3(round(vec3(srgb(d.r), srgb(d.g), srgb(d.b)) * 255.0));
    ldr[p] = q.r | (q.g << 8) | (q.b << 16) | (255u << 24);
}
