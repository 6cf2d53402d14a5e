//! The one trait through which the runtime knows a user's system.
//!
//! `#[lagrangian]` implements [`Lagrangian`] for the type of the annotated
//! `impl` block; the runtime never sees the macro otherwise. The trait can also
//! be implemented by hand, which is how the runtime's own tests use it.

use num_dual::{Dual, DualNum};

use crate::structure::{Coupling, ForceCoupling, Separability};
use crate::symmetry::Symmetry;

/// A real scalar the Lagrangian can be evaluated on: `f64` itself or any of
/// num-dual's dual numbers over `f64`.
///
/// Generated code is generic over this trait, so one body serves plain
/// evaluation, first derivatives ([`Dual64`](num_dual::Dual64),
/// [`DualArray`](crate::hyperdual::DualArray)) and the mixed second
/// derivatives of the one-step map ([`HyperDual64`](num_dual::HyperDual64),
/// [`HyperDualArray`](crate::hyperdual::HyperDualArray)).
pub trait Scalar: DualNum<Primitive = f64> + Copy {
    /// `true` for a dual number over plain `f64` with first derivatives
    /// only ([`Dual64`](num_dual::Dual64),
    /// [`DualArray`](crate::hyperdual::DualArray)): the chunks of a long
    /// Lagrangian reach it from their gradient in `f64`
    /// ([`chunk`](crate::chunk)) instead of being compiled for it.
    const FIRST_ORDER: bool = false;

    /// `true` for a number over plain `f64` with exact first and second
    /// derivatives ([`HyperDual64`](num_dual::HyperDual64),
    /// [`HyperDualArray`](crate::hyperdual::HyperDualArray),
    /// [`tape::Var`](crate::tape::Var), and a first-order dual number over
    /// one, `Dual<Dual64>` or `Dual<DualArray<_>>`, whose `ε·εᵢ` parts are
    /// mixed second derivatives): the chunks of a long Lagrangian reach it
    /// from their gradient and Hessian in `f64` ([`chunk`](crate::chunk)).
    const SECOND_ORDER: bool = false;
}

impl<T: DualNum<Primitive = f64> + Copy> Scalar for T {
    const FIRST_ORDER: bool = T::NDERIV == 1 && over_f64::<T>();
    const SECOND_ORDER: bool = T::NDERIV == 2 && over_f64::<T>();
}

/// Whether every part of `T` is a plain `f64`: nested to any depth, its
/// innermost element type has no derivatives and the size of an `f64` (not
/// a [`DoubleDouble`](crate::DoubleDouble), whose values a chunk evaluated
/// in `f64` would round). A number of derivative order at most two whose
/// parts are all `f64` is then exactly the second-order Taylor polynomial
/// `chunk::lift` builds: the product of any three of its parts with a zero
/// real part vanishes, whether the two orders come from one number
/// (`HyperDual64`) or from nesting (`Dual<Dual64>`).
const fn over_f64<T: DualNum>() -> bool {
    if T::NDERIV == 0 { core::mem::size_of::<T>() == core::mem::size_of::<f64>() } else { over_f64::<T::InnerDual>() }
}

/// A mechanical (or electromechanical) system with `N` degrees of freedom,
/// described by its Lagrangian `L(t, q, v)`.
///
/// Every method is generic over the [`Scalar`] it is evaluated on. Methods
/// with a default body describe optional parts of the model: a system without
/// dissipation or applied forces leaves them alone.
pub trait Lagrangian<const N: usize> {
    /// `true` when `L` does not depend explicitly on time.
    ///
    /// The generated implementation sets it from the signature of the user's
    /// `lagrangian` method (with or without a `t: f64` argument).
    const AUTONOMOUS: bool;

    /// `CYCLIC[i]` is `true` when `L` does not depend on `q[i]`, so that the
    /// momentum `p[i]` is conserved (Noether, translation of coordinate `i`).
    ///
    /// The macro proves it syntactically: `q[i]` never appears in the body and
    /// `q` is only ever indexed by integer literals. `false` means "not proven",
    /// not "depends".
    const CYCLIC: [bool; N];

