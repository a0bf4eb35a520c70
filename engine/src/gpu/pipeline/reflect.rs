//! What a shader declares, read from its SPIR-V: bindings by name with their access, the
//! push-constant block's member offsets (for the push-layout checks) and the workgroup size.

use std::collections::BTreeMap;

use ash::vk;

use super::{layout_source, spirv, Shader};
use crate::error::{Error, Result};

/// What reflection says a shader stage uses.
#[derive(Clone, Debug, Default)]
pub struct Reflected {
    /// set → binding → (type, count)
    pub sets: BTreeMap<u32, BTreeMap<u32, (vk::DescriptorType, u32)>>,
    /// Push-constant block size in bytes (0 when none).
    pub push_size: u32,
    /// Byte offset of each member of the push-constant block, in member order.
    pub push_offsets: Vec<u32>,
    pub workgroup: Option<(u32, u32, u32)>,
    /// Set 0's bindings by the name the GLSL gives each resource (a block's type name, an
    /// image's, sampler's or acceleration structure's variable name), and how the shader uses it.
    pub names: BTreeMap<String, (u32, Access)>,
}

/// How a shader uses a binding, from its SPIR-V decorations (`readonly`: NonWritable,
/// `writeonly`: NonReadable); sampled images, uniform blocks and acceleration structures are
/// read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    Read,
    Write,
    ReadWrite,
}

impl Access {
    pub fn reads(self) -> bool {
        self != Access::Write
    }
    pub fn writes(self) -> bool {
        self != Access::Read
    }
    pub(super) fn merge(self, o: Access) -> Access {
        if self == o {
            self
        } else {
            Access::ReadWrite
        }
    }
}

/// A `#[repr(C)]` push-constant struct as Rust lays it out ([`crate::push_layout!`]), for a test
/// to hold against its shader's reflected block.
pub struct PushLayout {
    /// The shaders that take this struct as their push constants.
    pub shaders: &'static [Shader],
    pub ty: &'static str,
    pub size: u32,
    pub offsets: &'static [u32],
}

/// The [`PushLayout`] of `$ty`, whose fields `$f` are, in order, the members of the push block of
/// each shader `$s` (explicit padding fields left out; a nested struct's fields as `a.b`).
#[macro_export]
macro_rules! push_layout {
    ($ty:ty, [$($s:expr),+ $(,)?], [$($($f:ident).+),* $(,)?]) => {
        $crate::gpu::PushLayout {
            shaders: &[$($s),+],
            ty: stringify!($ty),
            size: std::mem::size_of::<$ty>() as u32,
            offsets: &[$(std::mem::offset_of!($ty, $($f).+) as u32),*],
        }
    };
}

/// Member offsets of the push-constant block, read from the SPIR-V's decorations (rspirv-reflect
/// gives only the block's range): the PushConstant variable → its pointer type → the struct's
/// `OpMemberDecorate … Offset`. A member that is itself a struct (a `Camera`, a `Light`) gives
/// its own members' offsets in its place, flattened in order.
fn push_member_offsets(words: &[u32]) -> Vec<u32> {
    let insts = instructions(words);
    let find = |op: u32, f: &dyn Fn(&[u32]) -> bool| {
        insts
            .iter()
            .find(|(o, a)| *o == op && f(a))
            .map(|(_, a)| *a)
    };
    let Some(var) = find(op::VARIABLE, &|a| a.len() >= 3 && a[2] == op::PUSH_CONSTANT) else {
        return Vec::new();
    };
    let Some(ptr) = find(op::TYPE_POINTER, &|a| a.len() == 3 && a[0] == var[0]) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    struct_offsets(&insts, ptr[2], 0, &mut out);
    out
}

/// The flattened member offsets of struct type `id`, each plus `base`, appended to `out`.
fn struct_offsets(insts: &[(u32, &[u32])], id: u32, base: u32, out: &mut Vec<u32>) {
    let member_types = (insts.iter())
        .find(|(o, a)| *o == op::TYPE_STRUCT && a.first() == Some(&id))
        .map_or(&[][..], |(_, a)| &a[1..]);
    let mut members: Vec<(u32, u32)> = (insts.iter())
        .filter(|(o, a)| {
            *o == op::MEMBER_DECORATE && a.len() == 4 && a[0] == id && a[2] == op::OFFSET
        })
        .map(|(_, a)| (a[1], a[3]))
        .collect();
    members.sort();
    for (m, off) in members {
        let ty = member_types.get(m as usize).copied();
        let nested = ty
            .filter(|t| (insts.iter()).any(|(o, a)| *o == op::TYPE_STRUCT && a.first() == Some(t)));
        match nested {
            Some(t) => struct_offsets(insts, t, base + off, out),
            None => out.push(base + off),
        }
    }
}

/// SPIR-V opcodes, decorations and storage classes read here.
mod op {
    pub const NAME: u32 = 5;
    pub const TYPE_STRUCT: u32 = 30;
    pub const TYPE_POINTER: u32 = 32;
    pub const VARIABLE: u32 = 59;
    pub const DECORATE: u32 = 71;
    pub const MEMBER_DECORATE: u32 = 72;
    pub const OFFSET: u32 = 35;
    pub const BINDING: u32 = 33;
    pub const DESCRIPTOR_SET: u32 = 34;
    pub const NON_WRITABLE: u32 = 24;
    pub const NON_READABLE: u32 = 25;
    pub const PUSH_CONSTANT: u32 = 9;
    pub const STORAGE_BUFFER: u32 = 12;
    pub const UNIFORM_CONSTANT: u32 = 0;
}

