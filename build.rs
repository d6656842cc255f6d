//! Records the instruction-set extensions the build may use (from the
//! target CPU and target features, `.cargo/config.toml` or RUSTFLAGS) in
//! `LPVID_TARGET_FEATURES`. The binding stores them in the compiled module
//! as one string that `python/lpvid/_cpu.py` reads from the file, to refuse
//! a processor that lacks them before the module is loaded.

fn main() {
    let features = std::env::var("CARGO_CFG_TARGET_FEATURE").unwrap_or_default();
    println!("cargo:rustc-env=LPVID_TARGET_FEATURES={features}");
    println!("cargo:rerun-if-changed=build.rs");
}
