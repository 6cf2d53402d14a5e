//! The discrete forces of a Galerkin step on the tape (discrete
//! Lagrange–d'Alembert principle, docs/theory.md §6), for systems whose
//! size is known at run time: the virtual work `∫ F·δq dt` of the
//! interpolated variation `δq = Σ_m ℓ_m δQ_m`, by the step's own
//! quadrature, puts
//!
//! ```text
//! F^ρ = h Σ_j b_j ℓ_ρ(c_j) F(t_j, q(c_j), q̇(c_j))        F = Q − ∂R/∂v
//! ```
//!
//! on node `ρ`, as the compile-time Galerkin (`galerkin/forces.rs`) has it:
//! `F^ρ`, `ρ = 0 … s − 1`, joins the node equations, and the whole impulse
//! `Σ_ρ F^ρ + F^s = h Σ_j b_j F_j` (the basis sums to one) the momentum
//! change. The Newton block gains
//!
//! ```text
//! ∂F^ρ_i/∂D_{m,k} = Σ_j ℓ_ρ(c_j) (h b_j ℓ_m(c_j) ∂F_i/∂q_k + b_j ℓ_m'(c_j) ∂F_i/∂v_k)
//! ```
//!
//! with the Jacobians of `F` at each point from the one-point rules' forcing
//! code (`forcing.rs`: `Q` on dual lanes per colour class, `R` on a tape
//! with zero offsets), banded as the force's coupling is.

use super::Node;
use super::directional::Layout;
use super::forcing::Forcing;
use super::galerkin_rule::{BlockLayout, Rule};
use super::{TapeModel, filled, zeroed};
use crate::banded::LinearSolveError;
use crate::newton::Breakdown;

/// The buffers of a Galerkin step's forces (made at the first forced step).
#[derive(Debug)]
pub(super) struct GalerkinForcing {
    forcing: Forcing,
    layout: Layout,
    /// `ℓ_ρ(c_j)`, `ρ = 0 … s − 1`, at `j·s + ρ`.
    rows: Vec<f64>,
    /// The position, velocity and force at the point at hand.
    q: Vec<f64>,
    v: Vec<f64>,
    f: Vec<f64>,
    /// `∂F/∂q` and `∂F/∂v` at the point at hand, in the layout's storage.
    dq: Vec<f64>,
    dv: Vec<f64>,
}

impl GalerkinForcing {
    /// Buffers for `n` coordinates, the force's Jacobians of bandwidth
    /// `bandwidth` (`None`: dense), under `rule`.
    pub(super) fn new(n: usize, bandwidth: Option<usize>, rule: &Rule) -> Result<Self, LinearSolveError> {
        let layout = Layout { n, bandwidth };
        let s = rule.degree();
        let mut rows = vec![0.0; rule.points().len() * s];
        for (j, &c) in rule.points().iter().enumerate() {
            for rho in 0..s {
                rows[j * s + rho] = rule.basis(rho, c);
            }
        }
        let entries = n.checked_mul(layout.width());
        Ok(Self {
            forcing: Forcing::default(),
            layout,
            rows,
            q: filled(n, 0.0)?,
            v: filled(n, 0.0)?,
            f: filled(n, 0.0)?,
            dq: zeroed(entries, n)?,
            dv: zeroed(entries, n)?,
        })
    }

