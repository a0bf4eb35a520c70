//! The view-dependent layer's fit per surface (§3: S belongs to a material, not to a pixel).
//!
//! A fit per pixel (pooled over 5×5 pixels, session 24) holds only where some photo's mirror
//! direction meets an original light near that pixel: on the demo room's floor 7 % of the
//! pixels, and not where a new lamp's highlight falls. A floor is one material, so its
//! strength can come from every photo that shows a highlight anywhere on it.
//!
//! How. The frame's sums pass (`glossy_sums.comp`) runs from up to `FIT_VIEWS` input cameras
//! at `FIT_WIDTH` pixels under the original lighting; each pixel's centred sums go to its
//! triangle of the bake mesh. Triangles are grouped into patches (a `CELL` grid × the normal's
//! dominant axis), and each patch pools the patches within `GLOSSY_REGION` metres on its plane
//! (normals within ~25°, off the plane by at most 3 cm + 10 % of the distance). Centred sums
//! add up: the pooled fit is one strength per lobe with a diffuse part per pixel. The lobe
//! with the largest t statistic (slope over its standard error) wins if that exceeds
//! `GLOSSY_REGION_T`; otherwise the patch has none. A triangle takes its surface's patches'
//! fits around it under a tent of half a metre (`Near`), so that strengths change smoothly.
//! The result is one vec4 per triangle (w_1..3, t), then one per triangle with its surface's
//! normal where the triangle lies within PLANE_TILT of it (a flat floor from photos is bumpy;
//! zero elsewhere), which `glossy.comp` reads through the G-buffer's triangle ids.

use std::collections::{BTreeMap, HashMap};

use glam::Vec3;

mod fill;
mod smooth;

use super::{glossy, Lighting, Mode, Renderer};
use crate::constants::{E_FLOOR, GLOSSY_REGION, GLOSSY_REGION_T};
use crate::error::Result;
use crate::gpu::{vk, Buffer};
use crate::scene::{Camera, Mesh};
use smooth::Near;

/// Width in pixels of the renders from the input cameras.
const FIT_WIDTH: u32 = 128;
/// Input cameras rendered at most (evenly spread over the capture).
const FIT_VIEWS: usize = 48;
/// Edge of a patch's grid cell (m).
const CELL: f32 = 0.25;
const LOBES: usize = 3;
/// Degrees a triangle may tilt from its surface's normal and still take it (`surface_normal`).
const PLANE_TILT: f32 = 10.0;
/// Pseudo-albedos of one material differ by at most this factor per channel (shading the bake
/// misses, photo noise); ALBEDO_EPS keeps dark channels from deciding alone.
const ALBEDO_RATIO: f32 = 1.4;
const ALBEDO_EPS: f32 = 0.02;
/// Standard errors by which a patch's own slope must miss its plane's fit to refuse it
/// (`fill::holes`).
const REJECT_SE: f32 = 3.0;

/// The centred sums of the fit I_j ≈ D + s·X_j over a triangle's pixels: Σ|X − X̄|² and
/// Σ(X − X̄)·(I − Ī) per lobe, Σ|I − Ī|², the view samples and the pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FitSums {
    pub xx: [f32; LOBES],
    pub xi: [f32; LOBES],
    pub ii: f32,
    pub samples: f32,
    pub pixels: f32,
    /// Σ over the pixels of the photos' blend over E_src (the pseudo-albedo of eq. 5).
    pub albedo: Vec3,
}

impl FitSums {
    fn add(&mut self, o: &FitSums) {
        for c in 0..LOBES {
            self.xx[c] += o.xx[c];
            self.xi[c] += o.xi[c];
        }
        self.ii += o.ii;
        self.samples += o.samples;
        self.pixels += o.pixels;
        self.albedo += o.albedo;
    }

    /// The mean pseudo-albedo of the pixels.
    fn mean_albedo(&self) -> Vec3 {
        self.albedo / self.pixels.max(1.0)
    }

