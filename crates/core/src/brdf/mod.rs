//! BRDF models: analytic ones and neural BRDFs (`nbrdf`). One file per model; shared pieces (Fresnel) in their own module.

pub mod ashikhmin_shirley;
pub mod fresnel;
pub mod lobe;
pub mod nbrdf;

pub use ashikhmin_shirley::AshikhminShirley;
pub use lobe::LobeParams;
pub use nbrdf::{Nbrdf, NBRDF_WEIGHTS};
