//! Triangle meshes: OBJ (through tobj) and PLY (ascii and binary little-endian, our parser).
//! Every loader validates counts, indices and values and names the file in its errors.

use std::path::Path;

use glam::Vec3;

use crate::error::{Error, Result};

#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    /// Per-vertex colours in linear RGB when the file has them.
    pub colors: Option<Vec<[f32; 3]>>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    pub fn load(path: &Path) -> Result<Mesh> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .unwrap_or_default();
        let mesh = match ext.as_str() {
            "obj" => load_obj(path)?,
            "ply" => load_ply(path)?,
            _ => {
                return Err(Error::input(
                    path,
                    format!("mesh format \"{ext}\" is not supported; expected .obj or .ply"),
                ))
            }
        };
        mesh.validate().map_err(|m| Error::input(path, m))?;
        Ok(mesh)
    }

    pub fn validate(&self) -> Result<(), String> {
        if self.triangles.is_empty() {
            return Err("mesh has no triangles".into());
        }
        let n = self.positions.len() as u32;
        for (i, t) in self.triangles.iter().enumerate() {
            if let Some(bad) = t.iter().find(|&&v| v >= n) {
                return Err(format!(
                    "face {i} references vertex {bad}, but the mesh has {n} vertices"
                ));
            }
        }
        if let Some(i) = self
            .positions
            .iter()
            .position(|p| !p.iter().all(|v| v.is_finite()))
        {
            return Err(format!(
                "vertex {i} has a non-finite coordinate {:?}",
                self.positions[i]
            ));
        }
        Ok(())
    }

    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(Vec3::from(*p)), hi.max(Vec3::from(*p))),
        )
    }

    pub fn vertex(&self, i: u32) -> Vec3 {
        Vec3::from(self.positions[i as usize])
    }

    /// The triangle's corners.
    pub fn corners(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t];
        [self.vertex(a), self.vertex(b), self.vertex(c)]
    }

    /// Geometric normal (counter-clockwise winding is the front).
    pub fn face_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// Appends another mesh (used by the procedural scenes).
    pub fn append(&mut self, other: &Mesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles.extend(
            other
                .triangles
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }

    /// Writes a Wavefront OBJ (positions and faces).
    pub fn write_obj(&self, path: &Path) -> Result<()> {
        use std::fmt::Write as _;
        let mut s = String::with_capacity(self.positions.len() * 32 + self.triangles.len() * 24);
        for p in &self.positions {
            let _ = writeln!(s, "v {} {} {}", p[0], p[1], p[2]);
        }
        for t in &self.triangles {
            let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        crate::scene::write_atomic(path, s.as_bytes())
    }

    /// Writes a binary little-endian PLY (float positions, int faces).
    pub fn write_ply(&self, path: &Path) -> Result<()> {
        let mut out = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
             property float y\nproperty float z\nelement face {}\n\
             property list uchar int vertex_indices\nend_header\n",
            self.positions.len(),
            self.triangles.len()
        )
        .into_bytes();
        for p in &self.positions {
            for v in p {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        for t in &self.triangles {
            out.push(3);
            for v in t {
                out.extend_from_slice(&(*v as i32).to_le_bytes());
            }
        }
        crate::scene::write_atomic(path, &out)
    }
}

fn load_obj(path: &Path) -> Result<Mesh> {
    // tobj re-indexes without bounds checks in some paths, so check face indices first. Only
    // positions and faces are used: tobj is given those alone (its texture-coordinate and
    // normal indexing overflows on some inputs: a fuzzing finding), faces reduced to their
    // position indices.
    let text = super::files::read(path, super::files::FileKind::Mesh)?;
    let text = String::from_utf8_lossy(&text);
    let mut clean = String::with_capacity(text.len());
    let mut nv: i64 = 0;
    for (ln, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                nv += 1;
                clean.push_str(line);
                clean.push('\n');
            }
            Some(k @ ("o" | "g")) => {
                clean.push_str(k);
                clean.push_str(" m\n");
            }
            Some("f") => {
                clean.push('f');
                let toks: Vec<&str> = it.collect();
                if toks.len() < 3 {
                    return Err(Error::input(
                        path,
                        format!(
                            "line {}: a face needs at least 3 vertices, found {}",
                            ln + 1,
                            toks.len()
                        ),
                    ));
                }
                for tok in toks {
                    let idx = tok.split('/').next().unwrap_or("");
                    clean.push(' ');
                    clean.push_str(idx);
                    let v: i64 = idx.parse().map_err(|_| {
                        Error::input(
                            path,
                            format!("line {}: face index \"{tok}\" is not an integer", ln + 1),
                        )
                    })?;
                    let resolved = if v < 0 { nv + v + 1 } else { v };
                    if resolved < 1 || resolved > nv {
                        return Err(Error::input(
                            path,
                            format!(
                                "line {}: face index {v} is out of range ({nv} vertices defined so far)",
                                ln + 1
                            ),
                        ));
                    }
                }
                clean.push('\n');
            }
            _ => {}
        }
    }
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _) =
        tobj::load_obj_buf(&mut std::io::Cursor::new(clean.as_bytes()), &opts, |_| {
            Ok((Vec::new(), Default::default()))
        })
        .map_err(|e| Error::input(path, format!("OBJ parse error: {e}")))?;
    let mut mesh = Mesh::default();
    // Every model of an OBJ shares one vertex list in the file; tobj splits it per model.
    for m in models {
        let base = mesh.positions.len() as u32;
        let p = &m.mesh.positions;
        mesh.positions
            .extend(p.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        if m.mesh.indices.len() % 3 != 0 {
            return Err(Error::input(path, "face list is not made of triangles"));
        }
        mesh.triangles.extend(
            m.mesh
                .indices
                .chunks_exact(3)
                .map(|c| [c[0] + base, c[1] + base, c[2] + base]),
        );
    }
    Ok(mesh)
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum PlyType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl PlyType {
    fn parse(s: &str) -> Option<PlyType> {
        Some(match s {
            "char" | "int8" => PlyType::I8,
            "uchar" | "uint8" => PlyType::U8,
            "short" | "int16" => PlyType::I16,
            "ushort" | "uint16" => PlyType::U16,
            "int" | "int32" => PlyType::I32,
            "uint" | "uint32" => PlyType::U32,
            "float" | "float32" => PlyType::F32,
            "double" | "float64" => PlyType::F64,
            _ => return None,
        })
    }
    /// Whether an ASCII value is one this type holds: integer types take whole numbers in
    /// their range only (a fraction or "nan" as an index would otherwise become some index).
    fn holds(self, v: f64) -> bool {
        let range = match self {
            PlyType::I8 => (-128.0, 127.0),
            PlyType::U8 => (0.0, 255.0),
            PlyType::I16 => (-32768.0, 32767.0),
            PlyType::U16 => (0.0, 65535.0),
            PlyType::I32 => (-2147483648.0, 2147483647.0),
            PlyType::U32 => (0.0, 4294967295.0),
            PlyType::F32 | PlyType::F64 => return true,
        };
        v.fract() == 0.0 && (range.0..=range.1).contains(&v)
    }
    fn name(self) -> &'static str {
        match self {
            PlyType::I8 => "char",
            PlyType::U8 => "uchar",
            PlyType::I16 => "short",
            PlyType::U16 => "ushort",
            PlyType::I32 => "int",
            PlyType::U32 => "uint",
            PlyType::F32 => "float",
            PlyType::F64 => "double",
        }
    }
    fn size(self) -> usize {
        match self {
            PlyType::I8 | PlyType::U8 => 1,
            PlyType::I16 | PlyType::U16 => 2,
            PlyType::I32 | PlyType::U32 | PlyType::F32 => 4,
            PlyType::F64 => 8,
        }
    }
    fn read(self, b: &[u8]) -> f64 {
        match self {
            PlyType::I8 => b[0] as i8 as f64,
            PlyType::U8 => b[0] as f64,
            PlyType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            PlyType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            PlyType::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            PlyType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            PlyType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            PlyType::F64 => f64::from_le_bytes(b[..8].try_into().unwrap()),
        }
    }
}

