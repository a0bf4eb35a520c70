//! The relighting network of §5.1 (reference: `tools/train/model.py`): weights from a
//! safetensors file whose metadata key `relit.net` holds the configuration as JSON, run as a
//! sequence of conv / upsample-add dispatches on pack4 tensors.

use std::path::Path;
use std::sync::Arc;

use half::{bf16, f16};
use serde::{Deserialize, Serialize};

use super::conv::{Conv, Epilogue, NetKernels, Storage, Tensor};
use crate::error::{Error, Result};
use crate::gpu::{Gpu, Graph};

/// The network's shape (the paper: 66 in, width 66, 4 / 5×4 / 2 blocks, 6 out).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NetConfig {
    pub in_channels: u32,
    pub width: u32,
    pub trunk_blocks: u32,
    pub levels: u32,
    pub level_blocks: u32,
    pub tail_blocks: u32,
    pub out_channels: u32,
    /// What the output's diffuse channels correct (absent in files written before it: none).
    #[serde(default, skip_serializing_if = "NetBase::is_none")]
    pub base: NetBase,
    /// Soft threshold τ on the corrections (base ratio only; `model.py`): on covered pixels a
    /// correction c becomes sign(c)·max(|c| − τ, 0) in tonemapped space. 0: none.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub shrink: f32,
    /// Gate G on the corrections (base ratio only; `model.py`): on covered pixels a correction
    /// is scaled by min(1, f / G), f the new light's share of the pixel's light
    /// ([`crate::frame::output::new_light_share`]), so that where no lamp reaches the image is
    /// ratio's, exactly. 0: none.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub gate: f32,
    /// Gain (base ratio only; `model.py`): on covered pixels the diffuse correction becomes a
    /// gain on the ratio image that keeps its colour ([`crate::frame::output::gained`]).
    /// false: additive corrections.
    #[serde(default, skip_serializing_if = "is_false")]
    pub gain: bool,
    /// Agreement A (base ratio only; `model.py`): on covered pixels a correction is also scaled
    /// by min(1, D / A), D the input views' disagreement
    /// ([`crate::frame::output::disagreement`]): where the reprojected views agree the proxy
    /// is right and the image is ratio's. 0: none.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub agree: f32,
}

fn is_false(x: &bool) -> bool {
    !*x
}

fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

/// The image the network's diffuse output is added to, in tonemapped space (`model.py`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NetBase {
    /// The output is the image (the paper's formulation).
    #[default]
    None,
    /// The output corrects eq. 5's ratio-relit composite: an untrained (zero) output conv
    /// renders the ratio image, and training can only add to it.
    Ratio,
    /// The output corrects glossy mode's image (§3's L = a·E + S: eq. 5 on the photos' diffuse
    /// part plus the fitted view-dependent layer, [`crate::frame::glossy`]): an untrained
    /// output conv renders it, highlights included.
    Glossy,
}

impl NetBase {
    pub fn is_none(&self) -> bool {
        *self == NetBase::None
    }

    /// Whether the output corrects an image (ratio or glossy), so that the correction keys
    /// (shrink, gate, gain, agree) apply.
    pub fn corrects(&self) -> bool {
        matches!(self, NetBase::Ratio | NetBase::Glossy)
    }
}

impl NetConfig {
    pub fn paper(width: u32) -> NetConfig {
        NetConfig {
            in_channels: super::INPUT_CHANNELS,
            width,
            trunk_blocks: 4,
            levels: 5,
            level_blocks: 4,
            tail_blocks: 2,
            out_channels: 6,
            base: NetBase::None,
            shrink: 0.0,
            gate: 0.0,
            gain: false,
            agree: 0.0,
        }
    }
}

/// A fixup block: `relu(conv2(relu(conv1(x + b1a) + b1b) + b2a) * scale + b2b + x)`.
struct Block {
    conv1: Conv,
    conv2: Conv,
    bias1a: f32,
    bias1b: f32,
    bias2a: f32,
    scale: f32,
    bias2b: f32,
}

