//! Fuzzes the candidates reader of `plan --candidates`: any bytes, read as a CSV or (first
//! byte odd) an ASTM E1392 file, give direction pairs or a clear error, never a panic;
//! every accepted pair is two unit directions above the horizon, and no pair is given
//! twice.
#![no_main]
use brdf_basis::acquire::parse_candidates;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&kind, bytes)) = data.split_first() else {
        return;
    };
    let name = if kind % 2 == 1 { "fuzz.astm" } else { "fuzz.csv" };
    if let Ok(c) = parse_candidates(bytes, std::path::Path::new(name)) {
        assert!(!c.is_empty());
        let key = |v: &[f64; 3]| v.map(|x| (x * 1e9).round() as i64);
        let mut seen = std::collections::HashSet::new();
        for (wi, wo) in &c {
            for d in [wi, wo] {
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                assert!((n - 1.0).abs() < 1e-9 && d[2] > 0.0, "{d:?}");
            }
            assert!(seen.insert((key(wi), key(wo))), "a pair given twice");
        }
    }
});