#[derive(Debug)]
struct PlyProp {
    name: String,
    ty: PlyType,
    /// For list properties, the count type.
    list: Option<PlyType>,
}

#[derive(Debug)]
struct PlyElement {
    name: String,
    count: usize,
    props: Vec<PlyProp>,
}

/// Reads PLY values one at a time from either encoding.
enum PlyReader<'a> {
    Ascii(std::str::SplitAsciiWhitespace<'a>),
    Binary { data: &'a [u8], pos: usize },
}

/// Why a PLY value could not be read: the data ended, or an ASCII token is not of its type.
enum Misread {
    End,
    NotA(PlyType, String),
}

impl PlyReader<'_> {
    fn next(&mut self, ty: PlyType) -> std::result::Result<f64, Misread> {
        match self {
            PlyReader::Ascii(it) => {
                let tok = it.next().ok_or(Misread::End)?;
                match tok.parse::<f64>() {
                    Ok(v) if ty.holds(v) => Ok(v),
                    _ => Err(Misread::NotA(ty, tok.to_string())),
                }
            }
            PlyReader::Binary { data, pos } => {
                let n = ty.size();
                let b = data.get(*pos..*pos + n).ok_or(Misread::End)?;
                *pos += n;
                Ok(ty.read(b))
            }
        }
    }
}

