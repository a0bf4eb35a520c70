//! Pipelines built from embedded SPIR-V. Descriptor-set layouts and push-constant ranges come
//! from reflection (rspirv-reflect; spirv-reflect 0.2.3 aborts on SPIR-V >= 1.4 and on ray-query
//! modules). Set 0 is a push-descriptor set, so a pass binds its resources with one call and no
//! descriptor pools exist anywhere.

use std::collections::BTreeMap;
use std::sync::Arc;

use ash::vk;

use super::memory::Buffer;
use super::Gpu;
use crate::error::{Error, Result, VkContext};

/// An embedded shader, named by its path below `shaders_glsl/` or by its row in build.rs's
/// variant table. Only the generated constants of [`shaders`] make one, so a misspelt shader
/// fails the build.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Shader(&'static str);

impl Shader {
    pub fn name(self) -> &'static str {
        self.0
    }
}

impl std::fmt::Display for Shader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }
}

// `pub mod shaders` (one constant per shader, and `ALL`) and the SPIR-V table.
include!(concat!(env!("OUT_DIR"), "/shaders.rs"));

/// The SPIR-V of an embedded shader, as words.
pub fn spirv(shader: Shader) -> Result<Vec<u32>> {
    let bytes = SPIRV
        .iter()
        .find(|(s, _)| *s == shader)
        .map(|(_, b)| *b)
        .ok_or_else(|| Error::Other(format!("no embedded shader named {shader}")))?;
    ash::util::read_spv(&mut std::io::Cursor::new(bytes))
        .map_err(|e| Error::Other(format!("shader {shader}: bad SPIR-V: {e}")))
}

