//! Forward sensitivities: `S_k = ∂(q_k, p_k)/∂(q_0, v_0, θ)` along a run,
//! propagated by `S_{k+1} = Φ_x S_k + [0 | Φ_θ]` from
//! `S_0 = [[I, 0, 0], [L_vq, L_vv, L_vθ]]` (the initial momentum is the
//! Legendre transform of `v_0`).

use nalgebra::{DMatrix, RowDVector, SMatrix};

use super::Parametric;
use super::linearisation::{InitialMomentum, Piece, Rule, StepJacobian};
use super::transformed::{Linear, Start};
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
    /// `∂t_k/∂(q_0, v_0, θ)`, `2N + P` entries: zero under fixed steps,
    /// whose node times are constants; the node times of a time-transformed
    /// run and of energy-preserving steps move with the inputs.
    pub time: Vec<f64>,
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
        Jacobian { rows: 2 * N, cols, data, time: vec![0.0; cols] }
    }
}

/// A solution with the sensitivities of its rows.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Sensitivities<const N: usize> {
    /// The run, as [`Problem::solve`](crate::Problem::solve) returns it.
    pub solution: Solution,
    /// The names of the parameters (the last columns of each Jacobian).
    pub parameters: Vec<String>,
    /// `∂(q, p)/∂(q_0, v_0, θ)` at each row of the solution, in order; shorter
    /// than the solution only when [`error`](Self::error) is set.
    pub jacobians: Vec<Jacobian>,
    /// Why the sensitivities stop before the solution's last row: a step
    /// whose linearisation is singular or not finite.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub error: Option<Error>,
}

/// The tangent of a run: by blocks for the fixed steps of a rule, dense in
/// the extended phase `(q, t, p, p_t)` through the time transformation and
/// energy-preserving steps (`p_t = −E`).
enum Mode<const N: usize, const P: usize> {
    Fixed { rule: Rule, tangent: Tangent<N, P> },
    Extended { tangent: DMatrix<f64>, c: RowDVector<f64> },
}

impl<const N: usize, const P: usize> Mode<N, P> {
    /// `S_k` as a [`Jacobian`]: the rows of `q` and `p`, and of `t` in
    /// the extended phase.
    fn jacobian(&self) -> Jacobian {
        match self {
            Self::Fixed { tangent, .. } => tangent.jacobian(),
            Self::Extended { tangent, .. } => {
                let (m, cols) = (N + 1, 2 * N + P);
                let mut data = Vec::with_capacity(2 * N * cols);
                for i in (0..N).chain(m..m + N) {
                    data.extend(tangent.row(i).iter());
                }
                Jacobian { rows: 2 * N, cols, data, time: tangent.row(N).iter().copied().collect() }
            }
        }
    }
}

/// Propagates the tangent from node to node as the steps are taken,
/// keeping the Jacobians of the nodes the plan keeps as rows.
pub(crate) struct Propagation<'s, S, const N: usize, const P: usize> {
    system: &'s S,
    theta: [f64; P],
    every: usize,
    mode: Mode<N, P>,
    /// `(k, S_k)` of the nodes `k` with `k % every == 0`.
    kept: Vec<(u64, Jacobian)>,
    /// The last node's `k` (its tangent is the current one).
    last: Option<u64>,
    error: Option<Error>,
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
        Self::with(system, Mode::Fixed { rule, tangent }, every, node)
    }

    /// From the initial node `node` of a time-transformed run whose first
    /// node in `s` has the derivatives `start`.
    pub(crate) fn extended(system: &'s S, start: Start, every: usize, node: &State<N>) -> Self {
        Self::with(system, Mode::Extended { tangent: start.tangent, c: start.c }, every, node)
    }

    fn with(system: &'s S, mode: Mode<N, P>, every: usize, node: &State<N>) -> Self {
        let theta = system.parameters();
        let mut out = Self { system, theta, every, mode, kept: Vec::new(), last: None, error: None };
        out.keep(node.step);
        out
    }

    /// The step from `from`, made of `pieces` (or why they are not known),
    /// to the node `to`.
    pub(crate) fn step(&mut self, from: &State<N>, pieces: Result<&[Piece<N>], Error>, to: &State<N>) {
        if self.error.is_some() {
            return;
        }
        let Mode::Fixed { rule, tangent } = &mut self.mode else {
            self.error = Some(Error::Unsupported { what: "sensitivities of a step whose nodes were not kept" });
            return;
        };
        let pieces = match pieces {
            Ok(pieces) => pieces,
            Err(e) => {
                self.error = Some(e);
                return;
            }
        };
        match StepJacobian::of_step(self.system, rule, &self.theta, pieces) {
            Some(j) => *tangent = tangent.step(&j),
            None => {
                let h = to.t - from.t;
                self.error = Some(Error::SingularJacobian { state: (*from).into(), h, iterations: 0, rcond: 0.0 });
                return;
            }
        }
        self.keep(to.step);
    }

    /// The step to the node `to` of a time-transformed run, with its
    /// linearisation in the extended phase (or why it has none):
    /// `S_{k+1} = Φ_x S_k + Φ_θ [0 | 0 | I] + Φ_c ∂c/∂(q_0, v_0, θ)`.
    pub(crate) fn step_extended(&mut self, linear: Result<Linear, Error>, to: &State<N>) {
        if self.error.is_some() {
            return;
        }
        let Mode::Extended { tangent, c } = &mut self.mode else {
            self.error = Some(Error::Unsupported { what: "sensitivities of a step whose nodes were not kept" });
            return;
        };
        let linear = match linear {
            Ok(linear) => linear,
            Err(e) => {
                self.error = Some(e);
                return;
            }
        };
        let mut next = &linear.x * &*tangent + &linear.c * &*c;
        let mut params = next.columns_mut(2 * N, P);
        params += &linear.theta;
        *tangent = next;
        self.keep(to.step);
    }

    fn keep(&mut self, k: u64) {
        if self.every > 0 && k.is_multiple_of(self.every as u64) {
            self.kept.push((k, self.mode.jacobian()));
        }
        self.last = Some(k);
    }

    /// The Jacobians of the rows of `solution`.
    pub(crate) fn finish(self, solution: Solution) -> Sensitivities<N> {
        let Self { kept, last, mut error, mode, .. } = self;
        let mut jacobians = Vec::with_capacity(solution.len());
        for step in &solution.step {
            let found = step.and_then(|k| {
                kept.binary_search_by_key(&k, |(i, _)| *i)
                    .ok()
                    .map(|i| kept[i].1.clone())
                    .or_else(|| (last == Some(k)).then(|| mode.jacobian()))
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
