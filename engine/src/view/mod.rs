//! What the interactive viewer needs besides the frame: the window's picture with its HUD
//! ([`compose`]), the HUD's text and the key list ([`hud`]), the choice between the cheap
//! moving frame and the full still one ([`fluid`]), and camera paths recorded as `relit fly`
//! reads them ([`recorder`]). The window, the swapchain and presentation are `gpu::present`;
//! input handling stays in the CLI (`tools/relit/view.rs`).

pub mod compose;
pub mod fluid;
pub mod hud;
pub mod recorder;
