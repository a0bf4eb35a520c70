//! Compiles every shader under `shaders_glsl/` to SPIR-V 1.6 (Vulkan 1.3) with the glslang crate
//! and embeds them: `OUT_DIR/shaders.rs` lists `(name, spirv bytes)`, where the name is the path
//! below `shaders_glsl/` (`raster/gbuffer.vert`). `#include "x.glsl"` looks next to the including
//! file, then in `shaders_glsl/common/`. A GLSL error fails the build with file and line.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use glslang::include::{IncludeHandler, IncludeResult, IncludeType};
use glslang::{
    Compiler, CompilerOptions, ShaderInput, ShaderMessage, ShaderSource, ShaderStage,
    SourceLanguage, SpirvVersion, Target, VulkanVersion,
};

struct Includer {
    root_dir: PathBuf,
    common: PathBuf,
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

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let src_root = manifest.parent().unwrap().join("shaders_glsl");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    println!("cargo:rerun-if-changed={}", src_root.display());
    // intel_tex_2's ISPC kernels need the C++ runtime at link time.
    println!("cargo:rustc-link-lib=stdc++");

    let mut files = Vec::new();
    walk(&src_root, &mut files);
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

    let mut table = String::from("pub static SHADERS: &[(&str, &[u8])] = &[\n");
    let mut errors = Vec::new();
    for path in &files {
        println!("cargo:rerun-if-changed={}", path.display());
        let Some(stage) = stage_of(path) else {
            continue;
        };
        let rel = path
            .strip_prefix(&src_root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let text =
            std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let source = ShaderSource::from(text);
        let mut includer = Includer {
            root_dir: path.parent().unwrap().to_path_buf(),
            common: src_root.join("common"),
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
                writeln!(
                    table,
                    "    ({rel:?}, include_bytes!({:?})),",
                    spv.display().to_string()
                )
                .unwrap();
            }
            Err(e) => {
                // glslang names the top-level source "0"; put the file path there.
                let msg = e
                    .to_string()
                    .replace("ERROR: 0:", &format!("ERROR: {}:", path.display()));
                errors.push(format!("{}:\n{msg}", path.display()));
            }
        }
    }
    table.push_str("];\n");
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
    std::fs::write(out_dir.join("shaders.rs"), table).unwrap();
}
