//! GPU timestamp queries for per-pass timing (`relit bench`). Timing never decides a test.

use std::sync::Arc;

use ash::vk;

use super::Gpu;
use crate::error::{Error, Result, VkContext};

/// Up to `capacity` labelled spans per recording; `read` turns them into milliseconds.
pub struct Timer {
    gpu: Arc<Gpu>,
    pool: vk::QueryPool,
    capacity: u32,
    labels: Vec<String>,
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
            labels: Vec::new(),
        })
    }

    /// Clears the labels and the queries (host reset; call outside any recording).
    pub fn reset(&mut self) {
        self.labels.clear();
        unsafe {
            self.gpu
                .device
                .reset_query_pool(self.pool, 0, self.capacity * 2)
        };
    }

    /// Records the start of span `label`; returns its index for `end`.
    pub fn begin(&mut self, cmd: vk::CommandBuffer, label: &str) -> Result<u32> {
        let i = self.labels.len() as u32;
        if i >= self.capacity {
            return Err(Error::Other(format!(
                "timer full ({} spans)",
                self.capacity
            )));
        }
        self.labels.push(label.to_string());
        // Span boundaries are full barriers on both sides of the timestamp, so a span covers
        // exactly the commands inside it. lavapipe needs both: it bins a timestamp and takes
        // the time only when that bin is flushed, which a barrier does; without the second
        // barrier the time would be taken after the next (synchronous) compute dispatch.
        super::full_barrier(&self.gpu, cmd);
        unsafe {
            self.gpu.device.cmd_write_timestamp2(
                cmd,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pool,
                2 * i,
            )
        };
        super::full_barrier(&self.gpu, cmd);
        Ok(i)
    }

    pub fn end(&self, cmd: vk::CommandBuffer, span: u32) {
        super::full_barrier(&self.gpu, cmd);
        unsafe {
            self.gpu.device.cmd_write_timestamp2(
                cmd,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pool,
                2 * span + 1,
            )
        };
        super::full_barrier(&self.gpu, cmd);
    }

    /// (label, milliseconds) for every span, once the recording has completed.
    pub fn read(&self) -> Result<Vec<(String, f64)>> {
        let n = self.labels.len();
        if n == 0 {
            return Ok(Vec::new());
        }
        let mut data = vec![0u64; 2 * n];
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
        Ok(self
            .labels
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let ticks = (data[2 * i + 1] & mask).wrapping_sub(data[2 * i] & mask) & mask;
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
