//! The implicit time transformation behind a [`Scheme`]: its drivers on the
//! extended system of `N + 1` coordinates, named for each `N` by a sealed
//! trait, [`Extended`], implemented for `Dim<1>` … `Dim<1024>` (see
//! [`MAX_PROBLEM_N`] and [`crate::dim`]).
//!
//! A run-time `match N` over the candidates would instantiate every arm
//! for every size (each arm a whole integrator, refused at compile time
//! where `M ≠ N + 1`); through the table only the sizes a program uses are
//! instantiated, and for each only when its scheme is matched. A larger
//! compile-time size is a compile error naming the run-time size and the
//! drivers.

use super::scheme::{OnePoint, Scheme};
#[cfg(doc)]
use super::support::MAX_PROBLEM_N;
use crate::dense::{Hermite, Node};
use crate::derivatives::Segment;
use crate::dim::{Dim, ExtendedSize, Sealed};
use crate::discrete::{Midpoint, Trapezoid};
use crate::error::Error;
use crate::galerkin::{Galerkin, GalerkinIntegrator, Quadrature};
use crate::integrator::{Integrator, Stats};
use crate::newton::NewtonOptions;
use crate::sensitivity::Parametric;
use crate::sensitivity::energy;
use crate::sensitivity::linearisation::{Piece, Rule};
use crate::sensitivity::transformed::{self, Linear, Start};
use crate::solution::Stepping;
use crate::state::State;
use crate::system::Lagrangian;
use crate::time_transform::{Adaptive, Curvature, SStepper, TimeTransformed};

/// The transformed system in `s`.
type Tt<S, const N: usize> = TimeTransformed<S, Curvature, N>;

/// The adaptive driver around a one-point rule `R`.
type OnePointIn<S, R, const N: usize, const M: usize> = Adaptive<Integrator<Tt<S, N>, R, M>, S, Curvature, N, M>;

/// The adaptive driver around the Galerkin rule of degree `D`.
type GalerkinIn<S, const N: usize, const M: usize, const D: usize> =
    Adaptive<GalerkinIntegrator<Tt<S, N>, M, D, D>, S, Curvature, N, M>;

/// The implicit time-transformed driver of a [`Scheme::TimeTransformed`],
/// `N` physical and `M = N + 1` extended coordinates: one variant per
/// method in `s`.
// The variants are the drivers themselves, of their own sizes: one is
// built per run and never moved in the stepping loop, and a box would add
// an indirection to every step.
#[allow(clippy::large_enum_variant)]
#[derive(Clone)]
pub enum Transformed<S, const N: usize, const M: usize> {
    /// Midpoint in `s`.
    Midpoint(OnePointIn<S, Midpoint, N, M>),
    /// Trapezoid in `s`.
    Trapezoid(OnePointIn<S, Trapezoid, N, M>),
    /// α-β in `s`.
    AlphaBeta(OnePointIn<S, crate::discrete::AlphaBeta, N, M>),
    /// Galerkin s = 2 in `s`.
    Galerkin2(GalerkinIn<S, N, M, 2>),
    /// Galerkin s = 3 in `s`.
    Galerkin3(GalerkinIn<S, N, M, 3>),
    /// Galerkin s = 4 in `s`.
    Galerkin4(GalerkinIn<S, N, M, 4>),
}

/// Runs `$body` with `$d` bound to the driver of whichever variant `$x` is.
macro_rules! each {
    ($x:expr, $d:ident => $body:expr) => {
        match $x {
            Transformed::Midpoint($d) => $body,
            Transformed::Trapezoid($d) => $body,
            Transformed::AlphaBeta($d) => $body,
            Transformed::Galerkin2($d) => $body,
            Transformed::Galerkin3($d) => $body,
            Transformed::Galerkin4($d) => $body,
        }
    };
}