    /// Symmetries the user declared with `#[lagrangian(symmetry = ...)]`
    /// (docs/theory.md §7), whose momentum maps the runtime can follow
    /// ([`noether`](crate::noether)). Declared, not proven; empty by default.
    const SYMMETRIES: &'static [Symmetry<N>] = &[];

    /// `true` when `L` may be discontinuous in `(t, q, v)`: a branch, an
    /// index, a bound or a cast that depends on the coordinates, velocities or
    /// time (a potential step, a mass that jumps). Variational integrators
    /// assume a smooth `L`; across a discontinuity the discrete energy jumps
    /// and the trajectory is wrong at first order. `#[lagrangian]` refuses
    /// such a body unless the user acknowledges it with
    /// `#[lagrangian(discontinuous)]`, which sets this; the integrators then
    /// watch the discrete energy for jumps (see
    /// [`Stats::largest_energy_jump`](crate::Stats::largest_energy_jump)).
    const DISCONTINUOUS: bool = false;

    /// Whether `L = ½ vᵀM(q)v − V(t, q)` is proven, and whether `M` is proven
    /// constant ([`Separability`]). A separable system with constant `M` can
    /// be stepped explicitly; one with a quadratic kinetic energy has a
    /// Legendre map linear in `v`.
    ///
    /// `#[lagrangian]` proves it from the syntax of the body (see
    /// `docs/structure.md`): the degree in `v` of every term, and what the
    /// coefficients of the degree-2 terms depend on. The default,
    /// [`Separability::NotProven`], is always correct.
    const SEPARABILITY: Separability = Separability::NotProven;

    /// Which coordinates and velocities enter the Hessian of `L` in `(q, v)`
    /// together: its `q–q`, `q–v` and `v–v` blocks, each diagonal, banded or
    /// general ([`Coupling`]). An entry outside a block's pattern is zero
    /// everywhere; entries inside may or may not be.
    ///
    /// `#[lagrangian]` proves it from the index expressions of the body,
    /// including `q[i + c]` in `for` loops over neighbours; where it cannot,
    /// it says [`Pattern::General`](crate::structure::Pattern::General),
    /// the default.
    const COUPLING: Coupling = Coupling::GENERAL;

    /// The coupling pattern of the Jacobian in `q` and in `v` of the
    /// generalised force `Q − ∂R/∂v` of [`force`](Self::force) and
    /// [`dissipation`](Self::dissipation) ([`ForceCoupling`]). General by
    /// default; `#[lagrangian]` sets it, diagonal when neither method is
    /// given.
    const FORCE_COUPLING: ForceCoupling = ForceCoupling::GENERAL;

    /// The Lagrangian `L(t, q, v)`.
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> D;

    /// `true` when [`dissipation`](Self::dissipation) is provided.
    const HAS_DISSIPATION: bool = false;

    /// Rayleigh dissipation function `R(q, v)`; the force it exerts is `−∂R/∂v`.
    fn dissipation<D: Scalar>(&self, q: [D; N], v: [D; N]) -> D {
        let _ = (q, v);
        D::zero()
    }

    /// `true` when [`force`](Self::force) is provided.
    const HAS_FORCE: bool = false;

    /// Applied generalised forces `Q(t, q, v)` (forces, torques, electromotive forces).
    fn force<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> [D; N] {
        let _ = (t, q, v);
        [D::zero(); N]
    }

    /// The number `M` of holonomic constraints `g(t, q) = 0` the system is
    /// subject to ([`constraints`](Self::constraints)); 0 (none) by default.
    /// `#[lagrangian]` sets it from `fn constraints(&self, [t,] q) -> [f64; M]`.
    /// A constrained system runs only under
    /// [`Constrained`](crate::Constrained) steps, which hold `g = 0` and its
    /// hidden velocity-level form at every node; every other integrator
    /// refuses it at construction.
    const CONSTRAINTS: usize = 0;

    /// `false` when [`constraints`](Self::constraints) depends on time
    /// (the user's method takes `t`).
    const CONSTRAINTS_AUTONOMOUS: bool = true;

