//! `zwarp info`: the CPU and the GPU adapters zwarp can use.

use anyhow::Result;
use clap::Args;

/// Arguments of `zwarp info`.
#[derive(Args, Clone, Debug)]
pub struct InfoArgs {}

/// `zwarp info`.
pub fn run(_args: InfoArgs) -> Result<()> {
    println!("zwarp {}", env!("CARGO_PKG_VERSION"));
    println!("CPU backend: {} rayon threads", rayon::current_num_threads());
    let adapters = zwarp_gpu::list_adapters();
    if adapters.is_empty() {
        println!(
            "GPU backend: no adapter found (install a Vulkan driver, e.g. Debian's mesa-vulkan-drivers for lavapipe)"
        );
    }
    let any = !adapters.is_empty();
    for a in adapters {
        println!("GPU adapter: {} ({}, {}, driver {})", a.name, a.backend, a.device_type, a.driver);
    }
    // What `--backend gpu` will use: the device zwarp opens and the optional features that
    // decide how it times (timestamps vs fenced wall clock) and how culled objects are drawn
    // (indirect count vs per-slot indirect draws).
    if any {
        match zwarp_gpu::GpuContext::new() {
            Ok(ctx) => {
                let f = ctx.device.features();
                let yes = |x: zwarp_gpu::wgpu::Features| if f.contains(x) { "yes" } else { "no" };
                println!("GPU device used: {}", ctx.adapter);
                println!(
                    "GPU features: timestamps {}, multi_draw_indirect_count {}, indirect_first_instance {}",
                    yes(zwarp_gpu::wgpu::Features::TIMESTAMP_QUERY),
                    yes(zwarp_gpu::wgpu::Features::MULTI_DRAW_INDIRECT_COUNT),
                    yes(zwarp_gpu::wgpu::Features::INDIRECT_FIRST_INSTANCE),
                );
            }
            Err(e) => println!("GPU device: cannot be opened ({e})"),
        }
    }
    Ok(())
}