/// The shipped weights (how they were trained: `engine/weights/README.md`), built into the
/// binary so that every copy of relit has them.
pub const SHIPPED: &[u8] = include_bytes!("../../weights/relit.safetensors");
/// How errors and `relit info` name the shipped weights.
pub const SHIPPED_NAME: &str = "engine/weights/relit.safetensors";

/// Named parameters (OIHW or scalar), as f32.
pub trait Params {
    fn get(&self, name: &str, shape: &[usize]) -> Result<Vec<f32>>;
}

/// Parameters from a safetensors file.
pub struct SafetensorsParams {
    path: std::path::PathBuf,
    bytes: Vec<u8>,
}

impl SafetensorsParams {
    pub fn open(path: &Path) -> Result<(SafetensorsParams, NetConfig)> {
        let bytes = crate::scene::files::read(path, crate::scene::files::FileKind::Weights)?;
        SafetensorsParams::parse(path, bytes)
    }

    /// `bytes` as a weights file; `path` names them in errors.
    pub fn parse(path: &Path, bytes: Vec<u8>) -> Result<(SafetensorsParams, NetConfig)> {
        let (_, meta) = safetensors::SafeTensors::read_metadata(&bytes)
            .map_err(|e| Error::input(path, format!("not a safetensors file: {e}")))?;
        let cfg = meta
            .metadata()
            .as_ref()
            .and_then(|m| m.get("relit.net"))
            .ok_or_else(|| {
                Error::input(
                    path,
                    "metadata key \"relit.net\" (the network configuration as JSON) is missing",
                )
            })?;
        let cfg: NetConfig = serde_json::from_str(cfg)
            .map_err(|e| Error::input(path, format!("metadata \"relit.net\": {e}")))?;
        if cfg.width == 0 || cfg.levels == 0 || cfg.in_channels == 0 || cfg.out_channels == 0 {
            return Err(Error::input(
                path,
                "metadata \"relit.net\": width, levels, in_channels and out_channels must be > 0",
            ));
        }
        for (name, v) in [
            ("shrink", cfg.shrink),
            ("gate", cfg.gate),
            ("agree", cfg.agree),
        ] {
            if !(v >= 0.0 && v.is_finite()) || (v > 0.0 && !cfg.base.corrects()) {
                return Err(Error::input(
                    path,
                    format!(
                        "metadata \"relit.net\": {name} {v} must be finite, >= 0, and 0 unless base is \"ratio\" or \"glossy\""
                    ),
                ));
            }
        }
        if cfg.gain && !cfg.base.corrects() {
            return Err(Error::input(
                path,
                "metadata \"relit.net\": gain must be false unless base is \"ratio\" or \"glossy\"",
            ));
        }
        Ok((
            SafetensorsParams {
                path: path.to_path_buf(),
                bytes,
            },
            cfg,
        ))
    }
}

impl Params for SafetensorsParams {
    fn get(&self, name: &str, shape: &[usize]) -> Result<Vec<f32>> {
        let st = safetensors::SafeTensors::deserialize(&self.bytes)
            .map_err(|e| Error::input(&self.path, format!("not a safetensors file: {e}")))?;
        let t = st
            .tensor(name)
            .map_err(|_| Error::input(&self.path, format!("tensor \"{name}\" is missing")))?;
        if t.shape() != shape {
            return Err(Error::input(
                &self.path,
                format!(
                    "tensor \"{name}\": shape {:?}, expected {shape:?}",
                    t.shape()
                ),
            ));
        }
        let d = t.data();
        let v: Vec<f32> = match t.dtype() {
            safetensors::Dtype::F32 => bytemuck::pod_collect_to_vec(d),
            safetensors::Dtype::F16 => bytemuck::pod_collect_to_vec::<u8, f16>(d)
                .iter()
                .map(|x| x.to_f32())
                .collect(),
            safetensors::Dtype::BF16 => bytemuck::pod_collect_to_vec::<u8, bf16>(d)
                .iter()
                .map(|x| x.to_f32())
                .collect(),
            other => {
                return Err(Error::input(
                    &self.path,
                    format!("tensor \"{name}\": dtype {other:?}, expected F32, F16 or BF16"),
                ))
            }
        };
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(Error::input(
                &self.path,
                format!("tensor \"{name}\": element {i} is not finite"),
            ));
        }
        Ok(v)
    }
}

