//! Ask for an accuracy, not a method: a solve that chooses the method
//! family, its order and its step from a [`Tolerance`], and reports the
//! error it estimates.
//!
//! Three steps (the guide's page "automatic" has the details):
//!
//! 1. **Choice** ([`choice`]): the family from what `#[lagrangian]` proves
//!    (separability, constant mass, forces, time dependence) and, for
//!    systems the time transformation applies to, a survey of how strongly
//!    the fastest rate `ρ` of the linearisation varies along a pilot orbit;
//!    the order from the tolerance (for a composition the one of fewer
//!    predicted stages, [`choice::composition_order`]: Kahan–Li 8, the
//!    report's fastest at every target, or Yoshida 6 where Kahan–Li 8 would
//!    be held to its step cap).
//! 2. **Pilot** ([`pilot`]): the candidate runs over the first tenth of the
//!    span (a twentieth from `rtol = 1e-5` up; at least one period of the
//!    fastest mode) with `h` and `h/2`;
//!    Richardson's estimate of the global error, extrapolated to the end
//!    with the growth the pilot measures (linear for symplectic methods on
//!    integrable motion), gives the step that meets the tolerance. Where
//!    the survey ran Kahan–Li 8 at its step cap, one Yoshida 6 run at the
//!    same step is measured against it instead (their difference is Yoshida
//!    6's error), and Yoshida 6 runs at the cap when it meets the tolerance.
//!    Error growth faster than quadratic is exponential: when the round-off
//!    amplified over the span already exceeds the tolerance, the solve
//!    refuses ([`Error::Chaotic`](crate::Error::Chaotic)); a tolerance
//!    below the round-off floor of `f64` is refused with
//!    [`Error::ToleranceUnreachable`](crate::Error::ToleranceUnreachable).
//!    A pilot that fails moves on to the next candidate.
//! 3. **Run**: the chosen method with the chosen step through the user's
//!    [`Plan`](crate::Plan); the [`Solution`](crate::Solution) comes back
//!    with the [`Estimate`].

pub mod choice;
pub mod pilot;
mod solve;
mod tolerance;

pub use choice::{Candidate, Facts, Family, Fixed};
pub use pilot::{Cost, Growth};
pub use solve::{Auto, Estimate, Solved, solve_to};
pub use tolerance::Tolerance;