    /// Each lobe's strength (one lobe at most) and the winner's t statistic: s_c = Σxi/Σxx, ≥ 0,
    /// t_c = s_c·√(Σxx/σ²), σ² the residual per degree of freedom (samples less one mean per
    /// pixel). A lobe is out when its slope exceeds `glossy::lobe_s_max(c)`, and a lobe wider
    /// than the narrowest when the narrowest's slope is larger than its own (the highlights are
    /// sharper than the narrowest lobe) and a still wider lobe's slope is over its cap (they are
    /// stronger than a rough dielectric's): a near-mirror, such as hand_room2's mirror, whose
    /// patches took the middle lobe by chance and glowed around the lamp at oblique views.
    pub fn strengths(&self) -> [f32; 4] {
        let slope = |c: usize| (self.xi[c] / self.xx[c].max(1e-12)).max(0.0);
        let over = |c: usize| self.xx[c] > 1e-12 && slope(c) > glossy::lobe_s_max(c);
        let mut best = [0f32; 4];
        for c in 0..LOBES {
            let mirror = c > 0 && slope(0) > slope(c) && (c + 1..LOBES).any(over);
            if self.xx[c] <= 1e-12 || over(c) || mirror {
                continue;
            }
            let s = slope(c);
            let t = s * (self.xx[c] / self.residual_var(c, s)).sqrt();
            if t > best[3] {
                best = [0.0; 4];
                best[c] = s;
                best[3] = t;
            }
        }
        if best[3] < GLOSSY_REGION_T {
            return [0.0; 4];
        }
        best
    }

    /// Whether these sums reject the fit `f` (one lobe's strength): their own slope on f's lobe
    /// lies more than `REJECT_SE` standard errors from f's strength.
    fn rejects(&self, f: [f32; 4]) -> bool {
        let c = (0..LOBES)
            .max_by(|&a, &b| f[a].total_cmp(&f[b]))
            .unwrap_or(0);
        if self.xx[c] <= 1e-12 {
            return false;
        }
        let s = self.xi[c] / self.xx[c];
        let se = (self.residual_var(c, s) / self.xx[c]).sqrt();
        (s - f[c]).abs() > REJECT_SE * se
    }

    /// The residual variance per degree of freedom (samples less one mean per pixel) of the fit
    /// with slope s on lobe c.
    fn residual_var(&self, c: usize, s: f32) -> f32 {
        let dof = (self.samples - self.pixels - 1.0).max(1.0);
        (self.ii - s * self.xi[c]).max(1e-12) / dof
    }
}

/// Adds one render's sums (`glossy::SUM_PLANES` planes of `npix`) to the triangles' sums, by
/// the render's triangle ids (+1, 0: none), with the pseudo-albedo I_1 / E_src of its pixels.
pub fn accumulate(
    acc: &mut [FitSums],
    sums: &[[f32; 4]],
    gtri: &[u32],
    (i1, esrc): (&[[f32; 4]], &[[f32; 4]]),
) {
    let npix = gtri.len();
    let v = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
    for (p, &t) in gtri.iter().enumerate() {
        let s2 = sums[2 * npix + p];
        if t == 0 || s2[1] == 0.0 {
            continue;
        }
        let (xx, xi) = (sums[p], sums[npix + p]);
        acc[t as usize - 1].add(&FitSums {
            xx: [xx[0], xx[1], xx[2]],
            xi: [xi[0], xi[1], xi[2]],
            ii: s2[0],
            samples: s2[1],
            pixels: 1.0,
            albedo: v(i1[p]) / v(esrc[p]).max(Vec3::splat(E_FLOOR)),
        });
    }
}

/// A patch: the triangles of one grid cell whose normals share a dominant axis and whose
/// pseudo-albedos share a bin.
#[derive(Default)]
struct Patch {
    sums: FitSums,
    centre: Vec3,
    normal: Vec3,
    area: f32,
}

/// A grid cell and the normal's dominant axis (with its sign, 0..6).
type Cell = (i32, i32, i32, u8);

