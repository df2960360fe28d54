//! Reads the Embree API major that `embree-sys` found (cargo `links` metadata) and sets
//! `cfg(embree4)` for the safe wrapper, so the 3/4 differences are chosen at compile time.

fn main() {
    println!("cargo::rustc-check-cfg=cfg(embree4)");
    println!("cargo:rerun-if-env-changed=DEP_EMBREE_API");
    match std::env::var("DEP_EMBREE_API").as_deref() {
        Ok("4") => println!("cargo:rustc-cfg=embree4"),
        Ok("3") => {}
        other => panic!("embree-sys reported an unknown Embree API: {other:?}"),
    }
}
