//! Forward sensitivities: `S_k = ∂(q_k, p_k)/∂(q_0, v_0, θ)` along a run,
//! propagated by `S_{k+1} = Φ_x S_k + [0 | Φ_θ]` from
//! `S_0 = [[I, 0, 0], [L_vq, L_vv, L_vθ]]` (the initial momentum is the
//! Legendre transform of `v_0`).

use nalgebra::{DMatrix, SMatrix};

use super::Parametric;
use super::linearisation::{InitialMomentum, Piece, Rule, StepJacobian};
use crate::error::Error;
use crate::solution::Solution;
use crate::state::State;

/// `∂(q_k, p_k)/∂(q_0, v_0, θ)` at one node: `2N` rows (`q` then `p`) by
/// `2N + P` columns (`q_0`, `v_0`, then the parameters in the order of
/// [`Parametric::NAMES`]), row-major.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Jacobian {
    /// `2N`.
    pub rows: usize,
    /// `2N + P`.
    pub cols: usize,
    /// The entries, row after row.
    pub data: Vec<f64>,
}

impl Jacobian {
    /// Entry `(i, j)`: the derivative of state component `i` (`q` then `p`)
    /// with respect to input `j` (`q_0`, `v_0`, `θ`).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.data[i * self.cols + j]
    }

    /// As an nalgebra matrix.
    pub fn matrix(&self) -> DMatrix<f64> {
        DMatrix::from_row_slice(self.rows, self.cols, &self.data)
    }
}

/// The derivatives of the state with respect to `(q_0, v_0, θ)`, by blocks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Tangent<const N: usize, const P: usize> {
    pub(crate) q_q0: SMatrix<f64, N, N>,
    pub(crate) q_v0: SMatrix<f64, N, N>,
    pub(crate) q_theta: SMatrix<f64, N, P>,
    pub(crate) p_q0: SMatrix<f64, N, N>,
    pub(crate) p_v0: SMatrix<f64, N, N>,
    pub(crate) p_theta: SMatrix<f64, N, P>,
}

impl<const N: usize, const P: usize> Tangent<N, P> {
    /// `S_0`.
    pub(crate) fn initial(p0: &InitialMomentum<N, P>) -> Self {
        Self {
            q_q0: SMatrix::identity(),
            q_v0: SMatrix::zeros(),
            q_theta: SMatrix::zeros(),
            p_q0: p0.dq,
            p_v0: p0.dv,
            p_theta: p0.dtheta,
        }
    }

    /// `S_{k+1} = Φ_x S_k + [0 | Φ_θ]`.
    pub(crate) fn step(&self, j: &StepJacobian<N, P>) -> Self {
        let m = &j.state;
        Self {
            q_q0: m.dq_dq * self.q_q0 + m.dq_dp * self.p_q0,
            q_v0: m.dq_dq * self.q_v0 + m.dq_dp * self.p_v0,
            q_theta: m.dq_dq * self.q_theta + m.dq_dp * self.p_theta + j.dq_dtheta,
            p_q0: m.dp_dq * self.q_q0 + m.dp_dp * self.p_q0,
            p_v0: m.dp_dq * self.q_v0 + m.dp_dp * self.p_v0,
            p_theta: m.dp_dq * self.q_theta + m.dp_dp * self.p_theta + j.dp_dtheta,
        }
    }

    /// As a [`Jacobian`].
    pub(crate) fn jacobian(&self) -> Jacobian {
        let cols = 2 * N + P;
        let mut data = Vec::with_capacity(2 * N * cols);
        for (x0, v0, th) in [(&self.q_q0, &self.q_v0, &self.q_theta), (&self.p_q0, &self.p_v0, &self.p_theta)] {
            for i in 0..N {
                data.extend((0..N).map(|j| x0[(i, j)]));
                data.extend((0..N).map(|j| v0[(i, j)]));
                data.extend((0..P).map(|j| th[(i, j)]));
            }
        }
        Jacobian { rows: 2 * N, cols, data }
    }
}