fn load_ply(path: &Path) -> Result<Mesh> {
    let data = super::files::read(path, super::files::FileKind::Mesh)?;
    let bad = |m: String| Error::input(path, m);
    let end = data
        .windows(10)
        .position(|w| w == b"end_header")
        .ok_or_else(|| bad("PLY header has no end_header line".into()))?;
    let header = String::from_utf8_lossy(&data[..end]);
    let mut body_start = end + 10;
    // The header ends at the newline after end_header (\n or \r\n).
    while body_start < data.len() && (data[body_start] == b'\r' || data[body_start] == b' ') {
        body_start += 1;
    }
    if body_start < data.len() && data[body_start] == b'\n' {
        body_start += 1;
    }
    let (binary, elements) = parse_ply_header(path, &header)?;
    let body = &data[body_start.min(data.len())..];
    let text;
    let mut reader = if binary {
        PlyReader::Binary { data: body, pos: 0 }
    } else {
        text = String::from_utf8_lossy(body);
        PlyReader::Ascii(text.split_ascii_whitespace())
    };
    check_ply_size(path, &elements, binary, body.len())?;
    let declared = elements
        .iter()
        .map(|e| {
            let props: Vec<&str> = e.props.iter().map(|p| p.name.as_str()).collect();
            format!("{} {} ({})", e.count, e.name, props.join(" "))
        })
        .collect::<Vec<_>>()
        .join(", ");
    let mut mesh = Mesh::default();
    // An element without properties has nothing to read, whatever its count.
    for e in elements
        .iter()
        .filter(|e| !e.props.is_empty() || e.name == "vertex")
    {
        read_ply_element(path, e, &mut reader, &declared, &mut mesh)?;
    }
    if let PlyReader::Ascii(mut it) = reader {
        if it.next().is_some() {
            return Err(bad(
                "more data than the header declares (element counts are wrong)".into(),
            ));
        }
    }
    Ok(mesh)
}

/// The PLY header's lines after `end_header` is cut off: whether the body is binary, and the
/// elements with their properties.
fn parse_ply_header(path: &Path, header: &str) -> Result<(bool, Vec<PlyElement>)> {
    let bad = |m: String| Error::input(path, m);
    let mut lines = header.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return Err(bad("not a PLY file: the first line must be \"ply\"".into()));
    }
    let mut binary = None;
    let mut elements: Vec<PlyElement> = Vec::new();
    for (ln, line) in lines.enumerate() {
        let tok: Vec<&str> = line.split_whitespace().collect();
        let lno = ln + 2;
        match tok.as_slice() {
            ["format", "ascii", _] => binary = Some(false),
            ["format", "binary_little_endian", _] => binary = Some(true),
            ["format", f, ..] => {
                return Err(bad(format!(
                    "line {lno}: PLY format \"{f}\" is not supported; expected ascii or binary_little_endian"
                )))
            }
            ["element", name, count] => {
                let count = count.parse::<usize>().map_err(|_| {
                    bad(format!("line {lno}: element {name} count \"{count}\" is not a number"))
                })?;
                elements.push(PlyElement { name: name.to_string(), count, props: vec![] });
            }
            ["property", "list", ct, ty, name] => {
                let e = elements
                    .last_mut()
                    .ok_or_else(|| bad(format!("line {lno}: property before any element")))?;
                let (Some(ct), Some(ty)) = (PlyType::parse(ct), PlyType::parse(ty)) else {
                    return Err(bad(format!("line {lno}: unknown property type")));
                };
                e.props.push(PlyProp { name: name.to_string(), ty, list: Some(ct) });
            }
            ["property", ty, name] => {
                let e = elements
                    .last_mut()
                    .ok_or_else(|| bad(format!("line {lno}: property before any element")))?;
                let ty = PlyType::parse(ty)
                    .ok_or_else(|| bad(format!("line {lno}: unknown property type \"{ty}\"")))?;
                e.props.push(PlyProp { name: name.to_string(), ty, list: None });
            }
            ["comment", ..] | ["obj_info", ..] | [] => {}
            _ => return Err(bad(format!("line {lno}: unexpected header line \"{line}\""))),
        }
    }
    let binary = binary.ok_or_else(|| bad("PLY header has no format line".into()))?;
    Ok((binary, elements))
}

