//! Finds the installed Embree (4 first, then 3), runs bindgen over its `rtcore.h`, links the
//! matching library and tells dependents which API it found (`DEP_EMBREE_API` = 3 or 4).

use std::env;
use std::path::{Path, PathBuf};

/// An Embree installation: the directory holding `embree{3,4}/rtcore.h` and the API major.
struct Found {
    include: PathBuf,
    lib: Option<PathBuf>,
    api: u32,
}

const SYSTEM_INCLUDES: &[&str] = &["/usr/include", "/usr/local/include", "/opt/homebrew/include"];

fn find_in(include: &Path) -> Option<u32> {
    [4, 3].into_iter().find(|api| include.join(format!("embree{api}/rtcore.h")).is_file())
}

fn find() -> Result<Found, String> {
    if let Some(dir) = env::var_os("EMBREE_DIR") {
        let dir = PathBuf::from(dir);
        let include = dir.join("include");
        return match find_in(&include) {
            Some(api) => {
                let lib = ["lib", "lib64"]
                    .iter()
                    .map(|l| dir.join(l))
                    .find(|l| l.is_dir())
                    .unwrap_or_else(|| dir.join("lib"));
                Ok(Found { include, lib: Some(lib), api })
            }
            None => Err(format!(
                "EMBREE_DIR={} has neither include/embree4/rtcore.h nor include/embree3/rtcore.h: \
                 point it at an Embree install, or unset it and `apt-get install libembree-dev \
                 libclang-dev`",
                dir.display()
            )),
        };
    }
    SYSTEM_INCLUDES
        .iter()
        .map(PathBuf::from)
        .find_map(|include| find_in(&include).map(|api| Found { include, lib: None, api }))
        .ok_or_else(|| {
            "Embree was not found: install it with `apt-get install libembree-dev libclang-dev` \
             (Debian/Ubuntu), or set EMBREE_DIR to a directory holding include/embree{3,4}/rtcore.h \
             and lib/"
                .to_string()
        })
}

fn main() {
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo::rustc-check-cfg=cfg(embree4)");

    let found = match find() {
        Ok(found) => found,
        Err(message) => {
            eprintln!("error: {message}");
            std::process::exit(1);
        }
    };
    let header = found.include.join(format!("embree{}/rtcore.h", found.api));
    println!("cargo:rerun-if-changed={}", header.display());

    if let Some(lib) = &found.lib {
        println!("cargo:rustc-link-search=native={}", lib.display());
    }
    println!("cargo:rustc-link-lib=dylib=embree{}", found.api);
    if found.api == 4 {
        println!("cargo:rustc-cfg=embree4");
    }
    // Read by the root build script as DEP_EMBREE_API / DEP_EMBREE_INCLUDE.
    println!("cargo:api={}", found.api);
    println!("cargo:include={}", found.include.display());

    let bindings = bindgen::Builder::default()
        .header(header.to_string_lossy())
        .clang_arg(format!("-I{}", found.include.display()))
        .allowlist_function("rtc.*")
        .allowlist_type("RTC.*")
        .allowlist_var("RTC.*")
        .default_enum_style(bindgen::EnumVariation::Consts)
        .prepend_enum_name(false)
        .derive_default(true)
        .layout_tests(true)
        .generate();
    let bindings = match bindings {
        Ok(b) => b,
        Err(e) => {
            eprintln!(
                "error: bindgen failed on {} ({e}); is libclang installed? \
                 `apt-get install libembree-dev libclang-dev`, or set EMBREE_DIR",
                header.display()
            );
            std::process::exit(1);
        }
    };
    let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("bindings.rs");
    if let Err(e) = bindings.write_to_file(&out) {
        eprintln!("error: cannot write {}: {e}", out.display());
        std::process::exit(1);
    }
}
