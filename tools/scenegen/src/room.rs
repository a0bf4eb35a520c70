//! Seeded procedural indoor rooms: shell with an opening or two, furniture, materials, the
//! original lighting plus extra lights (§6), a capture camera set and a test path.

use std::collections::BTreeMap;

use glam::{Vec2, Vec3};
use relit_engine::cpu::MeshBvh;
use relit_engine::scene::coverage::visible_fraction;
use relit_engine::scene::synth::Rng;
use relit_engine::scene::{Camera, Light, LightShape, MaterialDoc};

use crate::prim::{tessellate, Prim, TriMesh};
use crate::texture::{self, Kind};

/// What the proxy mesh does with an object (MVS fails on large textureless or glossy surfaces).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    Textured,
    Textureless,
    Glossy,
}

#[derive(Clone, Debug)]
pub struct Object {
    pub name: String,
    pub prim: Prim,
    pub material: String,
    pub surface: Surface,
    /// Part of the room shell (walls, floor, ceiling): bumpy in the proxy, never rounded.
    pub shell: bool,
}

pub struct Material {
    pub doc: MaterialDoc,
    /// Texture to write as `textures/<name>.png`.
    pub texture: Option<image::RgbImage>,
}

pub struct Room {
    pub seed: u64,
    pub size: Vec3,
    pub objects: Vec<Object>,
    pub materials: BTreeMap<String, Material>,
    pub lights: Vec<Light>,
    /// (condition name, its lights)
    pub conditions: Vec<(String, Vec<String>)>,
    pub cameras: Vec<Camera>,
    /// Keyframes of the test path: (time s, position, look-at).
    pub path: Vec<(f32, Vec3, Vec3)>,
    pub path_fov_deg: f32,
    pub test_cameras: Vec<Camera>,
}

#[derive(Clone, Debug)]
pub struct RoomOptions {
    pub views: usize,
    pub width: u32,
    pub height: u32,
    pub extra_lights: usize,
    pub test_views: usize,
    /// Capture views aimed at each original light (as a person photographing a room takes a
    /// few shots of its lamps): the first `n_lights · light_views` views (at most half of
    /// `views`), so that E_src sees every light from several views
    /// ([`relit_engine::scene::MIN_VIEWS_PER_LIGHT`]).
    pub light_views: usize,
    /// Tints of the added lights.
    pub lamp_colours: LampColours,
    /// How far the proxy is from the true geometry, as a fraction of the default MVS-like
    /// degradation ([`crate::proxy::ProxyParams::scaled`]): 1 (default) as before, 0 the true
    /// surfaces remeshed at the proxy's edge length, as in rooms written by hand.
    pub proxy_error: f32,
    /// Wall colours and the glossy furniture ([`Finishes`]).
    pub finishes: Finishes,
}

/// What the room's surfaces are made of, beyond the furniture every room has.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Finishes {
    /// One pale plaster colour on every wall (the rooms before 2026-12-02).
    #[default]
    Classic,
    /// The classic room of the same seed, plus what tests/scenes/hand_room2 has and classic
    /// rooms lack: each wall its own colour (half of them saturated and untextured), a
    /// near-mirror on the north wall and a lacquered cabinet of a strong colour.
    Varied,
    /// The varied room of the same seed, stripped to what the rooms written by hand have: every
    /// surface untextured and matte except the mirror and the cabinet (classic and varied rooms' floor
    /// and table top are glossy), and only the shell, the table and chair, the mirror and the
    /// cabinet (no posters, shelves, bed, sofa, television or clutter). Large flat evenly lit
    /// diffuse surfaces, where the ratio image is already close to the truth.
    Sparse,
    /// The varied room of the same seed, every object and texture kept, everything matte but
    /// the mirror and the cabinet: textured, cluttered rooms whose floor and tables do not
    /// reflect (between varied, where they all do, and sparse).
    Matte,
}

/// Objects a sparse room keeps besides the shell (name prefixes).
const SPARSE_KEEPS: [&str; 4] = ["table_", "chair_", "mirror", "cabinet"];
/// Materials a sparse room keeps glossy (as tests/scenes/hand_room2 has them).
const GLOSSY_KEPT: [&str; 2] = ["mirror", "cabinet"];

/// How the added lights are tinted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum LampColours {
    /// Near-white tints, each channel in 0.6–1 (the datasets before 2026-12-01).
    #[default]
    Mild,
    /// Half mild, half saturated: a random hue at saturation 0.5–0.95 (red, green, blue,
    /// warm and cold lamps all occur), so a network meets lights whose colour differs from
    /// the original lighting's.
    Mixed,
}

/// A saturated tint of hue `h` (0–1) and saturation `s`: HSV with value 1.
pub fn hue_tint(h: f32, s: f32) -> Vec3 {
    let k = |n: f32| {
        let k = (n + h * 6.0) % 6.0;
        1.0 - s * (k.min(4.0 - k)).clamp(0.0, 1.0)
    };
    Vec3::new(k(5.0), k(3.0), k(1.0))
}

impl Default for RoomOptions {
    fn default() -> Self {
        RoomOptions {
            views: 32,
            width: 256,
            height: 192,
            extra_lights: 6,
            test_views: 8,
            light_views: 3,
            lamp_colours: LampColours::Mild,
            proxy_error: 1.0,
            finishes: Finishes::Classic,
        }
    }
}

/// Power every lighting condition emits, in watts (the §6 normalization: each condition is
/// "intensity 1", so mixing weights are intensities).
pub const CONDITION_POWER: f32 = 60.0;

fn pick<T: Copy>(rng: &mut Rng, xs: &[T]) -> T {
    xs[(rng.next_u64() % xs.len() as u64) as usize]
}