fn cell(c: Vec3, n: Vec3) -> Cell {
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let g = (c / CELL).floor();
    (
        g.x as i32,
        g.y as i32,
        g.z as i32,
        2 * axis as u8 + (n[axis] < 0.0) as u8,
    )
}

/// A pseudo-albedo's bin: each channel's log in steps of ln ALBEDO_RATIO (None: no pixels).
fn albedo_bin(s: &FitSums) -> Option<Bin> {
    let a = (s.pixels > 0.0).then(|| s.mean_albedo() + ALBEDO_EPS)?;
    Some(
        a.to_array()
            .map(|v| (v.ln() / ALBEDO_RATIO.ln()).floor() as i32),
    )
}

/// Whether patch q is on patch p's surface: within GLOSSY_REGION, normals within ~25°, q off
/// p's plane by at most 3 cm + 10 % of their distance.
fn same_plane(p: &Patch, q: &Patch) -> bool {
    let d = q.centre - p.centre;
    let dist = d.length();
    dist <= GLOSSY_REGION
        && p.normal.dot(q.normal) >= 0.9
        && d.dot(p.normal).abs() <= 0.03 + 0.1 * dist
}

/// Whether patch q is of patch p's surface and material: on its plane, and their pseudo-albedos
/// within ALBEDO_RATIO of each other in every channel (a mirror or a poster on a wall is another
/// material on the same plane).
fn same_surface(p: &Patch, q: &Patch) -> bool {
    if (p.sums.pixels == 0.0) != (q.sums.pixels == 0.0) {
        return false;
    }
    let (a, b) = (p.sums.mean_albedo(), q.sums.mean_albedo());
    let ratio = (a + ALBEDO_EPS) / (b + ALBEDO_EPS);
    same_plane(p, q)
        && ratio.max_element() <= ALBEDO_RATIO
        && ratio.min_element() >= 1.0 / ALBEDO_RATIO
}

/// A pseudo-albedo bin (`albedo_bin`).
type Bin = [i32; 3];
/// The bin of a cell's triangles without sums.
const UNSEEN: Bin = [i32::MIN; 3];
/// The patches of a mesh, by cell and albedo bin; ordered, so that every run pools them in one
/// order and a glossy frame is the same bytes each time.
type Patches = BTreeMap<Cell, Vec<(Bin, Patch)>>;
/// Each triangle's cell and bin.
type TriPatch = (Cell, Bin);
/// A cell's fits: per bin, (w_1..3, t).
type CellFits = Vec<(Bin, [f32; 4])>;

fn patches(mesh: &Mesh, acc: &[FitSums]) -> (Patches, Vec<TriPatch>) {
    let mut patches = Patches::new();
    let mut of_tri = Vec::with_capacity(mesh.triangles.len());
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = tri.map(|i| Vec3::from(mesh.positions[i as usize]));
        let cr = (b - a).cross(c - a);
        let (centre, area) = ((a + b + c) / 3.0, 0.5 * cr.length());
        let (k, bin) = (cell(centre, cr.normalize_or_zero()), albedo_bin(&acc[t]));
        // Triangles without sums (no photo, or in every original light's shadow) make their
        // cell's UNSEEN patch: no pool takes it, and it takes its plane's fit (`fill::holes`).
        let bin = bin.unwrap_or(UNSEEN);
        of_tri.push((k, bin));
        let list = patches.entry(k).or_default();
        let i = match list.iter().position(|(b, _)| *b == bin) {
            Some(i) => i,
            None => {
                list.push((bin, Patch::default()));
                list.len() - 1
            }
        };
        let p = &mut list[i].1;
        p.sums.add(&acc[t]);
        p.centre += area * centre;
        p.normal += 0.5 * cr;
        p.area += area;
    }
    for (_, p) in patches.values_mut().flatten() {
        p.centre /= p.area.max(1e-12);
        p.normal = p.normal.normalize_or_zero();
    }
    (patches, of_tri)
}