/// The shader whose reflection gives `shader`'s layout. No reflection crate reads
/// cooperative-matrix modules yet, so a `*_cm.comp` kernel takes the layout of its portable twin
/// (`*.comp`), which by construction declares the same bindings.
pub fn layout_source(shader: Shader) -> Shader {
    let Some(stem) = shader.0.strip_suffix("_cm.comp") else {
        return shader;
    };
    let twin = format!("{stem}.comp");
    shaders::ALL
        .iter()
        .copied()
        .find(|s| s.0 == twin)
        .unwrap_or(shader)
}

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
    fn merge(self, o: Access) -> Access {
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

/// A resource bound at one binding of set 0.
#[derive(Clone, Copy)]
pub enum Bind<'a> {
    Buffer(&'a Buffer),
    /// A window of a buffer: (buffer, offset, size) in bytes.
    BufferRange(&'a Buffer, u64, u64),
    StorageImage(vk::ImageView),
    /// A combined image sampler in SHADER_READ_ONLY_OPTIMAL layout.
    Sampled(vk::ImageView, vk::Sampler),
    Accel(vk::AccelerationStructureKHR),
}

pub struct Pipeline {
    pub gpu: Arc<Gpu>,
    pub raw: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub set_layout: vk::DescriptorSetLayout,
    pub bind_point: vk::PipelineBindPoint,
    pub bindings: BTreeMap<u32, (vk::DescriptorType, u32)>,
    /// The bindings by name, with their access ([`Reflected::names`]).
    pub names: BTreeMap<String, (u32, Access)>,
    pub push_size: u32,
    pub stages: vk::ShaderStageFlags,
    pub workgroup: (u32, u32, u32),
    pub name: String,
}

fn make_module(gpu: &Gpu, shader: Shader) -> Result<vk::ShaderModule> {
    let words = spirv(shader)?;
    unsafe {
        gpu.device
            .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
    }
    .vk("create shader module")
}

/// A pipeline layout with its push-descriptor set layout and what it was built from.
struct Layout {
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    bindings: BTreeMap<u32, (vk::DescriptorType, u32)>,
    names: BTreeMap<String, (u32, Access)>,
    push_size: u32,
}

/// Merges per-stage reflections into one set-0 layout and push range.
fn make_layout(
    gpu: &Gpu,
    name: &str,
    parts: &[(Reflected, vk::ShaderStageFlags)],
) -> Result<Layout> {
    let mut bindings: BTreeMap<u32, (vk::DescriptorType, u32, vk::ShaderStageFlags)> =
        BTreeMap::new();
    let mut push_size = 0;
    let mut names: BTreeMap<String, (u32, Access)> = BTreeMap::new();
    for (r, _) in parts {
        for (n, &(b, a)) in &r.names {
            let e = names.entry(n.clone()).or_insert((b, a));
            if e.0 != b {
                return Err(Error::Other(format!(
                    "{name}: \"{n}\" is binding {} in one stage and {b} in another",
                    e.0
                )));
            }
            e.1 = e.1.merge(a);
        }
    }
    for (r, stage) in parts {
        for (set, b) in &r.sets {
            if *set != 0 {
                return Err(Error::Other(format!(
                    "{name}: uses descriptor set {set}; Relit's pipelines use set 0 only"
                )));
            }
            for (binding, (ty, count)) in b {
                let e = bindings.entry(*binding).or_insert((
                    *ty,
                    *count,
                    vk::ShaderStageFlags::empty(),
                ));
                if e.0 != *ty {
                    return Err(Error::Other(format!(
                        "{name}: binding {binding} has type {:?} in one stage and {ty:?} in another",
                        e.0
                    )));
                }
                e.2 |= *stage;
            }
        }
        push_size = push_size.max(r.push_size);
    }
    let all_stages: vk::ShaderStageFlags = parts
        .iter()
        .fold(vk::ShaderStageFlags::empty(), |a, (_, s)| a | *s);
    let vk_bindings: Vec<vk::DescriptorSetLayoutBinding> = bindings
        .iter()
        .map(|(b, (ty, count, stages))| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(*b)
                .descriptor_type(*ty)
                .descriptor_count(*count)
                .stage_flags(*stages)
        })
        .collect();
    let d = &gpu.device;
    let set_layout = unsafe {
        d.create_descriptor_set_layout(
            &vk::DescriptorSetLayoutCreateInfo::default()
                .flags(vk::DescriptorSetLayoutCreateFlags::PUSH_DESCRIPTOR_KHR)
                .bindings(&vk_bindings),
            None,
        )
    }
    .vk("create descriptor set layout")?;
    let ranges = [vk::PushConstantRange::default()
        .stage_flags(all_stages)
        .offset(0)
        .size(push_size)];
    let set_layouts = [set_layout];
    let mut info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
    if push_size > 0 {
        info = info.push_constant_ranges(&ranges);
    }
    let layout = match unsafe { d.create_pipeline_layout(&info, None) } {
        Ok(l) => l,
        Err(e) => {
            unsafe { d.destroy_descriptor_set_layout(set_layout, None) };
            return Err(Error::Vk {
                what: "create pipeline layout",
                result: e,
            });
        }
    };
    let bindings = bindings
        .into_iter()
        .map(|(b, (t, c, _))| (b, (t, c)))
        .collect();
    Ok(Layout {
        set_layout,
        layout,
        bindings,
        names,
        push_size,
    })
}

/// Fixed-function state for a graphics pipeline (dynamic rendering, dynamic viewport).
pub struct GraphicsDesc<'a> {
    pub vert: Shader,
    pub frag: Shader,
    pub color_formats: &'a [vk::Format],
    pub depth_format: Option<vk::Format>,
    /// Vertex buffer stride and (location, format, offset) of each attribute (binding 0).
    pub vertex_stride: u32,
    pub attributes: &'a [(u32, vk::Format, u32)],
    pub cull: vk::CullModeFlags,
}

impl Pipeline {
    pub fn compute(gpu: &Arc<Gpu>, shader: Shader) -> Result<Pipeline> {
        Pipeline::compute_specialized(gpu, shader, &[])
    }