fn v3(rng: &mut Rng, lo: f32, hi: f32) -> Vec3 {
    Vec3::new(rng.range(lo, hi), rng.range(lo, hi), rng.range(lo, hi))
}

struct Builder<'a> {
    rng: &'a mut Rng,
    objects: Vec<Object>,
    materials: BTreeMap<String, Material>,
    /// Occupied floor rectangles (for placement without overlap).
    taken: Vec<(Vec2, Vec2)>,
}

impl Builder<'_> {
    fn material(
        &mut self,
        name: &str,
        kind: &str,
        albedo: Vec3,
        tex: Option<(Kind, f32)>,
        roughness: f32,
        specular: Vec3,
    ) -> String {
        let (texture, albedo, scale) = match tex {
            Some((k, scale)) => {
                let (img, mean) = texture::make(k, albedo, self.rng);
                (Some(img), mean, scale)
            }
            None => (None, albedo, 1.0),
        };
        let doc = MaterialDoc {
            kind: kind.into(),
            albedo: albedo.to_array(),
            albedo_texture: texture.as_ref().map(|_| format!("textures/{name}.png")),
            texture_scale: scale,
            roughness,
            specular: specular.to_array(),
        };
        self.materials
            .insert(name.into(), Material { doc, texture });
        name.into()
    }

    fn add(&mut self, name: &str, prim: Prim, material: &str, surface: Surface) {
        self.objects.push(Object {
            name: name.into(),
            prim,
            material: material.into(),
            surface,
            shell: false,
        });
    }

    fn free(&self, lo: Vec2, hi: Vec2) -> bool {
        self.taken.iter().all(|(a, b)| {
            hi.x + 0.15 < a.x || lo.x > b.x + 0.15 || hi.y + 0.15 < a.y || lo.y > b.y + 0.15
        })
    }

    /// A free spot for a `w × d` footprint inside `[lo, hi]`.
    fn place(&mut self, lo: Vec2, hi: Vec2, w: f32, d: f32) -> Option<Vec2> {
        for _ in 0..40 {
            let p = Vec2::new(
                self.rng.range(lo.x, hi.x - w),
                self.rng.range(lo.y, hi.y - d),
            );
            if self.free(p, p + Vec2::new(w, d)) {
                self.taken.push((p, p + Vec2::new(w, d)));
                return Some(p);
            }
        }
        None
    }
}

/// [`Finishes::Varied`]'s walls, mirror and cabinet, added to a classic room.
fn vary(b: &mut Builder, size: Vec3, door_x: f32) {
    for (i, wall) in ["wall_w", "wall_e", "wall_n", "wall_s"].iter().enumerate() {
        let name = format!("wall{i}");
        if b.rng.f32() < 0.5 {
            let c = hue_tint(b.rng.f32(), b.rng.range(0.5, 0.9)) * b.rng.range(0.35, 0.7);
            b.material(&name, "diffuse", c, None, 0.0, Vec3::ZERO);
        } else {
            let c = v3(b.rng, 0.3, 0.85);
            let tex = Some((Kind::Plaster, 0.5));
            b.material(&name, "diffuse", c, tex, 0.0, Vec3::ZERO);
        }
        for o in b.objects.iter_mut().filter(|o| o.name == *wall) {
            o.material = name.clone();
        }
    }
    // The mirror: 1 cm proud of the north wall (MVS merges it into the wall), clear of the
    // doorway, its bottom edge at table height.
    let (x0, x1, z0) = (-size.x / 2.0, size.x / 2.0, -size.z / 2.0);
    let (w, h) = (b.rng.range(0.6, 1.1), b.rng.range(0.8, 1.2));
    let y = b.rng.range(0.8, 1.1);
    let spots = (0..20)
        .map(|_| b.rng.range(x0 + 0.3, x1 - w - 0.3))
        .collect::<Vec<_>>();
    let rough = b.rng.range(0.02, 0.05);
    let grey = Vec3::splat(b.rng.range(0.85, 0.95));
    if let Some(x) = spots
        .into_iter()
        .find(|x| x + w < door_x - 0.1 || *x > door_x + 1.05)
    {
        let m = b.material("mirror", "conductor", Vec3::ZERO, None, rough, grey);
        let prim = boxp(Vec3::new(x, y, z0), Vec3::new(x + w, y + h, z0 + 0.01));
        b.add("mirror", prim, &m, Surface::Glossy);
    }
    // The cabinet: lacquer (a sharp coat over a strong colour) anywhere along the floor.
    let c = hue_tint(b.rng.f32(), b.rng.range(0.4, 0.9)) * b.rng.range(0.25, 0.6);
    let rough = b.rng.range(0.03, 0.1);
    let (w, d, h) = (
        b.rng.range(0.7, 1.0),
        b.rng.range(0.4, 0.5),
        b.rng.range(0.7, 1.0),
    );
    let (lo, hi) = (
        Vec2::new(x0 + 0.05, z0 + 0.05),
        Vec2::new(x1 - 0.05, -z0 - 0.05),
    );
    if let Some(p) = b.place(lo, hi, w, d) {
        let m = b.material("cabinet", "plastic", c, None, rough, Vec3::ZERO);
        let prim = boxp(Vec3::new(p.x, 0.0, p.y), Vec3::new(p.x + w, h, p.y + d));
        b.add("cabinet", prim, &m, Surface::Glossy);
    }
}