/// A patch: its cell and its index in the cell's list.
type PatchKey = (Cell, usize);

/// The patches by coarse cells of GLOSSY_REGION: those that can pool with a patch lie in the 27
/// coarse cells around its own.
struct Reach<'a> {
    cells: HashMap<(i32, i32, i32), Vec<Keyed<'a>>>,
}

/// A patch with its key.
type Keyed<'a> = (PatchKey, &'a Patch);

impl<'a> Reach<'a> {
    fn new(patches: &'a Patches) -> Reach<'a> {
        let mut cells: HashMap<(i32, i32, i32), Vec<_>> = HashMap::new();
        for (k, list) in patches {
            for (i, (_, p)) in list.iter().enumerate() {
                cells
                    .entry(Self::coarse(p.centre))
                    .or_default()
                    .push(((*k, i), p));
            }
        }
        Reach { cells }
    }

    fn coarse(c: Vec3) -> (i32, i32, i32) {
        let g = (c / GLOSSY_REGION).floor();
        (g.x as i32, g.y as i32, g.z as i32)
    }

    /// The patches on p's plane (`same_plane`), in one order every run.
    fn plane<'b>(&'b self, p: &'b Patch) -> impl Iterator<Item = &'b Keyed<'a>> + 'b {
        let (x, y, z) = Self::coarse(p.centre);
        let around =
            (-1..=1).flat_map(|a| (-1..=1).flat_map(move |b| (-1..=1).map(move |c| (a, b, c))));
        let cells =
            around.filter_map(move |(dx, dy, dz)| self.cells.get(&(x + dx, y + dy, z + dz)));
        cells.flatten().filter(move |(_, q)| same_plane(p, q))
    }

    /// Patch p's sums pooled with those of every patch on its surface (`same_surface`).
    fn pooled(&self, p: &Patch) -> FitSums {
        let mut sums = FitSums::default();
        for (_, q) in self.plane(p).filter(|(_, q)| same_surface(p, q)) {
            sums.add(&q.sums);
        }
        sums
    }
}

/// Per triangle of `mesh`: (w_1..3, t) from the sums pooled over its surface (module comment),
/// smoothed between patches (`Near`), and its surface's normal (`surface_normal`). Patches
/// without a fit of their own may take their plane's (`fill::holes`).
pub fn pool(mesh: &Mesh, acc: &[FitSums]) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
    let (patches, of_tri) = patches(mesh, acc);
    let reach = Reach::new(&patches);
    let pooled: HashMap<PatchKey, FitSums> = (patches.iter())
        .flat_map(|(k, list)| {
            (list.iter().enumerate()).map(|(i, (_, p))| ((*k, i), reach.pooled(p)))
        })
        .collect();
    let mut fits: HashMap<Cell, CellFits> = (patches.iter())
        .map(|(k, list)| {
            let f =
                (list.iter().enumerate()).map(|(i, (bin, _))| (*bin, pooled[&(*k, i)].strengths()));
            (*k, f.collect())
        })
        .collect();
    fill::holes(&patches, &reach, &pooled, &mut fits);
    let near = Near::new(&patches, &fits);
    (mesh.triangles.iter().zip(&of_tri))
        .map(|(tri, (k, bin))| {
            let list = fits.get(k).map_or(&[][..], |v| &v[..]);
            let own = list.iter().position(|(b, _)| b == bin);
            let [a, b, c] = tri.map(|i| Vec3::from(mesh.positions[i as usize]));
            let (centre, face) = ((a + b + c) / 3.0, (b - a).cross(c - a).normalize_or_zero());
            own.map_or([[0.0; 4]; 2], |i| {
                let key = (*k, i);
                let n = surface_normal(face, near.normal(&key, centre));
                [near.at(&key, centre, list[i].1), [n.x, n.y, n.z, 0.0]]
            })
        })
        .map(|[f, n]| (f, n))
        .unzip()
}

