//! Compiles every shader under `shaders_glsl/` to SPIR-V 1.6 (Vulkan 1.3) with the glslang crate
//! and embeds them: `OUT_DIR/shaders.rs` holds one typed constant per shader (`shaders::NET_CONV`
//! for `net/conv.comp`, so a misspelt name fails the build) and the SPIR-V bytes. Besides the
//! files, [`VARIANTS`] compiles one GLSL body several times with different defines (ncnn's way).
//! `#include "x.glsl"` looks next to the including file, then in `shaders_glsl/common/`;
//! `#include "constants.glsl"` is generated from `constants.table`, which also gives
//! `OUT_DIR/constants.rs`. A GLSL error fails the build with file and line.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glslang::include::{IncludeHandler, IncludeResult, IncludeType};
use glslang::{
    Compiler, CompilerOptions, ShaderInput, ShaderMessage, ShaderSource, ShaderStage,
    SourceLanguage, SpirvVersion, Target, VulkanVersion,
};

/// Shader variants: (name the engine asks for, GLSL body, defines). The body has no `#version`.
const VARIANTS: &[(&str, &str, &[&str])] = &[
    ("frame/features.comp", "frame/features.glsl", &[]),
    (
        "frame/features_f32.comp",
        "frame/features.glsl",
        &["STORE_F32"],
    ),
    ("frame/output.comp", "frame/output.glsl", &[]),
    ("frame/output_f32.comp", "frame/output.glsl", &["STORE_F32"]),
    ("net/conv.comp", "net/conv_portable.glsl", &[]),
    (
        "net/conv_f32.comp",
        "net/conv_portable.glsl",
        &["STORE_F32"],
    ),
    // The remainder of a block: its first 4 output channels.
    ("net/conv_r.comp", "net/conv_portable.glsl", &["OCG 1"]),
    (
        "net/conv_r_f32.comp",
        "net/conv_portable.glsl",
        &["STORE_F32", "OCG 1"],
    ),
    ("net/upsample_add.comp", "net/upsample_add.glsl", &[]),
    (
        "net/upsample_add_f32.comp",
        "net/upsample_add.glsl",
        &["STORE_F32"],
    ),
    // CPU devices: tensors by pointer.
    (
        "net/upsample_add_lp_f32.comp",
        "net/upsample_add.glsl",
        &["STORE_F32", "UP_POINTERS"],
    ),
];

struct Includer {
    root_dir: PathBuf,
    common: PathBuf,
    constants_glsl: String,
    seen: Vec<PathBuf>,
}

impl IncludeHandler for Includer {
    fn include(
        &mut self,
        _ty: IncludeType,
        header: &str,
        includer: &str,
        _depth: usize,
    ) -> Option<IncludeResult> {
        if header == "constants.glsl" {
            return Some(IncludeResult {
                name: "constants.glsl".into(),
                data: self.constants_glsl.clone(),
            });
        }
        let from = if includer.is_empty() {
            self.root_dir.clone()
        } else {
            Path::new(includer).parent()?.to_path_buf()
        };
        for dir in [from, self.common.clone()] {
            let p = dir.join(header);
            if let Ok(data) = std::fs::read_to_string(&p) {
                self.seen.push(p.clone());
                return Some(IncludeResult {
                    name: p.to_string_lossy().into_owned(),
                    data,
                });
            }
        }
        None
    }
}

fn stage_of(path: &Path) -> Option<ShaderStage> {
    match path.extension()?.to_str()? {
        "comp" => Some(ShaderStage::Compute),
        "vert" => Some(ShaderStage::Vertex),
        "frag" => Some(ShaderStage::Fragment),
        _ => None,
    }
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            walk(&p, out);
        } else {
            out.push(p);
        }
    }
}

/// One row of `constants.table`: name, GLSL type, value, meaning.
struct Constant {
    name: String,
    ty: String,
    value: String,
    doc: String,
}

fn read_constants(path: &Path) -> Vec<Constant> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut f = line.split_whitespace();
        let (Some(name), Some(ty), Some(value)) = (f.next(), f.next(), f.next()) else {
            panic!(
                "{}:{}: expected `NAME TYPE VALUE MEANING`",
                path.display(),
                n + 1
            );
        };
        let ok = match ty {
            "float" => value.parse::<f32>().is_ok(),
            "uint" => value.parse::<u32>().is_ok(),
            _ => panic!(
                "{}:{}: type {ty}: expected float or uint",
                path.display(),
                n + 1
            ),
        };
        assert!(ok, "{}:{}: {value} is not a {ty}", path.display(), n + 1);
        let doc = f.collect::<Vec<_>>().join(" ");
        let (name, ty, value) = (name.into(), ty.into(), value.into());
        out.push(Constant {
            name,
            ty,
            value,
            doc,
        });
    }
    out
}

fn constants_glsl(cs: &[Constant]) -> String {
    let mut s = String::from("// Generated by engine/build.rs from engine/constants.table.\n");
    s.push_str("#ifndef RELIT_CONSTANTS_GLSL\n#define RELIT_CONSTANTS_GLSL\n");
    for c in cs {
        let v = match c.ty.as_str() {
            "float" => format!("{:?}", c.value.parse::<f32>().unwrap()),
            _ => format!("{}u", c.value),
        };
        writeln!(s, "// {}\nconst {} {} = {v};", c.doc, c.ty, c.name).unwrap();
    }
    s.push_str("#endif\n");
    s
}