/// Intermediate tensors for one input size: three per pyramid level plus the output.
pub struct NetBuffers {
    levels: Vec<[Tensor; 3]>,
    pub out: Tensor,
    pub h: u32,
    pub w: u32,
}

pub struct Network {
    pub config: NetConfig,
    pub kernels: NetKernels,
    in_conv: Option<Conv>,
    trunk: Vec<Block>,
    down: Vec<Conv>,
    levels: Vec<Vec<Block>>,
    tail: Vec<Block>,
    out_conv: Conv,
}

impl Network {
    pub fn load(gpu: &Arc<Gpu>, path: &Path, storage: Storage) -> Result<Network> {
        let (params, cfg) = SafetensorsParams::open(path)?;
        Network::from_params(NetKernels::new(gpu, storage)?, cfg, &params)
    }

    /// The trained network that ships inside relit (`engine/weights/`).
    pub fn shipped(gpu: &Arc<Gpu>, storage: Storage) -> Result<Network> {
        let (params, cfg) = SafetensorsParams::parse(Path::new(SHIPPED_NAME), SHIPPED.to_vec())?;
        Network::from_params(NetKernels::new(gpu, storage)?, cfg, &params)
    }

    pub fn from_params(kernels: NetKernels, config: NetConfig, p: &dyn Params) -> Result<Network> {
        let w = config.width as usize;
        let conv = |name: &str, oc: usize, ic: usize, k: usize, stride: u32, bias: bool| {
            let wt = p.get(&format!("{name}.weight"), &[oc, ic, k, k])?;
            let b = if bias {
                Some(p.get(&format!("{name}.bias"), &[oc])?)
            } else {
                None
            };
            kernels.layer(&wt, b.as_deref(), oc as u32, ic as u32, k as u32, stride, 1)
        };
        let scalar = |name: String| -> Result<f32> { Ok(p.get(&name, &[1])?[0]) };
        let blocks = |prefix: &str, n: u32| -> Result<Vec<Block>> {
            (0..n)
                .map(|i| {
                    let b = format!("{prefix}.{i}");
                    Ok(Block {
                        conv1: conv(&format!("{b}.conv1"), w, w, 3, 1, false)?,
                        conv2: conv(&format!("{b}.conv2"), w, w, 3, 1, false)?,
                        bias1a: scalar(format!("{b}.bias1a"))?,
                        bias1b: scalar(format!("{b}.bias1b"))?,
                        bias2a: scalar(format!("{b}.bias2a"))?,
                        scale: scalar(format!("{b}.scale"))?,
                        bias2b: scalar(format!("{b}.bias2b"))?,
                    })
                })
                .collect()
        };
        let in_conv = if config.width != config.in_channels {
            Some(conv("in_conv", w, config.in_channels as usize, 3, 1, true)?)
        } else {
            None
        };
        Ok(Network {
            in_conv,
            trunk: blocks("trunk", config.trunk_blocks)?,
            down: (0..config.levels - 1)
                .map(|k| conv(&format!("down.{k}"), w, w, 4, 2, true))
                .collect::<Result<_>>()?,
            levels: (0..config.levels)
                .map(|k| blocks(&format!("levels.{k}"), config.level_blocks))
                .collect::<Result<_>>()?,
            tail: blocks("tail", config.tail_blocks)?,
            out_conv: conv("out_conv", config.out_channels as usize, w, 3, 1, true)?,
            config,
            kernels,
        })
    }