    /// The constraint values `g(t, q)`, written into `g`, whose length is
    /// [`CONSTRAINTS`](Self::CONSTRAINTS). Generic over the [`Scalar`] so
    /// that one evaluation on dual numbers seeded on `q` gives the
    /// constraint Jacobian `G = ∂g/∂q`. The default writes nothing.
    #[inline(always)]
    fn constraints<D: Scalar>(&self, t: D, q: &[D; N], g: &mut [D]) {
        let _ = (t, q, g);
    }

    /// `false` where energy-preserving steps are refused whatever the
    /// method: the runtime's own time-transformed systems, whose steps have
    /// a fixed `σ` and whose conserved quantity is not the physical energy.
    /// As a constant, it keeps the energy-step code of every method out of
    /// these systems' compiled steps. Nothing else sets it.
    #[doc(hidden)]
    const ENERGY_STEPS: bool = true;

    /// `true` when [`gradient_q`](Self::gradient_q) is plain `f64` code
    /// written for this system: `#[lagrangian]` sets it when it could
    /// transform the body into reverse-mode (adjoint) code, whose cost is a
    /// small multiple of one evaluation of `L` instead of `N` derivative
    /// components carried through every operation.
    const HAS_GRADIENT: bool = false;

    /// `∂L/∂q(t, q, v)`, written into `out`: what the explicit
    /// Störmer–Verlet path needs per step (`−∇V` for a separable `L`).
    ///
    /// The default evaluates [`lagrangian`](Self::lagrangian) on a dual
    /// number seeded on each `q[i]` in turn (`N` evaluations; the runtime's
    /// explicit path evaluates the body once on array duals instead when
    /// [`HAS_GRADIENT`](Self::HAS_GRADIENT) is false). `#[lagrangian]`
    /// overrides it with generated adjoint code where it can.
    #[inline(always)]
    fn gradient_q(&self, t: f64, q: &[f64; N], v: &[f64; N], out: &mut [f64; N]) {
        let (t, v) = (Dual::from_re(t), v.map(Dual::from_re));
        for i in 0..N {
            let mut qd = q.map(Dual::from_re);
            qd[i].eps = 1.0;
            out[i] = self.lagrangian(t, qd, v).eps;
        }
    }

    /// [`gradient_q`](Self::gradient_q), returning the value of `L` at
    /// `(t, q, v)` too: an explicit step checks with it that `L` is finite at
    /// the node it reaches (`L` can be NaN where its gradient is finite, as
    /// `0·ln(1 − q)` past `q = 1`) without evaluating `L` once more. The
    /// adjoint code computes `L` in its forward sweep anyway.
    ///
    /// The default calls `gradient_q`, then [`lagrangian`](Self::lagrangian).
    /// `#[lagrangian]` writes it as the same code as `gradient_q`, returning
    /// the value its forward sweep computes.
    #[inline(always)]
    fn value_gradient_q(&self, t: f64, q: &[f64; N], v: &[f64; N], out: &mut [f64; N]) -> f64 {
        self.gradient_q(t, q, v, out);
        self.lagrangian(t, *q, *v)
    }

    /// Adds `∂L/∂q(t, q, 0)` to `out` and returns whether `L(t, q, 0)` is
    /// finite: what the explicit steps of large systems need per step, the
    /// force `−∇V` of a separable `L` at the node they reach (into a buffer
    /// they cleared in an earlier pass over the coordinates) and the check
    /// of `L` there.
    ///
    /// The default adds [`value_gradient_q`](Self::value_gradient_q)'s
    /// gradient at `v = 0` and checks its value. `#[lagrangian]` writes it
    /// as the same code as `value_gradient_q` with every `v[i]` the constant
    /// `0.0` (so the compiler folds away the terms of the velocities alone),
    /// adding instead of clearing `out` first, and with the loops whose sums
    /// only the value of `L` reads summed in four interleaved partial sums:
    /// a loop that also adds to the gradient sums its terms in its reverse
    /// loop (one pass over the coordinates), whose partial sums the value
    /// adds at the end; one that does not keeps a forward loop of its own
    /// (which vectorises). Such sums enter `L` linearly; reassociated, they
    /// round differently, but the value is finite exactly when `L` summed in
    /// order is, except at overflow: where the ordered sum passes `f64::MAX`
    /// on its way and comes back (or a partial sum, or the value's last
    /// additions, do and the ordered one does not), the two checks differ.
    #[inline(always)]
    fn add_gradient_q_at_rest(&self, t: f64, q: &[f64; N], out: &mut [f64; N]) -> bool {
        let mut gradient = [0.0; N];
        let l = self.value_gradient_q(t, q, &[0.0; N], &mut gradient);
        for (o, g) in out.iter_mut().zip(gradient) {
            *o += g;
        }
        l.is_finite()
    }

