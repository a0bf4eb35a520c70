//! Procedural albedo textures (sRGB PNG): wood, tiles, fabric, posters. They give MVS-like
//! inputs texture to hold on to and the network varied albedo.

use glam::Vec3;
use relit_engine::scene::synth::Rng;

pub const SIZE: u32 = 256;

/// Smooth 2D value noise in [0, 1], periodic over `period` cells so textures tile.
pub struct Noise {
    grid: Vec<f32>,
    period: u32,
}

impl Noise {
    pub fn new(rng: &mut Rng, period: u32) -> Noise {
        Noise {
            grid: (0..period * period).map(|_| rng.f32()).collect(),
            period,
        }
    }
    /// `x`, `y` in cells.
    pub fn at(&self, x: f32, y: f32) -> f32 {
        let p = self.period as i64;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let s = |t: f32| t * t * (3.0 - 2.0 * t);
        let g = |i: i64, j: i64| self.grid[(i.rem_euclid(p) * p + j.rem_euclid(p)) as usize];
        let (i, j) = (x0 as i64, y0 as i64);
        let a = g(i, j) + (g(i + 1, j) - g(i, j)) * s(fx);
        let b = g(i, j + 1) + (g(i + 1, j + 1) - g(i, j + 1)) * s(fx);
        a + (b - a) * s(fy)
    }
    /// A few octaves, normalized to about [0, 1].
    pub fn fbm(&self, x: f32, y: f32, octaves: u32) -> f32 {
        let (mut sum, mut amp, mut norm, mut f) = (0.0, 1.0, 0.0, 1.0);
        for _ in 0..octaves {
            sum += amp * self.at(x * f, y * f);
            norm += amp;
            amp *= 0.5;
            f *= 2.0;
        }
        sum / norm
    }
}

#[derive(Clone, Copy, Debug)]
pub enum Kind {
    Wood,
    Tiles,
    Fabric,
    Poster,
    Plaster,
}

fn to_u8(c: Vec3) -> [u8; 3] {
    let c = c.clamp(Vec3::ZERO, Vec3::ONE);
    [c.x, c.y, c.z].map(|v| (relit_engine::scene::image::linear_to_srgb(v) * 255.0 + 0.5) as u8)
}

/// A linear-albedo texture around `base`, returned as an sRGB image and its mean linear albedo.
pub fn make(kind: Kind, base: Vec3, rng: &mut Rng) -> (image::RgbImage, Vec3) {
    let noise = Noise::new(rng, 16);
    let noise2 = Noise::new(rng, 8);
    let accent = Vec3::new(
        rng.range(0.2, 0.9),
        rng.range(0.2, 0.9),
        rng.range(0.2, 0.9),
    );
    let mut img = image::RgbImage::new(SIZE, SIZE);
    let mut sum = Vec3::ZERO;
    for y in 0..SIZE {
        for x in 0..SIZE {
            let (u, v) = (x as f32 / SIZE as f32, y as f32 / SIZE as f32);
            let c = match kind {
                Kind::Wood => {
                    // Rings stretched along u, with planks every quarter.
                    let plank = (v * 4.0).floor();
                    let rings = ((v * 4.0 * 10.0
                        + noise.fbm(u * 2.0, v * 16.0 + plank * 3.0, 3) * 6.0)
                        .sin()
                        * 0.5
                        + 0.5)
                        .powf(3.0);
                    let seam = if (v * 4.0).fract() < 0.02 { 0.55 } else { 1.0 };
                    base * (0.75 + 0.35 * rings - 0.1 * noise2.at(plank * 2.0, u * 8.0)) * seam
                }
                Kind::Tiles => {
                    let (tu, tv) = ((u * 4.0).fract(), (v * 4.0).fract());
                    let grout = tu < 0.04 || tv < 0.04;
                    let cell = (u * 4.0).floor() + 4.0 * (v * 4.0).floor();
                    if grout {
                        Vec3::splat(0.35)
                    } else {
                        base * (0.9
                            + 0.15 * noise2.at(cell, cell * 0.37)
                            + 0.05 * noise.fbm(u * 16.0, v * 16.0, 2))
                    }
                }
                Kind::Fabric => {
                    let weave = (((x / 2) + (y / 2)) % 2) as f32;
                    base * (0.8 + 0.25 * noise.fbm(u * 16.0, v * 16.0, 4) + 0.06 * weave)
                }
                Kind::Poster => {
                    // Bands, a disc and noise: content with edges, like a print.
                    let band = if ((u + noise.at(v * 4.0, 0.0) * 0.2) * 5.0).floor() as i32 % 2 == 0
                    {
                        base
                    } else {
                        accent
                    };
                    let d = Vec3::new(u - 0.6, v - 0.4, 0.0).length();
                    if d < 0.2 {
                        Vec3::ONE - accent * 0.7
                    } else {
                        band * (0.8 + 0.3 * noise.fbm(u * 8.0, v * 8.0, 3))
                    }
                }
                Kind::Plaster => base * (0.93 + 0.1 * noise.fbm(u * 16.0, v * 16.0, 4)),
            };
            let c = c.clamp(Vec3::splat(0.01), Vec3::splat(0.95));
            let px = to_u8(c);
            img.put_pixel(x, y, image::Rgb(px));
            sum += Vec3::from(
                px.map(|b| relit_engine::scene::image::srgb_to_linear(b as f32 / 255.0)),
            );
        }
    }
    (img, sum / (SIZE * SIZE) as f32)
}
