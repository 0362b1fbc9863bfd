//! Register-block shapes of the pairwise kernel, the cost model that picks one, and the
//! WGSL unrolled for each.

use super::SOURCE;

/// WGSL of the tiled entry point (appended to the definitions of [`SOURCE`]).
pub const TILED_SOURCE: &str = include_str!("pairwise_tiled.wgsl");

/// Register block and workgroup of the pairwise kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KernelShape {
    /// Texels (of 4 rows) per side of a register block: `4R x 4R` pairs.
    pub r: usize,
    /// Canonical lanes per workgroup (`lanes / 8` canonical runs per workgroup).
    pub lanes: usize,
    /// The tiled kernel (`pairwise/pairwise_tiled.wgsl`, [`Self::TILED`]): a workgroup of
    /// 256 invocations stages a 32 x 32 tile's rows in workgroup memory; otherwise one
    /// invocation per lane holds the whole register block.
    pub tiled: bool,
}

/// lavapipe shapes and their rates (G evaluated pair-cells/s, best of three, measured by
/// `BENCH_SHAPES=1 cargo bench --bench distance` on 2 cores of an AMD EPYC with lavapipe
/// 22.3 at N = 100 and 240; one 8-wide SIMD row per workgroup). Smaller blocks re-fetch
/// too often (4 x 4 pairs per invocation ran at 4.7, 8 x 8 at 10.7 in a first probe);
/// 24 x 24 spills.
const SOFTWARE_SHAPES: [(KernelShape, f64); 3] = [
    (KernelShape::register(4, 8), 15.4),
    (KernelShape::register(5, 8), 17.3),
    (KernelShape::register(6, 8), 14.6),
];

/// Hardware shapes and their raw rates (G evaluated pair-cells/s) on an NVIDIA H200
/// (Vulkan, driver 580.159), f64 totals on the device, N = 1,000, evaluation mask, best of
/// three (`BENCH_SHAPES=1 BENCH_SHAPES_N=100,240,1000 cargo bench --bench distance`,
/// scripts/gpu-bench.sh). The register kernel wins at every N measured (100, 240, 1,000:
/// 549 / 1,666 / 2,076 against the tiled kernel's 756 / 1,015 / 1,525, whose staging and
/// barriers cost more than the texel fetches they save: the register kernel's fetches hit
/// the texture cache); the tiled kernel stays a candidate for GPUs whose texture path is
/// slower (its rate here is what the cost model weighs).
const HARDWARE_SHAPES: [(KernelShape, f64); 2] = [
    (KernelShape::HARDWARE, 2076.0),
    (KernelShape::TILED, 1525.0),
];

impl KernelShape {
    /// The register kernel with `4r x 4r` pairs per invocation and `lanes` lanes.
    pub const fn register(r: usize, lanes: usize) -> Self {
        Self {
            r,
            lanes,
            tiled: false,
        }
    }

    /// The register kernel's hardware shape: 8 x 8 pairs (64 f32 accumulators), 64 lanes.
    /// On an NVIDIA H200: 2,066 G abs-diffs/s at N = 1,000 with the f64 totals added on
    /// the device (364 at N = 240 when the host read every partial back).
    pub const HARDWARE: Self = Self::register(2, 64);

    /// The tiled kernel, a hardware candidate ([`HARDWARE_SHAPES`]): 32 x 32 pairs per workgroup of 256
    /// invocations (4 x 8 pairs and one canonical lane each), rows staged in workgroup
    /// memory 64 cells at a time, one canonical run per workgroup.
    pub const TILED: Self = Self {
        r: 8,
        lanes: 8,
        tiled: true,
    };

    /// The shape for `n_rows` packed rows: the one with the least modelled time (padded
    /// pairs / measured rate) among the adapter kind's shapes, so that e.g. 100 rows use
    /// 20 x 20 blocks without padding on lavapipe.
    pub fn choose(n_rows: usize, software: bool) -> Self {
        let cost = |(s, rate): &(KernelShape, f64)| s.evaluated_pairs(n_rows) / rate;
        let shapes: &[(KernelShape, f64)] = match software {
            true => &SOFTWARE_SHAPES,
            false => &HARDWARE_SHAPES,
        };
        shapes
            .iter()
            .min_by(|a, b| cost(a).total_cmp(&cost(b)))
            .map(|s| s.0)
            .unwrap_or(Self::HARDWARE)
    }

