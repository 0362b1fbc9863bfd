//! Every shader parses and validates with naga; shared structs match the Rust layouts.

use brdf_basis::backend::gpu::pairwise::PairParams;
use brdf_basis::backend::gpu::tabulate::PackParams;
use brdf_basis::backend::gpu::{kernel_source, pairwise, pgd, tabulate};
use std::mem::{offset_of, size_of};

fn module(src: &str) -> (naga::Module, naga::valid::ModuleInfo) {
    module_with(src, naga::valid::Capabilities::empty())
}

fn module_with(
    src: &str,
    caps: naga::valid::Capabilities,
) -> (naga::Module, naga::valid::ModuleInfo) {
    let full = kernel_source(src);
    let m = naga::front::wgsl::parse_str(&full)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&full)));
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps)
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
    assert!(tabulate::SOURCE.contains(&format!(
        "const NIJ: u32 = {}u;",
        brdf_basis::backend::gpu::NIJ
    )));
    assert!(pairwise::SOURCE.contains(&format!(
        "const NIJ: u32 = {}u;",
        brdf_basis::backend::gpu::NIJ
    )));
    // The grid-table uniform holds exactly TABLE_LEN f32.
    let tables = m
        .global_variables
        .iter()
        .find(|(_, g)| g.name.as_deref() == Some("tables"))
        .map(|(_, g)| g.ty)
        .expect("var tables");
    match &m.types[tables].inner {
        naga::TypeInner::Array {
            size: naga::ArraySize::Constant(n),
            stride,
            ..
        } => assert_eq!(
            n.get() as usize * *stride as usize,
            4 * brdf_basis::backend::gpu::TABLE_LEN
        ),
        other => panic!("tables: {other:?}"),
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
fn f64_reduce_shader_validates_with_float64_only_and_matches_rust_structs() {
    use brdf_basis::backend::gpu::pairwise::{ReduceParams, REDUCE_SOURCE};
    // The kernel needs f64 (wgpu's SHADER_F64): without the capability naga refuses it.
    let full = kernel_source(REDUCE_SOURCE);
    let m = naga::front::wgsl::parse_str(&full).expect("parses");
    assert!(naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty()
    )
    .validate(&m)
    .is_err());
    let (m, _) = module_with(REDUCE_SOURCE, naga::valid::Capabilities::FLOAT64);
    let (span, members) = layout(&m, "ReduceParams");
    assert_eq!(span as usize, size_of::<ReduceParams>());
    let rust = [
        ("ss", offset_of!(ReduceParams, ss)),
        ("lane_runs", offset_of!(ReduceParams, lane_runs)),
        ("count", offset_of!(ReduceParams, count)),
        ("sum_base", offset_of!(ReduceParams, sum_base)),
        ("row", offset_of!(ReduceParams, row)),
    ];
    for ((n, o), (rn, ro)) in members.iter().zip(rust) {
        assert_eq!((n.as_str(), *o as usize), (rn, ro));
    }
    // The tiled entry point shares the template's definitions and unrolls nothing.
    let tiled = pairwise::kernel_source(pairwise::KernelShape::TILED, false);
    assert!(tiled.ends_with(pairwise::TILED_SOURCE));
    assert!(tiled.contains("struct PairParams"));
}

/// `const NAME: u32 = VALUEu;` declarations of a WGSL source.
fn u32_consts(src: &str) -> Vec<(String, usize)> {
    src.lines()
        .filter_map(|l| {
            let rest = l.trim().strip_prefix("const ")?;
            let (name, value) = rest.split_once(": u32 = ")?;
            let value = value.strip_suffix("u;")?.parse().ok()?;
            Some((name.to_string(), value))
        })
        .collect()
}