/// [`Finishes::Sparse`]: drops the furniture a sparse room lacks, then every texture (each
/// material keeps its texture's mean as a flat albedo), the materials nothing uses and the
/// gloss of all but the mirror and the cabinet ([`matten`]). What was textured is textureless
/// now, so the proxy degrades it as MVS degrades a blank surface.
fn sparsify(objects: &mut Vec<Object>, materials: &mut BTreeMap<String, Material>) {
    objects.retain(|o| o.shell || SPARSE_KEEPS.iter().any(|k| o.name.starts_with(k)));
    for o in objects
        .iter_mut()
        .filter(|o| o.surface == Surface::Textured)
    {
        o.surface = Surface::Textureless;
    }
    materials.retain(|name, _| objects.iter().any(|o| o.material == *name));
    for m in materials.values_mut() {
        m.texture = None;
        m.doc.albedo_texture = None;
        m.doc.texture_scale = 1.0;
    }
    matten(objects, materials);
}

/// Every material but the mirror and the cabinet made diffuse (a metal keeps its colour as a
/// diffuse albedo; textures stay), and the objects that were glossy to the proxy marked as what
/// they are now: MVS matches a matte surface by its texture, as any other.
fn matten(objects: &mut [Object], materials: &mut BTreeMap<String, Material>) {
    for o in objects
        .iter_mut()
        .filter(|o| o.surface == Surface::Glossy && !GLOSSY_KEPT.contains(&o.material.as_str()))
    {
        o.surface = match materials[&o.material].texture {
            Some(_) => Surface::Textured,
            None => Surface::Textureless,
        };
    }
    for (name, m) in materials.iter_mut() {
        if !GLOSSY_KEPT.contains(&name.as_str()) {
            if m.doc.kind == "conductor" {
                m.doc.albedo = m.doc.specular;
            }
            m.doc.kind = "diffuse".into();
            m.doc.roughness = 0.0;
            m.doc.specular = [0.0; 3];
        }
    }
}

fn boxp(lo: Vec3, hi: Vec3) -> Prim {
    Prim::Box {
        lo,
        hi,
        inward: false,
    }
}

/// Radiance of an emitter of `area` so that it emits `power` watts (Lambertian, one-sided):
/// Φ = π A L.
fn radiance_for(power: f32, area: f32, tint: Vec3) -> [f32; 3] {
    let l = power / (std::f32::consts::PI * area);
    (tint / tint.dot(Vec3::new(0.2126, 0.7152, 0.0722)) * l).to_array()
}

pub fn generate(seed: u64, o: &RoomOptions) -> Room {
    let mut rng = Rng::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x5EED);
    let size = Vec3::new(
        rng.range(3.8, 5.5),
        rng.range(2.45, 2.9),
        rng.range(3.2, 4.8),
    );
    let r = Bounds::of(size);
    let mut b = Builder {
        rng: &mut rng,
        objects: vec![],
        materials: BTreeMap::new(),
        taken: vec![],
    };
    // Each part draws from the room's one stream, in this order.
    shell(&mut b, &r, size);
    let door_x = doorway(&mut b, &r);
    let m = stock(&mut b);
    table(&mut b, &r, &m);
    sofa_or_bed(&mut b, &r, &m);
    shelf(&mut b, &r, &m);
    tv(&mut b, &r, &m);
    cylinders(&mut b, &r, &m);
    posters(&mut b, &r);
    if o.finishes != Finishes::Classic {
        // A stream of its own, so that the rest of the room is the classic one of this seed.
        let mut own = Rng::new(seed ^ 0xF141_54E5);
        std::mem::swap(b.rng, &mut own);
        vary(&mut b, size, door_x);
        std::mem::swap(b.rng, &mut own);
    }
    match o.finishes {
        Finishes::Sparse => sparsify(&mut b.objects, &mut b.materials),
        Finishes::Matte => matten(&mut b.objects, &mut b.materials),
        Finishes::Classic | Finishes::Varied => {}
    }

    let Builder {
        objects,
        materials,
        taken,
        ..
    } = b;

    let (lights, conditions) = lights(&mut rng, seed, o, &r, size);
    let inside = |p: Vec2| {
        taken.iter().all(|(a, b)| {
            p.x < a.x - 0.25 || p.x > b.x + 0.25 || p.y < a.y - 0.25 || p.y > b.y + 0.25
        })
    };
    let cameras = capture_cameras(
        &mut rng,
        (seed, o),
        (&objects, &lights),
        (&r, size),
        &inside,
    );
    let (path, path_fov_deg, test_cameras) = test_path(o, size, &inside);
    Room {
        seed,
        size,
        objects,
        materials,
        lights,
        conditions,
        cameras,
        path,
        path_fov_deg,
        test_cameras,
    }
}

/// The room's floor rectangle and height (m): x in [x0, x1], z in [z0, z1], y in [0, h].
#[derive(Clone, Copy)]
struct Bounds {
    x0: f32,
    x1: f32,
    z0: f32,
    z1: f32,
    h: f32,
}

impl Bounds {
    fn of(size: Vec3) -> Bounds {
        let (hx, hz) = (size.x / 2.0, size.z / 2.0);
        Bounds {
            x0: -hx,
            x1: hx,
            z0: -hz,
            z1: hz,
            h: size.y,
        }
    }

    /// The floor 5 cm in from the walls.
    fn inner(&self) -> (Vec2, Vec2) {
        (
            Vec2::new(self.x0 + 0.05, self.z0 + 0.05),
            Vec2::new(self.x1 - 0.05, self.z1 - 0.05),
        )
    }
}

/// The names of the materials the furniture shares.
struct Stock {
    tabletop: String,
    metal: String,
    fabric: String,
    tv: String,
    shelf: String,
}

