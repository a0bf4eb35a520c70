//! Primitives the rooms are built from, tessellated into triangle meshes with texture
//! coordinates (in metres, so textures tile at a physical scale). The same primitive yields the
//! true mesh (exact) and the proxy mesh (degraded, see `proxy.rs`).

use glam::{Vec2, Vec3};

#[derive(Clone, Debug)]
pub enum Prim {
    /// Axis-aligned box; `inward` faces point inside (the room shell).
    Box { lo: Vec3, hi: Vec3, inward: bool },
    /// Vertical cylinder standing on `base`, with caps.
    Cylinder {
        base: Vec3,
        radius: f32,
        height: f32,
    },
    /// One-sided parallelogram facing `u × v`.
    Quad { corner: Vec3, u: Vec3, v: Vec3 },
}

impl Prim {
    /// Smallest extent: parts thinner than MVS resolves are dropped from the proxy.
    pub fn thickness(&self) -> f32 {
        match self {
            Prim::Box { lo, hi, .. } => (*hi - *lo).min_element(),
            Prim::Cylinder { radius, height, .. } => (2.0 * radius).min(*height),
            Prim::Quad { .. } => 0.0,
        }
    }

    /// 2D footprint on the floor (x, z) for placement: (min, max).
    pub fn footprint(&self) -> (Vec2, Vec2) {
        match self {
            Prim::Box { lo, hi, .. } => (Vec2::new(lo.x, lo.z), Vec2::new(hi.x, hi.z)),
            Prim::Cylinder { base, radius, .. } => (
                Vec2::new(base.x - radius, base.z - radius),
                Vec2::new(base.x + radius, base.z + radius),
            ),
            Prim::Quad { corner, u, v } => {
                let ps = [*corner, *corner + *u, *corner + *v, *corner + *u + *v];
                let lo = ps
                    .iter()
                    .fold(Vec2::splat(f32::MAX), |a, p| a.min(Vec2::new(p.x, p.z)));
                let hi = ps
                    .iter()
                    .fold(Vec2::splat(f32::MIN), |a, p| a.max(Vec2::new(p.x, p.z)));
                (lo, hi)
            }
        }
    }
}

/// A triangle mesh with per-vertex normals and texture coordinates.
#[derive(Clone, Debug, Default)]
pub struct TriMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    pub fn append(&mut self, o: &TriMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&o.positions);
        self.normals.extend_from_slice(&o.normals);
        self.uvs.extend_from_slice(&o.uvs);
        self.triangles
            .extend(o.triangles.iter().map(|t| t.map(|i| i + base)));
    }

    /// Keeps the triangles `keep` accepts and drops vertices no triangle uses.
    pub fn filter_triangles(&self, mut keep: impl FnMut(usize) -> bool) -> TriMesh {
        let mut remap = vec![u32::MAX; self.positions.len()];
        let mut out = TriMesh::default();
        for (i, t) in self.triangles.iter().enumerate() {
            if !keep(i) {
                continue;
            }
            let nt = t.map(|v| {
                let v = v as usize;
                if remap[v] == u32::MAX {
                    remap[v] = out.positions.len() as u32;
                    out.positions.push(self.positions[v]);
                    out.normals.push(self.normals[v]);
                    out.uvs.push(self.uvs[v]);
                }
                remap[v]
            });
            out.triangles.push(nt);
        }
        out
    }

    pub fn centroid(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.triangles[t];
        (self.positions[a as usize] + self.positions[b as usize] + self.positions[c as usize]) / 3.0
    }

    pub fn to_mesh(&self) -> relit_engine::scene::Mesh {
        relit_engine::scene::Mesh {
            positions: self.positions.iter().map(|p| p.to_array()).collect(),
            colors: None,
            triangles: self.triangles.clone(),
        }
    }

    /// Binary little-endian PLY with positions, normals and texture coordinates (Mitsuba reads
    /// `u v` as UVs; Relit's loader skips what it does not use).
    pub fn ply_bytes(&self) -> Vec<u8> {
        let mut out = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
             property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
             property float u\nproperty float v\nelement face {}\n\
             property list uchar int vertex_indices\nend_header\n",
            self.positions.len(),
            self.triangles.len()
        )
        .into_bytes();
        for i in 0..self.positions.len() {
            let vals = [
                self.positions[i].x,
                self.positions[i].y,
                self.positions[i].z,
                self.normals[i].x,
                self.normals[i].y,
                self.normals[i].z,
                self.uvs[i].x,
                self.uvs[i].y,
            ];
            for v in vals {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        for t in &self.triangles {
            out.push(3);
            for v in t {
                out.extend_from_slice(&(*v as i32).to_le_bytes());
            }
        }
        out
    }
}

