//! The state of an integrator at a node.

/// The integrator's state at node `k`: time, position and discrete momentum
/// `p_k = ∂A(x_{k−1}, x_k)/∂q_k` (MATH.md §3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State<const N: usize> {
    /// Node index `k` (0 at the start).
    pub step: u64,
    /// `t_k`.
    pub t: f64,
    /// `q_k`.
    pub q: [f64; N],
    /// `p_k`.
    pub p: [f64; N],
}
