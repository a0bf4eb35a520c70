//! A small procedural room, written in any of the three scene formats: the bundled
//! `scenes/tiny_room` and the loader tests come from it. Its images are shaded on the CPU
//! (diffuse albedo × direct light from a ceiling panel with shadows, plus a constant ambient
//! term): enough for loaders and device tests. Realistic ground truth is `tools/scenegen`'s job.

use std::collections::BTreeMap;
use std::path::Path;

use glam::Vec3;

use super::{Camera, Light, LightShape, LightingPreset, Mesh, RgbImage, Scene, SceneFormat, View};
use crate::error::{Error, Result};

#[derive(Clone, Debug)]
pub struct SynthOptions {
    pub views: usize,
    pub width: u32,
    pub height: u32,
    pub seed: u64,
    /// Subdivisions per wall side (more triangles for ray-rate benchmarks).
    pub wall_subdiv: u32,
}

impl Default for SynthOptions {
    fn default() -> Self {
        SynthOptions {
            views: 6,
            width: 64,
            height: 48,
            seed: 1,
            wall_subdiv: 4,
        }
    }
}

/// SplitMix64: deterministic across platforms, no dependency.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
}

/// A grid of `n × n` quads spanning `corner + [0,1]·u + [0,1]·v`, facing `u × v`.
fn grid(corner: Vec3, u: Vec3, v: Vec3, n: u32) -> Mesh {
    let mut m = Mesh::default();
    for j in 0..=n {
        for i in 0..=n {
            let p = corner + u * (i as f32 / n as f32) + v * (j as f32 / n as f32);
            m.positions.push(p.into());
        }
    }
    let row = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = j * row + i;
            m.triangles.push([a, a + 1, a + row + 1]);
            m.triangles.push([a, a + row + 1, a + row]);
        }
    }
    m
}

/// An axis-aligned box with outward faces, from `lo` to `hi`.
fn boxed(lo: Vec3, hi: Vec3, n: u32, inward: bool) -> Mesh {
    let d = hi - lo;
    let (x, y, z) = (Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z);
    // (corner, u, v) with u × v pointing outward.
    let faces = [
        (lo, z, y),     // -X
        (lo + x, y, z), // +X
        (lo, x, z),     // -Y
        (lo + y, z, x), // +Y
        (lo, y, x),     // -Z
        (lo + z, x, y), // +Z
    ];
    let mut m = Mesh::default();
    for (c, u, v) in faces {
        let f = if inward {
            grid(c, v, u, n)
        } else {
            grid(c, u, v, n)
        };
        m.append(&f);
    }
    m
}

/// The room: walls, floor and ceiling facing inward, a table, a cabinet and a pillar. Returns
/// the mesh and a diffuse albedo per triangle.
pub fn room(subdiv: u32) -> (Mesh, Vec<[f32; 3]>) {
    let mut mesh = Mesh::default();
    let mut albedo = Vec::new();
    let mut add = |m: Mesh, a: [f32; 3], mesh: &mut Mesh| {
        albedo.extend(std::iter::repeat_n(a, m.triangles.len()));
        mesh.append(&m);
    };
    let room = boxed(
        Vec3::new(-2.0, 0.0, -1.75),
        Vec3::new(2.0, 2.6, 1.75),
        subdiv,
        true,
    );
    // Colour the room's faces: walls, floor (-Y face is third), ceiling.
    let per_face = room.triangles.len() / 6;
    let colors = [
        [0.7, 0.45, 0.4],
        [0.4, 0.55, 0.7],
        [0.55, 0.4, 0.25],
        [0.8, 0.8, 0.8],
        [0.65, 0.65, 0.6],
        [0.5, 0.65, 0.45],
    ];
    for (f, c) in colors.iter().enumerate() {
        let mut face = Mesh {
            positions: room.positions.clone(),
            colors: None,
            triangles: Vec::new(),
        };
        face.triangles = room.triangles[f * per_face..(f + 1) * per_face].to_vec();
        add(face, *c, &mut mesh);
    }
    add(
        boxed(
            Vec3::new(-0.6, 0.0, -0.4),
            Vec3::new(0.5, 0.75, 0.3),
            1,
            false,
        ),
        [0.6, 0.35, 0.2],
        &mut mesh,
    );
    add(
        boxed(
            Vec3::new(1.2, 0.0, -1.7),
            Vec3::new(1.9, 1.8, -1.1),
            1,
            false,
        ),
        [0.3, 0.3, 0.35],
        &mut mesh,
    );
    add(
        boxed(
            Vec3::new(-1.6, 0.0, 0.9),
            Vec3::new(-1.3, 2.6, 1.2),
            1,
            false,
        ),
        [0.85, 0.85, 0.8],
        &mut mesh,
    );
    // Drop the vertices the face split duplicated but no triangle uses.
    (compact(mesh), albedo)
}

fn compact(m: Mesh) -> Mesh {
    let mut remap = vec![u32::MAX; m.positions.len()];
    let mut out = Mesh::default();
    for t in &m.triangles {
        let mut nt = [0u32; 3];
        for k in 0..3 {
            let v = t[k] as usize;
            if remap[v] == u32::MAX {
                remap[v] = out.positions.len() as u32;
                out.positions.push(m.positions[v]);
            }
            nt[k] = remap[v];
        }
        out.triangles.push(nt);
    }
    out
}

