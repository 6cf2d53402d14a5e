//! lagrangian: structure-preserving integrators from a Lagrangian written as plain Rust.

pub use lagrangian_macros::lagrangian;
pub use lagrangian_runtime::*;

/// Everything a typical user needs: `use lagrangian::prelude::*;`.
pub mod prelude {
    pub use lagrangian_macros::lagrangian;
    pub use lagrangian_runtime::{Lagrangian, Scalar};
}

/// Paths named by code that `#[lagrangian]` generates. Not a public API.
#[doc(hidden)]
pub mod __private {
    pub use lagrangian_runtime::{Lagrangian, Scalar};
}