    /// Allocates the intermediate tensors for an `h × w` input.
    pub fn buffers(&self, h: u32, w: u32) -> Result<NetBuffers> {
        let gpu = &self.kernels.gpu;
        let st = self.kernels.storage;
        let c = self.config.width;
        let mut levels = Vec::new();
        let (mut lh, mut lw) = (h, w);
        for k in 0..self.config.levels {
            if k > 0 {
                (lh, lw) = self.down[k as usize - 1].out_size(lh, lw);
            }
            if lh == 0 || lw == 0 {
                return Err(Error::Other(format!(
                    "{w}x{h} is too small for {} pyramid levels",
                    self.config.levels
                )));
            }
            let t = |i: u32| Tensor::new(gpu, &format!("net level {k}.{i}"), c, lh, lw, st);
            levels.push([t(0)?, t(1)?, t(2)?]);
        }
        Ok(NetBuffers {
            levels,
            out: Tensor::new(gpu, "net out", self.config.out_channels, h, w, st)?,
            h,
            w,
        })
    }

    /// Runs `blocks` from `input`, alternating outputs between `a` and `b` with `t` as the
    /// temporary; returns the tensor that holds the result.
    fn blocks<'a>(
        &self,
        g: &mut Graph,
        blocks: &[Block],
        input: &'a Tensor,
        mut a: &'a Tensor,
        mut b: &'a Tensor,
        t: &'a Tensor,
    ) -> Result<&'a Tensor> {
        let k = &self.kernels;
        let mut x = input;
        for blk in blocks {
            if std::ptr::eq(x, a) {
                std::mem::swap(&mut a, &mut b);
            }
            let ep1 = Epilogue {
                in_bias: blk.bias1a,
                out_bias: blk.bias1b,
                relu: true,
                ..Default::default()
            };
            k.conv(g, &blk.conv1, x, t, ep1)?;
            let ep2 = Epilogue {
                in_bias: blk.bias2a,
                out_bias: blk.bias2b,
                scale: blk.scale,
                relu: true,
                residual: Some(x),
            };
            k.conv(g, &blk.conv2, t, a, ep2)?;
            x = a;
        }
        Ok(x)
    }

    /// Records the network on `input` (in_channels × h × w) into `bufs.out`, each layer a pass
    /// of `g`; with a timer, one span per stage: input conv, trunk, pyramid (downsampling),
    /// level k, upsample, tail, output.
    pub fn record(&self, g: &mut Graph, bufs: &NetBuffers, input: &Tensor) -> Result<()> {
        if (input.c, input.h, input.w) != (self.config.in_channels, bufs.h, bufs.w) {
            return Err(Error::Other(format!(
                "network input {}x{}x{}, expected {}x{}x{}",
                input.c, input.h, input.w, self.config.in_channels, bufs.h, bufs.w
            )));
        }
        let k = &self.kernels;
        let l0 = &bufs.levels[0];
        let x = match &self.in_conv {
            Some(c) => g.group("net: input conv", |g| {
                k.conv(g, c, input, &l0[0], Epilogue::default())?;
                Ok(&l0[0])
            })?,
            None => input,
        };
        let trunk = g.group("net: trunk", |g| {
            self.blocks(g, &self.trunk, x, &l0[1], &l0[0], &l0[2])
        })?;
        let sum = self.pyramid(g, bufs, trunk)?;
        let other = if std::ptr::eq(sum, &l0[0]) {
            &l0[1]
        } else {
            &l0[0]
        };
        let tail = g.group("net: tail", |g| {
            self.blocks(g, &self.tail, sum, other, sum, &l0[2])
        })?;
        g.group("net: output conv", |g| {
            k.conv(g, &self.out_conv, tail, &bufs.out, Epilogue::default())
        })
    }

    /// The pyramid from `trunk`: downsampling, each level's ResNet, and the coarser levels
    /// upsampled into the finest; returns the tensor holding the sum.
    fn pyramid<'a>(
        &self,
        g: &mut Graph,
        bufs: &'a NetBuffers,
        trunk: &'a Tensor,
    ) -> Result<&'a Tensor> {
        // The raw pyramid first: each level's ResNet may then reuse its input buffer.
        let mut pyramid = vec![trunk];
        g.group("net: pyramid", |g| {
            for (k, d) in self.down.iter().enumerate() {
                let out = &bufs.levels[k + 1][0];
                self.kernels
                    .conv(g, d, pyramid[k], out, Epilogue::default())?;
                pyramid.push(out);
            }
            Ok(())
        })?;
        let mut results = Vec::new();
        for (k, (blocks, lv)) in self.levels.iter().zip(&bufs.levels).enumerate() {
            let input = pyramid[k];
            let (a, b) = if std::ptr::eq(input, &lv[1]) {
                (&lv[0], &lv[1])
            } else {
                (&lv[1], &lv[0])
            };
            results.push(g.group(&format!("net: level {k}"), |g| {
                self.blocks(g, blocks, input, a, b, &lv[2])
            })?);
        }
        let sum = results[0];
        g.group("net: upsample", |g| {
            for r in &results[1..] {
                self.kernels.upsample_add(g, r, sum)?;
            }
            Ok(())
        })?;
        Ok(sum)
    }

    /// Runs the network on planar CHW input and returns planar CHW output (tests, tools).
    pub fn run(&self, input: &[f32], h: u32, w: u32) -> Result<Vec<f32>> {
        let gpu = &self.kernels.gpu;
        let x = Tensor::new(
            gpu,
            "net input",
            self.config.in_channels,
            h,
            w,
            self.kernels.storage,
        )?;
        x.upload_chw(input)?;
        let bufs = self.buffers(h, w)?;
        let mut res = Ok(());
        gpu.submit(|cmd| res = self.record(&mut Graph::new(gpu, cmd, None), &bufs, &x))?;
        res?;
        bufs.out.download_chw()
    }

    /// Multiply-adds × 2 of one inference at h × w.
    pub fn flops(&self, h: u32, w: u32) -> f64 {
        let mut total = 0.0;
        if let Some(c) = &self.in_conv {
            total += c.flops(h, w);
        }
        let block = |b: &[Block], h, w| -> f64 {
            b.iter()
                .map(|b| b.conv1.flops(h, w) + b.conv2.flops(h, w))
                .sum()
        };
        total += block(&self.trunk, h, w);
        let (mut lh, mut lw) = (h, w);
        for (k, lv) in self.levels.iter().enumerate() {
            if k > 0 {
                let d = &self.down[k - 1];
                total += d.flops(lh, lw);
                (lh, lw) = d.out_size(lh, lw);
            }
            total += block(lv, lh, lw);
        }
        total + block(&self.tail, h, w) + self.out_conv.flops(h, w)
    }
}

/// Random parameters with fan-in scaled weights (benchmarks: the values only need to stay
/// finite and away from denormals). Scalars: biases 0, scales 1.
pub struct RandomParams(pub u64);

impl Params for RandomParams {
    fn get(&self, name: &str, shape: &[usize]) -> Result<Vec<f32>> {
        let n: usize = shape.iter().product();
        if shape.len() != 4 {
            let v = if name.ends_with("scale") { 1.0 } else { 0.0 };
            return Ok(vec![v; n]);
        }
        let seed = name.bytes().fold(self.0 ^ 0xcbf29ce484222325, |h, b| {
            (h ^ b as u64).wrapping_mul(0x100000001b3)
        });
        let mut rng = crate::scene::synth::Rng::new(seed);
        let a = (3.0 / (shape[1] * shape[2] * shape[3]) as f32).sqrt();
        Ok((0..n).map(|_| rng.range(-a, a)).collect())
    }
}