    /// `true` when [`gradient_qv`](Self::gradient_qv) is plain `f64` code
    /// and [`gradient_qv_scalar`](Self::gradient_qv_scalar) the same code
    /// generic over the scalar, written for this system (set by
    /// `#[lagrangian]` with [`HAS_GRADIENT`](Self::HAS_GRADIENT)).
    const HAS_GRADIENT_QV: bool = false;

    /// `∂L/∂q` into `out_q` and `∂L/∂v` into `out_v`, at `(t, q, v)`: what
    /// the residual of an implicit step needs at each quadrature point.
    ///
    /// The default evaluates [`lagrangian`](Self::lagrangian) on a dual
    /// number seeded on each coordinate in turn (`2N` evaluations; the
    /// runtime evaluates the body once on array duals instead when
    /// [`HAS_GRADIENT_QV`](Self::HAS_GRADIENT_QV) is false). `#[lagrangian]`
    /// overrides it with generated adjoint code where it can.
    #[inline(always)]
    fn gradient_qv(&self, t: f64, q: &[f64; N], v: &[f64; N], out_q: &mut [f64; N], out_v: &mut [f64; N]) {
        self.gradient_q(t, q, v, out_q);
        let (t, q) = (Dual::from_re(t), q.map(Dual::from_re));
        for i in 0..N {
            let mut vd = v.map(Dual::from_re);
            vd[i].eps = 1.0;
            out_v[i] = self.lagrangian(t, q, vd).eps;
        }
    }

    /// `∂L/∂q` into `out_q` and `∂L/∂v` into `out_v` at `(t, q, v)` on any
    /// [`Scalar`]; all four slices have `N` entries.
    ///
    /// On dual numbers this is forward over reverse: with `q` and `v`
    /// carrying a direction `(δq, δv)`, the derivative parts of the outputs
    /// are the Hessian-vector product `∇²L·(δq, δv)` (in `q` and `v`), what
    /// the Newton matrix of an implicit step is assembled from, one colour
    /// class of columns at a time. `#[lagrangian]` writes it as the same
    /// adjoint code as [`gradient_qv`](Self::gradient_qv), generic over the
    /// scalar, and sets [`HAS_GRADIENT_QV`](Self::HAS_GRADIENT_QV).
    ///
    /// The default evaluates [`lagrangian`](Self::lagrangian) on dual
    /// numbers over `D`, seeded on each coordinate in turn (`2N`
    /// evaluations): correct, but the runtime uses this method only when
    /// `HAS_GRADIENT_QV` is set. Slices shorter than `N` panic (indexing).
    #[inline]
    fn gradient_qv_scalar<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) {
        let t = Dual::from_re(t);
        let qd: [Dual<D>; N] = core::array::from_fn(|i| Dual::from_re(q[i]));
        let vd: [Dual<D>; N] = core::array::from_fn(|i| Dual::from_re(v[i]));
        for i in 0..N {
            let mut x = qd;
            x[i].eps = D::one();
            out_q[i] = self.lagrangian(t, x, vd).eps;
        }
        for i in 0..N {
            let mut x = vd;
            x[i].eps = D::one();
            out_v[i] = self.lagrangian(t, qd, x).eps;
        }
    }

    /// [`gradient_qv_scalar`](Self::gradient_qv_scalar), returning the value
    /// of `L` at `(t, q, v)` too: an implicit step checks with it that the
    /// action it solves for is finite (`L` can be NaN where its derivatives
    /// are finite, as `ln(1 − q)` past `q = 1` on the wrong branch) without
    /// evaluating `L` once more. The adjoint code computes `L` in its
    /// forward sweep anyway.
    ///
    /// The default calls `gradient_qv_scalar`, then
    /// [`lagrangian`](Self::lagrangian). `#[lagrangian]` writes it as the
    /// same code as `gradient_qv_scalar`, returning the value its forward
    /// sweep computes.
    #[inline]
    fn value_gradient_qv_scalar<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) -> D {
        self.gradient_qv_scalar(t, q, v, out_q, out_v);
        self.lagrangian(t, core::array::from_fn(|i| q[i]), core::array::from_fn(|i| v[i]))
    }
}

