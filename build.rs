//! Tells the rod kernel whether this build is optimized: `cfg(tdpcr_unoptimized)` at
//! opt-level 0. The kernel's integration loop is inlined into its AVX2 copy in every
//! optimized build, the test profile (opt-level 2, debug assertions on) included; keyed
//! to debug assertions before, the test profile called it out of line, compiled without
//! AVX2 and FMA, and every fused multiply–add became a call (42 % of a tiny design search's
//! time in the test profile, by perf).

fn main() {
    println!("cargo::rustc-check-cfg=cfg(tdpcr_unoptimized)");
    println!("cargo::rerun-if-changed=build.rs");
    if std::env::var("OPT_LEVEL").as_deref() == Ok("0") {
        println!("cargo::rustc-cfg=tdpcr_unoptimized");
    }
}
