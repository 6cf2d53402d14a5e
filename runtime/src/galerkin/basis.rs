//! Lagrange bases on `[0, 1]` for the Galerkin polynomial of one step.
//!
//! The degree-`s` polynomial of a step is written through its values at
//! `s + 1` control nodes `0 = τ_0 < τ_1 < … < τ_s = 1`:
//!
//! ```text
//! q_h(τ) = Σ_{m=0}^{s} ℓ_m(τ) Q_m,      ℓ_m(τ) = Π_{k≠m} (τ − τ_k)/(τ_m − τ_k)
//! ℓ_m'(τ) = Σ_{k≠m} 1/(τ_m − τ_k) · Π_{l≠m,k} (τ − τ_l)/(τ_m − τ_l)
//! ```
//!
//! Both are evaluated in this product ("modified Lagrange", first barycentric)
//! form, which is backward stable (Higham, *IMA J. Numer. Anal.* 24, 2004) and,
//! unlike the second barycentric form, needs no special case where a
//! quadrature point coincides with a control node (Lobatto quadrature on
//! Lobatto nodes). They are evaluated once, when a
//! [`Galerkin`](super::Galerkin) is built, never while stepping.
//!
//! Node families: equispaced `τ_m = m/s` (Chen, Guo & Wu (finite elements) §2.3 uses `0, ½, 1`) or
//! the Gauss–Lobatto points, whose Lebesgue constant grows like `log s`
//! instead of `2^s/(s log s)`, so the interior nodes stay well conditioned
//! at high degree. The discrete trajectory does not depend on the choice (the
//! polynomial space is the same); only the conditioning of the step's Newton
//! block does.

use super::quadrature::gauss_lobatto_into;
use crate::real::Real;

/// Where the control nodes of the step polynomial sit in `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum NodeFamily {
    /// `τ_m = m/s`, as in Chen, Guo & Wu (finite elements).
    Equispaced,
    /// The `s + 1` Gauss–Lobatto points (better conditioned at high degree).
    #[default]
    GaussLobatto,
}

impl NodeFamily {
    /// The `s + 1` control nodes `τ_0 = 0 < … < τ_s = 1`.
    pub(crate) fn nodes<T: Real>(self, s: usize) -> Vec<T> {
        match self {
            NodeFamily::Equispaced => (0..=s).map(|m| T::from(m as f64) / s as f64).collect(),
            NodeFamily::GaussLobatto => lobatto_nodes(s + 1),
        }
    }
}

/// The `n ≥ 2` Gauss–Lobatto points on `[0, 1]`.
fn lobatto_nodes<T: Real>(n: usize) -> Vec<T> {
    let (mut x, mut w) = (vec![T::zero(); n], vec![T::zero(); n]);
    gauss_lobatto_into(&mut x, &mut w);
    x
}

/// `ℓ_m(τ)` for the nodes `x`.
pub(crate) fn lagrange<T: Real>(x: &[T], m: usize, tau: T) -> T {
    (0..x.len()).filter(|&k| k != m).map(|k| (tau - x[k]) / (x[m] - x[k])).product()
}

/// `ℓ_m'(τ)` for the nodes `x`.
pub(crate) fn lagrange_derivative<T: Real>(x: &[T], m: usize, tau: T) -> T {
    (0..x.len())
        .filter(|&k| k != m)
        .map(|k| {
            let rest: T = (0..x.len()).filter(|&l| l != m && l != k).map(|l| (tau - x[l]) / (x[m] - x[l])).product();
            rest / (x[m] - x[k])
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_interpolates_and_differentiates_polynomials() {
        for family in [NodeFamily::Equispaced, NodeFamily::GaussLobatto] {
            for s in 1..=8 {
                let x = family.nodes::<f64>(s);
                assert_eq!(x.len(), s + 1);
                assert_eq!((x[0], x[s]), (0.0, 1.0));
                // p(τ) = (τ − 0.3)^s is reproduced, with its derivative.
                let p = |t: f64| (t - 0.3f64).powi(s as i32);
                let dp = |t: f64| s as f64 * (t - 0.3f64).powi(s as i32 - 1);
                for tau in [0.0, 0.17, 0.5, 0.93, 1.0, 1.6] {
                    let v: f64 = (0..=s).map(|m| lagrange(&x, m, tau) * p(x[m])).sum();
                    let d: f64 = (0..=s).map(|m| lagrange_derivative(&x, m, tau) * p(x[m])).sum();
                    assert!((v - p(tau)).abs() <= 1e-13, "{family:?} s={s} τ={tau}: {v} vs {}", p(tau));
                    assert!((d - dp(tau)).abs() <= 1e-11, "{family:?} s={s} τ={tau}: {d} vs {}", dp(tau));
                }
            }
        }
    }

    #[test]
    fn many_lobatto_nodes_are_increasing() {
        let x = lobatto_nodes::<f64>(40);
        assert_eq!(x.len(), 40);
        assert!(x.windows(2).all(|w| w[0] < w[1]));
    }
}
