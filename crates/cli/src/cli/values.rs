//! The command line's names for the library's settings enums: one `clap::ValueEnum`
//! mirror per enum (the library has no clap), converted both ways. Each mirror's
//! variants are the library's, in its order, with its docs (clap shows them in `--help`);
//! the conversions match every variant, so a variant added to the library does not
//! compile here until it is named, and a unit test checks that every name is the
//! library's spelling.

use brdf_basis::acquire::Criterion;
use brdf_basis::backend::weighted::ObjectiveKind;
use brdf_basis::backend::BackendChoice;
use brdf_basis::fit::{GramMode, Solver};
use brdf_basis::merl::{Mask, Weighting};
use brdf_basis::run::SelectMethod;

/// `pub(crate) enum $arg` deriving `clap::ValueEnum`, with the variants of the library's
/// `$lib`, and `From` both ways.
macro_rules! mirror {
    ($(#[$m:meta])* $arg:ident => $lib:ident { $($(#[$vm:meta])* $v:ident,)+ }) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
        pub(crate) enum $arg {
            $($(#[$vm])* $v,)+
        }

        impl From<$arg> for $lib {
            fn from(a: $arg) -> Self {
                match a {
                    $($arg::$v => $lib::$v,)+
                }
            }
        }

        impl From<$lib> for $arg {
            fn from(l: $lib) -> Self {
                match l {
                    $($lib::$v => $arg::$v,)+
                }
            }
        }
    };
}

mirror! {
    /// `--backend`.
    BackendArg => BackendChoice {
        /// On a hardware GPU, each operation on the back-end measured faster for it
        /// (`brdf-basis info` prints which); else the CPU back-end (faster than a software
        /// rasteriser: ~18 G abs-diffs/s on 2 cores against ~4 for lavapipe).
        Auto,
        /// The GPU back-end on the best adapter, software ones (lavapipe) included.
        Gpu,
        /// The multi-threaded CPU back-end.
        Cpu,
    }
}

mirror! {
    /// `--mask`.
    MaskArg => Mask {
        /// Valid cells with theta_i, theta_o <= 80 deg and 2 theta_d >= 3 deg (paper VI-E).
        Evaluation,
        /// Every valid cell (both directions above the horizon).
        Valid,
    }
}

mirror! {
    /// `--weighting`.
    WeightingArg => Weighting {
        /// Every cell of the mask weighs 1 (the paper's Eq. 5).
        Uniform,
        /// A cell weighs the exact measure of its bin (the paper's future work).
        SolidAngle,
    }
}

mirror! {
    /// `--objective`.
    ObjectiveArg => ObjectiveKind {
        /// L2 on raw reflectance (SPEC 5, the paper's).
        L2,
        /// Relative: weights `1 / (f + eps)^2`.
        Relative,
        /// Log: weights `(c / (1 + f c))^2`.
        Log,
    }
}

mirror! {
    /// `fit --solver`.
    SolverArg => Solver {
        /// Exact active-set Lawson-Hanson (f64).
        Exact,
        /// Accelerated projected gradient, batched over targets; targets whose KKT violation
        /// stays above tolerance are re-solved exactly.
        Pgd,
    }
}

mirror! {
    /// `fit --gram`.
    GramArg => GramMode {
        /// The separable closed form (module `separable`) when every lobe is analytic, else
        /// the back-end's grid pass.
        Auto,
        /// Always the back-end's pass over the grid (GPU kernel or CPU twin).
        Grid,
    }
}

mirror! {
    /// `plan --criterion`, `cv --acquisition --plans`.
    CriterionArg => Criterion {
        /// Greedy on the mean training score.
        Error,
        /// Greedy on the condition number of the sampled design.
        Condition,
        /// Uniform random candidates.
        Random,
        /// The peer baseline of Nielsen et al. 2015 (its own PCA of the training materials, no
        /// basis).
        Nielsen,
    }
}

mirror! {
    /// `select --method`.
    MethodArg => SelectMethod {
        /// The paper's Algorithm 1 (leave-one-out contributions).
        Empirical,
        /// k-medoids on the distance matrix, seeded runs per k.
        Kmedoids,
        /// GCUK (genetic clustering for unknown k) on the distance matrix.
        Gcuk,
        /// Greedy forward selection by fitting error (SPEC 8).
        Greedy,
        /// Swap refinement of the greedy basis by fitting error (SPEC 8).
        Swap,
        /// Genetic algorithm over k-subsets by fitting error.
        Ga,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    /// Every name of the mirror `A` is the library's spelling of the value it converts
    /// to, and the mirror has as many values as `all` lists.
    fn same_names<A, L>(all: &[L], spell: impl Fn(L) -> String)
    where
        A: ValueEnum + Copy + Into<L> + From<L>,
        L: Copy + PartialEq + std::fmt::Debug,
    {
        assert_eq!(A::value_variants().len(), all.len());
        for &l in all {
            let a = A::from(l);
            let name = a.to_possible_value().expect("named").get_name().to_string();
            assert_eq!(name, spell(l), "{l:?}");
            assert!(a.into() == l);
        }
    }

    fn serde_name<T: serde::Serialize>(t: T) -> String {
        serde_json::to_value(t)
            .expect("json")
            .as_str()
            .expect("a string")
            .to_string()
    }

    #[test]
    fn the_command_lines_names_are_the_librarys() {
        use BackendChoice as B;
        same_names::<BackendArg, _>(&[B::Auto, B::Gpu, B::Cpu], |b| b.to_string());
        same_names::<MaskArg, _>(&Mask::ALL, |m| m.as_str().to_string());
        same_names::<WeightingArg, _>(&Weighting::ALL, |w| w.as_str().to_string());
        same_names::<ObjectiveArg, _>(&ObjectiveKind::ALL, serde_name);
        same_names::<SolverArg, _>(&Solver::ALL, |s| s.name().to_string());
        same_names::<GramArg, _>(&GramMode::ALL, |g| g.name().to_string());
        // One text form in the library (Python parses with it): names, JSON and parse agree.
        for s in Solver::ALL {
            assert_eq!(
                (serde_name(s), s.name().parse()),
                (s.name().to_string(), Ok(s))
            );
        }
        for g in GramMode::ALL {
            assert_eq!(
                (serde_name(g), g.name().parse()),
                (g.name().to_string(), Ok(g))
            );
        }
        assert!("bogus"
            .parse::<Solver>()
            .unwrap_err()
            .contains("give exact or pgd"));
        assert!("bogus"
            .parse::<GramMode>()
            .unwrap_err()
            .contains("give auto or grid"));
        use Criterion as C;
        let criteria = [C::Error, C::Condition, C::Random, C::Nielsen];
        same_names::<CriterionArg, _>(&criteria, |c| c.as_str().to_string());
        same_names::<MethodArg, _>(&SelectMethod::ALL, |m| m.as_str().to_string());
    }
}
