//! GPU timestamp queries for per-pass timing (`relit bench`). Timing never decides a test.

use std::sync::Arc;

use ash::vk;

use super::Gpu;
use crate::error::{Error, Result, VkContext};

/// Up to `capacity` labelled spans per recording; `read` turns them into milliseconds. Only
/// the pass graph writes timestamps ([`super::Graph`]): a span runs from one timestamp to the
/// next, and the graph puts them between passes, where its barriers already are.
pub struct Timer {
    gpu: Arc<Gpu>,
    pool: vk::QueryPool,
    capacity: u32,
    stamps: u32,
    spans: Vec<(String, u32, u32)>,
}

impl Timer {
    pub fn new(gpu: &Arc<Gpu>, capacity: u32) -> Result<Timer> {
        if gpu.caps.timestamp_valid_bits == 0 {
            return Err(Error::Device(
                "the queue does not support timestamps".into(),
            ));
        }
        let pool = unsafe {
            gpu.device.create_query_pool(
                &vk::QueryPoolCreateInfo::default()
                    .query_type(vk::QueryType::TIMESTAMP)
                    .query_count(capacity * 2),
                None,
            )
        }
        .vk("create query pool")?;
        unsafe { gpu.device.reset_query_pool(pool, 0, capacity * 2) };
        Ok(Timer {
            gpu: gpu.clone(),
            pool,
            capacity,
            stamps: 0,
            spans: Vec::new(),
        })
    }

    /// Clears the spans and the queries (host reset; call outside any recording).
    pub fn reset(&mut self) {
        self.spans.clear();
        self.stamps = 0;
        unsafe {
            self.gpu
                .device
                .reset_query_pool(self.pool, 0, self.capacity * 2)
        };
    }

    /// Records a timestamp once all earlier commands are done; returns its query.
    pub(crate) fn stamp(&mut self, cmd: vk::CommandBuffer) -> Result<u32> {
        if self.stamps >= self.capacity * 2 || self.spans.len() as u32 >= self.capacity {
            return Err(Error::Other(format!(
                "timer full ({} spans)",
                self.capacity
            )));
        }
        let q = self.stamps;
        self.stamps += 1;
        unsafe {
            self.gpu.device.cmd_write_timestamp2(
                cmd,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pool,
                q,
            )
        };
        Ok(q)
    }

    /// Names the span between the timestamps `from` and `to`.
    pub(crate) fn span(&mut self, label: String, from: u32, to: u32) {
        self.spans.push((label, from, to));
    }

    /// (label, milliseconds) for every span, once the recording has completed.
    pub fn read(&self) -> Result<Vec<(String, f64)>> {
        let n = self.stamps as usize;
        if self.spans.is_empty() {
            return Ok(Vec::new());
        }
        let mut data = vec![0u64; n];
        unsafe {
            self.gpu.device.get_query_pool_results(
                self.pool,
                0,
                &mut data,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .vk("read timestamps")?;
        let bits = self.gpu.caps.timestamp_valid_bits;
        let mask = if bits >= 64 {
            u64::MAX
        } else {
            (1u64 << bits) - 1
        };
        let period = self.gpu.caps.timestamp_period_ns as f64;
        Ok((self.spans.iter())
            .map(|(l, a, b)| {
                let (a, b) = (data[*a as usize] & mask, data[*b as usize] & mask);
                let ticks = b.wrapping_sub(a) & mask;
                (l.clone(), ticks as f64 * period * 1e-6)
            })
            .collect())
    }
}

impl Drop for Timer {
    fn drop(&mut self) {
        unsafe { self.gpu.device.destroy_query_pool(self.pool, None) };
    }
}