/// Shell: floor, ceiling, walls as separate inward quads so each has its own material.
fn shell(b: &mut Builder, r: &Bounds, size: Vec3) {
    let Bounds { x0, x1, z0, z1, h } = *r;
    let wall_c = Vec3::new(
        b.rng.range(0.45, 0.85),
        b.rng.range(0.45, 0.85),
        b.rng.range(0.45, 0.85),
    );
    let wall = b.material(
        "wall",
        "diffuse",
        wall_c,
        Some((Kind::Plaster, 0.5)),
        0.0,
        Vec3::ZERO,
    );
    let floor_kind = pick(b.rng, &[Kind::Wood, Kind::Tiles]);
    let floor_c = match floor_kind {
        Kind::Wood => Vec3::new(0.45, 0.28, 0.15) * b.rng.range(0.7, 1.3),
        _ => v3(b.rng, 0.3, 0.7),
    };
    let floor_r = b.rng.range(0.05, 0.3);
    let floor = b.material(
        "floor",
        "plastic",
        floor_c,
        Some((floor_kind, 0.8)),
        floor_r,
        Vec3::ZERO,
    );
    let ceiling = b.material(
        "ceiling",
        "diffuse",
        Vec3::splat(0.8),
        None,
        0.0,
        Vec3::ZERO,
    );
    let shell = [
        (
            "floor",
            Prim::Quad {
                corner: Vec3::new(x0, 0.0, z0),
                u: Vec3::Z * size.z,
                v: Vec3::X * size.x,
            },
            &floor,
            Surface::Glossy,
        ),
        (
            "ceiling",
            Prim::Quad {
                corner: Vec3::new(x0, h, z0),
                u: Vec3::X * size.x,
                v: Vec3::Z * size.z,
            },
            &ceiling,
            Surface::Textureless,
        ),
        (
            "wall_w",
            Prim::Quad {
                corner: Vec3::new(x0, 0.0, z0),
                u: Vec3::Y * h,
                v: Vec3::Z * size.z,
            },
            &wall,
            Surface::Textureless,
        ),
        (
            "wall_e",
            Prim::Quad {
                corner: Vec3::new(x1, 0.0, z0),
                u: Vec3::Z * size.z,
                v: Vec3::Y * h,
            },
            &wall,
            Surface::Textureless,
        ),
        (
            "wall_n",
            Prim::Quad {
                corner: Vec3::new(x0, 0.0, z0),
                u: Vec3::X * size.x,
                v: Vec3::Y * h,
            },
            &wall,
            Surface::Textureless,
        ),
        (
            "wall_s",
            Prim::Quad {
                corner: Vec3::new(x0, 0.0, z1),
                u: Vec3::Y * h,
                v: Vec3::X * size.x,
            },
            &wall,
            Surface::Textureless,
        ),
    ];
    for (n, p, m, s) in shell {
        b.objects.push(Object {
            name: n.into(),
            prim: p,
            material: m.clone(),
            surface: s,
            shell: true,
        });
    }
}

/// An opening: a doorway niche in the north wall (a recess 0.5 m deep, its own dark walls); returns its left edge (x).
fn doorway(b: &mut Builder, r: &Bounds) -> f32 {
    let Bounds { x0, x1, z0, .. } = *r;
    let door_x = b.rng.range(x0 + 0.4, x1 - 1.4);
    let dark = b.material("niche", "diffuse", Vec3::splat(0.25), None, 0.0, Vec3::ZERO);
    b.objects.push(Object {
        name: "doorway".into(),
        // The niche's back wall, 4 mm in front of the wall (it hides the wall there).
        prim: Prim::Quad {
            corner: Vec3::new(door_x, 0.0, z0 + 0.004),
            u: Vec3::X * 0.95,
            v: Vec3::Y * 2.05,
        },
        material: dark,
        surface: Surface::Textureless,
        shell: true,
    });
    b.taken.push((
        Vec2::new(door_x - 0.2, z0),
        Vec2::new(door_x + 1.15, z0 + 0.9),
    ));
    door_x
}

/// The materials the furniture shares (in this order: each draws from the room's stream).
fn stock(b: &mut Builder) -> Stock {
    let wood_c = Vec3::new(0.5, 0.32, 0.18) * b.rng.range(0.6, 1.3);
    let top_r = b.rng.range(0.02, 0.3);
    let tabletop = b.material(
        "tabletop",
        "plastic",
        wood_c,
        Some((Kind::Wood, 1.0)),
        top_r,
        Vec3::ZERO,
    );
    let metal_r = b.rng.range(0.1, 0.5);
    let metal = b.material(
        "metal",
        "conductor",
        Vec3::ZERO,
        None,
        metal_r,
        Vec3::new(0.9, 0.88, 0.85),
    );
    let fabric_c = v3(b.rng, 0.15, 0.7);
    let fabric = b.material(
        "fabric",
        "diffuse",
        fabric_c,
        Some((Kind::Fabric, 2.0)),
        0.0,
        Vec3::ZERO,
    );
    let tv_r = b.rng.range(0.02, 0.06);
    let tv = b.material("tv", "plastic", Vec3::splat(0.02), None, tv_r, Vec3::ZERO);
    let shelf_c = v3(b.rng, 0.3, 0.8);
    let shelf = b.material("shelf", "diffuse", shelf_c, None, 0.0, Vec3::ZERO);
    Stock {
        tabletop,
        metal,
        fabric,
        tv,
        shelf,
    }
}

