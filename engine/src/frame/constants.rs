//! The frame's constants: one push-constant block shared by every novel-view frame pass
//! (reproject, irradiance, target mirror, glossy sums and layer, features, output), declared
//! once in `shaders_glsl/frame/frame_constants.glsl` and filled once per frame by
//! [`super::Renderer`] (`frame_constants`). Each pass reads the members it needs.
//!
//! 108 bytes, within the 128 Vulkan guarantees for push constants. The output pass's novel
//! camera (a [`GpuCamera`](crate::scene::GpuCamera), 80 bytes) would not fit with the rest: it
//! reads it from the `NovelCamera` buffer ([`super::FrameBuffers::camera`]). The view culling
//! pass keeps a push block of its own ([`super::view_cull::Push`]): it runs in a submission of
//! its own before the frame's active views are chosen, with grid fields no other pass reads.

use crate::gpu::shaders;

/// The frame's push constants (`frame_constants.glsl`'s block, member for member).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FrameConstants {
    /// The novel camera's centre (w = 1).
    pub eye: [f32; 4],
    /// The novel view's size in pixels.
    pub width: u32,
    pub height: u32,
    /// The input views' size in pixels.
    pub view_w: u32,
    pub view_h: u32,
    /// Input views in the capture.
    pub nviews: u32,
    /// The frame's active views (the `Active` buffer).
    pub nactive: u32,
    /// An input view left out of the frame (`u32::MAX`: none; the target mirror's).
    pub exclude: u32,
    /// Added lights.
    pub nlights: u32,
    /// Declared original lights (drawn where seen, dimmed).
    pub norig: u32,
    /// Live lights ([`super::live`]): their count and which added lights they are.
    pub nlive: u32,
    pub live_mask: u32,
    /// Per-light control ([`super::lighting`]): the original lights with E_add layers (0 or
    /// all), the first of those layers, and whether some original light has a factor of its
    /// own ([`super::Lighting::per_light`]).
    pub nsplit: u32,
    pub split_layer: u32,
    pub per_light: u32,
    /// §4.1.4: 0 keeps the original lighting, 1 removes it.
    pub alpha_dim: f32,
    /// The output's mode ([`mode_code`]).
    pub mode: u32,
    /// The display image's linear scale (output).
    pub exposure: f32,
    /// 1: the output fills holes from the nearest covered pixels
    /// ([`super::output::fill_holes`]).
    pub fill: u32,
    /// [`crate::net::NetBase`]: 0 none, 1 ratio, 2 glossy.
    pub base: u32,
    /// [`crate::net::NetConfig::shrink`].
    pub shrink: f32,
    /// [`crate::net::NetConfig::gate`].
    pub gate: f32,
    /// [`crate::net::NetConfig::gain`]: 1 on, 0 off.
    pub gain: u32,
    /// [`crate::net::NetConfig::agree`].
    pub agree: f32,
}

/// Vulkan's guaranteed `maxPushConstantsSize`.
pub const PUSH_LIMIT: usize = 128;
const _: () = assert!(std::mem::size_of::<FrameConstants>() <= PUSH_LIMIT);

/// FrameConstants as every frame pass's shader declares it (tests/gpu.rs checks).
pub(crate) const PUSH_LAYOUT: crate::gpu::PushLayout = crate::push_layout!(
    FrameConstants,
    [
        shaders::FRAME_REPROJECT,
        shaders::FRAME_IRRADIANCE,
        shaders::FRAME_TARGET_MIRROR,
        shaders::FRAME_GLOSSY_SUMS,
        shaders::FRAME_GLOSSY,
        shaders::FRAME_FEATURES,
        shaders::FRAME_FEATURES_F32,
        shaders::FRAME_OUTPUT,
        shaders::FRAME_OUTPUT_F32,
    ],
    [
        eye,
        width,
        height,
        view_w,
        view_h,
        nviews,
        nactive,
        exclude,
        nlights,
        norig,
        nlive,
        live_mask,
        nsplit,
        split_layer,
        per_light,
        alpha_dim,
        mode,
        exposure,
        fill,
        base,
        shrink,
        gate,
        gain,
        agree
    ]
);

/// The output shader's code for `mode` (`output.glsl`'s MODE_*).
pub fn mode_code(mode: super::Mode) -> u32 {
    use super::Mode;
    match mode {
        Mode::Network => 0,
        Mode::Ulr => 1,
        Mode::Ratio => 2,
        Mode::RatioFilled => 3,
        Mode::Glossy => 4,
    }
}