/// The normal the layer's lobes take on a triangle of normal `face`: its surface's (`smooth`),
/// where the two are within PLANE_TILT (a proxy made from photos tilts a flat floor's triangles
/// by a few degrees, and a 3° tilt moves a highlight by a narrow lobe's width); else none (zero:
/// the layer smooths the G-buffer's normals instead, as on a curved surface).
fn surface_normal(face: Vec3, smooth: Vec3) -> Vec3 {
    let c = face.dot(smooth);
    match c.abs() >= PLANE_TILT.to_radians().cos() {
        true => smooth * c.signum(),
        false => Vec3::ZERO,
    }
}

/// `cam` at `width` pixels across (same field of view).
fn at_width(cam: &Camera, width: u32) -> Camera {
    let f = width as f32 / cam.width as f32;
    Camera {
        width,
        height: ((cam.height as f32 * f).round() as u32).max(1),
        fx: cam.fx * f,
        fy: cam.fy * f,
        cx: cam.cx * f,
        cy: cam.cy * f,
        ..*cam
    }
}

/// The input views the fit renders from: all but the excluded one, at most FIT_VIEWS evenly.
fn fit_views(n: usize, exclude: Option<u32>) -> Vec<usize> {
    let all: Vec<usize> = (0..n).filter(|&j| Some(j as u32) != exclude).collect();
    let k = all.len().min(FIT_VIEWS);
    (0..k).map(|i| all[i * all.len() / k]).collect()
}

/// The fit per triangle of the renderer's bake mesh, from its input views (module comment),
/// then each triangle's surface normal: the layer's buffer.
pub(super) fn fit(r: &mut Renderer) -> Result<Vec<[f32; 4]>> {
    let mesh_tris = r.scene.geom.triangles.len();
    if r.scene.originals.is_empty() {
        // No declared original light: the sums are all zero, and so is the fit.
        return Ok(vec![[0.0; 4]; 2 * mesh_tris]);
    }
    let mut acc = vec![FitSums::default(); mesh_tris];
    let lighting = Lighting {
        intensities: vec![0.0; r.scene.lights.len()],
        ..Default::default()
    };
    // Only the passes the sums need (no target mirror, no features).
    let display_only = std::mem::replace(&mut r.display_only, true);
    let res = gather(r, &lighting, &mut acc);
    r.display_only = display_only;
    res?;
    let (fits, normals) = pool(&r.scene.geom, &acc);
    Ok([fits, normals].concat())
}

/// Renders the sums from the fit's input cameras into the triangles' sums.
fn gather(r: &mut Renderer, lighting: &Lighting, acc: &mut [FitSums]) -> Result<()> {
    for j in fit_views(r.scene.data.cameras.len(), r.exclude) {
        let cam = at_width(&r.scene.data.cameras[j], FIT_WIDTH.min(r.scene.views.width));
        r.render_glossy_sums(&cam, lighting)?;
        let b = r.buffers_ref().expect("a frame was rendered");
        let npix = (b.width * b.height) as usize;
        let sums: Vec<[f32; 4]> = b.glossy_sums.download_vec()?;
        let gtri = b.gbuf.download()?.tri;
        let (comp, irr): (_, Vec<[f32; 4]>) = (b.composites()?, b.irr.download_vec()?);
        let sums = &sums[..glossy::SUM_PLANES * npix];
        accumulate(acc, sums, &gtri[..npix], (&comp[..npix], &irr[..npix]));
    }
    Ok(())
}

impl Renderer {
    /// Renders the sums pass (`glossy_sums.comp`) at `cam` under `lighting` instead of the
    /// layer, as the fit's renders do; read them in the buffers' `glossy_sums`.
    pub fn render_glossy_sums(&mut self, cam: &Camera, lighting: &Lighting) -> Result<()> {
        let fitting = std::mem::replace(&mut self.fitting, true);
        let res = self.render(cam, lighting, Mode::Glossy, 1.0, None);
        self.fitting = fitting;
        res
    }