/// A table with 4 cm legs (metal or wood) in the middle region, and a chair beside it.
fn table(b: &mut Builder, r: &Bounds, m: &Stock) {
    let (inner_lo, inner_hi) = r.inner();
    let Stock {
        tabletop,
        metal,
        fabric,
        ..
    } = m;
    if let Some(p) = b.place(
        inner_lo + Vec2::splat(0.6),
        inner_hi - Vec2::splat(0.6),
        1.2,
        0.75,
    ) {
        let th = b.rng.range(0.72, 0.78);
        b.add(
            "table_top",
            boxp(
                Vec3::new(p.x, th - 0.04, p.y),
                Vec3::new(p.x + 1.2, th, p.y + 0.75),
            ),
            tabletop,
            Surface::Glossy,
        );
        let leg_m = if b.rng.f32() < 0.5 {
            metal.clone()
        } else {
            tabletop.clone()
        };
        for (i, (dx, dz)) in [(0.03, 0.03), (1.13, 0.03), (0.03, 0.68), (1.13, 0.68)]
            .iter()
            .enumerate()
        {
            let lo = Vec3::new(p.x + dx, 0.0, p.y + dz);
            b.add(
                &format!("table_leg{i}"),
                boxp(lo, lo + Vec3::new(0.04, th - 0.04, 0.04)),
                &leg_m,
                Surface::Textured,
            );
        }
        // A chair with thin (1.5 cm) legs: MVS loses them.
        let c = Vec2::new(p.x + 0.4, p.y + 0.85);
        if b.free(c, c + Vec2::new(0.45, 0.45)) {
            b.taken.push((c, c + Vec2::new(0.45, 0.45)));
            b.add(
                "chair_seat",
                boxp(
                    Vec3::new(c.x, 0.43, c.y),
                    Vec3::new(c.x + 0.45, 0.47, c.y + 0.45),
                ),
                fabric,
                Surface::Textured,
            );
            b.add(
                "chair_back",
                boxp(
                    Vec3::new(c.x, 0.47, c.y + 0.41),
                    Vec3::new(c.x + 0.45, 0.9, c.y + 0.45),
                ),
                fabric,
                Surface::Textured,
            );
            for (i, (dx, dz)) in [(0.0, 0.0), (0.435, 0.0), (0.0, 0.435), (0.435, 0.435)]
                .iter()
                .enumerate()
            {
                let lo = Vec3::new(c.x + dx, 0.0, c.y + dz);
                b.add(
                    &format!("chair_leg{i}"),
                    boxp(lo, lo + Vec3::new(0.015, 0.43, 0.015)),
                    metal,
                    Surface::Glossy,
                );
            }
        }
    }
}

/// A sofa or a bed block against the south wall.
fn sofa_or_bed(b: &mut Builder, r: &Bounds, m: &Stock) {
    let Bounds { x0, x1, z1, .. } = *r;
    let Stock {
        tabletop, fabric, ..
    } = m;
    if b.rng.f32() < 0.5 {
        if let Some(p) = b.place(
            Vec2::new(x0 + 0.1, z1 - 1.0),
            Vec2::new(x1 - 0.1, z1 - 0.02),
            2.0,
            0.9,
        ) {
            b.add(
                "sofa_base",
                boxp(
                    Vec3::new(p.x, 0.0, p.y),
                    Vec3::new(p.x + 2.0, 0.45, p.y + 0.9),
                ),
                fabric,
                Surface::Textured,
            );
            b.add(
                "sofa_back",
                boxp(
                    Vec3::new(p.x, 0.45, p.y + 0.7),
                    Vec3::new(p.x + 2.0, 0.85, p.y + 0.9),
                ),
                fabric,
                Surface::Textured,
            );
            b.add(
                "sofa_arm_l",
                boxp(
                    Vec3::new(p.x, 0.45, p.y),
                    Vec3::new(p.x + 0.2, 0.65, p.y + 0.7),
                ),
                fabric,
                Surface::Textured,
            );
            b.add(
                "sofa_arm_r",
                boxp(
                    Vec3::new(p.x + 1.8, 0.45, p.y),
                    Vec3::new(p.x + 2.0, 0.65, p.y + 0.7),
                ),
                fabric,
                Surface::Textured,
            );
        }
    } else if let Some(p) = b.place(
        Vec2::new(x0 + 0.1, z1 - 2.1),
        Vec2::new(x1 - 0.1, z1 - 0.02),
        1.5,
        2.05,
    ) {
        let sheet_c = v3(b.rng, 0.6, 0.9);
        let sheet = b.material(
            "sheet",
            "diffuse",
            sheet_c,
            Some((Kind::Fabric, 2.0)),
            0.0,
            Vec3::ZERO,
        );
        b.add(
            "bed_base",
            boxp(
                Vec3::new(p.x, 0.0, p.y),
                Vec3::new(p.x + 1.5, 0.3, p.y + 2.0),
            ),
            tabletop,
            Surface::Glossy,
        );
        b.add(
            "bed_mattress",
            boxp(
                Vec3::new(p.x + 0.02, 0.3, p.y + 0.02),
                Vec3::new(p.x + 1.48, 0.52, p.y + 1.98),
            ),
            &sheet,
            Surface::Textured,
        );
        b.add(
            "bed_head",
            boxp(
                Vec3::new(p.x, 0.0, p.y + 1.98),
                Vec3::new(p.x + 1.5, 1.0, p.y + 2.05),
            ),
            tabletop,
            Surface::Glossy,
        );
    }
}

/// A shelf against the east wall with 1.8 cm boards (thin: lost by MVS).
fn shelf(b: &mut Builder, r: &Bounds, m: &Stock) {
    let Bounds { x1, z0, z1, .. } = *r;
    let shelf = &m.shelf;
    if let Some(p) = b.place(
        Vec2::new(x1 - 0.4, z0 + 0.2),
        Vec2::new(x1 - 0.01, z1 - 0.2),
        0.38,
        1.0,
    ) {
        let (lo, hi) = (
            Vec3::new(p.x, 0.0, p.y),
            Vec3::new(p.x + 0.38, 1.8, p.y + 1.0),
        );
        b.add(
            "shelf_side0",
            boxp(lo, Vec3::new(hi.x, hi.y, lo.z + 0.04)),
            shelf,
            Surface::Textured,
        );
        b.add(
            "shelf_side1",
            boxp(Vec3::new(lo.x, 0.0, hi.z - 0.04), hi),
            shelf,
            Surface::Textured,
        );
        for i in 0..4 {
            let y = 0.05 + i as f32 * 0.45;
            b.add(
                &format!("shelf_board{i}"),
                boxp(
                    Vec3::new(lo.x, y, lo.z + 0.04),
                    Vec3::new(hi.x, y + 0.018, hi.z - 0.04),
                ),
                shelf,
                Surface::Textured,
            );
            // Boxes on the shelves give texture and occluders.
            let bx = b.rng.range(0.1, 0.5);
            let box_c = v3(b.rng, 0.1, 0.9);
            let color = b.material(&format!("box{i}"), "diffuse", box_c, None, 0.0, Vec3::ZERO);
            let z = b.rng.range(lo.z + 0.05, hi.z - 0.05 - bx);
            b.add(
                &format!("shelf_item{i}"),
                boxp(
                    Vec3::new(lo.x + 0.05, y + 0.018, z),
                    Vec3::new(hi.x - 0.05, y + 0.018 + bx.min(0.4), z + bx),
                ),
                &color,
                Surface::Textured,
            );
        }
    }
}

