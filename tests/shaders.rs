//! Every shader parses and validates with naga; shared structs match the Rust layouts.

use brdf_basis::backend::LobeParams;
use brdf_basis::gpu::pairwise::PairParams;
use brdf_basis::gpu::tabulate::PackParams;
use brdf_basis::gpu::{kernel_source, pairwise, pgd, tabulate};
use std::mem::{offset_of, size_of};

fn module(src: &str) -> (naga::Module, naga::valid::ModuleInfo) {
    let full = kernel_source(src);
    let m = naga::front::wgsl::parse_str(&full)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&full)));
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&m)
    .unwrap_or_else(|e| panic!("validation: {e:?}"));
    (m, info)
}

fn layout(m: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
    for (_, ty) in m.types.iter() {
        if ty.name.as_deref() == Some(name) {
            if let naga::TypeInner::Struct { members, span } = &ty.inner {
                return (
                    *span,
                    members
                        .iter()
                        .map(|mm| (mm.name.clone().unwrap_or_default(), mm.offset))
                        .collect(),
                );
            }
        }
    }
    panic!("struct {name} not found")
}

#[test]
fn tabulate_shader_validates_and_matches_rust_structs() {
    let (m, _) = module(tabulate::SOURCE);
    let (span, members) = layout(&m, "PackParams");
    assert_eq!(span as usize, size_of::<PackParams>());
    let rust = [
        ("n_cells", offset_of!(PackParams, n_cells)),
        ("chunk", offset_of!(PackParams, chunk)),
        ("first_block", offset_of!(PackParams, first_block)),
        ("n_blocks", offset_of!(PackParams, n_blocks)),
    ];
    assert_eq!(members.len(), rust.len());
    for ((n, o), (rn, ro)) in members.iter().zip(rust) {
        assert_eq!((n.as_str(), *o as usize), (rn, ro));
    }
    assert!(tabulate::SOURCE.contains(&format!("const BPI: u32 = {}u;", tabulate::BPI)));
    assert!(tabulate::SOURCE.contains(&format!("const NIJ: u32 = {}u;", tabulate::NIJ)));
    assert!(pairwise::SOURCE.contains(&format!("const NIJ: u32 = {}u;", tabulate::NIJ)));
    let (span, members) = layout(&m, "Lobe");
    assert_eq!(span as usize, size_of::<LobeParams>());
    let rust = [
        ("kd", offset_of!(LobeParams, kd)),
        ("ks", offset_of!(LobeParams, ks)),
        ("f0", offset_of!(LobeParams, f0)),
        ("n", offset_of!(LobeParams, n)),
    ];
    for ((n, o), (rn, ro)) in members.iter().zip(rust) {
        assert_eq!((n.as_str(), *o as usize), (rn, ro));
    }
}

#[test]
fn pairwise_shader_validates_and_matches_rust_structs() {
    // Every shape the back-end can pick, unrolled.
    for shape in pairwise::KernelShape::all() {
        for diagonal in [false, true] {
            let src = pairwise::kernel_source(shape, diagonal);
            assert!(
                !src.lines().any(|l| l.trim_start().starts_with("//@")),
                "every template line expanded"
            );
            module(&src);
        }
    }
    let (m, _) = module(&pairwise::kernel_source(
        pairwise::KernelShape::HARDWARE,
        false,
    ));
    let (span, members) = layout(&m, "PairParams");
    assert_eq!(span as usize, size_of::<PairParams>());
    let rust = [
        ("n_cells", offset_of!(PairParams, n_cells)),
        ("row_stride", offset_of!(PairParams, row_stride)),
        ("run_iters", offset_of!(PairParams, run_iters)),
        ("n_runs", offset_of!(PairParams, n_runs)),
        ("block_offset", offset_of!(PairParams, block_offset)),
        ("n_blocks", offset_of!(PairParams, n_blocks)),
        ("analytic_blocks", offset_of!(PairParams, analytic_blocks)),
        ("measured_blocks", offset_of!(PairParams, measured_blocks)),
        ("measured_base", offset_of!(PairParams, measured_base)),
        ("zero_base", offset_of!(PairParams, zero_base)),
        ("_pad0", offset_of!(PairParams, _pad0)),
        ("_pad1", offset_of!(PairParams, _pad1)),
    ];
    assert_eq!(members.len(), rust.len());
    for ((n, o), (rn, ro)) in members.iter().zip(rust) {
        assert_eq!((n.as_str(), *o as usize), (rn, ro));
    }
}

#[test]
fn shared_constants_agree() {
    let common = brdf_basis::gpu::COMMON_WGSL;
    assert!(common.contains(&format!("const TEX_W: u32 = {}u;", pairwise::TEX_W)));
    assert!(common.contains(&format!(
        "const T_LOG2_COS_H: u32 = {}u;",
        brdf_basis::gpu::TABLE_LOG2_COS_H
    )));
    assert!(common.contains(&format!(
        "const T_ABS_COS_P: u32 = {}u;",
        brdf_basis::gpu::TABLE_ABS_COS_P
    )));
    assert!(common.contains(&format!(
        "const T_LEN: u32 = {}u;",
        brdf_basis::gpu::TABLE_LEN
    )));
}

#[test]
fn pgd_shader_validates_and_matches_rust_structs() {
    for columns in [1, 6, 32] {
        module(&pgd::kernel_source(columns));
    }
    let (m, _) = module(&pgd::kernel_source(6));
    let (span, members) = layout(&m, "PgdUniforms");
    assert_eq!(span as usize, size_of::<pgd::PgdUniforms>());
    let rust = [
        ("m", offset_of!(pgd::PgdUniforms, m)),
        ("n_targets", offset_of!(pgd::PgdUniforms, n_targets)),
        ("steps", offset_of!(pgd::PgdUniforms, steps)),
        ("max_iter", offset_of!(pgd::PgdUniforms, max_iter)),
        ("inv_l", offset_of!(pgd::PgdUniforms, inv_l)),
        ("tol", offset_of!(pgd::PgdUniforms, tol)),
        ("_pad0", offset_of!(pgd::PgdUniforms, _pad0)),
        ("_pad1", offset_of!(pgd::PgdUniforms, _pad1)),
    ];
    assert_eq!(members.len(), rust.len());
    for ((n, o), (rn, ro)) in members.iter().zip(rust) {
        assert_eq!((n.as_str(), *o as usize), (rn, ro));
    }
    assert!(pgd::SOURCE.contains(&format!("const S_LEN: u32 = {}u;", pgd::STATE_LEN)));
}