    /// At the unknowns `x` of a step of size `h` from `node`: adds `F^ρ` to
    /// the node equations `residual` (row `i·s + ρ`, when given), the
    /// impulse `h Σ_j b_j F_j` to `impulse` (when given), and with `block`
    /// `∂F^ρ/∂D` to the Newton block in its storage. Returns the largest
    /// `|F^ρ_i|` added, the scale of the residual's new terms.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn add(
        &mut self,
        model: &dyn TapeModel,
        rule: &Rule,
        node: &Node<'_>,
        h: f64,
        x: &[f64],
        mut residual: Option<&mut [f64]>,
        mut impulse: Option<&mut [f64]>,
        mut block: Option<(BlockLayout, &mut [f64])>,
    ) -> Result<f64, Breakdown> {
        let (n, s) = (self.layout.n, rule.degree());
        let width = self.layout.width();
        let carry = (!node.plain).then_some(node.q_carry);
        let mut largest: f64 = 0.0;
        for (j, (&c, &b)) in rule.points().iter().zip(rule.weights()).enumerate() {
            let (col, col_d) = rule.columns(j);
            for i in 0..n {
                let d = &x[i * s..(i + 1) * s];
                let e = carry.map_or(0.0, |e| e[i]);
                // `q_k + (e + Σ ℓ_m D_m)` and `(Σ ℓ_m' D_m)/h`, as the action's recording forms them.
                let mut acc = if e != 0.0 { e + d[0] * col[0] } else { d[0] * col[0] };
                let mut slope = d[0] * col_d[0];
                for m in 1..s {
                    acc += d[m] * col[m];
                    slope += d[m] * col_d[m];
                }
                self.q[i] = node.q[i] + acc;
                self.v[i] = slope / h;
            }
            let t = node.t + h * c;
            let jacobians = block.is_some().then_some((self.layout, &mut self.dq[..], &mut self.dv[..]));
            self.forcing.point_force(model, (t, &self.q, &self.v), &mut self.f, jacobians)?;
            let w = b * h;
            let row = &self.rows[j * s..(j + 1) * s];
            if let Some(r) = residual.as_deref_mut() {
                for i in 0..n {
                    for (rho, &l) in row.iter().enumerate() {
                        let force = w * (l * self.f[i]);
                        r[i * s + rho] += force;
                        largest = largest.max(force.abs());
                    }
                }
            }
            if let Some(impulse) = impulse.as_deref_mut() {
                for (p, &f) in impulse.iter_mut().zip(&self.f) {
                    *p += w * f;
                }
            }
            if let Some((layout, band)) = block.as_mut() {
                for i in 0..n {
                    for slot in 0..width {
                        let k = match self.layout.bandwidth {
                            Some(bw) => match (i + slot).checked_sub(bw).filter(|&k| k < n) {
                                Some(k) => k,
                                None => continue,
                            },
                            None => slot,
                        };
                        let (dq, dv) = (self.dq[i * width + slot], self.dv[i * width + slot]);
                        for m in 0..s {
                            let along = (w * col[m]) * dq + (b * col_d[m]) * dv;
                            for (rho, &l) in row.iter().enumerate() {
                                band[layout.slot(i * s + rho, k * s + m)] += l * along;
                            }
                        }
                    }
                }
            }
        }
        if let Some((_, band)) = block
            && !band.iter().all(|x| x.is_finite())
        {
            return Err(Breakdown::NonFinite("force jacobian"));
        }
        Ok(largest)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::galerkin::NodeFamily;
    use crate::integrator::tape_step::forcing::tests::Forced;
    use crate::integrator::tape_step::generalized_force;

    /// `∂F^ρ/∂D` in the Newton block against central differences of the
    /// node forces `F^ρ`, for bands of width 3, 5 and 7 and the dense
    /// pattern, degrees 1 to 3, Gauss–Legendre and Gauss–Lobatto points; and
    /// the impulse `h Σ_j b_j F_j` as the sum of the forces on all `s + 1`
    /// nodes.
    #[test]
    fn the_block_gains_the_derivative_of_the_node_forces() {
        let n = 9;
        let q0: Vec<f64> = (0..n).map(|i| 0.4 * (0.7 * i as f64).sin()).collect();
        let (zero, h) = (vec![0.0; n], 0.05);
        let node = Node { step: 0, t: 0.3, q: &q0, p: &zero, q_carry: &zero, p_carry: &zero, plain: true };
        for s in 1..=3 {
            for (lobatto, r) in [(false, s), (true, s + 1)] {
                let rule = Rule::new(s, NodeFamily::GaussLobatto, lobatto, r);
                let unknowns = n * s;
                let x: Vec<f64> = (0..unknowns).map(|u| 0.03 * (1.3 * u as f64 + 0.2).cos()).collect();
                for bandwidth in [Some(1), Some(2), Some(3), None] {
                    let case = format!("s = {s}, lobatto {lobatto}, bandwidth {bandwidth:?}");
                    let mut forcing = GalerkinForcing::new(n, bandwidth, &rule).unwrap();
                    // The block of the unknowns, dense: it holds any band.
                    let layout = BlockLayout::new(unknowns, None);
                    let mut block = vec![0.0; unknowns * unknowns];
                    let mut r = vec![0.0; unknowns];
                    let mut impulse = vec![0.0; n];
                    let forces = Some((layout, &mut block[..]));
                    forcing.add(&Forced, &rule, &node, h, &x, Some(&mut r), Some(&mut impulse), forces).unwrap();
                    // The values: F^ρ and the impulse from the force at the points.
                    let (mut rows, mut total) = (vec![0.0; unknowns], vec![0.0; n]);
                    for (j, (&c, &b)) in rule.points().iter().zip(rule.weights()).enumerate() {
                        let (col, col_d) = rule.columns(j);
                        let point = |i: usize| (0..s).map(|m| col[m] * x[i * s + m]).sum::<f64>() + q0[i];
                        let q: Vec<f64> = (0..n).map(point).collect();
                        let v: Vec<f64> =
                            (0..n).map(|i| (0..s).map(|m| col_d[m] * x[i * s + m]).sum::<f64>() / h).collect();
                        let mut f = vec![0.0; n];
                        generalized_force(&Forced, node.t + c * h, &q, &v, &mut f);
                        for i in 0..n {
                            total[i] += b * h * f[i];
                            for rho in 0..s {
                                rows[i * s + rho] += b * h * rule.basis(rho, c) * f[i];
                            }
                        }
                    }
                    for (what, got, expected) in [("rows", &r, &rows), ("impulse", &impulse, &total)] {
                        let gap = got.iter().zip(expected).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
                        assert!(gap < 1e-15, "{case}: {what} {gap:e}");
                    }
                    let (mut largest, mut scale) = (0.0f64, 0.0f64);
                    for u in 0..unknowns {
                        let eps = 1e-6;
                        let mut shifted = x.clone();
                        let mut at = |d: f64| {
                            shifted[u] = x[u] + d;
                            let mut r = vec![0.0; unknowns];
                            forcing.add(&Forced, &rule, &node, h, &shifted, Some(&mut r), None, None).unwrap();
                            r
                        };
                        let (up, down) = (at(eps), at(-eps));
                        for e in 0..unknowns {
                            let fd = (up[e] - down[e]) / (2.0 * eps);
                            let entry = block[layout.slot(e, u)];
                            largest = largest.max((fd - entry).abs());
                            scale = scale.max(entry.abs());
                        }
                    }
                    // Entries of order 1 (h times derivatives of order 1/h);
                    // central differences of step 1e-6 are good to ~1e-9.
                    assert!(scale > 0.1 && largest < 1e-7, "{case}: {largest:e} of {scale:e}");
                }
            }
        }
    }
}