/// A TV (4 cm panel, glossy) on a low cabinet along the west wall.
fn tv(b: &mut Builder, r: &Bounds, m: &Stock) {
    let Bounds { x0, z0, z1, .. } = *r;
    let Stock {
        tabletop,
        metal,
        tv,
        ..
    } = m;
    if let Some(p) = b.place(
        Vec2::new(x0 + 0.01, z0 + 0.3),
        Vec2::new(x0 + 0.5, z1 - 0.3),
        0.45,
        1.4,
    ) {
        b.add(
            "tv_cabinet",
            boxp(
                Vec3::new(p.x, 0.0, p.y),
                Vec3::new(p.x + 0.45, 0.5, p.y + 1.4),
            ),
            tabletop,
            Surface::Glossy,
        );
        b.add(
            "tv_panel",
            boxp(
                Vec3::new(p.x + 0.15, 0.6, p.y + 0.1),
                Vec3::new(p.x + 0.19, 1.3, p.y + 1.3),
            ),
            tv,
            Surface::Glossy,
        );
        b.add(
            "tv_foot",
            boxp(
                Vec3::new(p.x + 0.12, 0.5, p.y + 0.6),
                Vec3::new(p.x + 0.22, 0.6, p.y + 0.8),
            ),
            metal,
            Surface::Glossy,
        );
    }
}

/// Cylinders: a stool or vase and a floor-lamp stand.
fn cylinders(b: &mut Builder, r: &Bounds, m: &Stock) {
    let (inner_lo, inner_hi) = r.inner();
    let Stock { metal, fabric, .. } = m;
    for i in 0..2 {
        let r = b.rng.range(0.12, 0.25);
        if let Some(p) = b.place(
            inner_lo + Vec2::splat(0.2),
            inner_hi - Vec2::splat(0.2),
            2.0 * r,
            2.0 * r,
        ) {
            let m = if i == 0 {
                metal.clone()
            } else {
                fabric.clone()
            };
            let h = b.rng.range(0.4, 0.9);
            b.add(
                &format!("cylinder{i}"),
                Prim::Cylinder {
                    base: Vec3::new(p.x + r, 0.0, p.y + r),
                    radius: r,
                    height: h,
                },
                &m,
                Surface::Textured,
            );
        }
    }
}

/// Posters: 1 cm thick prints on the walls (thin: they merge into the wall in the proxy).
fn posters(b: &mut Builder, r: &Bounds) {
    let Bounds { x0, x1, z0, z1, .. } = *r;
    for i in 0..2 {
        let name = format!("poster{i}");
        let base = v3(b.rng, 0.2, 0.9);
        let (w, hh) = (b.rng.range(0.4, 0.8), b.rng.range(0.5, 0.9));
        let m = b.material(
            &name,
            "diffuse",
            base,
            Some((Kind::Poster, 1.0 / w.max(hh))),
            0.0,
            Vec3::ZERO,
        );
        let y = b.rng.range(1.2, 1.6);
        let prim = if i == 0 {
            let x = b.rng.range(x0 + 1.4, x1 - w - 0.2);
            boxp(Vec3::new(x, y, z1 - 0.01), Vec3::new(x + w, y + hh, z1))
        } else {
            let z = b.rng.range(z0 + 0.2, z1 - w - 0.2);
            boxp(Vec3::new(x1 - 0.01, y, z), Vec3::new(x1, y + hh, z + w))
        };
        b.add(&name, prim, &m, Surface::Textured);
    }
}