/// A borrowed system is the same system (the integrator borrows it to run a
/// one-point rule as a Galerkin rule in another real type).
impl<S: Lagrangian<N> + ?Sized, const N: usize> Lagrangian<N> for &S {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const CYCLIC: [bool; N] = S::CYCLIC;
    const SYMMETRIES: &'static [Symmetry<N>] = S::SYMMETRIES;
    const DISCONTINUOUS: bool = S::DISCONTINUOUS;
    const HAS_DISSIPATION: bool = S::HAS_DISSIPATION;
    const HAS_FORCE: bool = S::HAS_FORCE;
    const SEPARABILITY: Separability = S::SEPARABILITY;
    const COUPLING: Coupling = S::COUPLING;
    const FORCE_COUPLING: ForceCoupling = S::FORCE_COUPLING;
    const ENERGY_STEPS: bool = S::ENERGY_STEPS;

    #[inline(always)]
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> D {
        (**self).lagrangian(t, q, v)
    }

    #[inline(always)]
    fn dissipation<D: Scalar>(&self, q: [D; N], v: [D; N]) -> D {
        (**self).dissipation(q, v)
    }

    #[inline(always)]
    fn force<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> [D; N] {
        (**self).force(t, q, v)
    }

    const HAS_GRADIENT: bool = S::HAS_GRADIENT;

    #[inline(always)]
    fn gradient_q(&self, t: f64, q: &[f64; N], v: &[f64; N], out: &mut [f64; N]) {
        (**self).gradient_q(t, q, v, out);
    }

    #[inline(always)]
    fn value_gradient_q(&self, t: f64, q: &[f64; N], v: &[f64; N], out: &mut [f64; N]) -> f64 {
        (**self).value_gradient_q(t, q, v, out)
    }

    #[inline(always)]
    fn add_gradient_q_at_rest(&self, t: f64, q: &[f64; N], out: &mut [f64; N]) -> bool {
        (**self).add_gradient_q_at_rest(t, q, out)
    }

    const HAS_GRADIENT_QV: bool = S::HAS_GRADIENT_QV;

    #[inline(always)]
    fn gradient_qv(&self, t: f64, q: &[f64; N], v: &[f64; N], out_q: &mut [f64; N], out_v: &mut [f64; N]) {
        (**self).gradient_qv(t, q, v, out_q, out_v);
    }

    #[inline(always)]
    fn gradient_qv_scalar<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) {
        (**self).gradient_qv_scalar(t, q, v, out_q, out_v);
    }

    #[inline(always)]
    fn value_gradient_qv_scalar<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) -> D {
        (**self).value_gradient_qv_scalar(t, q, v, out_q, out_v)
    }
}

/// A system whose number of degrees of freedom is known only at run time (a
/// chain built from data, a lattice read from a file), described by its
/// Lagrangian `L(t, q, v)` over slices.
///
/// It is the run-time-sized twin of [`Lagrangian`]: `#[lagrangian]` implements
/// it when the user's `lagrangian` takes `q: &[f64], v: &[f64]` (and the impl
/// block has `fn dimension(&self) -> usize`), with the same checks and the
/// same structure analysis. Why a second trait: [`Lagrangian`] passes
/// `[D; N]` by value, which a const `N` of 10⁵ cannot afford on a 2 MiB
/// thread stack, and whose monomorphised forward-mode derivatives make the
/// compile time grow with `N`. Slices live on the heap and have one
/// compiled body for every size.
///
/// What is not here: `CYCLIC` (a slice system's cyclic coordinates would be
/// a run-time set) and declared symmetries. Such systems are stepped in
/// reverse mode only (docs/large-systems.md).
pub trait DynLagrangian {
    /// `true` when `L` does not depend explicitly on time (see
    /// [`Lagrangian::AUTONOMOUS`]).
    const AUTONOMOUS: bool;

