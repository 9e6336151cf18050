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
    for a in adapters {
        println!("GPU adapter: {} ({}, {}, driver {})", a.name, a.backend, a.device_type, a.driver);
    }
    Ok(())
}