/// A grid over `corner + [0,1]·u + [0,1]·v` with cells of at most `edge` metres, facing `u × v`.
pub fn grid(corner: Vec3, u: Vec3, v: Vec3, edge: f32) -> TriMesh {
    let nu = ((u.length() / edge).ceil() as u32).max(1);
    let nv = ((v.length() / edge).ceil() as u32).max(1);
    let n = u.cross(v).normalize();
    let mut m = TriMesh::default();
    for j in 0..=nv {
        for i in 0..=nu {
            let (fu, fv) = (i as f32 / nu as f32, j as f32 / nv as f32);
            m.positions.push(corner + u * fu + v * fv);
            m.normals.push(n);
            m.uvs.push(Vec2::new(fu * u.length(), fv * v.length()));
        }
    }
    let row = nu + 1;
    for j in 0..nv {
        for i in 0..nu {
            let a = j * row + i;
            m.triangles.push([a, a + 1, a + row + 1]);
            m.triangles.push([a, a + row + 1, a + row]);
        }
    }
    m
}

/// The six faces of a box as (corner, u, v) with u × v pointing outward.
pub fn box_faces(lo: Vec3, hi: Vec3) -> [(Vec3, Vec3, Vec3); 6] {
    let d = hi - lo;
    let (x, y, z) = (Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z);
    [
        (lo, z, y),
        (lo + x, y, z),
        (lo, x, z),
        (lo + y, z, x),
        (lo, y, x),
        (lo + z, x, y),
    ]
}

/// Tessellates a primitive with edges of at most `edge` metres.
pub fn tessellate(p: &Prim, edge: f32) -> TriMesh {
    let mut m = TriMesh::default();
    match p {
        Prim::Box { lo, hi, inward } => {
            for (c, u, v) in box_faces(*lo, *hi) {
                m.append(&if *inward {
                    grid(c, v, u, edge)
                } else {
                    grid(c, u, v, edge)
                });
            }
        }
        Prim::Quad { corner, u, v } => m = grid(*corner, *u, *v, edge),
        Prim::Cylinder {
            base,
            radius,
            height,
        } => {
            let seg = ((std::f32::consts::TAU * radius / edge).ceil() as u32).clamp(12, 256);
            let rows = ((height / edge).ceil() as u32).max(1);
            let ring = |k: u32| {
                let a = k as f32 / seg as f32 * std::f32::consts::TAU;
                Vec3::new(a.cos(), 0.0, a.sin())
            };
            for j in 0..=rows {
                for k in 0..=seg {
                    let d = ring(k);
                    let y = height * j as f32 / rows as f32;
                    m.positions.push(*base + d * *radius + Vec3::Y * y);
                    m.normals.push(d);
                    m.uvs.push(Vec2::new(
                        k as f32 / seg as f32 * std::f32::consts::TAU * radius,
                        y,
                    ));
                }
            }
            let row = seg + 1;
            for j in 0..rows {
                for k in 0..seg {
                    let a = j * row + k;
                    // Outward: (k → k+1) runs counter-clockwise seen from above... check with the
                    // normal: the ring goes from +X towards +Z, so this winding faces outward.
                    m.triangles.push([a, a + row + 1, a + 1]);
                    m.triangles.push([a, a + row, a + row + 1]);
                }
            }
            // Caps: fans around a centre vertex.
            for (y, up) in [(*height, true), (0.0, false)] {
                let c = m.positions.len() as u32;
                let n = if up { Vec3::Y } else { -Vec3::Y };
                m.positions.push(*base + Vec3::Y * y);
                m.normals.push(n);
                m.uvs.push(Vec2::ZERO);
                for k in 0..=seg {
                    m.positions.push(*base + ring(k) * *radius + Vec3::Y * y);
                    m.normals.push(n);
                    m.uvs.push(Vec2::new(ring(k).x, ring(k).z) * *radius);
                }
                for k in 0..seg {
                    let (a, b) = (c + 1 + k, c + 2 + k);
                    m.triangles.push(if up { [c, b, a] } else { [c, a, b] });
                }
            }
        }
    }
    m
}