    /// `true` when `L` may be discontinuous (see
    /// [`Lagrangian::DISCONTINUOUS`]).
    const DISCONTINUOUS: bool = false;

    /// What the macro proved about the form of `L` (see
    /// [`Lagrangian::SEPARABILITY`]).
    const SEPARABILITY: Separability = Separability::NotProven;

    /// The coupling pattern of the Hessian of `L` (see
    /// [`Lagrangian::COUPLING`]). A proven bandwidth does not depend on the
    /// dimension: offsets `q[i + c]` bound it.
    const COUPLING: Coupling = Coupling::GENERAL;

    /// The coupling pattern of the Jacobian in `q` and in `v` of the
    /// generalised force `Q − ∂R/∂v` of [`force`](Self::force) and
    /// [`dissipation`](Self::dissipation) (see
    /// [`Lagrangian::FORCE_COUPLING`]): the step's Newton matrix is banded
    /// with the wider of this band and that of [`COUPLING`](Self::COUPLING),
    /// and the force's Jacobian is taken in `2b + 1` compressed directions.
    /// General by default.
    const FORCE_COUPLING: ForceCoupling = ForceCoupling::GENERAL;

    /// The number of coordinates `n`: `q` and `v` passed to
    /// [`lagrangian`](Self::lagrangian) have this length.
    fn dimension(&self) -> usize;

    /// The Lagrangian `L(t, q, v)` with `q.len() == v.len() == self.dimension()`.
    fn lagrangian<D: Scalar>(&self, t: D, q: &[D], v: &[D]) -> D;

    /// `true` when [`dissipation`](Self::dissipation) is provided.
    const HAS_DISSIPATION: bool = false;

    /// The Rayleigh dissipation function `R(q, v)`, with `q.len() == v.len()
    /// == self.dimension()`; the force it exerts is `−∂R/∂v`. The runtime
    /// records it on its tape (one reverse sweep gives the force, a
    /// compressed second-order sweep its Jacobian), so a banded `R` costs
    /// `O(n)` per step. Zero by default.
    fn dissipation<D: Scalar>(&self, q: &[D], v: &[D]) -> D {
        let _ = (q, v);
        D::zero()
    }

    /// `true` when [`force`](Self::force) is provided.
    const HAS_FORCE: bool = false;

    /// The applied generalised forces `Q(t, q, v)` written into `f`, which
    /// arrives filled with zeros; all three slices have
    /// `self.dimension()` entries. Generic over the [`Scalar`]: the runtime
    /// takes the force's Jacobian by evaluating it on dual numbers seeded
    /// in `2b + 1` compressed directions for a force whose
    /// [`FORCE_COUPLING`](Self::FORCE_COUPLING) is banded (`n` otherwise).
    /// The default writes nothing.
    fn force<D: Scalar>(&self, t: D, q: &[D], v: &[D], f: &mut [D]) {
        let _ = (t, q, v, f);
    }

    /// The number `M` of holonomic constraints `g(t, q) = 0` (see
    /// [`Lagrangian::CONSTRAINTS`]); 0 (none) by default. A constrained
    /// run-time-sized system runs only under
    /// [`DynConstrained`](crate::DynConstrained), which finds
    /// the structure of `G = ∂g/∂q` by itself and solves the steps of a
    /// banded one in `O(n)`; [`Problem`](crate::Problem) at a run-time size
    /// refuses it.
    fn constraint_count(&self) -> usize {
        0
    }

    /// `false` when [`constraints`](Self::constraints) depends on time.
    const CONSTRAINTS_AUTONOMOUS: bool = true;