    /// Lobe pairs the kernel evaluates per cell for `n_rows` rows (padding included; a
    /// diagonal register block evaluates its texel pairs `i <= j`).
    pub fn evaluated_pairs(&self, n_rows: usize) -> f64 {
        let nb = n_rows.max(1).div_ceil(self.side()) as f64;
        let block = (self.side() * self.side()) as f64;
        let diagonal = match self.tiled {
            true => block,
            false => block * (self.r + 1) as f64 / (2 * self.r) as f64,
        };
        nb * (nb - 1.0) / 2.0 * block + nb * diagonal
    }

    /// Every shape [`Self::choose`] can return.
    pub fn all() -> impl Iterator<Item = Self> {
        SOFTWARE_SHAPES
            .iter()
            .map(|s| s.0)
            .chain([Self::HARDWARE, Self::TILED])
    }

    /// Whether this shape is tuned for a software adapter (longest runs).
    pub fn is_software(&self) -> bool {
        SOFTWARE_SHAPES.iter().any(|s| s.0 == *self)
    }

    /// Lobes per side of a register block (`4R`).
    pub fn side(&self) -> usize {
        4 * self.r
    }
}

/// The kernel for `shape`: the template with `R` and `LANES` defined and its `//@` lines
/// expanded into the unrolled register block. `diagonal`: the variant for register blocks
/// on the diagonal (`I = J`), which fetches the `R` texels once and accumulates only the
/// texel pairs `(i <= j)` (the rest mirror them).
/// The tiled shape has one kernel for both (its diagonal tiles evaluate every pair).
pub fn kernel_source(shape: KernelShape, diagonal: bool) -> String {
    if shape.tiled {
        let defs = &SOURCE[..SOURCE.find("@compute").expect("the template's entry point")];
        return format!("{defs}{TILED_SOURCE}");
    }
    assert!(
        shape
            .lanes
            .is_multiple_of(brdf_basis_core::backend::cpu::CANONICAL_LANES),
        "lanes of a workgroup come in whole canonical runs"
    );
    let (r, side) = (shape.r, shape.side());
    const XYZW: [char; 4] = ['x', 'y', 'z', 'w'];
    // Accumulator (row i of the block, texel j of the columns) is computed?
    let live = |i: usize, j: usize| !diagonal || i / 4 <= j;
    let mut out = format!(
        "const R: u32 = {r}u;\nconst LANES: u32 = {}u;\n",
        shape.lanes
    );
    for line in SOURCE.lines() {
        let indent = &line[..line.len() - line.trim_start().len()];
        let mut emit = |s: String| {
            out.push_str(indent);
            out.push_str(&s);
            out.push('\n');
        };
        let pairs = || (0..side).flat_map(|i| (0..r).map(move |j| (i, j)));
        match line.trim() {
            "//@DECLARE" => pairs()
                .filter(|&(i, j)| live(i, j))
                .for_each(|(i, j)| emit(format!("var acc_{i}_{j} = vec4<f32>(0.0);"))),
            "//@SOURCES" => {
                (0..r).for_each(|i| emit(format!("let sa{i} = source(ra + {i}u);")));
                if !diagonal {
                    (0..r).for_each(|j| emit(format!("let sb{j} = source(rb + {j}u);")));
                }
            }
            "//@FETCH" => {
                (0..r).for_each(|i| emit(format!("let a{i} = rows(sa{i}, c, e, info.y, info.z);")));
                (0..r).for_each(|j| {
                    emit(if diagonal {
                        format!("let b{j} = a{j};")
                    } else {
                        format!("let b{j} = rows(sb{j}, c, e, info.y, info.z);")
                    })
                });
            }
            "//@ACCUMULATE" => pairs().filter(|&(i, j)| live(i, j)).for_each(|(i, j)| {
                emit(format!(
                    "acc_{i}_{j} = step(acc_{i}_{j}, a{}.{}, b{j});",
                    i / 4,
                    XYZW[i % 4]
                ))
            }),
            "//@STORE" => pairs().filter(|&(i, j)| live(i, j)).for_each(|(i, j)| {
                (0..4).for_each(|q| {
                    emit(format!(
                        "partial[o + {}u] = acc_{i}_{j}.{};",
                        i * side + 4 * j + q,
                        XYZW[q]
                    ))
                })
            }),
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    out
}
