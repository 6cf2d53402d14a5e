//! Step densities (monitors) `g(t, q) > 0`: how much physical time one unit
//! of the new independent variable `s` takes.

use num_dual::HyperDual;

use crate::system::{Lagrangian, Scalar};

/// A step density (monitor) `g(t, q) > 0`: the physical time one unit of `s`
/// takes, `dt/ds = g`. Small where the motion is fast.
///
/// `g` enters the transformed Lagrangian, whose derivatives the runtime takes
/// with dual numbers, so the monitor is evaluated on any [`Scalar`] (a plain
/// `f64` closure could not supply its derivatives, and without them the map
/// would not be symplectic). It gets the system too, so a monitor may be
/// computed from the dynamics ([`Curvature`]).
pub trait StepDensity<const N: usize> {
    /// `true` when `g` depends on `t`: then `t` is not cyclic in the
    /// transformed Lagrangian and `p_t` is not conserved.
    const TIME_DEPENDENT: bool = false;

    /// `g(t, q)`.
    fn density<S, D>(&self, system: &S, t: D, q: &[D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar;

    /// `Err` for a monitor that cannot be evaluated for `N` coordinates (an
    /// index out of range); checked before integrating.
    fn check(&self) -> Result<(), &'static str> {
        Ok(())
    }
}

/// `g = |x|^α` with `x` the coordinates at `indices`: for central-force
/// problems `α = 3/2` (steps proportional to the local orbital time scale,
/// `r^{3/2}` for Kepler) or `α = 1`. Rotation invariant when the indices span
/// the rotated plane, so the angular momentum stays conserved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadiusPower<const K: usize> {
    pub(super) indices: [usize; K],
    pub(super) exponent: f64,
}

impl<const K: usize> RadiusPower<K> {
    /// `|x|^exponent` with `x = (q[indices[0]], …)`; `None` for no index or
    /// an exponent that is not finite. Indices out of range are refused by
    /// [`StepDensity::check`] when the integrator starts.
    pub fn new(indices: [usize; K], exponent: f64) -> Option<Self> {
        (K > 0 && exponent.is_finite()).then_some(Self { indices, exponent })
    }
}

impl<const K: usize, const N: usize> StepDensity<N> for RadiusPower<K> {
    #[inline]
    fn density<S, D>(&self, _system: &S, _t: D, q: &[D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let mut r2 = D::zero();
        for &i in &self.indices {
            r2 += q[i] * q[i];
        }
        r2.powf(0.5 * self.exponent)
    }

    fn check(&self) -> Result<(), &'static str> {
        if self.indices.iter().all(|&i| i < N) {
            Ok(())
        } else {
            Err("a coordinate index of the `RadiusPower` monitor is out of range")
        }
    }
}

/// The automatic monitor: `g = (κ² + floor²)^{-1/4}`, with
/// `κ = ‖∂²L/∂q²(t, q, 0)‖_F` the curvature of the potential, so that `g` is
/// the local time scale `1/ω` of small oscillations (for Kepler, `κ = √5/r³`
/// in Cartesian coordinates and `2/r³` in polar ones: `g ∝ r^{3/2}`; for a
/// harmonic oscillator a constant). `floor > 0` (units of `1/time²`) caps
/// the physical step at `σ/√floor` where the potential is flat.
///
/// It depends on `(t, q)` only, so the map stays symplectic and
/// time-reversible, and the Frobenius norm is invariant under rotations of
/// Cartesian coordinates, so a rotation symmetry of `L` is kept. It assumes
/// a roughly constant mass matrix (it reads the potential, not `∂²L/∂v²`).
/// Cost: `N(N+1)/2` evaluations of `L` on nested hyper-duals per call.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Curvature {
    pub(super) floor: f64,
}

impl Curvature {
    /// The automatic monitor with the given floor; `None` unless it is finite and positive.
    pub fn new(floor: f64) -> Option<Self> {
        (floor.is_finite() && floor > 0.0).then_some(Self { floor })
    }
}

impl<const N: usize> StepDensity<N> for Curvature {
    const TIME_DEPENDENT: bool = true;

    fn density<S, D>(&self, system: &S, t: D, q: &[D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        self.of(t, q, |t, q, v| system.lagrangian(t, q, v))
    }
}

impl Curvature {
    /// `g(t, q)` of the Lagrangian `lagrangian` (evaluated on hyper-duals):
    /// the density of [`StepDensity::density`], and of the sensitivities,
    /// which evaluate it with the Lagrangian at parameters `θ`.
    pub(crate) fn of<D: Scalar, const N: usize>(
        &self,
        t: D,
        q: &[D; N],
        lagrangian: impl Fn(HyperDual<D>, [HyperDual<D>; N], [HyperDual<D>; N]) -> HyperDual<D>,
    ) -> D {
        let mut k2 = D::from(self.floor * self.floor);
        let v = [HyperDual::from_re(D::zero()); N];
        for i in 0..N {
            for j in i..N {
                let mut qh = q.map(HyperDual::from_re);
                qh[i].eps1 = D::one();
                qh[j].eps2 = D::one();
                let h = lagrangian(HyperDual::from_re(t), qh, v).eps1eps2;
                k2 += if i == j { h * h } else { h * h * 2.0 };
            }
        }
        k2.powf(-0.25)
    }
}