impl<S: Lagrangian<N>, const N: usize, const M: usize> Transformed<S, N, M> {
    /// Starts the driver of `inner` in `s` (the schemes
    /// [`supports`](super::supports) accepts around a time transformation).
    #[allow(clippy::too_many_arguments)]
    fn start(
        system: S,
        inner: &Scheme,
        density: Curvature,
        sigma: f64,
        newton: Option<NewtonOptions>,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
    ) -> Result<Self, Error>
    where
        Dim<N>: ExtendedSize<M>,
    {
        let tt = TimeTransformed::new(system, density);
        macro_rules! go {
            ($builder:expr, $variant:ident) => {{
                let b = $builder;
                let b = match newton {
                    Some(o) => b.newton(o),
                    None => b,
                };
                b.start::<M>(t0, q0, v0).map(Transformed::$variant)
            }};
        }
        match inner {
            Scheme::OnePoint(OnePoint::Midpoint) => go!(tt.rule(Midpoint, sigma), Midpoint),
            Scheme::OnePoint(OnePoint::Trapezoid) => go!(tt.rule(Trapezoid, sigma), Trapezoid),
            Scheme::OnePoint(OnePoint::AlphaBeta(m)) => go!(tt.rule(*m, sigma), AlphaBeta),
            Scheme::Galerkin { degree: 2, nodes, .. } => {
                go!(tt.galerkin(Galerkin::<2, 2>::new(*nodes, Quadrature::gauss_legendre()), sigma), Galerkin2)
            }
            Scheme::Galerkin { degree: 3, nodes, .. } => {
                go!(tt.galerkin(Galerkin::<3, 3>::new(*nodes, Quadrature::gauss_legendre()), sigma), Galerkin3)
            }
            Scheme::Galerkin { degree: 4, nodes, .. } => {
                go!(tt.galerkin(Galerkin::<4, 4>::new(*nodes, Quadrature::gauss_legendre()), sigma), Galerkin4)
            }
            _ => Err(Error::Unsupported { what: "this method in `s` under the time transformation" }),
        }
    }
}

/// The derivatives of a run: each variant's last step as a Galerkin step
/// in `s` (`sensitivity/transformed.rs` linearises it).
impl<S: Lagrangian<N>, const N: usize, const M: usize> Transformed<S, N, M> {
    /// The transformed system in `s`.
    fn transformed(&self) -> &Tt<S, N> {
        each!(self, d => d.inner().transformed())
    }

    /// The current node in `s`: `[s, x (M), p̃ (M)]`.
    fn node(&self) -> Vec<f64> {
        let x = each!(self, d => d.extended_state());
        core::iter::once(x.t).chain(x.q).chain(x.p).collect()
    }

    /// The rule in `s` and the last step, from the node `from` (of
    /// [`node`](Self::node)) to the current one, as a Galerkin step; `None`
    /// where the step was not kept.
    fn last_step(&self, from: &[f64]) -> Option<(Rule, Piece<M>)> {
        let segment = |to: State<M>| {
            let x0: [f64; M] = core::array::from_fn(|i| from[1 + i]);
            Piece::segment(&Segment::between((from[0], x0), (to.t, to.q)))
        };
        macro_rules! kept {
            ($d:expr) => {{
                let it = $d.inner();
                let l = it.memory.as_ref()?;
                (Rule::galerkin(&it.method), Piece::kept(l.t0, l.h, l.q0, l.carry, &l.d))
            }};
        }
        Some(match self {
            Self::Midpoint(d) => (Rule::one_point(&OnePoint::Midpoint), segment(d.extended_state())),
            Self::Trapezoid(d) => (Rule::one_point(&OnePoint::Trapezoid), segment(d.extended_state())),
            Self::AlphaBeta(d) => {
                (Rule::one_point(&OnePoint::AlphaBeta(d.inner().method)), segment(d.extended_state()))
            }
            Self::Galerkin2(d) => kept!(d),
            Self::Galerkin3(d) => kept!(d),
            Self::Galerkin4(d) => kept!(d),
        })
    }

    /// Whether the last step was a landing step (its size solved for its
    /// end time).
    fn landed(&self) -> bool {
        each!(self, d => d.landed_here())
    }
}

/// Every variant through the one stepper trait; dense output by the cubic
/// Hermite in physical time, as each driver's own.
impl<S: Lagrangian<N>, const N: usize, const M: usize> Stepping<N> for Transformed<S, N, M> {
    type System = S;
    type Native = Hermite<N>;

    fn system(&self) -> &S {
        each!(self, d => Stepping::system(d))
    }

    fn state(&self) -> State<N> {
        each!(self, d => Stepping::state(d))
    }

    fn velocity(&self) -> Result<[f64; N], Error> {
        each!(self, d => Stepping::velocity(d))
    }

    fn stats(&self) -> Stats {
        each!(self, d => Stepping::stats(d))
    }

    fn step(&mut self) -> Result<(), Error> {
        each!(self, d => Stepping::step(d))
    }

    fn step_toward(&mut self, t_end: f64, last_h: Option<f64>) -> Result<(), Error> {
        each!(self, d => Stepping::step_toward(d, t_end, last_h))
    }

    fn land(&mut self, t: f64) -> Result<(), Error> {
        each!(self, d => Stepping::land(d, t))
    }

