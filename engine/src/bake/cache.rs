//! A bake on disk: `SCENE/.relit/bake-<key>/`, keyed by a hash of everything its maps depend
//! on (the bake's version and parameters, the mesh, the views and their photos, the original
//! lights). [`BakeCache`] owns the key, the file layout, the writes (temp file, then rename:
//! a killed bake never leaves a partial entry) and the loading; the bake's stages write through
//! it and the frame reads through it.
//!
//! Layout: `params.json` (what made it); per view `<view>.esrc.exr` and `<view>.msrc.exr`;
//! `albedo_mesh.bin`; `source_cache.bin`; per added light an entry `light-<key>/` holding its
//! `surface_cache.bin` and `<view>.eadd.exr`. Every EXR map gets a BC6H copy (`.bc6h`).

use std::path::{Path, PathBuf};

use super::{BakeParams, DenoiseParams, GpuLight};
use crate::error::{Error, Result};
use crate::scene::image::{load_rgb, write_exr, RgbImage};
use crate::scene::{write_atomic, Light, Scene};

/// Bump when a pass changes what it computes: old caches are then not reused.
pub const BAKE_VERSION: u32 = 8;

/// FNV-1a 64: a stable hash (std's hasher may change between Rust versions).
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 = (self.0 ^ x as u64).wrapping_mul(0x0000_0100_0000_01B3);
        }
    }
    fn file(&mut self, p: &Path) -> Result<()> {
        let b = std::fs::read(p).map_err(|e| Error::io(p, e))?;
        self.bytes(&(b.len() as u64).to_le_bytes());
        self.bytes(&b);
        Ok(())
    }
}

/// One bake of a scene: its directory, from the key.
#[derive(Clone, Debug)]
pub struct BakeCache {
    dir: PathBuf,
}

