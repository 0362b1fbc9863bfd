//! Validates every WGSL kernel with naga when the crate is built, so that a shader that
//! does not parse or validate fails `cargo build` with naga's message (file, line and
//! column), not a test or a user's run.
//!
//! Each kernel is checked as the host module compiles it: `common.wgsl` first, then the
//! constants the host prepends (`const M` of the PGD kernel), then the kernel. The
//! templated kernels (`pairwise.wgsl`, `weighted.wgsl`) are checked with their `//@`
//! marker lines empty (the shape-specialised lines the host writes there are checked for
//! every shape by `tests/shaders.rs`), and the tiled pairwise kernel after the pairwise
//! definitions it is appended to. Only the f64 reduction may use `f64`.

use naga::valid::{Capabilities, ValidationFlags, Validator};
use std::path::Path;

fn read(rel: &str) -> String {
    println!("cargo:rerun-if-changed=src/{rel}");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("src").join(rel);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn validate(name: &str, source: &str, caps: Capabilities) {
    let module = naga::front::wgsl::parse_str(source).unwrap_or_else(|e| {
        panic!(
            "{name} does not parse:\n{}",
            e.emit_to_string_with_path(source, name)
        )
    });
    if let Err(e) = Validator::new(ValidationFlags::all(), caps).validate(&module) {
        panic!(
            "{name} does not validate:\n{}",
            e.emit_to_string_with_path(source, name)
        );
    }
}

fn main() {
    let common = read("common.wgsl");
    let with_common = |kernel: &str| format!("{common}\n{kernel}");
    let none = Capabilities::empty();
    validate("tabulate.wgsl", &with_common(&read("tabulate.wgsl")), none);
    validate("nbrdf.wgsl", &with_common(&read("nbrdf.wgsl")), none);
    validate(
        "pgd.wgsl",
        &with_common(&format!("const M: u32 = 13u;\n{}", read("pgd.wgsl"))),
        none,
    );
    validate(
        "weighted.wgsl",
        &with_common(&format!(
            "const K: u32 = 12u;\nconst STRIDE: u32 = 92u;\n{}",
            read("weighted.wgsl")
        )),
        none,
    );
    let pairwise = read("pairwise/pairwise.wgsl");
    validate(
        "pairwise/pairwise.wgsl",
        &with_common(&format!(
            "const R: u32 = 4u;\nconst LANES: u32 = 64u;\n{pairwise}"
        )),
        none,
    );
    let defs = &pairwise[..pairwise
        .find("@compute")
        .expect("pairwise.wgsl's entry point")];
    validate(
        "pairwise/pairwise_tiled.wgsl",
        &with_common(&format!("{defs}{}", read("pairwise/pairwise_tiled.wgsl"))),
        none,
    );
    validate(
        "pairwise/reduce_f64.wgsl",
        &with_common(&read("pairwise/reduce_f64.wgsl")),
        Capabilities::FLOAT64,
    );
}