/// A solution with the sensitivities of its rows.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Sensitivities<const N: usize> {
    /// The run, as [`Problem::solve`](crate::Problem::solve) returns it.
    pub solution: Solution<N>,
    /// The names of the parameters (the last columns of each Jacobian).
    pub parameters: Vec<String>,
    /// `∂(q, p)/∂(q_0, v_0, θ)` at each row of the solution, in order; shorter
    /// than the solution only when [`error`](Self::error) is set.
    pub jacobians: Vec<Jacobian>,
    /// Why the sensitivities stop before the solution's last row: a step
    /// whose linearisation is singular or not finite.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub error: Option<Error<N>>,
}

/// Propagates the tangent from node to node as the steps are taken,
/// keeping the Jacobians of the nodes the plan keeps as rows.
pub(crate) struct Propagation<'s, S, const N: usize, const P: usize> {
    system: &'s S,
    rule: Rule,
    theta: [f64; P],
    every: usize,
    tangent: Tangent<N, P>,
    /// `(k, S_k)` of the nodes `k` with `k % every == 0`.
    pub(crate) kept: Vec<(u64, Jacobian)>,
    /// The last node's `(k, S_k)`.
    pub(crate) last: Option<(u64, Tangent<N, P>)>,
    pub(crate) error: Option<Error<N>>,
}

impl<'s, S: Parametric<N, P>, const N: usize, const P: usize> Propagation<'s, S, N, P> {
    /// From the initial node `node` (step 0) of the problem's initial data.
    pub(crate) fn new(
        system: &'s S,
        rule: Rule,
        initial: (f64, [f64; N], [f64; N]),
        every: usize,
        node: &State<N>,
    ) -> Self {
        let theta = system.parameters();
        let tangent = Tangent::initial(&InitialMomentum::at(system, &theta, initial));
        let mut out = Self { system, rule, theta, every, tangent, kept: Vec::new(), last: None, error: None };
        out.keep(node.step);
        out
    }

    /// The step from `from`, made of `pieces` (or why they are not known),
    /// to the node `to`.
    pub(crate) fn step(&mut self, from: &State<N>, pieces: Result<&[Piece<N>], Error<N>>, to: &State<N>) {
        if self.error.is_some() {
            return;
        }
        let pieces = match pieces {
            Ok(pieces) => pieces,
            Err(e) => {
                self.error = Some(e);
                return;
            }
        };
        match StepJacobian::of_step(self.system, &self.rule, &self.theta, pieces) {
            Some(j) => self.tangent = self.tangent.step(&j),
            None => {
                let h = to.t - from.t;
                self.error = Some(Error::SingularJacobian { state: *from, h, iterations: 0, rcond: 0.0 });
                return;
            }
        }
        self.keep(to.step);
    }

    fn keep(&mut self, k: u64) {
        if self.every > 0 && k.is_multiple_of(self.every as u64) {
            self.kept.push((k, self.tangent.jacobian()));
        }
        self.last = Some((k, self.tangent));
    }

    /// The Jacobians of the rows of `solution`.
    pub(crate) fn finish(self, solution: Solution<N>) -> Sensitivities<N> {
        let Self { kept, last, mut error, .. } = self;
        let mut jacobians = Vec::with_capacity(solution.len());
        for step in &solution.step {
            let found = step.and_then(|k| {
                kept.binary_search_by_key(&k, |(i, _)| *i)
                    .ok()
                    .map(|i| kept[i].1.clone())
                    .or_else(|| last.as_ref().filter(|(i, _)| *i == k).map(|(_, s)| s.jacobian()))
            });
            match found {
                Some(j) => jacobians.push(j),
                None => {
                    error.get_or_insert(Error::Unsupported { what: "sensitivities of a row between nodes" });
                    break;
                }
            }
        }
        Sensitivities { solution, parameters: S::NAMES.iter().map(ToString::to_string).collect(), jacobians, error }
    }
}