    /// Makes the view-dependent fit per surface for the views the frames use, unless it is
    /// made or being made (its own renders come here too, and bind zeros meanwhile).
    pub(super) fn ensure_glossy_fit(&mut self) -> Result<()> {
        let made = self
            .glossy_fit
            .as_ref()
            .is_some_and(|f| f.0 == self.exclude);
        if made || self.fitting {
            return Ok(());
        }
        self.refit_glossy().map(|_| ())
    }

    /// Makes the view-dependent fit per surface again (frame/glossy_fit/) and returns how long
    /// it took: what a scene's first glossy frame adds (`relit bench frame` reports it).
    pub fn refit_glossy(&mut self) -> Result<std::time::Duration> {
        let t0 = std::time::Instant::now();
        self.glossy_fit = None;
        self.fitting = true;
        let fit = fit(self);
        self.fitting = false;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let buf = Buffer::from_slice(&self.gpu, "glossy fit", usage, &fit?)?;
        self.glossy_fit = Some((self.exclude, buf));
        Ok(t0.elapsed())
    }

    /// The view-dependent fit per triangle the last glossy frame used (None before one): the
    /// fits (w_1..3, t) of the bake mesh's triangles, then their surface normals.
    pub fn glossy_fit(&self) -> Result<Option<Vec<[f32; 4]>>> {
        (self.glossy_fit.as_ref())
            .map(|f| f.1.download_vec())
            .transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Adds the quad `o + [0, 1]·u + [0, 1]·v` (two triangles, normal u × v) to `m`.
    fn quad(m: &mut Mesh, o: Vec3, u: Vec3, v: Vec3) -> [usize; 2] {
        let i = m.positions.len() as u32;
        for p in [o, o + u, o + u + v, o + v] {
            m.positions.push(p.to_array());
        }
        m.triangles.push([i, i + 1, i + 2]);
        m.triangles.push([i, i + 2, i + 3]);
        [m.triangles.len() - 2, m.triangles.len() - 1]
    }

    /// Sums of 100 pixels seen 10 times each, of pseudo-albedo `a`: lobe 2 with variance 100
    /// and slope `s`, residual variance 0.01.
    fn sums(s: f32, a: f32) -> FitSums {
        sums_of(100.0, s, a)
    }

    /// `sums` of n pixels (variance n, 10n samples).
    fn sums_of(n: f32, s: f32, a: f32) -> FitSums {
        FitSums {
            xx: [0.0, n, 0.0],
            xi: [0.0, n * s, 0.0],
            ii: n * s * s + 0.01,
            samples: 10.0 * n,
            pixels: n,
            albedo: Vec3::splat(n * a),
        }
    }

    /// Sums over all three lobes of 100 pixels seen 10 times each (pseudo-albedo 0.3).
    fn lobes(xx: [f32; LOBES], xi: [f32; LOBES], ii: f32) -> FitSums {
        FitSums {
            xx,
            xi,
            ii,
            samples: 1000.0,
            pixels: 100.0,
            albedo: Vec3::splat(30.0),
        }
    }

    fn empty() -> Mesh {
        Mesh {
            positions: Vec::new(),
            colors: None,
            triangles: Vec::new(),
        }
    }

    #[test]
    fn one_patch_with_highlights_gives_its_strength_to_its_whole_surface() {
        let mut m = empty();
        let mut acc = Vec::new();
        for i in 0..4 {
            for j in 0..4 {
                let o = Vec3::new(i as f32 * CELL + 0.01, 0.0, j as f32 * CELL + 0.01);
                quad(&mut m, o, Vec3::Z * 0.2, Vec3::X * 0.2);
                // Only the first quad's photos see a light in their lobes.
                let s = if i + j == 0 {
                    sums(0.06, 0.4)
                } else {
                    sums(0.0, 0.4)
                };
                let none = FitSums {
                    xx: [0.0; 3],
                    xi: [0.0; 3],
                    ..s
                };
                acc.extend([if i + j == 0 { s } else { none }; 2]);
            }
        }
        let (fit, _) = pool(&m, &acc);
        for f in &fit {
            assert!(
                (f[1] - 0.06).abs() < 1e-3 && f[0] == 0.0 && f[2] == 0.0,
                "{f:?}"
            );
            assert!(f[3] >= GLOSSY_REGION_T);
        }
    }

    /// A floor whose triangles tilt by up to 4° (a proxy from photos) takes the plane's normal
    /// on every triangle; a column's facets, 30° apart, take none (the layer smooths the
    /// G-buffer's normals there).
    #[test]
    fn a_bumpy_floor_takes_its_planes_normal_and_a_column_none() {
        let mut m = empty();
        let mut acc = Vec::new();
        for i in 0..8 {
            for j in 0..8 {
                let o = Vec3::new(i as f32 * 0.1, 0.0, j as f32 * 0.1);
                let k = m.triangles.len();
                quad(&mut m, o, Vec3::Z * 0.1, Vec3::X * 0.1);
                // Lift or lower one corner by up to 7 mm over 10 cm: a tilt of up to 4°.
                let sign = if (i + j) % 2 == 0 { 1.0 } else { -1.0 };
                let lift = sign * 0.007 * (((i * 7 + j * 3) % 5) as f32 / 4.0);
                m.positions[m.triangles[k][2] as usize][1] += lift;
                acc.extend([sums(0.05, 0.4); 2]);
            }
        }
        let floor = m.triangles.len();
        for f in 0..12 {
            let a = |k: i32| (k as f32 * 30f32).to_radians();
            let p = |k: i32| Vec3::new(2.0 + 0.2 * a(k).cos(), 0.0, 2.0 + 0.2 * a(k).sin());
            quad(&mut m, p(f), p(f + 1) - p(f), Vec3::Y);
            acc.extend([sums(0.05, 0.4); 2]);
        }
        let (fit, normals) = pool(&m, &acc);
        let tilt = |n: Vec3| n.dot(Vec3::Y).clamp(-1.0, 1.0).acos().to_degrees();
        let most = (0..floor)
            .map(|t| tilt(m.face_normal(t)))
            .fold(0.0, f32::max);
        assert!(most > 3.0, "the floor's triangles tilt (by up to {most}°)");
        for t in 0..floor {
            let n = Vec3::from_slice(&normals[t][..3]);
            assert!(
                fit[t][1] > 0.0 && tilt(n) < 1.0,
                "{}°: {n}",
                tilt(m.face_normal(t))
            );
        }
        assert!(
            normals[floor..].iter().all(|n| *n == [0.0; 4]),
            "{:?}",
            &normals[floor..]
        );
    }

    #[test]
    fn another_material_on_the_same_plane_keeps_its_own_fit() {
        let mut m = empty();
        let mut acc = Vec::new();
        // A wall (pseudo-albedo 0.2, its photos agree where a lobe predicts a highlight) with a
        // mirror (0.9, strong highlights) beside it on the same plane.
        for i in 0..4 {
            let o = Vec3::new(0.0, 1.0, i as f32 * CELL + 0.01);
            quad(&mut m, o, Vec3::Y * 0.2, Vec3::Z * 0.2);
            let s = if i == 0 {
                sums(0.06, 0.9)
            } else {
                sums(0.0, 0.2)
            };
            acc.extend([s; 2]);
        }
        let (fit, _) = pool(&m, &acc);
        assert!((fit[0][1] - 0.06).abs() < 1e-3 && (fit[1][1] - 0.06).abs() < 1e-3);
        for f in &fit[2..] {
            assert_eq!(f[..3], [0.0; 3], "the wall takes none of the mirror's fit");
        }
    }

    /// A floor's patches of odd pseudo-albedo (E_src errs beside shadows) take the floor's fit
    /// when they have too few photos to tell (a), and so do triangles without sums (in every
    /// original light's shadow, c); one whose many photos show no highlight keeps none (b).
    #[test]
    fn holes_in_a_floor_take_its_fit_unless_their_photos_refuse_it() {
        let mut m = empty();
        let mut acc = Vec::new();
        let (few, refuses, unseen) = ((1, 1), (6, 6), (3, 5));
        let mut tris = HashMap::new();
        for i in 0..8 {
            for j in 0..8 {
                let o = Vec3::new(i as f32 * CELL + 0.01, 0.0, j as f32 * CELL + 0.01);
                tris.insert((i, j), quad(&mut m, o, Vec3::Z * 0.2, Vec3::X * 0.2));
                let s = match (i, j) {
                    k if k == few => sums_of(2.0, 0.05, 1.0),
                    k if k == refuses => sums(0.0, 1.0),
                    k if k == unseen => FitSums::default(),
                    _ => sums(0.05, 0.4),
                };
                acc.extend([s; 2]);
            }
        }
        let (fit, _) = pool(&m, &acc);
        for (k, ts) in &tris {
            for &t in ts {
                let want = if *k == refuses { 0.0 } else { 0.05 };
                assert!((fit[t][1] - want).abs() < 1e-3, "{k:?}: {:?}", fit[t]);
            }
        }
    }

    #[test]
    fn the_t_threshold_decides() {
        // t = s·√(Σxx·dof/residual) = s·√(100·899/0.01) ≈ 3000·s against GLOSSY_REGION_T.
        let t = |s: f32| s * (100.0f32 * 899.0 / 0.01).sqrt();
        let (weak, strong) = (
            0.5 * GLOSSY_REGION_T / t(1.0),
            2.0 * GLOSSY_REGION_T / t(1.0),
        );
        assert_eq!(sums(weak, 0.3).strengths(), [0.0; 4]);
        let f = sums(strong, 0.3).strengths();
        assert!((f[1] - strong).abs() < 1e-4 && (f[3] - t(strong)).abs() < 0.05 * t(strong));
    }

    /// A near-mirror: the narrowest lobe's slope is above the middle one's and the widest one's
    /// is over its cap, so the middle lobe, though it explains the views best, is out and the
    /// narrowest takes the surface.
    #[test]
    fn a_near_mirror_takes_the_narrowest_lobe() {
        // Slopes 0.1, 0.06, 0.09; t 42, 147, 27: lobe 2 explains the views best, but lobe 3's
        // slope is over its cap (GLOSSY_WIDE_S).
        let mut f = lobes([100.0, 400.0, 100.0], [10.0, 24.0, 9.0], 1.5);
        let w = f.strengths();
        assert_eq!((w[1], w[2]), (0.0, 0.0), "{w:?}");
        assert!((w[0] - 0.1).abs() < 1e-6, "{w:?}");
        // Without the over-cap lobe the middle one wins, and so it does with highlights wider
        // than the narrowest lobe (its slope 0.05, below the middle one's).
        f.xi[2] = 5.0;
        assert!(f.strengths()[1] > 0.0, "{:?}", f.strengths());
        (f.xi[0], f.xi[2]) = (5.0, 9.0);
        assert!(f.strengths()[1] > 0.0, "{:?}", f.strengths());
    }

    /// A bright plastic reflecting a large window: its widest lobe's slope, above what a
    /// dielectric reflects, is out and a narrower lobe takes the surface (sg800003's box top).
    #[test]
    fn a_wide_lobe_stronger_than_a_dielectric_is_out() {
        let mut f = lobes([0.0, 400.0, 100.0], [0.0, 12.0, 10.0], 1.0);
        let w = f.strengths();
        assert!(w[2] == 0.0 && (w[1] - 0.03).abs() < 1e-6, "{w:?}");
        f.xi[2] = 7.0; // slope 0.07: a dielectric's, and it explains the views best
        assert!(
            (f.strengths()[2] - 0.07).abs() < 1e-6,
            "{:?}",
            f.strengths()
        );
    }
}