/// The room's ceiling panel (the original lighting) and a lamp a user might add.
pub fn room_lights() -> (Vec<Light>, Vec<LightingPreset>) {
    let lights = vec![
        Light {
            name: "ceiling".into(),
            shape: LightShape::Quad {
                corner: Vec3::new(-0.4, 2.59, -0.3),
                edge_u: Vec3::new(0.0, 0.0, 0.6),
                edge_v: Vec3::new(0.8, 0.0, 0.0),
            },
            radiance: [8.0, 7.6, 7.0],
            original: true,
            estimated: false,
        },
        Light {
            name: "lamp".into(),
            shape: LightShape::Disk {
                center: Vec3::new(1.5, 1.9, 1.2),
                normal: Vec3::new(-0.5, -1.0, -0.4).normalize(),
                radius: 0.12,
            },
            radiance: [20.0, 14.0, 8.0],
            original: false,
            estimated: false,
        },
    ];
    let presets = vec![LightingPreset {
        name: "lamp_on_dimmed".into(),
        dim: 0.5,
        intensities: BTreeMap::from([("lamp".to_string(), 1.0)]),
        originals: BTreeMap::new(),
    }];
    (lights, presets)
}

/// Shades one view on the CPU: albedo × (ambient + direct light from the panel's centre).
pub fn shade(mesh: &Mesh, albedo: &[[f32; 3]], cam: &Camera, light: &Light) -> RgbImage {
    let mut img = RgbImage::new(cam.width, cam.height);
    let lc = light.shape.center();
    let power = light.radiance.map(|r| r * light.shape.area());
    let o = cam.center();
    for y in 0..cam.height {
        for x in 0..cam.width {
            let d = cam.ray_dir(glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
            let Some(h) = crate::cpu::closest_hit(mesh, o, d, 1e-3, 100.0) else {
                continue;
            };
            let p = o + d * h.t;
            let mut n = mesh.face_normal(h.tri as usize);
            if n.dot(d) > 0.0 {
                n = -n;
            }
            let to_l = lc - p;
            let dist2 = to_l.length_squared();
            let l = to_l / dist2.sqrt();
            let cos = n.dot(l).max(0.0) * (-l.y).max(0.0);
            let lit = cos > 0.0
                && !crate::cpu::occluded(mesh, p + n * 1e-3, l, 1e-3, dist2.sqrt() - 0.02);
            let a = albedo[h.tri as usize];
            let e = |k: usize| {
                0.25 + if lit {
                    power[k] * cos / (std::f32::consts::PI * dist2)
                } else {
                    0.0
                }
            };
            img.set(x, y, [a[0] * e(0), a[1] * e(1), a[2] * e(2)]);
        }
    }
    img
}

/// Cameras inside the room looking at its content, as a handheld capture would.
pub fn capture_cameras(opts: &SynthOptions) -> Vec<Camera> {
    let mut rng = Rng::new(opts.seed);
    (0..opts.views)
        .map(|i| {
            let a = i as f32 / opts.views as f32 * std::f32::consts::TAU + rng.range(-0.2, 0.2);
            let pos = Vec3::new(1.35 * a.cos(), rng.range(1.2, 1.7), 1.1 * a.sin());
            let target = Vec3::new(
                rng.range(-0.5, 0.5),
                rng.range(0.4, 1.0),
                rng.range(-0.5, 0.5),
            );
            let fx = opts.width as f32 * rng.range(0.55, 0.75);
            Camera::look_at(pos, target, Vec3::Y, opts.width, opts.height, fx)
        })
        .collect()
}

/// Writes the room in `format` under `dir`: mesh, EXR images, cameras, lights.
pub fn write_room(dir: &Path, format: SceneFormat, opts: &SynthOptions) -> Result<Scene> {
    let images = dir.join("images");
    std::fs::create_dir_all(&images).map_err(|e| Error::io(&images, e))?;
    let (mesh, albedo) = room(opts.wall_subdiv);
    let (lights, presets) = room_lights();
    let mesh_path = match format {
        SceneFormat::Relit => dir.join("mesh.ply"),
        SceneFormat::Colmap | SceneFormat::Transforms => dir.join("mesh.ply"),
        SceneFormat::Sibr => {
            let m = dir.join("meshes");
            std::fs::create_dir_all(&m).map_err(|e| Error::io(&m, e))?;
            m.join("recon.ply")
        }
    };
    mesh.write_ply(&mesh_path)?;
    let mut views = Vec::new();
    for (i, cam) in capture_cameras(opts).into_iter().enumerate() {
        let name = format!("{i:03}.exr");
        let path = images.join(&name);
        super::image::write_exr(&path, &shade(&mesh, &albedo, &cam, &lights[0]))?;
        views.push(View {
            name,
            image: path,
            camera: cam,
        });
    }
    let scene = Scene {
        root: dir.to_path_buf(),
        format,
        views,
        mesh,
        mesh_path,
        true_mesh_path: None,
        synthetic: None,
        lights,
        presets,
    };
    super::write_scene(dir, &scene, format)?;
    Ok(scene)
}
