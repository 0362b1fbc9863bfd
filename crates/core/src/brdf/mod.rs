//! BRDF models: analytic ones and neural BRDFs (`nbrdf`). One file per model; shared pieces (Fresnel) in their own module.

mod ashikhmin_shirley;
pub mod fresnel;
mod lobe;
mod nbrdf;

pub use ashikhmin_shirley::*;
pub use lobe::*;
pub use nbrdf::*;
