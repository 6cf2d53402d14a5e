//! Runtime of [`lagrangian`](https://docs.rs/lagrangian): discrete Lagrangians,
//! hyper-dual derivatives of the step action and the Newton stepper.
//!
//! Most users depend on the facade crate `lagrangian` and never name this
//! crate; it is separate so that the proc-macro crate and the numerics can be
//! built and tested apart.

pub mod system;

pub use num_dual;
pub use system::{Lagrangian, Scalar};
