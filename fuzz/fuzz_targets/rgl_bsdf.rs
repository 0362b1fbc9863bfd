//! Fuzzes the RGL-EPFL `.bsdf` reader (the `tensor_file` container and the field checks).
//! Any input is parsed as a whole file; an accepted file must evaluate to finite values.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzz.bsdf");
    if let Ok(b) = brdf_basis::rgl::parse(data.to_vec(), path) {
        for (wi, wo) in [
            ([0.0, 0.0, 1.0], [0.5, 0.0, 0.866]),
            ([0.6, 0.2, 0.77], [-0.5, -0.3, 0.81]),
            ([0.99, 0.0, 0.14], [-0.98, 0.0, 0.2]),
        ] {
            assert!(b.eval(wi, wo).iter().all(|v| v.is_finite()));
        }
    }
});
