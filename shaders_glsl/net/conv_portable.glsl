// Portable convolution body (conv.comp, conv_f32.comp): register-blocked, one invocation computes
// PX consecutive output pixels of a row times the 16 output channels of one block (OCG = 4
// groups of 4), with fp32 arithmetic (faster than fp16 where there is no native half). The
// remainder variants (conv_r*.comp, OCG = 1) compute only the first 4 channels of a block: a
// width of 66 = 4 × 16 + 2 then costs 68 channels of work instead of 80. Dispatch grid:
// (ceil(out_w / PX / 8), ceil(out_h / 8), output blocks from pc.ocb_base).
#include "conv.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

const uint PX = 8u; // STEP/ZERO below are written out for 8
#ifndef OCG
#define OCG 4
#endif

void main() {
    uint ox0 = gl_GlobalInvocationID.x * PX;
    uint oy = gl_GlobalInvocationID.y;
    uint ocb = pc.ocb_base + gl_WorkGroupID.z;
    if (ox0 >= pc.out_w || oy >= pc.out_h) return;
    // Unrolled by hand (macros, constant indices): lavapipe keeps the accumulators in registers
    // only when every index is a constant, and NIR does not unroll loops this large by itself.
    vec4 acc[PX][4];
#define ZERO(p) acc[p][0] = vec4(0.0); acc[p][1] = vec4(0.0); acc[p][2] = vec4(0.0); acc[p][3] = vec4(0.0);
    ZERO(0) ZERO(1) ZERO(2) ZERO(3) ZERO(4) ZERO(5) ZERO(6) ZERO(7)
    for (uint c4 = 0u; c4 < pc.in_c4; ++c4) {
        for (uint ky = 0u; ky < pc.ksize; ++ky) {
            int iy = int(oy * pc.stride + ky) - int(pc.pad);
            if (iy < 0 || iy >= int(pc.in_h)) continue;
            for (uint kx = 0u; kx < pc.ksize; ++kx) {
                uint wi = weight_index(ocb, ky * pc.ksize + kx, c4 * 4u);
                // 4 input channels x 16 output channels.
#define W(i, j) vec4 w##i##j = vec4(w4[wi + i * 4u + j]);
#if OCG == 4
#define WROW(i) W(i, 0) W(i, 1) W(i, 2) W(i, 3)
#else
#define WROW(i) W(i, 0)
#endif
                WROW(0) WROW(1) WROW(2) WROW(3)
                int ix0 = int(ox0 * pc.stride + kx) - int(pc.pad);
#define FMA(p, j) acc[p][j] += v.x * w0##j + v.y * w1##j + v.z * w2##j + v.w * w3##j;
#if OCG == 4
#define FMAS(p) FMA(p, 0) FMA(p, 1) FMA(p, 2) FMA(p, 3)
#else
#define FMAS(p) FMA(p, 0)
#endif
#define STEP(p) { vec4 v = sample_in(c4, ix0 + int(p * pc.stride), iy); FMAS(p) }
                // Inside the image (all but the edge invocations): no bounds checks.
#define FAST(p) { vec4 v = vec4(x[row + p * pc.stride]) + pc.in_bias; FMAS(p) }
                if (ix0 >= 0 && ix0 + int((PX - 1u) * pc.stride) < int(pc.in_w)) {
                    uint row = (c4 * pc.in_h + uint(iy)) * pc.in_w + uint(ix0);
                    FAST(0) FAST(1) FAST(2) FAST(3) FAST(4) FAST(5) FAST(6) FAST(7)
                } else {
                    STEP(0) STEP(1) STEP(2) STEP(3) STEP(4) STEP(5) STEP(6) STEP(7)
                }
            }
        }
    }
    uint oc4_end = (pc.out_c + 3u) / 4u;
    for (uint p = 0u; p < PX; ++p) {
        if (ox0 + p >= pc.out_w) break;
        for (uint j = 0u; j < uint(OCG); ++j) {
            uint oc4 = ocb * 4u + j;
            if (oc4 < oc4_end) store(oc4, ox0 + p, oy, acc[p][j]);
        }
    }
}