/// The module's instructions as (opcode, operands).
fn instructions(words: &[u32]) -> Vec<(u32, &[u32])> {
    let mut insts = Vec::new();
    let mut i = 5; // the module header
    while i < words.len() {
        let (n, op) = ((words[i] >> 16) as usize, words[i] & 0xffff);
        if n == 0 || i + n > words.len() {
            break;
        }
        insts.push((op, &words[i + 1..i + n]));
        i += n;
    }
    insts
}

/// A literal string operand.
fn literal(words: &[u32]) -> String {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

/// Set 0's bindings by name, with their access (see [`Reflected::names`]).
fn binding_names(words: &[u32]) -> Result<BTreeMap<String, (u32, Access)>> {
    let insts = instructions(words);
    let name_of = |id: u32| {
        (insts.iter())
            .find(|(o, a)| *o == op::NAME && a.len() >= 2 && a[0] == id)
            .map(|(_, a)| literal(&a[1..]))
            .filter(|n| !n.is_empty())
    };
    let decorated = |id: u32, d: u32| {
        (insts.iter()).find(|(o, a)| *o == op::DECORATE && a.len() >= 2 && a[0] == id && a[1] == d)
    };
    let all_members = |ty: u32, d: u32| {
        let n = (insts.iter())
            .find(|(o, a)| *o == op::TYPE_STRUCT && a.first() == Some(&ty))
            .map_or(0, |(_, a)| a.len() - 1);
        let marked = (insts.iter())
            .filter(|(o, a)| *o == op::MEMBER_DECORATE && a.len() >= 3 && a[0] == ty && a[2] == d)
            .count();
        n > 0 && marked == n
    };
    let mut out = BTreeMap::new();
    for (_, a) in insts
        .iter()
        .filter(|(o, a)| *o == op::VARIABLE && a.len() >= 3)
    {
        let (ptr_ty, var, class) = (a[0], a[1], a[2]);
        let set = decorated(var, op::DESCRIPTOR_SET).map(|(_, d)| d[2]);
        let Some(binding) = decorated(var, op::BINDING).map(|(_, d)| d[2]) else {
            continue;
        };
        if set != Some(0) {
            continue;
        }
        let pointee = (insts.iter())
            .find(|(o, p)| *o == op::TYPE_POINTER && p.len() == 3 && p[0] == ptr_ty)
            .map(|(_, p)| p[2]);
        let is_block = pointee.is_some_and(|t| {
            insts
                .iter()
                .any(|(o, s)| *o == op::TYPE_STRUCT && s.first() == Some(&t))
        });
        // A block is named by its type (`buffer Comp { … }`), anything else by its variable.
        let name = match (is_block, pointee) {
            (true, Some(t)) => name_of(t),
            _ => name_of(var),
        }
        .ok_or_else(|| Error::Other(format!("binding {binding} has no name in the SPIR-V")))?;
        let (read_only, write_only) = match (is_block, pointee) {
            (true, Some(t)) if class == op::STORAGE_BUFFER => (
                decorated(var, op::NON_WRITABLE).is_some() || all_members(t, op::NON_WRITABLE),
                decorated(var, op::NON_READABLE).is_some() || all_members(t, op::NON_READABLE),
            ),
            // Uniform blocks are read-only.
            (true, _) => (true, false),
            _ if class == op::UNIFORM_CONSTANT => (
                decorated(var, op::NON_WRITABLE).is_some() || !is_storage_image(&insts, pointee),
                decorated(var, op::NON_READABLE).is_some(),
            ),
            _ => (false, false),
        };
        let access = match (read_only, write_only) {
            (true, _) => Access::Read,
            (false, true) => Access::Write,
            _ => Access::ReadWrite,
        };
        if out.insert(name.clone(), (binding, access)).is_some() {
            return Err(Error::Other(format!("two bindings are named {name}")));
        }
    }
    Ok(out)
}

/// Whether `ty` is a storage image (OpTypeImage with Sampled = 2); sampled images, samplers
/// and acceleration structures are read-only.
fn is_storage_image(insts: &[(u32, &[u32])], ty: Option<u32>) -> bool {
    const TYPE_IMAGE: u32 = 25;
    ty.is_some_and(|t| {
        (insts.iter()).any(|(o, a)| *o == TYPE_IMAGE && a.len() >= 7 && a[0] == t && a[6] == 2)
    })
}

pub fn reflect(shader: Shader) -> Result<Reflected> {
    let src = layout_source(shader);
    let words = spirv(src)?;
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let err = |e: rspirv_reflect::ReflectError| Error::Other(format!("reflecting {src}: {e:?}"));
    let r = rspirv_reflect::Reflection::new_from_spirv(&bytes).map_err(err)?;
    let mut sets = BTreeMap::new();
    for (set, bindings) in r.get_descriptor_sets().map_err(err)? {
        let mut out = BTreeMap::new();
        for (binding, info) in bindings {
            let count = match info.binding_count {
                rspirv_reflect::BindingCount::One => 1,
                rspirv_reflect::BindingCount::StaticSized(n) => n as u32,
                rspirv_reflect::BindingCount::Unbounded => {
                    return Err(Error::Other(format!(
                        "{src}: unbounded array at set {set} binding {binding} is not supported"
                    )))
                }
            };
            out.insert(
                binding,
                (vk::DescriptorType::from_raw(info.ty.0 as i32), count),
            );
        }
        sets.insert(set, out);
    }
    let push_size = r
        .get_push_constant_range()
        .map_err(err)?
        .map(|p| p.offset + p.size)
        .unwrap_or(0);
    Ok(Reflected {
        sets,
        push_size,
        push_offsets: push_member_offsets(&words),
        workgroup: r.get_compute_group_size(),
        names: binding_names(&words).map_err(|e| Error::Other(format!("reflecting {src}: {e}")))?,
    })
}