/// Guards against absurd counts before allocating or looping: every value takes at least one
/// byte in binary and one character plus a separator in ASCII.
fn check_ply_size(path: &Path, elements: &[PlyElement], binary: bool, body: usize) -> Result<()> {
    let min_values: usize = elements
        .iter()
        .map(|e| e.count.saturating_mul(e.props.len()))
        .fold(0, usize::saturating_add);
    let min_bytes = if binary {
        min_values
    } else {
        min_values.saturating_mul(2).saturating_sub(1)
    };
    if min_bytes > body {
        return Err(Error::input(
            path,
            format!(
                "header declares {} but the file has only {} bytes of data",
                elements
                    .iter()
                    .map(|e| format!("{} {}", e.count, e.name))
                    .collect::<Vec<_>>()
                    .join(", "),
                body
            ),
        ));
    }
    Ok(())
}

/// Reads element `e`'s records into `mesh`: vertex positions and colours, and faces fanned into
/// triangles. `declared` (the header's elements) explains a face too short to be one.
fn read_ply_element(
    path: &Path,
    e: &PlyElement,
    reader: &mut PlyReader,
    declared: &str,
    mesh: &mut Mesh,
) -> Result<()> {
    let bad = |m: String| Error::input(path, m);
    let idx = |n: &str| e.props.iter().position(|p| p.name == n);
    let is_vertex = e.name == "vertex";
    let is_face = e.name == "face";
    let (xi, yi, zi) = (idx("x"), idx("y"), idx("z"));
    let (ri, gi, bi) = (idx("red"), idx("green"), idx("blue"));
    if is_vertex && (xi.is_none() || yi.is_none() || zi.is_none()) {
        return Err(bad("vertex element lacks x, y or z".into()));
    }
    let fi = idx("vertex_indices").or_else(|| idx("vertex_index"));
    if is_vertex {
        mesh.positions.reserve(e.count.min(1 << 26));
    }
    let mut colors = Vec::new();
    for i in 0..e.count {
        let mut vals = [0f64; 3];
        let mut col = [0f64; 3];
        for (pi, p) in e.props.iter().enumerate() {
            let truncated = |m: Misread| match m {
                Misread::End => bad(format!(
                    "file ends inside {} {i} of {} (header declares {})",
                    e.name, e.count, e.count
                )),
                Misread::NotA(ty, tok) => bad(format!(
                    "{} {i}: property {} is \"{tok}\", not of its type {}",
                    e.name,
                    p.name,
                    ty.name()
                )),
            };
            if let Some(ct) = p.list {
                let n = reader.next(ct).map_err(truncated)? as usize;
                let mut poly = Vec::with_capacity(n.min(64));
                for _ in 0..n {
                    poly.push(reader.next(p.ty).map_err(truncated)?);
                }
                if is_face && Some(pi) == fi {
                    fan_ply_face(path, i, &poly, declared, &mut mesh.triangles)?;
                }
            } else {
                let v = reader.next(p.ty).map_err(truncated)?;
                if Some(pi) == xi {
                    vals[0] = v
                } else if Some(pi) == yi {
                    vals[1] = v
                } else if Some(pi) == zi {
                    vals[2] = v
                } else if Some(pi) == ri {
                    col[0] = v
                } else if Some(pi) == gi {
                    col[1] = v
                } else if Some(pi) == bi {
                    col[2] = v
                }
            }
        }
        if is_vertex {
            mesh.positions.push(vals.map(|v| v as f32));
            if let Some(ri) = ri {
                // 8-bit colours are sRGB-encoded 0..255; float ones are taken as 0..1.
                let scale = if e.props[ri].ty == PlyType::U8 {
                    255.0
                } else {
                    1.0
                };
                colors.push(col.map(|c| crate::scene::image::srgb_to_linear((c / scale) as f32)));
            }
        }
    }
    if is_vertex && !colors.is_empty() {
        mesh.colors = Some(colors);
    }
    Ok(())
}

/// Face `i`'s vertex indices `poly` as a triangle fan, appended to `triangles`.
fn fan_ply_face(
    path: &Path,
    i: usize,
    poly: &[f64],
    declared: &str,
    triangles: &mut Vec<[u32; 3]>,
) -> Result<()> {
    let bad = |m: String| Error::input(path, m);
    let n = poly.len();
    if n < 3 {
        return Err(bad(format!(
            "face {i} has {n} vertices; at least 3 needed (if the faces \
             do have 3 or more, the header's counts or property types do \
             not match the data; it declares {declared})"
        )));
    }
    for k in 1..n - 1 {
        let tri = [poly[0], poly[k], poly[k + 1]];
        if tri.iter().any(|&v| v < 0.0) {
            return Err(bad(format!("face {i} has a negative vertex index")));
        }
        triangles.push(tri.map(|v| v as u32));
    }
    Ok(())
}