    /// The constraint values `g(t, q)` written into `g`, of length
    /// [`constraint_count`](Self::constraint_count); generic over the
    /// [`Scalar`] so that dual numbers seeded on `q` give `G`. The default
    /// writes nothing.
    fn constraints<D: Scalar>(&self, t: D, q: &[D], g: &mut [D]) {
        let _ = (t, q, g);
    }

    /// `true` when [`gradient_q`](Self::gradient_q) is generated adjoint
    /// code (see [`Lagrangian::HAS_GRADIENT`]).
    const HAS_GRADIENT: bool = false;

    /// `∂L/∂q(t, q, v)` written into `out`, all four of length
    /// `self.dimension()`.
    ///
    /// The default evaluates [`lagrangian`](Self::lagrangian) on a dual
    /// number seeded on each `q[i]` in turn (`n` evaluations of `L`); the
    /// runtime calls this only when [`HAS_GRADIENT`](Self::HAS_GRADIENT) is
    /// set and records `L` on its tape otherwise.
    fn gradient_q(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        let t = Dual::from_re(t);
        let v: Vec<Dual<f64>> = v.iter().map(|&x| Dual::from_re(x)).collect();
        let mut qd: Vec<Dual<f64>> = q.iter().map(|&x| Dual::from_re(x)).collect();
        for (i, out) in out.iter_mut().enumerate().take(q.len()) {
            qd[i].eps = 1.0;
            *out = self.lagrangian(t, &qd, &v).eps;
            qd[i].eps = 0.0;
        }
    }

    /// [`gradient_q`](Self::gradient_q), returning the value of `L` at
    /// `(t, q, v)` too, which an explicit step checks at the node it
    /// reaches (see [`Lagrangian::value_gradient_q`]). The runtime calls
    /// this only when [`HAS_GRADIENT`](Self::HAS_GRADIENT) is set.
    ///
    /// The default calls `gradient_q`, then [`lagrangian`](Self::lagrangian).
    /// `#[lagrangian]` writes it as the same code as `gradient_q`, returning
    /// the value its forward sweep computes.
    fn value_gradient_q(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) -> f64 {
        self.gradient_q(t, q, v, out);
        self.lagrangian(t, q, v)
    }

    /// Adds `∂L/∂q(t, q, 0)` to `out` and returns whether `L(t, q, 0)` is
    /// finite (see [`Lagrangian::add_gradient_q_at_rest`]; the runtime calls
    /// this only when [`HAS_GRADIENT`](Self::HAS_GRADIENT) is set).
    ///
    /// The default adds [`value_gradient_q`](Self::value_gradient_q)'s
    /// gradient at `v = 0`, computed into vectors it allocates, and checks
    /// its value. `#[lagrangian]` writes it as the same code as
    /// `value_gradient_q` with every `v[i]` the constant `0.0`, adding
    /// instead of clearing `out` first, with the loops whose sums only the
    /// value reads reassociated (and summed in their reverse loops where
    /// they have one).
    fn add_gradient_q_at_rest(&self, t: f64, q: &[f64], out: &mut [f64]) -> bool {
        let mut gradient = vec![0.0; out.len()];
        let l = self.value_gradient_q(t, q, &vec![0.0; q.len()], &mut gradient);
        for (o, g) in out.iter_mut().zip(gradient) {
            *o += g;
        }
        l.is_finite()
    }

    /// `true` when [`gradient_qv_scalar`](Self::gradient_qv_scalar) is
    /// generated adjoint code (see [`Lagrangian::HAS_GRADIENT_QV`]).
    const HAS_GRADIENT_QV: bool = false;