#[test]
fn shared_constants_agree() {
    use brdf_basis::backend::gpu::{
        COMMON_WGSL, TABLE_ABS_COS_P, TABLE_COS_D, TABLE_COS_H, TABLE_LEN, TABLE_SIN_D, TABLE_SIN_H,
    };
    let rust = [
        ("T_COS_H", TABLE_COS_H),
        ("T_SIN_H", TABLE_SIN_H),
        ("T_COS_D", TABLE_COS_D),
        ("T_SIN_D", TABLE_SIN_D),
        ("T_ABS_COS_P", TABLE_ABS_COS_P),
        ("T_LEN", TABLE_LEN),
        ("TEX_W", brdf_basis::backend::gpu::TEX_W),
    ];
    let wgsl = u32_consts(COMMON_WGSL);
    assert_eq!(
        wgsl,
        rust.iter()
            .map(|(n, v)| (n.to_string(), *v))
            .collect::<Vec<_>>(),
        "crates/gpu/src/common.wgsl against crates/gpu/src/lib.rs"
    );
    // Each table row is 90 (theta) or 180 (phi_d) entries, in order, without overlap.
    let rows = [
        (TABLE_COS_H, 90),
        (TABLE_SIN_H, 90),
        (TABLE_COS_D, 90),
        (TABLE_SIN_D, 90),
        (TABLE_ABS_COS_P, 180),
    ];
    for w in rows.windows(2) {
        assert_eq!(w[0].0 + w[0].1, w[1].0);
    }
    assert_eq!(TABLE_ABS_COS_P + 180, TABLE_LEN);
    // Every shared constant and function is used by some kernel: nothing dead in common.
    let kernels = [
        tabulate::SOURCE.to_string(),
        pairwise::kernel_source(pairwise::KernelShape::HARDWARE, false),
        pgd::kernel_source(6),
    ];
    let mut names: Vec<String> = wgsl.into_iter().map(|(n, _)| n).collect();
    names.extend(COMMON_WGSL.lines().filter_map(|l| {
        let rest = l.trim().strip_prefix("fn ")?;
        Some(rest.split('(').next()?.to_string())
    }));
    names.extend(COMMON_WGSL.lines().filter_map(|l| {
        Some(
            l.trim()
                .strip_prefix("struct ")?
                .trim_end_matches(" {")
                .to_string(),
        )
    }));
    for n in &names {
        let used = kernels.iter().any(|k| k.contains(n.as_str()))
            || COMMON_WGSL.matches(n.as_str()).count() > 1;
        assert!(used, "`{n}` in common.wgsl is used by no kernel");
    }
    // And the grid tables hold what the kernels expect at each offset.
    let g = brdf_basis::merl::GridTables::new();
    let t = brdf_basis::backend::gpu::grid_table_f32(&g);
    assert_eq!(t.len(), TABLE_LEN);
    for i in 0..90 {
        assert_eq!(t[TABLE_COS_H + i], g.cos_h[i] as f32);
        assert_eq!(t[TABLE_SIN_H + i], g.sin_h[i] as f32);
        assert_eq!(t[TABLE_COS_D + i], g.cos_d[i] as f32);
        assert_eq!(t[TABLE_SIN_D + i], g.sin_d[i] as f32);
    }
    for k in 0..180 {
        assert_eq!(t[TABLE_ABS_COS_P + k], g.abs_cos_p[k] as f32);
    }
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

#[test]
fn flip_shader_validates_and_matches_rust_structs() {
    use brdf_basis::backend::gpu::flip::{FlipUniforms, SOURCE};
    let (m, _) = module(SOURCE);
    let (span, members) = layout(&m, "FlipUniforms");
    assert_eq!(span as usize, size_of::<FlipUniforms>());
    let rust = [
        ("width", offset_of!(FlipUniforms, width)),
        ("height", offset_of!(FlipUniforms, height)),
        ("pairs", offset_of!(FlipUniforms, pairs)),
        ("rs", offset_of!(FlipUniforms, rs)),
        ("rf", offset_of!(FlipUniforms, rf)),
        ("cmax", offset_of!(FlipUniforms, cmax)),
        ("pccmax", offset_of!(FlipUniforms, pccmax)),
        ("_pad", offset_of!(FlipUniforms, _pad)),
    ];
    assert_eq!(members.len(), rust.len());
    for ((n, o), (rn, ro)) in members.iter().zip(rust) {
        assert_eq!((n.as_str(), *o as usize), (rn, ro));
    }
}