impl BakeCache {
    /// The cache of `scene` baked with `p` (the view slice and the lights asked for do not change
    /// the key; E_add's parameters key the light entries, [`BakeCache::light_dir`]).
    pub fn of(scene: &Scene, p: &BakeParams) -> Result<BakeCache> {
        let mut h = Fnv::new();
        h.bytes(&BAKE_VERSION.to_le_bytes());
        for v in [p.irradiance_samples, p.source_cache_samples, p.seed] {
            h.bytes(&v.to_le_bytes());
        }
        h.bytes(&p.texel_size.to_le_bytes());
        h.bytes(&[p.mesh_process as u8]);
        let d = p.denoise;
        for v in [d.radius as f32, d.sigma_px, d.sigma_depth, d.normal_power] {
            h.bytes(&v.to_le_bytes());
        }
        h.file(&scene.mesh_path)?;
        // Photos in integer formats have clipped pixels left out since then: their bakes from
        // before are keyed apart (EXR scenes keep their key: nothing changed for them).
        if scene
            .views
            .iter()
            .any(|v| !crate::scene::image::is_exr(&v.image))
        {
            h.bytes(b"clipped pixels left out");
        }
        for v in &scene.views {
            h.bytes(v.name.as_bytes());
            h.bytes(bytemuck::bytes_of(&v.camera.to_gpu(0.0, 0.0)));
            h.file(&v.image)?;
        }
        // Original lights shape E_src and the albedo; added lights have entries of their own.
        for l in scene.lights.iter().filter(|l| l.original) {
            h.bytes(l.name.as_bytes());
            h.bytes(bytemuck::bytes_of(&GpuLight::new(l)));
        }
        let dir = scene.root.join(".relit").join(format!("bake-{:016x}", h.0));
        Ok(BakeCache { dir })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Makes the directory and records `p` in it; removes the temp files of an interrupted run
    /// (never read, only renamed into place when whole).
    pub fn prepare(&self, p: &BakeParams) -> Result<()> {
        std::fs::create_dir_all(&self.dir).map_err(|e| Error::io(&self.dir, e))?;
        write_params(&self.dir.join("params.json"), p)?;
        for path in self.entry_files() {
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            if name.ends_with(".tmp") || name.contains(".tmp.") {
                let _ = std::fs::remove_file(&path);
            }
        }
        Ok(())
    }

    /// E_src of a view (§4.1.1).
    pub fn esrc(&self, view: &str) -> PathBuf {
        self.dir.join(format!("{view}.esrc.exr"))
    }

    /// M_src, the mirror image of a view (§4.2.1).
    pub fn msrc(&self, view: &str) -> PathBuf {
        self.dir.join(format!("{view}.msrc.exr"))
    }

    /// The albedo mesh (§4.1.2).
    pub fn albedo(&self) -> PathBuf {
        self.dir.join("albedo_mesh.bin")
    }

    /// The source cache (E_src's indirect part on the mesh).
    pub fn source_cache(&self) -> PathBuf {
        self.dir.join("source_cache.bin")
    }

    /// An added light's entry: keyed by what the light is (shape, place, size, radiance; not
    /// its name) and E_add's parameters, so moving one light or changing E_add's sample counts
    /// re-bakes the light entries alone.
    pub fn light_dir(&self, light: &Light, p: &BakeParams) -> PathBuf {
        let mut h = Fnv::new();
        h.bytes(bytemuck::bytes_of(&GpuLight::traced(light)));
        for v in [p.added_samples, p.cache_samples, p.bounces] {
            h.bytes(&v.to_le_bytes());
        }
        self.dir.join(format!("light-{:016x}", h.0))
    }

    /// E_add of a view for an added light (§4.1.3).
    pub fn eadd(&self, view: &str, light: &Light, p: &BakeParams) -> PathBuf {
        self.light_dir(light, p).join(format!("{view}.eadd.exr"))
    }

    /// An added light's surface cache.
    pub fn surface_cache(&self, light: &Light, p: &BakeParams) -> PathBuf {
        self.light_dir(light, p).join("surface_cache.bin")
    }

    /// BC6H copy of a cached map: `v000.esrc.exr` → `v000.esrc.bc6h`.
    pub fn bc6h(exr: &Path) -> PathBuf {
        exr.with_extension("bc6h")
    }

    /// Whether every map the frame reads is there. Added lights' entries are not needed: the
    /// frame bakes a missing one when the light is used.
    pub fn is_complete(&self, scene: &Scene) -> bool {
        self.albedo().exists()
            && scene
                .views
                .iter()
                .all(|v| self.esrc(&v.name).exists() && self.msrc(&v.name).exists())
    }

    /// The lights `p` asks for ([`super::run::wanted_lights`]) whose entry lacks a view's map.
    pub fn missing_lights<'a>(&self, scene: &'a Scene, p: &BakeParams) -> Vec<&'a Light> {
        let missing = |l: &Light| {
            scene
                .views
                .iter()
                .any(|v| !self.eadd(&v.name, l, p).exists())
        };
        let wanted = super::run::wanted_lights(scene, p);
        wanted.into_iter().filter(|l| missing(l)).collect()
    }

    /// Per-vertex albedo (rgb, weight), tagged "RALB".
    pub fn read_albedo(&self, expected: usize) -> Result<Vec<[f32; 4]>> {
        super::storage::read_vec4s(
            &self.albedo(),
            b"RALB",
            expected,
            "albedo-mesh cache",
            "vertices",
        )
    }

    pub fn write_albedo(&self, a: &[[f32; 4]]) -> Result<()> {
        super::storage::write_vec4s(&self.albedo(), b"RALB", a)
    }

    /// A surface cache (the source's, [`Self::source_cache`], or a light's,
    /// [`Self::surface_cache`]): one vec4 per texel, tagged "RCAC".
    pub fn read_texels(path: &Path, texels: usize) -> Result<Vec<[f32; 4]>> {
        super::storage::read_vec4s(path, b"RCAC", texels, "surface-cache", "texels")
    }

    /// Writes a surface cache atomically, making its light's directory first.
    pub fn write_texels(path: &Path, values: &[[f32; 4]]) -> Result<()> {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
        super::storage::write_vec4s(path, b"RCAC", values)
    }

    /// Writes a w×h map (rgb of each vec4) as EXR, atomically.
    pub fn write_map(path: &Path, w: u32, h: u32, px: &[[f32; 4]]) -> Result<()> {
        let pixels = px.iter().map(|p| [p[0], p[1], p[2]]).collect();
        write_exr(
            path,
            &RgbImage {
                width: w,
                height: h,
                pixels,
            },
        )
    }

    /// A cached map as vec4s (alpha 1), for the frame passes and the tests.
    pub fn load_map(path: &Path) -> Result<Vec<[f32; 4]>> {
        Ok(from_image(&load_rgb(path)?))
    }

    /// Encodes every cached EXR map that has no BC6H copy yet (the EXR is the finished entry;
    /// its BC6H copy is derived, so a kill between the two only costs a re-encode).
    pub fn compress_missing(&self) -> Result<()> {
        for path in self.entry_files() {
            if path.extension().is_none_or(|x| x != "exr") || Self::bc6h(&path).exists() {
                continue;
            }
            let img = load_rgb(&path)?;
            let px: Vec<[f32; 4]> = from_image(&img);
            let quality = super::storage::Bc6hQuality::Basic;
            let blocks = super::storage::encode_bc6h(img.width, img.height, &px, quality);
            super::storage::write_bc6h(&Self::bc6h(&path), img.width, img.height, &blocks)?;
        }
        Ok(())
    }

    /// The files of the cache: its own and those of its lights' entries (`light-*/`).
    fn entry_files(&self) -> Vec<PathBuf> {
        let list = |d: &Path| -> Vec<PathBuf> {
            let mut v: Vec<PathBuf> = std::fs::read_dir(d)
                .map(|rd| rd.flatten().map(|e| e.path()).collect())
                .unwrap_or_default();
            v.sort();
            v
        };
        let mut out = Vec::new();
        for p in list(&self.dir) {
            if p.is_dir() {
                out.extend(list(&p).into_iter().filter(|f| f.is_file()));
            } else {
                out.push(p);
            }
        }
        out
    }

    /// The complete, current bakes of `scene` (their key matches the scene's files as they are
    /// now), best first (most E_src rays, then most E_add paths).
    pub fn complete(scene: &Scene) -> Result<Vec<BakeParams>> {
        let mut cands = vec![BakeParams::final_quality(), BakeParams::preview()];
        if let Ok(rd) = std::fs::read_dir(scene.root.join(".relit")) {
            let mut dirs: Vec<_> = rd.flatten().map(|e| e.path()).collect();
            dirs.sort();
            cands.extend(
                dirs.iter()
                    .filter_map(|d| read_params(&d.join("params.json"))),
            );
        }
        let mut out: Vec<(PathBuf, BakeParams)> = Vec::new();
        for p in cands {
            let c = BakeCache::of(scene, &p)?;
            if out.iter().all(|(d, _)| *d != c.dir) && c.is_complete(scene) {
                out.push((c.dir, p));
            }
        }
        out.sort_by_key(|(_, p)| std::cmp::Reverse((p.irradiance_samples, p.added_samples)));
        Ok(out.into_iter().map(|(_, p)| p).collect())
    }
}