fn constants_rs(cs: &[Constant]) -> String {
    let mut s = String::new();
    for c in cs {
        let (ty, v) = match c.ty.as_str() {
            "float" => ("f32", format!("{:?}", c.value.parse::<f32>().unwrap())),
            _ => ("u32", c.value.clone()),
        };
        writeln!(s, "/// {}\npub const {}: {ty} = {v};", c.doc, c.name).unwrap();
    }
    s
}

/// `net/conv_cm.comp` → `NET_CONV_CM`; `raster/gbuffer.vert` → `RASTER_GBUFFER_VERT`.
fn const_name(rel: &str) -> String {
    rel.trim_end_matches(".comp")
        .replace(['/', '.'], "_")
        .to_uppercase()
}

/// (name, source text, directory its includes start from) of every shader to compile.
fn sources(src_root: &Path) -> Vec<(String, String, PathBuf)> {
    let mut files = Vec::new();
    walk(src_root, &mut files);
    let mut out = Vec::new();
    for path in &files {
        println!("cargo:rerun-if-changed={}", path.display());
    }
    for path in files.iter().filter(|p| stage_of(p).is_some()) {
        let rel = path
            .strip_prefix(src_root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let text =
            std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        out.push((rel, text, path.parent().unwrap().to_path_buf()));
    }
    for (name, body, defines) in VARIANTS {
        assert!(
            !out.iter().any(|(n, _, _)| n == name),
            "variant {name} is also a file under shaders_glsl/"
        );
        let body = src_root.join(body);
        let file = body.file_name().unwrap().to_string_lossy();
        let mut text =
            String::from("#version 460\n#extension GL_GOOGLE_include_directive : require\n");
        for d in *defines {
            writeln!(text, "#define {d}").unwrap();
        }
        writeln!(text, "#include \"{file}\"").unwrap();
        out.push((name.to_string(), text, body.parent().unwrap().to_path_buf()));
    }
    out.sort();
    out
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let src_root = manifest.parent().unwrap().join("shaders_glsl");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    println!("cargo:rerun-if-changed={}", src_root.display());
    // intel_tex_2's ISPC kernels need the C++ runtime at link time.
    println!("cargo:rustc-link-lib=stdc++");
    let table = manifest.join("constants.table");
    println!("cargo:rerun-if-changed={}", table.display());
    let constants = read_constants(&table);
    std::fs::write(out_dir.join("constants.rs"), constants_rs(&constants)).unwrap();
    let constants_glsl = constants_glsl(&constants);

    let compiler = Compiler::acquire().expect("glslang initialisation");
    let options = CompilerOptions {
        source_language: SourceLanguage::GLSL,
        target: Target::Vulkan {
            version: VulkanVersion::Vulkan1_3,
            spirv_version: SpirvVersion::SPIRV1_6,
        },
        version_profile: None,
        messages: ShaderMessage::DEFAULT | ShaderMessage::VULKAN_RULES | ShaderMessage::SPV_RULES,
    };

    let mut ids = String::from("pub mod shaders {\n    use super::Shader;\n");
    let mut table = String::from("static SPIRV: &[(Shader, &[u8])] = &[\n");
    let mut all =
        String::from("    /// Every embedded shader.\n    pub const ALL: &[Shader] = &[\n");
    let mut errors = Vec::new();
    for (rel, text, dir) in sources(&src_root) {
        let stage = stage_of(Path::new(&rel)).unwrap();
        let source = ShaderSource::from(text);
        let mut includer = Includer {
            root_dir: dir,
            common: src_root.join("common"),
            constants_glsl: constants_glsl.clone(),
            seen: Vec::new(),
        };
        let result = (|| {
            let input = ShaderInput::new(
                &source,
                stage,
                &options,
                None::<&[(&str, Option<&str>)]>,
                Some(&mut includer),
            )?;
            let shader = glslang::Shader::new(compiler, input).parse()?;
            shader.compile()
        })();
        match result {
            Ok(words) => {
                let spv = out_dir.join(rel.replace('/', "__") + ".spv");
                let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
                std::fs::write(&spv, bytes).unwrap();
                let id = const_name(&rel);
                writeln!(ids, "    pub const {id}: Shader = Shader({rel:?});").unwrap();
                writeln!(all, "        {id},").unwrap();
                writeln!(
                    table,
                    "    (shaders::{id}, include_bytes!({:?})),",
                    spv.display().to_string()
                )
                .unwrap();
            }
            Err(e) => {
                // glslang names the top-level source "0"; put the shader's name there.
                let msg = e
                    .to_string()
                    .replace("ERROR: 0:", &format!("ERROR: {rel}:"));
                errors.push(format!("{rel}:\n{msg}"));
            }
        }
    }
    if !errors.is_empty() {
        for e in &errors {
            eprintln!("{e}");
        }
        panic!(
            "{} shader(s) failed to compile:\n{}",
            errors.len(),
            errors.join("\n")
        );
    }
    all.push_str("    ];\n");
    ids.push_str(&all);
    ids.push_str("}\n");
    table.push_str("];\n");
    std::fs::write(out_dir.join("shaders.rs"), ids + &table).unwrap();
}