    fn native(&self, start: &Node<N>, end: &Node<N>) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

/// The sizes `N` (1 to [`MAX_PROBLEM_N`]) a [`Problem`](super::Problem)
/// can step: for each, the extended system of `N + 1` coordinates of a
/// [`Scheme::TimeTransformed`]. Sealed and implemented for every such
/// `Dim<N>`, so a program with a literal size never names it.
#[diagnostic::on_unimplemented(
    message = "`Problem` steps compile-time sizes up to 1024, not {N}",
    note = "state the problem with `Vec<f64>` coordinates (run-time size) or use a driver (`Integrator`, `TimeTransformed`) directly"
)]
pub trait Extended<const N: usize>: Sealed {
    /// The driver, with `M = N + 1`.
    #[doc(hidden)]
    type Transformed<S: Lagrangian<N> + Clone>: Stepping<N, System = S, Native = Hermite<N>> + Clone;

    /// Starts it.
    #[doc(hidden)]
    #[allow(clippy::too_many_arguments)]
    fn start<S: Lagrangian<N> + Clone>(
        system: S,
        inner: &Scheme,
        density: Curvature,
        sigma: f64,
        newton: Option<NewtonOptions>,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
    ) -> Result<Self::Transformed<S>, Error>;

    /// The current node in `s` of `d`: `[s, x, p̃]`.
    #[doc(hidden)]
    fn node<S: Lagrangian<N> + Clone>(d: &Self::Transformed<S>) -> Vec<f64>;

    /// The linearisation of the last step of `d`, from the node `from`
    /// (of [`node`](Self::node)); `None` where it was not kept, a Newton
    /// block is singular or a derivative is not finite.
    #[doc(hidden)]
    fn linearise<S: Parametric<N, P>, const P: usize>(d: &Self::Transformed<S>, from: &[f64]) -> Option<Linear>;

    /// The derivatives of the first node in `s` of a run from `initial`.
    #[doc(hidden)]
    fn start_tangent<S: Parametric<N, P>, const P: usize>(
        d: &Self::Transformed<S>,
        initial: (f64, [f64; N], [f64; N]),
    ) -> Option<Start>;

    /// The linearisation in the extended phase `(q, t, p, −E)` of the
    /// energy-preserving step `seg` of the one-point rule `rule`; `pinned`:
    /// its end time was given (`sensitivity/energy.rs`).
    #[doc(hidden)]
    fn linearise_energy<S: Parametric<N, P>, const P: usize>(
        system: &S,
        rule: &Rule,
        seg: &Segment<N>,
        pinned: bool,
    ) -> Option<Linear>;

    /// The derivatives of the first node `(q_0, t_0, p_0, −E_L)` of an
    /// energy-preserving run from `initial`.
    #[doc(hidden)]
    fn energy_start<S: Parametric<N, P>, const P: usize>(
        system: &S,
        initial: (f64, [f64; N], [f64; N]),
    ) -> Option<Start>;
}

/// The table: `impl Extended<n> for Dim<n>` with `M = n + 1`.
macro_rules! table {
    ($($n:literal)*) => {$(
        impl Extended<$n> for Dim<$n> {
            type Transformed<S: Lagrangian<$n> + Clone> = Transformed<S, $n, { $n + 1 }>;
            fn start<S: Lagrangian<$n> + Clone>(
                system: S,
                inner: &Scheme,
                density: Curvature,
                sigma: f64,
                newton: Option<NewtonOptions>,
                t0: f64,
                q0: [f64; $n],
                v0: [f64; $n],
            ) -> Result<Self::Transformed<S>, Error> {
                Transformed::start(system, inner, density, sigma, newton, t0, q0, v0)
            }
            fn node<S: Lagrangian<$n> + Clone>(d: &Self::Transformed<S>) -> Vec<f64> {
                d.node()
            }
            fn linearise<S: Parametric<$n, P>, const P: usize>(d: &Self::Transformed<S>, from: &[f64]) -> Option<Linear> {
                let (rule, piece) = d.last_step(from)?;
                transformed::linearise::<S, $n, { $n + 1 }, P>(d.transformed(), &rule, &piece, d.landed())
            }
            fn start_tangent<S: Parametric<$n, P>, const P: usize>(
                d: &Self::Transformed<S>,
                initial: (f64, [f64; $n], [f64; $n]),
            ) -> Option<Start> {
                transformed::start::<S, $n, { $n + 1 }, P>(d.transformed(), initial)
            }
            fn linearise_energy<S: Parametric<$n, P>, const P: usize>(
                system: &S,
                rule: &Rule,
                seg: &Segment<$n>,
                pinned: bool,
            ) -> Option<Linear> {
                energy::linearise::<S, $n, { $n + 1 }, P>(system, rule, seg, pinned)
            }
            fn energy_start<S: Parametric<$n, P>, const P: usize>(
                system: &S,
                initial: (f64, [f64; $n], [f64; $n]),
            ) -> Option<Start> {
                energy::start::<S, $n, { $n + 1 }, P>(system, initial)
            }
        }
    )*};
}

crate::dim::sizes!(table);
