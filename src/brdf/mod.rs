//! Analytic BRDF models. One file per model; shared pieces (Fresnel) in their own module.

pub mod ashikhmin_shirley;
pub mod fresnel;
pub mod lobe;

pub use ashikhmin_shirley::AshikhminShirley;
pub use lobe::LobeParams;
