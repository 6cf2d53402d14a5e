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

/// A node of the discrete trajectory whose number of coordinates is known
/// at run time: the same `(k, t_k, q_k, p_k)` as [`State`], with `q_k` and
/// `p_k` on the heap.
///
/// It is the state a run-time-sized driver
/// ([`Stepper<S, Dyn>`](crate::Stepper), [`DynConstrained`](crate::DynConstrained))
/// holds, and the state an
/// [`Error`](crate::Error) carries whatever the size of the system that
/// failed, so that errors of systems of different sizes are one type. A
/// [`State`] converts into it with `From`, and back with `TryFrom` (which
/// fails with [`Error::WrongLength`](crate::Error::WrongLength) when the
/// lengths differ):
///
/// ```
/// use lagrangian_runtime::{PhasePoint, State};
///
/// let state = State { step: 3, t: 0.5, q: [1.0, 2.0], p: [0.0, -1.0] };
/// let point = PhasePoint::from(state);
/// assert_eq!(point.q, [1.0, 2.0]);
/// let back: State<2> = point.try_into()?;
/// assert_eq!(back, state);
/// # Ok::<(), lagrangian_runtime::Error>(())
/// ```
#[derive(Debug, Default, PartialEq)]
pub struct PhasePoint<T = f64> {
    /// Node index `k` (0 at the start).
    pub step: u64,
    /// `t_k`.
    pub t: T,
    /// `q_k`.
    pub q: Vec<T>,
    /// `p_k`.
    pub p: Vec<T>,
}

/// `clone_from` reuses the target's `q` and `p` buffers.
impl<T: Clone> Clone for PhasePoint<T> {
    fn clone(&self) -> Self {
        Self { step: self.step, t: self.t.clone(), q: self.q.clone(), p: self.p.clone() }
    }

    fn clone_from(&mut self, source: &Self) {
        self.step = source.step;
        self.t.clone_from(&source.t);
        self.q.clone_from(&source.q);
        self.p.clone_from(&source.p);
    }
}

impl<T: crate::Real> PhasePoint<T> {
    /// The point rounded to `f64` (each value's leading part).
    pub fn to_f64(&self) -> PhasePoint {
        PhasePoint {
            step: self.step,
            t: self.t.to_f64(),
            q: self.q.iter().map(|x| x.to_f64()).collect(),
            p: self.p.iter().map(|x| x.to_f64()).collect(),
        }
    }
}

impl<const N: usize, T> From<State<N, T>> for PhasePoint<T> {
    fn from(State { step, t, q, p }: State<N, T>) -> Self {
        PhasePoint { step, t, q: q.into(), p: p.into() }
    }
}

/// A point equals a state with the same node index, time, position and
/// momentum (a state of another length is never equal).
impl<const N: usize, T: PartialEq> PartialEq<State<N, T>> for PhasePoint<T> {
    fn eq(&self, other: &State<N, T>) -> bool {
        self.step == other.step && self.t == other.t && self.q == other.q && self.p == other.p
    }
}

/// See the comparison of a [`PhasePoint`] with a [`State`].
impl<const N: usize, T: PartialEq> PartialEq<PhasePoint<T>> for State<N, T> {
    fn eq(&self, other: &PhasePoint<T>) -> bool {
        other == self
    }
}
