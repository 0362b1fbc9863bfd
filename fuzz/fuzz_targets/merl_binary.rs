//! Fuzzes the MERL `.binary` parser. Inputs are mapped onto a full-size file: the first
//! 12 bytes of the input replace the header (when present), the rest patches values at
//! positions chosen by the input, and the last byte may truncate the file, so the fuzzer
//! reaches the size, header, NaN/inf, negative-cell and no-valid-cell paths cheaply.
#![no_main]
use libfuzzer_sys::fuzz_target;

const N: usize = 1_458_000;

fuzz_target!(|data: &[u8]| {
    let mut bytes = Vec::with_capacity(12 + 24 * N);
    for d in [90i32, 90, 180] {
        bytes.extend_from_slice(&d.to_le_bytes());
    }
    bytes.resize(12 + 24 * N, 0);
    let (head, rest) = data.split_at(data.len().min(12));
    bytes[..head.len()].copy_from_slice(head);
    // Patches: (u32 value index, f64 value) records.
    for rec in rest.chunks_exact(12) {
        let idx = u32::from_le_bytes([rec[0], rec[1], rec[2], rec[3]]) as usize % (3 * N);
        let o = 12 + 8 * idx;
        bytes[o..o + 8].copy_from_slice(&rec[4..12]);
    }
    if let Some(&t) = rest.last() {
        if t % 7 == 0 {
            bytes.truncate(bytes.len() - 1 - t as usize);
        }
    }
    if let Ok(t) = brdf_basis::merl::parse_binary(&bytes, std::path::Path::new("fuzz.binary")) {
        assert!(t.valid_count() > 0);
        assert!(t.rgb.iter().all(|v| v.is_finite()));
    }
});
