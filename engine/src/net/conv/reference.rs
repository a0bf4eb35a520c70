//! CPU references of the kernels, in f64, that the tests hold the GPU results against.

/// CPU reference of [`NetKernels::conv`](super::NetKernels::conv) on planar CHW data (OIHW weights), in f64.
#[allow(clippy::too_many_arguments)]
pub fn conv_reference(
    x: &[f32],
    (c, h, w): (u32, u32, u32),
    weights: &[f32],
    bias: &[f32],
    oc: u32,
    (k, stride, pad): (u32, u32, u32),
    in_bias: f32,
    out_bias: f32,
    scale: f32,
    relu: bool,
    residual: Option<&[f32]>,
) -> Vec<f32> {
    let oh = (h + 2 * pad - k) / stride + 1;
    let ow = (w + 2 * pad - k) / stride + 1;
    let mut out = vec![0f32; (oc * oh * ow) as usize];
    for o in 0..oc {
        for y in 0..oh {
            for xo in 0..ow {
                let mut acc = 0f64;
                for i in 0..c {
                    for ky in 0..k {
                        for kx in 0..k {
                            let iy = (y * stride + ky) as i64 - pad as i64;
                            let ix = (xo * stride + kx) as i64 - pad as i64;
                            if iy < 0 || ix < 0 || iy >= h as i64 || ix >= w as i64 {
                                continue;
                            }
                            let v = x[((i * h) as i64 * w as i64 + iy * w as i64 + ix) as usize]
                                as f64
                                + in_bias as f64;
                            acc += v * weights[(((o * c + i) * k + ky) * k + kx) as usize] as f64;
                        }
                    }
                }
                let idx = ((o * oh + y) * ow + xo) as usize;
                let mut v = (acc + bias[o as usize] as f64) * scale as f64 + out_bias as f64;
                if let Some(r) = residual {
                    v += r[idx] as f64;
                }
                if relu {
                    v = v.max(0.0);
                }
                out[idx] = v as f32;
            }
        }
    }
    out
}

/// CPU reference of [`NetKernels::upsample_add`](super::NetKernels::upsample_add): `dst + up(src)`, planar CHW.
pub fn upsample_add_reference(
    src: &[f32],
    (c, sh, sw): (u32, u32, u32),
    dst: &[f32],
    (dh, dw): (u32, u32),
) -> Vec<f32> {
    let coord = |d: u32, n_in: u32, n_out: u32| {
        let s = ((d as f64 + 0.5) * n_in as f64 / n_out as f64 - 0.5).max(0.0);
        let i0 = (s as u32).min(n_in - 1);
        (i0, (i0 + 1).min(n_in - 1), s - i0 as f64)
    };
    let mut out = dst.to_vec();
    for ch in 0..c {
        for y in 0..dh {
            let (y0, y1, fy) = coord(y, sh, dh);
            for x in 0..dw {
                let (x0, x1, fx) = coord(x, sw, dw);
                let at = |yy: u32, xx: u32| src[((ch * sh + yy) * sw + xx) as usize] as f64;
                let top = at(y0, x0) * (1.0 - fx) + at(y0, x1) * fx;
                let bot = at(y1, x0) * (1.0 - fx) + at(y1, x1) * fx;
                out[((ch * dh + y) * dw + x) as usize] += (top * (1.0 - fy) + bot * fy) as f32;
            }
        }
    }
    out
}
