// Portable convolution body (conv.comp, conv_f32.comp): register-blocked, one invocation computes
// PX consecutive output pixels of a row times the 16 output channels of one block, with fp32
// arithmetic (faster than fp16 where there is no native half). Dispatch grid:
// (ceil(out_w / PX / 8), ceil(out_h / 8), output blocks).
#include "conv.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

const uint PX = 8u;

void main() {
    uint ox0 = gl_GlobalInvocationID.x * PX;
    uint oy = gl_GlobalInvocationID.y;
    uint ocb = gl_WorkGroupID.z;
    if (ox0 >= pc.out_w || oy >= pc.out_h) return;
    vec4 acc[PX][4];
    for (uint p = 0u; p < PX; ++p)
        for (uint j = 0u; j < 4u; ++j) acc[p][j] = vec4(0.0);
    for (uint c4 = 0u; c4 < pc.in_c4; ++c4) {
        for (uint ky = 0u; ky < pc.ksize; ++ky) {
            int iy = int(oy * pc.stride + ky) - int(pc.pad);
            if (iy < 0 || iy >= int(pc.in_h)) continue;
            for (uint kx = 0u; kx < pc.ksize; ++kx) {
                uint wi = weight_index(ocb, ky * pc.ksize + kx, c4 * 4u);
                // 4 input channels x 16 output channels.
                vec4 wt[4][4];
                for (uint i = 0u; i < 4u; ++i)
                    for (uint j = 0u; j < 4u; ++j) wt[i][j] = vec4(w4[wi + i * 4u + j]);
                for (uint p = 0u; p < PX; ++p) {
                    vec4 v = sample_in(c4, int((ox0 + p) * pc.stride + kx) - int(pc.pad), iy);
                    for (uint j = 0u; j < 4u; ++j)
                        acc[p][j] += v.x * wt[0][j] + v.y * wt[1][j] + v.z * wt[2][j] + v.w * wt[3][j];
                }
            }
        }
    }
    uint oc4_end = (pc.out_c + 3u) / 4u;
    for (uint p = 0u; p < PX; ++p) {
        if (ox0 + p >= pc.out_w) break;
        for (uint j = 0u; j < 4u; ++j) {
            uint oc4 = ocb * 4u + j;
            if (oc4 < oc4_end) store(oc4, ox0 + p, oy, acc[p][j]);
        }
    }
}
