//! What `#[lagrangian]` proves about the structure of a system, for the
//! runtime to choose cheaper paths at compile time.
//!
//! The macro reads the user's body and sets
//! [`Lagrangian::SEPARABILITY`](crate::Lagrangian::SEPARABILITY),
//! [`Lagrangian::COUPLING`](crate::Lagrangian::COUPLING) and
//! [`Lagrangian::FORCE_COUPLING`](crate::Lagrangian::FORCE_COUPLING). Every
//! value is a proven upper bound: a [`Pattern`] names the entries that *may*
//! be non-zero, never fewer, and [`Separability::NotProven`] or
//! [`Pattern::General`] mean "the syntax proves nothing better", not "the
//! system has no structure". Hand-written implementations of the trait get
//! these conservative answers unless they say otherwise.

/// Which entries of an `N × N` matrix may be non-zero.
///
/// Entry `(i, j)` is structurally zero when `|i − j|` exceeds the bandwidth.
/// Constructed through [`Pattern::banded`], a pattern is normalised: a
/// bandwidth of 0 is [`Diagonal`](Pattern::Diagonal), one that reaches the
/// corner (`N − 1` or more) is [`General`](Pattern::General).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Pattern {
    /// Only the diagonal may be non-zero (a zero matrix is diagonal too).
    Diagonal,
    /// Entries with `|i − j| ≤ bandwidth` may be non-zero; `1 ≤ bandwidth < N − 1`.
    Banded {
        /// The largest `|i − j|` of an entry that may be non-zero.
        bandwidth: usize,
    },
    /// Any entry may be non-zero.
    General,
}

impl Pattern {
    /// The pattern of an `n × n` matrix with the given bandwidth, normalised
    /// (see [`Pattern`]).
    pub const fn banded(n: usize, bandwidth: usize) -> Pattern {
        if n <= 1 || bandwidth == 0 {
            Pattern::Diagonal
        } else if bandwidth >= n - 1 {
            Pattern::General
        } else {
            Pattern::Banded { bandwidth }
        }
    }

    /// The bandwidth: `Some(0)` for a diagonal pattern, `None` for a general
    /// one.
    pub const fn bandwidth(self) -> Option<usize> {
        match self {
            Pattern::Diagonal => Some(0),
            Pattern::Banded { bandwidth } => Some(bandwidth),
            Pattern::General => None,
        }
    }

    /// Whether entry `(i, j)` may be non-zero; `false` means proven zero.
    pub const fn may_couple(self, i: usize, j: usize) -> bool {
        let distance = i.abs_diff(j);
        match self.bandwidth() {
            Some(bandwidth) => distance <= bandwidth,
            None => true,
        }
    }

    /// The least pattern containing both (for the sum of two matrices).
    pub const fn union(self, other: Pattern) -> Pattern {
        match (self.bandwidth(), other.bandwidth()) {
            (Some(a), Some(b)) => {
                let bandwidth = if a > b { a } else { b };
                if bandwidth == 0 { Pattern::Diagonal } else { Pattern::Banded { bandwidth } }
            }
            _ => Pattern::General,
        }
    }
}

/// The coupling pattern of the Hessian of a scalar function of `(q, v)`,
/// block by block: `q_q[i][j]` is `∂²/∂qᵢ∂qⱼ`, `q_v` is `∂²/∂qᵢ∂vⱼ` (the
/// same pattern as its transpose, since patterns are symmetric), `v_v` is
/// `∂²/∂vᵢ∂vⱼ` (the mass matrix, for a Lagrangian).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Coupling {
    /// The position–position block.
    pub q_q: Pattern,
    /// The position–velocity block.
    pub q_v: Pattern,
    /// The velocity–velocity block.
    pub v_v: Pattern,
}

impl Coupling {
    /// Nothing proven: every block general.
    pub const GENERAL: Coupling = Coupling { q_q: Pattern::General, q_v: Pattern::General, v_v: Pattern::General };

    /// The pattern of all three blocks together: the coupling of the whole
    /// `2N × 2N` Hessian, with `qᵢ` and `vᵢ` counted as the same index.
    pub const fn overall(self) -> Pattern {
        self.q_q.union(self.q_v).union(self.v_v)
    }
}

/// The coupling pattern of the Jacobian of the generalised force
/// `F(t, q, v) = Q(t, q, v) − ∂R/∂v(q, v)` (applied forces and Rayleigh
/// dissipation): entry `(i, j)` of `q` is `∂Fᵢ/∂qⱼ`, of `v` is `∂Fᵢ/∂vⱼ`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ForceCoupling {
    /// `∂F/∂q`.
    pub q: Pattern,
    /// `∂F/∂v`.
    pub v: Pattern,
}

