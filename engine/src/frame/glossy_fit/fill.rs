//! The holes in a surface's fit (see `holes`).

use std::collections::HashMap;

use super::{Cell, CellFits, FitSums, PatchKey, Patches, Reach};
use crate::constants::GLOSSY_REGION_T;

/// The t statistic a fit needs to reach patches beyond its own pool: twice what it needs to
/// stand. hand_room's floor fits s = 0.27 at t = 19 from the few patches that see its ceiling
/// light; spread over the rest of the floor, the lamp's highlight came out twice the truth's
/// (−2.4 dB). The demo room's floor fits at t ≈ 90.
const FILL_T: f32 = 2.0 * GLOSSY_REGION_T;

/// A patch without a fit takes the fit of its plane's main material (the patch on its plane
/// whose pooled sums hold the most pixels) where that fit reaches FILL_T and the patch's own
/// sums do not reject it (`FitSums::rejects`).
///
/// Why. The demo room's wood floor had holes 25 cm wide beside the column and the table, where
/// the lamp's highlight in the main job's walk ended in stair steps: cells in every original
/// light's shadow, whose triangles have no sums (their UNSEEN patch), and patches whose
/// pseudo-albedo (I_1 / E_src; E_src errs beside shadows) put them in a bin of their own with too
/// few photos for a fit. Neither has evidence of a material of its own. A patch whose photos
/// contradict the plane's lobe keeps none, and a material with photos enough to decide (a
/// mirror on a wall) has its own fit and is no hole.
pub(super) fn holes(
    patches: &Patches,
    reach: &Reach,
    pooled: &HashMap<PatchKey, FitSums>,
    fits: &mut HashMap<Cell, CellFits>,
) {
    let mut fills = Vec::new();
    for (k, list) in patches {
        for (i, (_, p)) in list.iter().enumerate() {
            if fits[k][i].1[3] > 0.0 {
                continue;
            }
            let main = (reach.plane(p)).fold(None, |m: Option<&PatchKey>, (q, _)| match m {
                Some(b) if pooled[b].pixels >= pooled[q].pixels => Some(b),
                _ => Some(q),
            });
            let Some((mk, mi)) = main else { continue };
            let f = fits[mk][*mi].1;
            if f[3] >= FILL_T && !p.sums.rejects(f) {
                fills.push((*k, i, f));
            }
        }
    }
    for (k, i, f) in fills {
        if let Some(list) = fits.get_mut(&k) {
            list[i].1 = f;
        }
    }
}