    /// A compute pipeline whose specialization constants 0, 1, … take `spec` (u32 each).
    pub fn compute_specialized(gpu: &Arc<Gpu>, shader: Shader, spec: &[u32]) -> Result<Pipeline> {
        let r = reflect(shader)?;
        let workgroup = r.workgroup.unwrap_or((1, 1, 1));
        let Layout {
            set_layout,
            layout,
            bindings,
            names,
            push_size,
        } = make_layout(gpu, shader.name(), &[(r, vk::ShaderStageFlags::COMPUTE)])?;
        let module = make_module(gpu, shader)?;
        let entries: Vec<vk::SpecializationMapEntry> = (0..spec.len() as u32)
            .map(|i| vk::SpecializationMapEntry {
                constant_id: i,
                offset: i * 4,
                size: 4,
            })
            .collect();
        let spec_info = vk::SpecializationInfo::default()
            .map_entries(&entries)
            .data(bytemuck::cast_slice(spec));
        let mut stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main");
        if !spec.is_empty() {
            stage = stage.specialization_info(&spec_info);
        }
        let info = [vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(layout)];
        let res = unsafe {
            gpu.device
                .create_compute_pipelines(vk::PipelineCache::null(), &info, None)
        };
        unsafe { gpu.device.destroy_shader_module(module, None) };
        let raw = match res {
            Ok(p) => p[0],
            Err((_, e)) => {
                unsafe {
                    gpu.device.destroy_pipeline_layout(layout, None);
                    gpu.device.destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(Error::Vk {
                    what: "create compute pipeline",
                    result: e,
                });
            }
        };
        Ok(Pipeline {
            gpu: gpu.clone(),
            raw,
            layout,
            set_layout,
            bind_point: vk::PipelineBindPoint::COMPUTE,
            bindings,
            names,
            push_size,
            stages: vk::ShaderStageFlags::COMPUTE,
            workgroup,
            name: shader.name().to_string(),
        })
    }

    pub fn graphics(gpu: &Arc<Gpu>, desc: &GraphicsDesc) -> Result<Pipeline> {
        let name = format!("{}+{}", desc.vert, desc.frag);
        let parts = [
            (reflect(desc.vert)?, vk::ShaderStageFlags::VERTEX),
            (reflect(desc.frag)?, vk::ShaderStageFlags::FRAGMENT),
        ];
        let Layout {
            set_layout,
            layout,
            bindings,
            names,
            push_size,
        } = make_layout(gpu, &name, &parts)?;
        let vm = make_module(gpu, desc.vert)?;
        let fm = make_module(gpu, desc.frag)?;
        let stages = [
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::VERTEX)
                .module(vm)
                .name(c"main"),
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(fm)
                .name(c"main"),
        ];
        let vb = [vk::VertexInputBindingDescription::default()
            .binding(0)
            .stride(desc.vertex_stride)
            .input_rate(vk::VertexInputRate::VERTEX)];
        let attrs: Vec<_> = desc
            .attributes
            .iter()
            .map(|(loc, fmt, off)| {
                vk::VertexInputAttributeDescription::default()
                    .location(*loc)
                    .binding(0)
                    .format(*fmt)
                    .offset(*off)
            })
            .collect();
        let mut vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
        if !desc.attributes.is_empty() {
            vertex_input = vertex_input
                .vertex_binding_descriptions(&vb)
                .vertex_attribute_descriptions(&attrs);
        }
        let ia = vk::PipelineInputAssemblyStateCreateInfo::default()
            .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        let vp = vk::PipelineViewportStateCreateInfo::default()
            .viewport_count(1)
            .scissor_count(1);
        let rs = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(desc.cull)
            .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
            .line_width(1.0);
        let ms = vk::PipelineMultisampleStateCreateInfo::default()
            .rasterization_samples(vk::SampleCountFlags::TYPE_1);
        let ds = vk::PipelineDepthStencilStateCreateInfo::default()
            .depth_test_enable(desc.depth_format.is_some())
            .depth_write_enable(desc.depth_format.is_some())
            .depth_compare_op(vk::CompareOp::LESS);
        let blend: Vec<_> = desc
            .color_formats
            .iter()
            .map(|_| {
                vk::PipelineColorBlendAttachmentState::default()
                    .color_write_mask(vk::ColorComponentFlags::RGBA)
            })
            .collect();
        let cb = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend);
        let dyn_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dyn_states);
        let mut rendering = vk::PipelineRenderingCreateInfo::default()
            .color_attachment_formats(desc.color_formats)
            .depth_attachment_format(desc.depth_format.unwrap_or(vk::Format::UNDEFINED));
        let info = [vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&ia)
            .viewport_state(&vp)
            .rasterization_state(&rs)
            .multisample_state(&ms)
            .depth_stencil_state(&ds)
            .color_blend_state(&cb)
            .dynamic_state(&dynamic)
            .layout(layout)
            .push_next(&mut rendering)];
        let res = unsafe {
            gpu.device
                .create_graphics_pipelines(vk::PipelineCache::null(), &info, None)
        };
        unsafe {
            gpu.device.destroy_shader_module(vm, None);
            gpu.device.destroy_shader_module(fm, None);
        }
        let raw = match res {
            Ok(p) => p[0],
            Err((_, e)) => {
                unsafe {
                    gpu.device.destroy_pipeline_layout(layout, None);
                    gpu.device.destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(Error::Vk {
                    what: "create graphics pipeline",
                    result: e,
                });
            }
        };
        Ok(Pipeline {
            gpu: gpu.clone(),
            raw,
            layout,
            set_layout,
            bind_point: vk::PipelineBindPoint::GRAPHICS,
            bindings,
            names,
            push_size,
            stages: vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
            workgroup: (1, 1, 1),
            name,
        })
    }

    /// Whether the shader declares a binding named `name`.
    pub fn has_binding(&self, name: &str) -> bool {
        self.names.contains_key(name)
    }

    /// Binds and dispatches with the resources of `binds` that the shader declares (passes
    /// that share one table of named resources, like the frame's).
    pub fn dispatch_subset(
        &self,
        cmd: vk::CommandBuffer,
        binds: &[(&str, Bind)],
        push: &[u8],
        threads: (u32, u32, u32),
    ) -> Result<()> {
        let mine: Vec<(&str, Bind)> = (binds.iter())
            .filter(|(n, _)| self.has_binding(n))
            .copied()
            .collect();
        self.dispatch(cmd, &mine, push, threads)
    }

    /// The binding numbers of `binds`: each name must be one the shader declares, and each
    /// binding it declares must be given.
    fn numbered<'b>(&self, binds: &[(&str, Bind<'b>)]) -> Result<Vec<(u32, Bind<'b>)>> {
        let known = || self.names.keys().cloned().collect::<Vec<_>>().join(", ");
        let mut out = Vec::with_capacity(binds.len());
        for (n, b) in binds {
            let (i, _) = self.names.get(*n).ok_or_else(|| {
                Error::Other(format!(
                    "{}: no binding named \"{n}\" (it declares {})",
                    self.name,
                    known()
                ))
            })?;
            out.push((*i, *b));
        }
        if let Some(missing) =
            (self.names.iter()).find(|(_, (i, _))| !out.iter().any(|o| o.0 == *i))
        {
            return Err(Error::Other(format!(
                "{}: binding \"{}\" not given",
                self.name, missing.0
            )));
        }
        Ok(out)
    }

    /// Binds the pipeline, pushes set 0 (each resource to the binding of its name) and the
    /// push constants. Each binding the shader declares must be given exactly once, with a
    /// resource of the reflected type.
    pub fn bind(&self, cmd: vk::CommandBuffer, binds: &[(&str, Bind)], push: &[u8]) -> Result<()> {
        let binds = self.numbered(binds)?;
        self.bind_numbered(cmd, &binds, push)
    }

    fn bind_numbered(
        &self,
        cmd: vk::CommandBuffer,
        binds: &[(u32, Bind)],
        push: &[u8],
    ) -> Result<()> {
        if push.len() as u32 != self.push_size {
            return Err(Error::Other(format!(
                "{}: push constants are {} bytes, shader declares {}",
                self.name,
                push.len(),
                self.push_size
            )));
        }
        let mut buf_infos = Vec::with_capacity(binds.len());
        let mut img_infos = Vec::with_capacity(binds.len());
        let mut accels = Vec::with_capacity(binds.len());
        for (binding, b) in binds {
            let (ty, _) = self.bindings.get(binding).ok_or_else(|| {
                Error::Other(format!("{}: shader has no binding {binding}", self.name))
            })?;
            let ok = matches!(
                (b, *ty),
                (
                    Bind::Buffer(_) | Bind::BufferRange(..),
                    vk::DescriptorType::STORAGE_BUFFER | vk::DescriptorType::UNIFORM_BUFFER
                ) | (Bind::StorageImage(_), vk::DescriptorType::STORAGE_IMAGE)
                    | (
                        Bind::Sampled(..),
                        vk::DescriptorType::COMBINED_IMAGE_SAMPLER
                    )
                    | (
                        Bind::Accel(_),
                        vk::DescriptorType::ACCELERATION_STRUCTURE_KHR
                    )
            );
            if !ok {
                let name = (self.names.iter())
                    .find(|(_, (i, _))| i == binding)
                    .map_or(String::new(), |(n, _)| n.clone());
                return Err(Error::Other(format!(
                    "{}: binding \"{name}\" is {ty:?} in the shader",
                    self.name
                )));
            }
            match b {
                Bind::Buffer(buf) => buf_infos.push(
                    vk::DescriptorBufferInfo::default()
                        .buffer(buf.raw)
                        .range(vk::WHOLE_SIZE),
                ),
                Bind::BufferRange(buf, offset, size) => buf_infos.push(
                    vk::DescriptorBufferInfo::default()
                        .buffer(buf.raw)
                        .offset(*offset)
                        .range(*size),
                ),
                Bind::StorageImage(v) => img_infos.push(
                    vk::DescriptorImageInfo::default()
                        .image_view(*v)
                        .image_layout(vk::ImageLayout::GENERAL),
                ),
                Bind::Sampled(v, s) => img_infos.push(
                    vk::DescriptorImageInfo::default()
                        .image_view(*v)
                        .sampler(*s)
                        .image_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL),
                ),
                Bind::Accel(a) => accels.push([*a]),
            }
        }
        let mut as_writes: Vec<vk::WriteDescriptorSetAccelerationStructureKHR> = accels
            .iter()
            .map(|a| {
                vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(a)
            })
            .collect();
        let (mut bi, mut ii) = (0, 0);
        let mut as_iter = as_writes.iter_mut();
        let mut writes = Vec::with_capacity(binds.len());
        for (binding, b) in binds {
            let ty = self.bindings[binding].0;
            let w = vk::WriteDescriptorSet::default()
                .dst_binding(*binding)
                .descriptor_type(ty);
            let w = match b {
                Bind::Buffer(_) | Bind::BufferRange(..) => {
                    bi += 1;
                    w.buffer_info(std::slice::from_ref(&buf_infos[bi - 1]))
                }
                Bind::StorageImage(_) | Bind::Sampled(..) => {
                    ii += 1;
                    w.image_info(std::slice::from_ref(&img_infos[ii - 1]))
                }
                // The count is not implied by a pNext struct: set it explicitly.
                Bind::Accel(_) => w
                    .descriptor_count(1)
                    .push_next(as_iter.next().expect("one write per accel")),
            };
            writes.push(w);
        }
        unsafe {
            let d = &self.gpu.device;
            d.cmd_bind_pipeline(cmd, self.bind_point, self.raw);
            if !writes.is_empty() {
                self.gpu.push_desc.cmd_push_descriptor_set(
                    cmd,
                    self.bind_point,
                    self.layout,
                    0,
                    &writes,
                );
            }
            if !push.is_empty() {
                d.cmd_push_constants(cmd, self.layout, self.stages, 0, push);
            }
        }
        Ok(())
    }

    /// Binds and dispatches exactly `groups` workgroups (tile-based kernels).
    pub fn dispatch_groups(
        &self,
        cmd: vk::CommandBuffer,
        binds: &[(&str, Bind)],
        push: &[u8],
        groups: (u32, u32, u32),
    ) -> Result<()> {
        self.bind(cmd, binds, push)?;
        unsafe {
            self.gpu
                .device
                .cmd_dispatch(cmd, groups.0, groups.1, groups.2)
        };
        Ok(())
    }

    /// Binds and dispatches enough workgroups to cover `threads` invocations.
    pub fn dispatch(
        &self,
        cmd: vk::CommandBuffer,
        binds: &[(&str, Bind)],
        push: &[u8],
        threads: (u32, u32, u32),
    ) -> Result<()> {
        self.bind(cmd, binds, push)?;
        let (wx, wy, wz) = self.workgroup;
        unsafe {
            self.gpu.device.cmd_dispatch(
                cmd,
                threads.0.div_ceil(wx),
                threads.1.div_ceil(wy),
                threads.2.div_ceil(wz),
            )
        };
        Ok(())
    }
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        unsafe {
            let d = &self.gpu.device;
            d.destroy_pipeline(self.raw, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// A linear, clamp-to-edge sampler.
pub struct Sampler {
    gpu: Arc<Gpu>,
    pub raw: vk::Sampler,
}

impl Sampler {
    pub fn linear(gpu: &Arc<Gpu>) -> Result<Sampler> {
        let info = vk::SamplerCreateInfo::default()
            .mag_filter(vk::Filter::LINEAR)
            .min_filter(vk::Filter::LINEAR)
            .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_EDGE);
        let raw = unsafe { gpu.device.create_sampler(&info, None) }.vk("create sampler")?;
        Ok(Sampler {
            gpu: gpu.clone(),
            raw,
        })
    }
}

impl Drop for Sampler {
    fn drop(&mut self) {
        unsafe { self.gpu.device.destroy_sampler(self.raw, None) };
    }
}
