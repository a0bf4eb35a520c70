//! Which frame the viewer renders next. While the camera or a light moves it shows a cheap
//! frame (ratio mode, at a resolution divided by 1, 2 or 4 so that it keeps up with
//! [`MOVING_BUDGET_S`]); once nothing has changed for [`STILL_AFTER_S`] it renders the full
//! frame once and keeps showing it. G forces one kind.

/// Seconds without a change before the full frame is rendered.
pub const STILL_AFTER_S: f64 = 0.3;
/// A moving frame that takes longer than this (8 fps) halves the moving resolution; one that
/// takes less than [`UPSCALE_BELOW_S`] doubles it again.
pub const MOVING_BUDGET_S: f64 = 1.0 / 8.0;
pub const UPSCALE_BELOW_S: f64 = 1.0 / 20.0;
/// The largest divisor of the moving resolution.
pub const MAX_DIVISOR: u32 = 4;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Policy {
    /// Cheap frames while moving, the full frame when still.
    Auto,
    /// Always the full frame.
    Still,
    /// Always the cheap frame.
    Moving,
}

impl Policy {
    pub fn parse(s: &str) -> Option<Policy> {
        match s {
            "auto" => Some(Policy::Auto),
            "still" => Some(Policy::Still),
            "moving" => Some(Policy::Moving),
            _ => None,
        }
    }

    /// The G key's cycle.
    pub fn next(self) -> Policy {
        match self {
            Policy::Auto => Policy::Still,
            Policy::Still => Policy::Moving,
            Policy::Moving => Policy::Auto,
        }
    }
}

/// What to render next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Next {
    /// The cheap frame at the render resolution divided by `divisor`.
    Moving { divisor: u32 },
    /// The full frame.
    Still,
    /// Show the last frame again.
    Keep,
}

#[derive(Clone, Debug)]
pub struct Fluid {
    pub policy: Policy,
    pub divisor: u32,
    last_change: f64,
    shown: Option<Next>,
}

impl Fluid {
    pub fn new(policy: Policy) -> Fluid {
        Fluid {
            policy,
            divisor: 1,
            last_change: f64::NEG_INFINITY,
            shown: None,
        }
    }

    /// The frame to render at time `now` (s): `changed` when the view or lighting moved since
    /// the last call, `refresh` when the same view needs rendering again (a light's cache refined).
    pub fn next(&mut self, changed: bool, refresh: bool, now: f64) -> Next {
        if changed {
            self.last_change = now;
        }
        let moving = Next::Moving {
            divisor: self.divisor,
        };
        let want = match self.policy {
            Policy::Still => Next::Still,
            Policy::Moving => moving,
            Policy::Auto if changed || now - self.last_change < STILL_AFTER_S => moving,
            Policy::Auto => Next::Still,
        };
        let same = matches!(
            (self.shown, want),
            (Some(Next::Still), Next::Still) | (Some(Next::Moving { .. }), Next::Moving { .. })
        );
        if same && !changed && !refresh {
            return Next::Keep;
        }
        want
    }

    /// Records that `what` was rendered in `seconds`; a moving frame adapts the divisor.
    pub fn rendered(&mut self, what: Next, seconds: f64) {
        if let Next::Moving { .. } = what {
            if seconds > MOVING_BUDGET_S && self.divisor < MAX_DIVISOR {
                self.divisor *= 2;
            } else if seconds < UPSCALE_BELOW_S && self.divisor > 1 {
                self.divisor /= 2;
            }
        }
        if what != Next::Keep {
            self.shown = Some(what);
        }
    }

    /// Whether the frame on screen is the still one.
    pub fn showing_still(&self) -> bool {
        self.shown == Some(Next::Still)
    }
}

/// The moving frame's resolution: `res` divided by `divisor`, at least 16 pixels a side.
pub fn moving_res(res: (u32, u32), divisor: u32) -> (u32, u32) {
    (
        (res.0 / divisor).max(16.min(res.0)),
        (res.1 / divisor).max(16.min(res.1)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_moves_cheaply_then_renders_the_still_frame_once() {
        let mut f = Fluid::new(Policy::Auto);
        let n = f.next(true, false, 0.0);
        assert_eq!(n, Next::Moving { divisor: 1 });
        f.rendered(n, 0.2); // too slow: the next moving frame is smaller
        assert_eq!(f.next(true, false, 0.1), Next::Moving { divisor: 2 });
        f.rendered(Next::Moving { divisor: 2 }, 0.06);
        assert_eq!(f.next(false, false, 0.2), Next::Keep);
        let s = f.next(false, false, 0.1 + STILL_AFTER_S + 0.01);
        assert_eq!(s, Next::Still);
        f.rendered(s, 2.0);
        assert!(f.showing_still());
        assert_eq!(f.next(false, false, 5.0), Next::Keep);
        assert_eq!(
            f.next(false, true, 5.1),
            Next::Still,
            "a refresh re-renders"
        );
        assert_eq!(f.next(true, false, 6.0), Next::Moving { divisor: 2 });
        f.rendered(Next::Moving { divisor: 2 }, 0.01);
        assert_eq!(
            f.divisor, 1,
            "a fast moving frame raises the resolution again"
        );
    }

    #[test]
    fn forced_policies_render_one_kind() {
        let mut f = Fluid::new(Policy::Still);
        assert_eq!(f.next(true, false, 0.0), Next::Still);
        f.rendered(Next::Still, 1.0);
        assert_eq!(f.next(false, false, 0.1), Next::Keep);
        f.policy = Policy::Moving;
        assert_eq!(f.next(false, false, 10.0), Next::Moving { divisor: 1 });
        assert_eq!(Policy::Auto.next().next().next(), Policy::Auto);
        assert_eq!(moving_res((256, 192), 4), (64, 48));
        assert_eq!(moving_res((40, 30), 4), (16, 16));
    }
}
