//! `arbor devices` (included by main.rs only): the Vulkan devices arbor can use.

use anyhow::{bail, Result};
use arbor::gpu::Context;

use crate::common::print_out;

/// `arbor devices`: one line per Vulkan device.
pub(crate) fn run() -> Result<()> {
    let list = Context::list_devices()?;
    if list.is_empty() {
        bail!("no Vulkan 1.2 device with a compute queue");
    }
    let mut text = String::new();
    for d in list {
        text += &format!(
            "{}: {} ({}, Vulkan {}, {}), maxStorageBufferRange {} bytes, timestampPeriod {} ns, subgroup {}, ray query {}\n",
            d.index,
            d.name,
            d.kind,
            d.api_version,
            d.driver,
            d.max_storage_buffer_range,
            d.timestamp_period_ns,
            d.subgroup_size,
            match &d.ray_query_missing {
                None => "yes".to_string(),
                Some(m) => format!("no (lacks {m})"),
            }
        );
    }
    Ok(print_out(&text)?)
}