/// The original lighting (ceiling panel(s) and sometimes a window-like emitter on a wall) and the extra lights, each a condition of its own; returns the lights and the conditions.
fn lights(
    rng: &mut Rng,
    seed: u64,
    o: &RoomOptions,
    r: &Bounds,
    size: Vec3,
) -> (Vec<Light>, Vec<(String, Vec<String>)>) {
    let Bounds { x0, x1, z0, z1, h } = *r;
    let mut lights = Vec::new();
    let panels = if rng.f32() < 0.5 { 1 } else { 2 };
    for i in 0..panels {
        let (w, d) = (rng.range(0.5, 0.9), rng.range(0.5, 0.9));
        let c = Vec3::new(
            if panels == 1 {
                0.0
            } else {
                (i as f32 - 0.5) * size.x * 0.45
            },
            h - 0.005,
            rng.range(-0.3, 0.3),
        );
        lights.push(Light {
            name: format!("ceiling{i}"),
            // X × Z = -Y: the panel faces down.
            shape: LightShape::Quad {
                corner: c - Vec3::new(w / 2.0, 0.0, d / 2.0),
                edge_u: Vec3::X * w,
                edge_v: Vec3::Z * d,
            },
            radiance: [0.0; 3],
            original: true,
            estimated: false,
        });
    }
    if rng.f32() < 0.5 {
        let (w, hh) = (rng.range(0.8, 1.3), rng.range(0.8, 1.2));
        let z = rng.range(z0 + 0.3, z1 - w - 0.3);
        lights.push(Light {
            name: "window".into(),
            // On the west wall, Y × Z = +X: facing into the room.
            shape: LightShape::Quad {
                corner: Vec3::new(x0 + 0.005, 1.0, z),
                edge_u: Vec3::Y * hh,
                edge_v: Vec3::Z * w,
            },
            radiance: [0.0; 3],
            original: true,
            estimated: false,
        });
    }
    let originals: Vec<usize> = (0..lights.len()).collect();
    let total_area: f32 = originals.iter().map(|&i| lights[i].shape.area()).sum();
    let warm = Vec3::new(1.0, 0.93, 0.82);
    for &i in &originals {
        // Power shared in proportion to area: one radiance for the whole original set.
        lights[i].radiance = radiance_for(CONDITION_POWER, total_area, warm);
    }
    // Extra lights at random positions, each a condition of its own at the same power.
    for i in 0..o.extra_lights {
        let c = Vec3::new(
            rng.range(x0 + 0.4, x1 - 0.4),
            rng.range(0.6, h - 0.3),
            rng.range(z0 + 0.4, z1 - 0.4),
        );
        let target = Vec3::new(
            rng.range(-0.5, 0.5),
            rng.range(0.0, 0.5),
            rng.range(-0.5, 0.5),
        ) * size;
        let n = (target - c).normalize_or(Vec3::NEG_Y);
        let mut tint = Vec3::new(
            rng.range(0.6, 1.0),
            rng.range(0.6, 1.0),
            rng.range(0.6, 1.0),
        );
        // A stream of its own, so that the rest of the room is the same for every choice.
        let mut tints = Rng::new(seed ^ 0x7147_C010 ^ (i as u64).wrapping_mul(0x2545_F491));
        if o.lamp_colours == LampColours::Mixed && tints.f32() < 0.5 {
            tint = hue_tint(tints.f32(), tints.range(0.5, 0.95));
        }
        let shape = if rng.f32() < 0.5 {
            LightShape::Disk {
                center: c,
                normal: n,
                radius: rng.range(0.06, 0.15),
            }
        } else {
            let t1 = n.any_orthonormal_vector();
            let t2 = n.cross(t1);
            let (w, d) = (rng.range(0.1, 0.3), rng.range(0.1, 0.3));
            // edge_u × edge_v must be n: (t2 × t1) = -n, so use u = t1, v = t2 (t1 × t2 = n).
            LightShape::Quad {
                corner: c - t1 * (w / 2.0) - t2 * (d / 2.0),
                edge_u: t1 * w,
                edge_v: t2 * d,
            }
        };
        let area = shape.area();
        lights.push(Light {
            name: format!("extra{i}"),
            shape,
            radiance: radiance_for(CONDITION_POWER, area, tint),
            original: false,
            estimated: false,
        });
    }
    let mut conditions = vec![(
        "original".to_string(),
        originals.iter().map(|&i| lights[i].name.clone()).collect(),
    )];
    for l in lights.iter().filter(|l| !l.original) {
        conditions.push((l.name.clone(), vec![l.name.clone()]));
    }
    (lights, conditions)
}

/// Capture cameras: a handheld walk around the room, looking at content.
fn capture_cameras(
    rng: &mut Rng,
    (seed, o): (u64, &RoomOptions),
    (objects, lights): (&[Object], &[Light]),
    (r, size): (&Bounds, Vec3),
    inside: &dyn Fn(Vec2) -> bool,
) -> Vec<Camera> {
    let Bounds { x0, x1, z0, z1, .. } = *r;
    let content: Vec<Vec3> = objects
        .iter()
        .filter(|o| !o.shell)
        .map(|o| {
            let (lo, hi) = o.prim.footprint();
            let c = (lo + hi) / 2.0;
            Vec3::new(c.x, 0.7, c.y)
        })
        .collect();
    let mut cameras = light_cameras(seed, o, objects, lights, size, &inside);
    let mut tries = 0;
    while cameras.len() < o.views && tries < 10_000 {
        tries += 1;
        let p = Vec2::new(
            rng.range(x0 + 0.35, x1 - 0.35),
            rng.range(z0 + 0.35, z1 - 0.35),
        );
        if !inside(p) {
            continue;
        }
        let pos = Vec3::new(p.x, rng.range(1.2, 1.8), p.y);
        let t = if !content.is_empty() && rng.f32() < 0.7 {
            content[(rng.next_u64() % content.len() as u64) as usize] + v3(rng, -0.4, 0.4)
        } else {
            Vec3::new(rng.range(x0, x1), rng.range(0.3, 1.5), rng.range(z0, z1))
        };
        if (t - pos).length() < 1.0 {
            continue;
        }
        let fx = o.width as f32 * rng.range(0.5, 0.75);
        cameras.push(Camera::look_at(pos, t, Vec3::Y, o.width, o.height, fx));
    }
    cameras
}

