//! A recorded sequence of passes over named resources (kajiya's way, in small): a pass is a
//! pipeline, its push constants and its size; the resources it binds are the ones of the
//! graph's table whose names its shader declares, and reflection says which it reads and which
//! it writes. A barrier goes before a pass that reads or writes a resource an earlier pass wrote,
//! or writes one an earlier pass read, since the last barrier (resources are told apart by their
//! Vulkan handles, so a name set again to another buffer is another resource); each pass gets a
//! timer span.

use std::collections::{BTreeMap, BTreeSet};

use ash::vk;

use super::{full_barrier, Bind, Gpu, Pipeline, Timer};
use crate::error::{Error, Result};

pub struct Graph<'a, 't> {
    gpu: &'a Gpu,
    cmd: vk::CommandBuffer,
    resources: BTreeMap<&'a str, Bind<'a>>,
    /// Resources (by handle) written, and read, since the last barrier.
    written: BTreeSet<u64>,
    read: BTreeSet<u64>,
    timer: Option<&'t mut Timer>,
    /// Barriers recorded (for tests).
    pub barriers: u32,
}

impl<'a, 't> Graph<'a, 't> {
    pub fn new(gpu: &'a Gpu, cmd: vk::CommandBuffer, timer: Option<&'t mut Timer>) -> Self {
        Graph {
            gpu,
            cmd,
            resources: BTreeMap::new(),
            written: BTreeSet::new(),
            read: BTreeSet::new(),
            timer,
            barriers: 0,
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

    /// Work recorded by `f` (a render pass, a sub-graph like the network) that reads and writes
    /// the named resources; `label` None when `f` makes its own timer spans.
    pub fn external(
        &mut self,
        label: Option<&str>,
        reads: &[&str],
        writes: &[&str],
        f: impl FnOnce(vk::CommandBuffer, Option<&mut Timer>) -> Result<()>,
    ) -> Result<()> {
        let mut uses = Vec::with_capacity(reads.len() + writes.len());
        for (names, r, w) in [(reads, true, false), (writes, false, true)] {
            for n in names {
                let b = self.resources.get(n).ok_or_else(|| {
                    Error::Other(format!(
                        "pass {label:?}: no resource named \"{n}\" in the graph"
                    ))
                })?;
                uses.push((handle(b), r, w));
            }
        }
        self.hazards(&uses);
        let span = match (label, self.timer.as_deref_mut()) {
            (Some(l), Some(t)) => Some(t.begin(self.cmd, l)?),
            _ => None,
        };
        f(
            self.cmd,
            if span.is_none() {
                self.timer.as_deref_mut()
            } else {
                None
            },
        )?;
        if let (Some(s), Some(t)) = (span, self.timer.as_deref()) {
            t.end(self.cmd, s);
        }
        Ok(())
    }

    /// Resources an earlier submission wrote (the frame's G-buffer, rendered before the view
    /// culling's read-back): their first use here waits for those writes.
    pub fn written_before(&mut self, names: &[&str]) -> Result<()> {
        for n in names {
            let b = self
                .resources
                .get(n)
                .ok_or_else(|| Error::Other(format!("no resource named \"{n}\" in the graph")))?;
            self.written.insert(handle(b));
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

    fn step(
        &mut self,
        label: &str,
        p: &Pipeline,
        record: impl FnOnce(vk::CommandBuffer) -> Result<()>,
    ) -> Result<()> {
        let uses: Vec<(u64, bool, bool)> = (p.names.iter())
            .filter_map(|(n, (_, a))| {
                Some((
                    handle(self.resources.get(n.as_str())?),
                    a.reads(),
                    a.writes(),
                ))
            })
            .collect();
        self.hazards(&uses);
        let span = match self.timer.as_deref_mut() {
            Some(t) => Some(t.begin(self.cmd, label)?),
            None => None,
        };
        record(self.cmd)?;
        if let (Some(s), Some(t)) = (span, self.timer.as_deref()) {
            t.end(self.cmd, s);
        }
        Ok(())
    }

    /// A barrier when any use depends on an earlier one since the last barrier; then notes
    /// the uses (resource handle, reads, writes).
    fn hazards(&mut self, uses: &[(u64, bool, bool)]) {
        let depends = (uses.iter())
            .any(|(h, _, w)| self.written.contains(h) || (*w && self.read.contains(h)));
        if depends {
            full_barrier(self.gpu, self.cmd);
            self.barriers += 1;
            self.written.clear();
            self.read.clear();
        }
        for &(h, r, w) in uses {
            if r {
                self.read.insert(h);
            }
            if w {
                self.written.insert(h);
            }
        }
    }
}

/// The Vulkan handle that tells a bound resource apart.
fn handle(b: &Bind) -> u64 {
    use ash::vk::Handle;
    match b {
        Bind::Buffer(buf) | Bind::BufferRange(buf, ..) => buf.raw.as_raw(),
        Bind::StorageImage(v) | Bind::Sampled(v, _) => v.as_raw(),
        Bind::Accel(a) => a.as_raw(),
    }
}
