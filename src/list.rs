//! `splatbench list`: what is registered.

use harness::render::Kernel;
use methods::MethodKind;
use scenes::paths::PathSpec;

/// `splatbench list`: methods, scene generators, camera paths and kernels.
pub fn main() -> anyhow::Result<()> {
    println!("methods:");
    for m in MethodKind::ALL {
        println!("  {:<12} {}", m.name(), m.describe());
    }
    println!("scene generators (generator:points[:seed]):");
    for g in scenes::generators::Generator::ALL {
        println!("  {:<12} {}", g.name(), g.describe());
    }
    println!("camera paths (or a keyframe .toml file):");
    for (name, what) in PathSpec::BUILTIN {
        println!("  {name:<12} {what}");
    }
    println!("kernels:");
    for k in Kernel::ALL {
        println!("  {:<12} {}", k.name(), k.describe());
    }
    Ok(())
}
