//! What a frame shows: its mode.

/// The mode commands render in when the user names neither a mode nor weights: the one that
/// scores best on the validation rooms and holds on the held-out ones (`tools/train/evaluate.py`,
/// README "Evaluation"). Network: since 2026-12-06 the shipped network (ratio base, gated,
/// its diffuse correction a gain, scaled by the input views' disagreement) meets the floor, at
/// or above ratio on covered pixels in every validation and held-out room and lighting, and
/// above it by 0.4 dB on the held-out means. Before it, ratio-filled (ratio's image, the
/// network only in the holes) was the default, as it must be again whenever the shipped
/// network does not meet the floor.
pub const DEFAULT_MODE: Mode = Mode::Network;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// The network's output (needs weights).
    Network,
    /// The `I_1` composite alone: unstructured-lumigraph-style blending, the baseline.
    Ulr,
    /// `I_1 / E_src · (E_add + E_src − E_rem)`: the composite relit by eq. 5's pseudo-albedo
    /// rule, a diffuse relighting baseline without the network (no view-dependent effects).
    Ratio,
    /// Ratio where some input view sees the surface (`I_1` not black), the network's image in
    /// the holes no view sees, which ratio leaves black (needs weights).
    RatioFilled,
    /// §3's L = a·E + S without the network: the photos' diffuse part relit by eq. 5 plus the
    /// view-dependent layer fitted from the photos and their mirror images ([`glossy`]), so
    /// highlights move with the view and a lamp shows its own; ratio's image where no fit holds.
    Glossy,
}

impl Mode {
    /// Whether the frame runs the network in this mode.
    pub fn needs_network(self) -> bool {
        matches!(self, Mode::Network | Mode::RatioFilled)
    }

    /// Whether the frame runs the view-dependent layer ([`glossy`]) in this mode.
    pub fn needs_glossy(self) -> bool {
        matches!(self, Mode::Glossy)
    }
}