    /// `∂L/∂q` into `out_q` and `∂L/∂v` into `out_v` at `(t, q, v)` on any
    /// [`Scalar`], all five slices of length `self.dimension()`; on dual
    /// numbers, Hessian-vector products (see
    /// [`Lagrangian::gradient_qv_scalar`]).
    ///
    /// The default evaluates [`lagrangian`](Self::lagrangian) on dual
    /// numbers over `D` seeded on each coordinate in turn (`2n` evaluations,
    /// allocating); the runtime calls this only when
    /// [`HAS_GRADIENT_QV`](Self::HAS_GRADIENT_QV) is set. Outputs shorter
    /// than the inputs receive only their first entries.
    fn gradient_qv_scalar<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) {
        let t = Dual::from_re(t);
        let mut qd: Vec<Dual<D>> = q.iter().map(|&x| Dual::from_re(x)).collect();
        let mut vd: Vec<Dual<D>> = v.iter().map(|&x| Dual::from_re(x)).collect();
        for (i, out) in out_q.iter_mut().enumerate().take(qd.len()) {
            qd[i].eps = D::one();
            *out = self.lagrangian(t, &qd, &vd).eps;
            qd[i].eps = D::zero();
        }
        for (i, out) in out_v.iter_mut().enumerate().take(vd.len()) {
            vd[i].eps = D::one();
            *out = self.lagrangian(t, &qd, &vd).eps;
            vd[i].eps = D::zero();
        }
    }
}

/// A borrowed run-time-sized system is the same system.
impl<S: DynLagrangian + ?Sized> DynLagrangian for &S {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const DISCONTINUOUS: bool = S::DISCONTINUOUS;
    const SEPARABILITY: Separability = S::SEPARABILITY;
    const COUPLING: Coupling = S::COUPLING;
    const FORCE_COUPLING: ForceCoupling = S::FORCE_COUPLING;
    const HAS_DISSIPATION: bool = S::HAS_DISSIPATION;
    const HAS_FORCE: bool = S::HAS_FORCE;

    #[inline(always)]
    fn dimension(&self) -> usize {
        (**self).dimension()
    }

    #[inline(always)]
    fn lagrangian<D: Scalar>(&self, t: D, q: &[D], v: &[D]) -> D {
        (**self).lagrangian(t, q, v)
    }

    #[inline(always)]
    fn dissipation<D: Scalar>(&self, q: &[D], v: &[D]) -> D {
        (**self).dissipation(q, v)
    }

    #[inline(always)]
    fn force<D: Scalar>(&self, t: D, q: &[D], v: &[D], f: &mut [D]) {
        (**self).force(t, q, v, f);
    }

    fn constraint_count(&self) -> usize {
        (**self).constraint_count()
    }

    const CONSTRAINTS_AUTONOMOUS: bool = S::CONSTRAINTS_AUTONOMOUS;

    #[inline(always)]
    fn constraints<D: Scalar>(&self, t: D, q: &[D], g: &mut [D]) {
        (**self).constraints(t, q, g);
    }

    const HAS_GRADIENT: bool = S::HAS_GRADIENT;

    #[inline(always)]
    fn gradient_q(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        (**self).gradient_q(t, q, v, out);
    }

    #[inline(always)]
    fn value_gradient_q(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) -> f64 {
        (**self).value_gradient_q(t, q, v, out)
    }

    #[inline(always)]
    fn add_gradient_q_at_rest(&self, t: f64, q: &[f64], out: &mut [f64]) -> bool {
        (**self).add_gradient_q_at_rest(t, q, out)
    }

    const HAS_GRADIENT_QV: bool = S::HAS_GRADIENT_QV;

    #[inline(always)]
    fn gradient_qv_scalar<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) {
        (**self).gradient_qv_scalar(t, q, v, out_q, out_v);
    }
}

/// The generalised force `F = Q(t, q, v) − ∂R/∂v(q, v)` on any [`Scalar`].
///
/// `∂R/∂v_i` comes from one evaluation of `R` on a dual number over `D`
/// seeded on `v_i` (`N` evaluations in all). Systems without `force` or
/// `dissipation` get zeros without evaluating anything.
#[inline]
pub fn generalized_force<S, D, const N: usize>(system: &S, t: D, q: [D; N], v: [D; N]) -> [D; N]
where
    S: Lagrangian<N> + ?Sized,
    D: Scalar,
{
    let mut f = if S::HAS_FORCE { system.force(t, q, v) } else { [D::zero(); N] };
    if S::HAS_DISSIPATION {
        let q = q.map(Dual::from_re);
        for i in 0..N {
            let mut vd = v.map(Dual::from_re);
            vd[i].eps = D::one();
            f[i] -= system.dissipation(q, vd).eps;
        }
    }
    f
}
