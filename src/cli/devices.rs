//! `whitted devices`: the Vulkan devices and which one each backend picks.

use super::Ui;
use crate::gpu;
use crate::run::auto_reason;
use anyhow::Result;
use clap::Args;

#[derive(Args)]
pub struct DevicesArgs {
    /// Print the list as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: DevicesArgs, _ui: Ui) -> Result<u8> {
    let list = match gpu::devices() {
        Ok(l) => l,
        Err(e) => {
            if a.json {
                println!(
                    "{}",
                    serde_json::json!({ "devices": [], "error": e.to_string() })
                );
            } else {
                println!("{e}");
                println!("--backend auto renders on the CPU mirror; --backend gpu fails.");
            }
            return Ok(0);
        }
    };
    let gpu_pick = gpu::choose(&list, None, false).ok();
    let auto_pick = gpu::choose(&list, None, true).ok();
    if a.json {
        let json = serde_json::json!({
            "devices": list,
            "gpu": gpu_pick,
            "auto": auto_pick,
        });
        println!("{}", serde_json::to_string_pretty(&json)?);
        return Ok(0);
    }
    if list.is_empty() {
        println!("no Vulkan device: the loader reports none");
    }
    for d in &list {
        println!("{}: {}", d.index, d.name);
        println!(
            "    type: {}; driver: {}; Vulkan {}",
            d.kind.name(),
            d.driver,
            d.api_version
        );
        println!(
            "    maxStorageBufferRange: {} bytes ({:.0} MiB); maxComputeWorkGroupInvocations: {}; \
             subgroup size: {}",
            d.max_storage_buffer_range,
            d.max_storage_buffer_range as f64 / 1048576.0,
            d.max_compute_work_group_invocations,
            d.subgroup_size
        );
        println!(
            "    timestamps: {}",
            if d.timestamps {
                format!("yes ({} ns per tick)", d.timestamp_period_ns)
            } else {
                "no".into()
            }
        );
        if let Some(why) = &d.unusable {
            println!("    unusable: {why}");
        }
    }
    match gpu_pick {
        Some(i) => println!("--backend gpu: device {i} ({})", list[i].name),
        None => println!("--backend gpu: no usable device (it fails)"),
    }
    match auto_pick {
        Some(i) => println!("--backend auto: device {i} ({})", list[i].name),
        None => {
            let why = if crate::run::no_gpu_here() {
                crate::run::NO_GPU_FILE.to_string()
            } else {
                auto_reason(&list)
            };
            println!("--backend auto: the CPU mirror ({why})")
        }
    }
    Ok(0)
}