impl ForceCoupling {
    /// Nothing proven.
    pub const GENERAL: ForceCoupling = ForceCoupling { q: Pattern::General, v: Pattern::General };

    /// No force: both Jacobians are zero.
    pub const NONE: ForceCoupling = ForceCoupling { q: Pattern::Diagonal, v: Pattern::Diagonal };

    /// The pattern of both blocks together.
    pub const fn overall(self) -> Pattern {
        self.q.union(self.v)
    }
}

/// Whether `L` is proven to have the natural form `L = ½ vᵀM(q)v − V(t, q)`.
///
/// The variants are ordered from least to most proven.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Separability {
    /// No such form proven: `L` may have terms linear or of higher degree in
    /// `v`, a mass matrix depending on `t`, or a body the analysis cannot
    /// follow.
    NotProven,
    /// `L = T(q, v) − V(t, q)` with `T = ½ vᵀM(q)v` homogeneous of degree 2
    /// in `v`; the mass matrix `M` may depend on `q` (not on `t`).
    QuadraticKinetic,
    /// As [`QuadraticKinetic`](Separability::QuadraticKinetic) with a
    /// constant mass matrix: `M` depends on neither `q` nor `t`, so `M` and
    /// `M⁻¹` can be computed once. `M` is not proven regular (a system
    /// without kinetic energy has `M = 0`).
    ConstantMass,
}

impl Separability {
    /// Whether the kinetic energy is proven a quadratic form in `v` (with a
    /// constant or position-dependent mass matrix).
    pub const fn is_quadratic_kinetic(self) -> bool {
        !matches!(self, Separability::NotProven)
    }

    /// Whether the mass matrix is proven constant: `L = ½ vᵀMv − V(t, q)`.
    pub const fn has_constant_mass(self) -> bool {
        matches!(self, Separability::ConstantMass)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn banded_normalises_at_both_ends() {
        assert_eq!(Pattern::banded(5, 0), Pattern::Diagonal);
        assert_eq!(Pattern::banded(1, 3), Pattern::Diagonal);
        assert_eq!(Pattern::banded(5, 1), Pattern::Banded { bandwidth: 1 });
        assert_eq!(Pattern::banded(5, 3), Pattern::Banded { bandwidth: 3 });
        assert_eq!(Pattern::banded(5, 4), Pattern::General);
        assert_eq!(Pattern::banded(2, 1), Pattern::General);
        assert_eq!(Pattern::banded(0, 0), Pattern::Diagonal);
    }

    #[test]
    fn may_couple_follows_the_bandwidth() {
        let band = Pattern::banded(10, 2);
        assert!(band.may_couple(3, 5) && band.may_couple(5, 3) && band.may_couple(4, 4));
        assert!(!band.may_couple(2, 5) && !band.may_couple(9, 0));
        assert!(!Pattern::Diagonal.may_couple(0, 1));
        assert!(Pattern::General.may_couple(0, 9));
    }

    #[test]
    fn unions_take_the_wider_pattern() {
        let b1 = Pattern::Banded { bandwidth: 1 };
        assert_eq!(Pattern::Diagonal.union(Pattern::Diagonal), Pattern::Diagonal);
        assert_eq!(Pattern::Diagonal.union(b1), b1);
        assert_eq!(Pattern::Banded { bandwidth: 3 }.union(b1), Pattern::Banded { bandwidth: 3 });
        assert_eq!(b1.union(Pattern::General), Pattern::General);
        let coupling = Coupling { q_q: b1, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };
        assert_eq!(coupling.overall(), b1);
        assert_eq!(Coupling::GENERAL.overall(), Pattern::General);
        assert_eq!(ForceCoupling::NONE.overall(), Pattern::Diagonal);
    }

    #[test]
    fn separability_is_ordered_by_what_is_proven() {
        assert!(Separability::NotProven < Separability::QuadraticKinetic);
        assert!(Separability::QuadraticKinetic < Separability::ConstantMass);
        assert!(!Separability::NotProven.is_quadratic_kinetic());
        assert!(Separability::QuadraticKinetic.is_quadratic_kinetic());
        assert!(!Separability::QuadraticKinetic.has_constant_mass());
        assert!(Separability::ConstantMass.has_constant_mass() && Separability::ConstantMass.is_quadratic_kinetic());
    }
}
