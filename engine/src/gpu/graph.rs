//! A recorded sequence of passes over named resources (kajiya's way, in small): a pass is a
//! pipeline, its push constants and its size; the resources it binds are the ones of the
//! graph's table whose names its shader declares, and reflection says which it reads and which
//! it writes. Work that binds no descriptors (the network's kernels read device addresses)
//! names its resources itself ([`Graph::compute`]).
//!
//! A barrier goes before a pass that reads or writes a resource an earlier pass wrote, or
//! writes one an earlier pass read, since the last barrier (resources are told apart by their
//! Vulkan handles, so a name set again to another buffer is another resource). It is one
//! command carrying a buffer or image barrier for each resource written since the last one
//! (`gpu/barrier.rs`). With a timer, each pass or group is a span; its timestamps sit between
//! passes and add no barriers on a GPU. On a CPU device (lavapipe takes a timestamp's time at
//! its next flush, which a barrier is) the barrier the next pass needs anyway follows them,
//! and one is added only where the next pass would need none.

use std::collections::{BTreeMap, BTreeSet};

use ash::vk;

use super::barrier::{self, BarrierCount, Target, Write};
use super::{Bind, Gpu, Pipeline, Timer};
use crate::error::{Error, Result};

/// How a pass that names its own resources uses one of them.
#[derive(Clone, Copy)]
pub enum Use<'a> {
    Read(Bind<'a>),
    Write(Bind<'a>),
    ReadWrite(Bind<'a>),
}

/// One use as the hazard check sees it: (handle, barrier target, reads, writes).
type Touch = (u64, Target, bool, bool);

pub struct Graph<'a, 't> {
    gpu: &'a Gpu,
    cmd: vk::CommandBuffer,
    resources: BTreeMap<&'a str, Bind<'a>>,
    /// Resources (by handle) written, and read, since the last barrier, and the stages of the
    /// work since then.
    written: BTreeMap<u64, Write>,
    read: BTreeSet<u64>,
    stages: vk::PipelineStageFlags2,
    spans: Spans<'t>,
    /// Barriers recorded so far.
    pub barriers: BarrierCount,
}

/// The timer's side of a graph: the open span, how deep in groups the graph is, and whether
/// a timestamp still waits for the barrier that flushes it.
struct Spans<'t> {
    timer: Option<&'t mut Timer>,
    open: Option<(String, u32)>,
    groups: u32,
    flush_due: bool,
}

impl<'a, 't> Graph<'a, 't> {
    pub fn new(gpu: &'a Gpu, cmd: vk::CommandBuffer, timer: Option<&'t mut Timer>) -> Self {
        Graph {
            gpu,
            cmd,
            resources: BTreeMap::new(),
            written: BTreeMap::new(),
            read: BTreeSet::new(),
            stages: vk::PipelineStageFlags2::NONE,
            spans: Spans {
                timer,
                open: None,
                groups: 0,
                flush_due: false,
            },
            barriers: BarrierCount::default(),
        }
    }

    /// Puts `bind` in the table under `name` (replacing what was there).
    pub fn set(&mut self, name: &'a str, bind: Bind<'a>) -> &mut Self {
        self.resources.insert(name, bind);
        self
    }

    /// A compute pass over `threads` invocations.
    pub fn dispatch(
        &mut self,
        label: &str,
        p: &Pipeline,
        push: &[u8],
        threads: (u32, u32, u32),
    ) -> Result<()> {
        let binds = self.binds_for(p)?;
        self.step(label, p, |cmd| p.dispatch(cmd, &binds, push, threads))
    }

    /// A compute pass over `threads` invocations that first puts its own resources `binds` in
    /// the table (a pass's private buffers, or what it reads and writes this time); each of
    /// them must be a binding its shader declares (a misspelt name is an error, not unbound).
    pub fn pass(
        &mut self,
        label: &str,
        p: &Pipeline,
        binds: impl IntoIterator<Item = (&'a str, Bind<'a>)>,
        push: &[u8],
        threads: (u32, u32, u32),
    ) -> Result<()> {
        self.set_declared(label, p, binds)?;
        self.dispatch(label, p, push, threads)
    }

    /// A compute pass of exactly `groups` workgroups.
    pub fn dispatch_groups(
        &mut self,
        label: &str,
        p: &Pipeline,
        push: &[u8],
        groups: (u32, u32, u32),
    ) -> Result<()> {
        let binds = self.binds_for(p)?;
        self.step(label, p, |cmd| p.dispatch_groups(cmd, &binds, push, groups))
    }

    /// A compute pass on its own `binds` only, left out of the table (one-off passes: the
    /// viewer's compose, a texture fetch, a ray cast); uses come from reflection as for any.
    pub fn dispatch_with(
        &mut self,
        label: &str,
        p: &Pipeline,
        binds: &[(&str, Bind)],
        push: &[u8],
        threads: (u32, u32, u32),
    ) -> Result<()> {
        let touches: Vec<Touch> = (binds.iter())
            .filter_map(|(n, b)| {
                let (_, a) = p.names.get(*n)?;
                Some((handle(b), Target::of(b), a.reads(), a.writes()))
            })
            .collect();
        let stage = vk::PipelineStageFlags2::COMPUTE_SHADER;
        self.run(label, &touches, stage, |cmd| {
            p.dispatch(cmd, binds, push, threads)
        })
    }

    /// Compute work recorded by `f` on the resources `uses` names (kernels that take device
    /// addresses, or several dispatches that write disjoint parts of one output).
    pub fn compute(
        &mut self,
        label: &str,
        uses: &[Use],
        f: impl FnOnce(vk::CommandBuffer) -> Result<()>,
    ) -> Result<()> {
        let touches: Vec<Touch> = uses.iter().map(touch).collect();
        let stage = vk::PipelineStageFlags2::COMPUTE_SHADER;
        self.run(label, &touches, stage, f)
    }

    /// Work recorded by `f` (a render pass, a copy) that reads and writes the named resources.
    pub fn external(
        &mut self,
        label: &str,
        reads: &[&str],
        writes: &[&str],
        f: impl FnOnce(vk::CommandBuffer) -> Result<()>,
    ) -> Result<()> {
        let mut touches = Vec::with_capacity(reads.len() + writes.len());
        for (names, r) in [(reads, true), (writes, false)] {
            for n in names {
                let b = self.resources.get(n).ok_or_else(|| {
                    Error::Other(format!(
                        "pass \"{label}\": no resource named \"{n}\" in the graph"
                    ))
                })?;
                touches.push((handle(b), Target::of(b), r, !r));
            }
        }
        self.run(label, &touches, vk::PipelineStageFlags2::ALL_COMMANDS, f)
    }

    /// The passes `f` records, timed as one span `label` (the network's stages).
    pub fn group<R>(&mut self, label: &str, f: impl FnOnce(&mut Self) -> Result<R>) -> Result<R> {
        self.enter(label)?;
        self.spans.groups += 1;
        let r = f(self);
        self.spans.groups -= 1;
        r
    }

    /// Resources an earlier submission wrote (the frame's G-buffer, rendered before the view
    /// culling's read-back): their first use here waits for those writes.
    pub fn written_before(&mut self, names: &[&str]) -> Result<()> {
        for n in names {
            let b = self
                .resources
                .get(n)
                .ok_or_else(|| Error::Other(format!("no resource named \"{n}\" in the graph")))?;
            let w = Write {
                target: Target::of(b),
                stage: vk::PipelineStageFlags2::ALL_COMMANDS,
                access: vk::AccessFlags2::MEMORY_WRITE,
            };
            self.written.insert(handle(b), w);
        }
        Ok(())
    }

    /// Ends the graph for commands recorded after it outside any graph (a copy to the
    /// swapchain image): what it wrote is made visible to them, and the open span ends.
    pub fn finish(mut self) -> Result<BarrierCount> {
        self.boundary(None)?;
        if !self.written.is_empty() {
            self.barrier();
        }
        Ok(self.barriers)
    }

    /// Each `binds` entry into the table; it must be a binding `p` declares.
    fn set_declared(
        &mut self,
        label: &str,
        p: &Pipeline,
        binds: impl IntoIterator<Item = (&'a str, Bind<'a>)>,
    ) -> Result<()> {
        for (name, bind) in binds {
            if !p.names.contains_key(name) {
                return Err(Error::Other(format!(
                    "{}: pass \"{label}\" binds \"{name}\", which the shader does not declare \
                     (it declares {:?})",
                    p.name,
                    p.names.keys().collect::<Vec<_>>()
                )));
            }
            self.set(name, bind);
        }
        Ok(())
    }

    /// The table's resources that `p` declares; each declared name must be in the table.
    fn binds_for(&self, p: &Pipeline) -> Result<Vec<(&'a str, Bind<'a>)>> {
        (p.names.keys())
            .map(|n| {
                (self.resources.get_key_value(n.as_str()))
                    .map(|(k, b)| (*k, *b))
                    .ok_or_else(|| {
                        Error::Other(format!(
                            "{}: its binding \"{n}\" names no resource of the pass graph",
                            p.name
                        ))
                    })
            })
            .collect()
    }

    /// A pipeline's pass: its uses are its shader's bindings, as reflection declares them.
    fn step(
        &mut self,
        label: &str,
        p: &Pipeline,
        record: impl FnOnce(vk::CommandBuffer) -> Result<()>,
    ) -> Result<()> {
        let touches: Vec<Touch> = (p.names.iter())
            .filter_map(|(n, (_, a))| {
                let b = self.resources.get(n.as_str())?;
                Some((handle(b), Target::of(b), a.reads(), a.writes()))
            })
            .collect();
        let stage = match p.bind_point {
            vk::PipelineBindPoint::COMPUTE => vk::PipelineStageFlags2::COMPUTE_SHADER,
            _ => vk::PipelineStageFlags2::ALL_GRAPHICS,
        };
        self.run(label, &touches, stage, record)
    }

    /// Opens the span (outside groups), puts the barrier the touches need, records.
    fn run(
        &mut self,
        label: &str,
        touches: &[Touch],
        stage: vk::PipelineStageFlags2,
        record: impl FnOnce(vk::CommandBuffer) -> Result<()>,
    ) -> Result<()> {
        self.enter(label)?;
        self.hazards(touches, stage);
        record(self.cmd)
    }

    /// A barrier when any touch depends on an earlier use since the last barrier (or a
    /// timestamp waits to be flushed); then notes the touches.
    fn hazards(&mut self, touches: &[Touch], stage: vk::PipelineStageFlags2) {
        let depends = (touches.iter())
            .any(|(h, _, _, w)| self.written.contains_key(h) || (*w && self.read.contains(h)));
        if depends || self.spans.flush_due {
            if !depends {
                self.barriers.for_timer += 1;
            }
            self.barrier();
        }
        self.spans.flush_due = false;
        self.stages |= stage;
        let access = match stage {
            vk::PipelineStageFlags2::COMPUTE_SHADER => vk::AccessFlags2::SHADER_STORAGE_WRITE,
            _ => vk::AccessFlags2::MEMORY_WRITE,
        };
        for &(h, target, r, w) in touches {
            if r {
                self.read.insert(h);
            }
            if w {
                let (stage, access) = match self.written.get(&h) {
                    Some(o) => (o.stage | stage, o.access | access),
                    None => (stage, access),
                };
                let w = Write {
                    target,
                    stage,
                    access,
                };
                self.written.insert(h, w);
            }
        }
    }

    /// One barrier command for every write since the last one.
    fn barrier(&mut self) {
        let writes: Vec<Write> = self.written.values().copied().collect();
        let after = match self.stages {
            vk::PipelineStageFlags2::NONE => vk::PipelineStageFlags2::ALL_COMMANDS,
            s => s,
        };
        barrier::record(self.gpu, self.cmd, &writes, after, &mut self.barriers);
        self.written.clear();
        self.read.clear();
        self.stages = vk::PipelineStageFlags2::NONE;
    }

    /// A span boundary before a pass outside any group.
    fn enter(&mut self, label: &str) -> Result<()> {
        match self.spans.groups {
            0 => self.boundary(Some(label)),
            _ => Ok(()),
        }
    }

    /// With a timer: a timestamp that ends the open span and begins `next`.
    fn boundary(&mut self, next: Option<&str>) -> Result<()> {
        let Some(t) = self.spans.timer.as_deref_mut() else {
            return Ok(());
        };
        if next.is_none() && self.spans.open.is_none() {
            return Ok(());
        }
        let s = t.stamp(self.cmd)?;
        if let Some((l, from)) = self.spans.open.take() {
            t.span(l, from, s);
        }
        self.spans.open = next.map(|l| (l.to_string(), s));
        // lavapipe takes the time at its next flush: a barrier must follow before more work.
        // A GPU writes it in order on its own.
        self.spans.flush_due = self.gpu.caps.device_type == vk::PhysicalDeviceType::CPU;
        Ok(())
    }
}

impl Drop for Graph<'_, '_> {
    /// The last span ends where the graph does (a full timer has already said so).
    fn drop(&mut self) {
        let _ = self.boundary(None);
    }
}

fn touch(u: &Use) -> Touch {
    let (b, r, w) = match u {
        Use::Read(b) => (b, true, false),
        Use::Write(b) => (b, false, true),
        Use::ReadWrite(b) => (b, true, true),
    };
    (handle(b), Target::of(b), r, w)
}

/// The Vulkan handle that tells a bound resource apart.
fn handle(b: &Bind) -> u64 {
    use ash::vk::Handle;
    match b {
        Bind::Buffer(buf) | Bind::BufferRange(buf, ..) => buf.raw.as_raw(),
        Bind::StorageImage(img) | Bind::Sampled(img, _) => img.raw.as_raw(),
        Bind::Accel(a) => a.as_raw(),
    }
}
