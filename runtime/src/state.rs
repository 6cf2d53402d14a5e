//! The state of an integrator at a node.

/// The integrator's state at node `k`: time, position and discrete momentum
/// `p_k = ∂A(x_{k−1}, x_k)/∂q_k` (docs/theory.md §3).
///
/// `T` is the real type of the integrator: `f64`, or an extended-precision
/// [`Real`](crate::Real) for a Galerkin integrator run in it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State<const N: usize, T = f64> {
    /// Node index `k` (0 at the start).
    pub step: u64,
    /// `t_k`.
    pub t: T,
    /// `q_k`.
    pub q: [T; N],
    /// `p_k`.
    pub p: [T; N],
}

impl<const N: usize, T: crate::Real> State<N, T> {
    /// The state rounded to `f64` (each value's leading part).
    pub fn to_f64(&self) -> State<N> {
        State { step: self.step, t: self.t.to_f64(), q: self.q.map(|x| x.to_f64()), p: self.p.map(|x| x.to_f64()) }
    }
}