/// Test path: a loop through free space, looking towards the room's middle; its keyframes, field of view and the test cameras along it.
fn test_path(
    o: &RoomOptions,
    size: Vec3,
    inside: &dyn Fn(Vec2) -> bool,
) -> (Vec<(f32, Vec3, Vec3)>, f32, Vec<Camera>) {
    let (hx, hz) = (size.x / 2.0, size.z / 2.0);
    let mut path = Vec::new();
    let n_keys = 6;
    for k in 0..=n_keys {
        let a = k as f32 / n_keys as f32 * std::f32::consts::TAU;
        let mut p = Vec2::new(a.cos() * (hx - 0.9), a.sin() * (hz - 0.9));
        for _ in 0..20 {
            if inside(p) {
                break;
            }
            p *= 0.9;
        }
        let pos = Vec3::new(p.x, 1.5 + 0.1 * (2.0 * a).sin(), p.y);
        let look = Vec3::new(-p.x * 0.3, 0.8, -p.y * 0.3);
        path.push((k as f32 * 2.0, pos, look));
    }
    let path_fov_deg: f32 = 70.0;
    let test_cameras = (0..o.test_views)
        .map(|i| {
            let t = path.last().unwrap().0 * (i as f32 + 0.5) / o.test_views as f32;
            let (pos, look) = sample_path(&path, t);
            let fx = o.width as f32 / 2.0 / (path_fov_deg.to_radians() / 2.0).tan();
            Camera::look_at(pos, look, Vec3::Y, o.width, o.height, fx)
        })
        .collect();
    (path, path_fov_deg, test_cameras)
}

/// Capture cameras aimed at the original lights, `o.light_views` per light taken in turn (at most
/// `o.views / 2` in all). Each stands in free space at 1.2–1.8 m, 1–4 m from the light on its
/// emitting side and not at a grazing angle, and looks at a point 0.2–0.7 m below the light
/// (jittered), so the frame shows the light and the walls and floor around it; a pose is kept
/// only when the light's outline projects inside the image's central 80% and at least ¾ of
/// its samples are unoccluded by the true geometry. Poses come from their own random stream, so
/// the other cameras are those a scene without light views would have.
fn light_cameras(
    seed: u64,
    o: &RoomOptions,
    objects: &[Object],
    lights: &[Light],
    size: Vec3,
    inside: &dyn Fn(Vec2) -> bool,
) -> Vec<Camera> {
    let originals: Vec<&Light> = lights.iter().filter(|l| l.original).collect();
    let n = (originals.len() * o.light_views).min(o.views / 2);
    if n == 0 {
        return Vec::new();
    }
    let mut rng = Rng::new(seed.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ 0x11_6874);
    let mut geometry = TriMesh::default();
    for obj in objects {
        geometry.append(&tessellate(&obj.prim, crate::TRUE_EDGE));
    }
    let bvh = MeshBvh::new(&geometry.to_mesh());
    let (hx, hz) = (size.x / 2.0, size.z / 2.0);
    let mut cameras = Vec::new();
    for k in 0..n {
        let light = originals[k % originals.len()];
        let (c, normal) = (light.shape.center(), light.shape.normal());
        let outline = outline(&light.shape);
        for _ in 0..2000 {
            let p = Vec2::new(
                rng.range(-hx + 0.35, hx - 0.35),
                rng.range(-hz + 0.35, hz - 0.35),
            );
            if !inside(p) {
                continue;
            }
            let pos = Vec3::new(p.x, rng.range(1.2, 1.8), p.y);
            let to_cam = pos - c;
            let dist = to_cam.length();
            let cos = normal.dot(to_cam) / dist;
            if !(1.0..=4.0).contains(&dist) || !(0.35..=0.9).contains(&cos) {
                continue;
            }
            let target = c - Vec3::Y * rng.range(0.2, 0.7)
                + Vec3::new(rng.range(-0.2, 0.2), 0.0, rng.range(-0.2, 0.2));
            let fx = o.width as f32 * rng.range(0.5, 0.75);
            let cam = Camera::look_at(pos, target, Vec3::Y, o.width, o.height, fx);
            let (w, h) = (o.width as f32, o.height as f32);
            let framed = outline.iter().all(|q| {
                cam.project(*q).is_some_and(|(px, _)| {
                    px.x > 0.1 * w && px.x < 0.9 * w && px.y > 0.1 * h && px.y < 0.9 * h
                })
            });
            if framed && visible_fraction(&bvh, &cam, &light.shape) >= 0.75 {
                cameras.push(cam);
                break;
            }
        }
    }
    cameras
}

/// Points on a light's rim: a quad's corners, eight points around a disk.
fn outline(shape: &LightShape) -> Vec<Vec3> {
    match shape {
        LightShape::Quad {
            corner,
            edge_u,
            edge_v,
        } => vec![
            *corner,
            *corner + *edge_u,
            *corner + *edge_v,
            *corner + *edge_u + *edge_v,
        ],
        LightShape::Disk {
            center,
            normal,
            radius,
        } => {
            let (t1, t2) = normal.normalize_or_zero().any_orthonormal_pair();
            (0..8)
                .map(|i| {
                    let a = i as f32 * std::f32::consts::FRAC_PI_4;
                    *center + *radius * (a.cos() * t1 + a.sin() * t2)
                })
                .collect()
        }
    }
}

/// Catmull-Rom interpolation of positions and look-at points at time `t` (clamped ends).
pub fn sample_path(keys: &[(f32, Vec3, Vec3)], t: f32) -> (Vec3, Vec3) {
    let n = keys.len();
    if n == 1 {
        return (keys[0].1, keys[0].2);
    }
    let t = t.clamp(keys[0].0, keys[n - 1].0);
    let i = keys.windows(2).position(|w| t <= w[1].0).unwrap_or(n - 2);
    let f = (t - keys[i].0) / (keys[i + 1].0 - keys[i].0).max(1e-9);
    let at = |k: isize| keys[k.clamp(0, n as isize - 1) as usize];
    let cr = |p0: Vec3, p1: Vec3, p2: Vec3, p3: Vec3| {
        0.5 * (2.0 * p1
            + (p2 - p0) * f
            + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * f * f
            + (3.0 * p1 - p0 - 3.0 * p2 + p3) * f * f * f)
    };
    let i = i as isize;
    (
        cr(at(i - 1).1, at(i).1, at(i + 1).1, at(i + 2).1),
        cr(at(i - 1).2, at(i).2, at(i + 1).2, at(i + 2).2),
    )
}