fn from_image(img: &RgbImage) -> Vec<[f32; 4]> {
    img.pixels.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect()
}

/// `params.json`: the parameters that made a cache, so readers can find every bake of a scene
/// (the key alone cannot be inverted).
fn write_params(path: &Path, p: &BakeParams) -> Result<()> {
    let d = p.denoise;
    let doc = serde_json::json!({
        "irradiance_samples": p.irradiance_samples, "source_cache_samples": p.source_cache_samples,
        "added_samples": p.added_samples,
        "cache_samples": p.cache_samples, "texel_size": p.texel_size, "bounces": p.bounces, "seed": p.seed, "mesh_process": p.mesh_process,
        "denoise": { "radius": d.radius, "sigma_px": d.sigma_px, "sigma_depth": d.sigma_depth,
                     "normal_power": d.normal_power },
    });
    write_atomic(path, doc.to_string().as_bytes())
}

fn read_params(path: &Path) -> Option<BakeParams> {
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).ok()?).ok()?;
    let u = |k: &str| v.get(k)?.as_u64().map(|x| x as u32);
    let d = v.get("denoise")?;
    let f = |k: &str| d.get(k)?.as_f64().map(|x| x as f32);
    Some(BakeParams {
        irradiance_samples: u("irradiance_samples")?,
        source_cache_samples: u("source_cache_samples")?,
        added_samples: u("added_samples")?,
        cache_samples: u("cache_samples")?,
        bounces: u("bounces")?,
        texel_size: v.get("texel_size")?.as_f64()? as f32,
        seed: u("seed")?,
        views: None,
        lights: None,
        denoise: DenoiseParams {
            radius: d.get("radius")?.as_i64()? as i32,
            sigma_px: f("sigma_px")?,
            sigma_depth: f("sigma_depth")?,
            normal_power: f("normal_power")?,
        },
        compress: true,
        mesh_process: v.get("mesh_process")?.as_bool()?,
    })
}
