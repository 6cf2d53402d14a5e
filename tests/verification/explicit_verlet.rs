//! The explicit path: for `L = ½ vᵀMv − V(t, q)` with a constant mass
//! matrix (proven by `#[lagrangian]`, `Lagrangian::SEPARABILITY`) and no
//! forces, the trapezoid rule's DEL is explicit (Störmer–Verlet), and the
//! integrator takes it without Newton. The user asks for `Trapezoid`; the
//! fast path is taken without being asked. These tests check that no Newton
//! iteration is spent and that the trajectories agree with the general
//! Newton path (the same system with its structure hidden) to round-off.
use lagrangian::prelude::*;
use lagrangian::structure::Separability;

/// `L = ½ v² + g cos q`.
pub struct Pendulum;

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + 9.81 * q[0].cos()
    }
}

/// An FPU-β chain with fixed ends, written with a loop over neighbours.
pub struct Fpu<const N: usize> {
    /// Quartic coupling.
    pub beta: f64,
}

#[lagrangian]
impl<const N: usize> Fpu<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.0;
        for i in 0..N {
            l += 0.5 * v[i] * v[i];
        }
        let mut left = 0.0;
        for i in 0..N {
            let d = q[i] - left;
            l -= 0.5 * d * d + 0.25 * self.beta * d * d * d * d;
            left = q[i];
        }
        let d = -left;
        l -= 0.5 * d * d + 0.25 * self.beta * d * d * d * d;
        l
    }
}

/// The same system with its structure hidden: the general Newton path.
struct Hidden<S>(S);

impl<S: Lagrangian<N>, const N: usize> Lagrangian<N> for Hidden<S> {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const CYCLIC: [bool; N] = S::CYCLIC;
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> D {
        self.0.lagrangian(t, q, v)
    }
}

/// Largest difference of `q` and `p` between the explicit and the Newton path over `n` steps.
fn compare<S: Lagrangian<N>, const N: usize>(
    system: impl Fn() -> S,
    q0: [f64; N],
    v0: [f64; N],
    h: f64,
    n: usize,
) -> (f64, u64, f64) {
    let mut fast = Integrator::new(system(), Trapezoid, h).start(0.0, q0, v0).unwrap();
    let mut slow = Integrator::new(Hidden(system()), Trapezoid, h).start(0.0, q0, v0).unwrap();
    let mut worst = 0.0f64;
    for _ in 0..n {
        fast.step().unwrap();
        slow.step().unwrap();
        for i in 0..N {
            worst = worst.max((fast.state().q[i] - slow.state().q[i]).abs());
            worst = worst.max((fast.state().p[i] - slow.state().p[i]).abs());
        }
    }
    let newton = slow.stats().newton_iterations as f64 / slow.stats().steps as f64;
    (worst, fast.stats().newton_iterations, newton)
}

#[test]
fn the_macro_proves_the_structure_the_fast_path_needs() {
    assert_eq!(<Pendulum as Lagrangian<1>>::SEPARABILITY, Separability::ConstantMass);
    assert_eq!(<Fpu<16> as Lagrangian<16>>::SEPARABILITY, Separability::ConstantMass);
    assert_eq!(<Hidden<Pendulum> as Lagrangian<1>>::SEPARABILITY, Separability::NotProven);
}

#[test]
fn pendulum_trapezoid_is_explicit_and_agrees_with_newton() {
    // The two paths round differently (Verlet's closed form against Newton's
    // corrections), by an ulp or so per step; on the pendulum those
    // differences shift the phase and grow linearly with time (measured:
    // 2.6e-15 after 1e3 steps, 3.7e-14 after 1e4, against |p| ≤ 3.1), so the
    // bound is 1e-13 at 1e4 steps and 1e-14 at 1e3.
    let (short, _, _) = compare(|| Pendulum, [1.0], [0.0], 0.01, 1_000);
    let (worst, fast_iterations, newton) = compare(|| Pendulum, [1.0], [0.0], 0.01, 10_000);
    println!(
        "pendulum, trapezoid steps: explicit path {fast_iterations} Newton iterations, general path {newton:.2} \
         per step; largest difference in q, p {short:.1e} over 1e3 steps, {worst:.1e} over 1e4"
    );
    assert_eq!(fast_iterations, 0);
    assert!(short < 1e-14, "explicit and Newton paths differ by {short:e} over 1e3 steps");
    assert!(worst < 1e-13, "explicit and Newton paths differ by {worst:e} over 1e4 steps");
}

#[test]
fn fpu_chain_trapezoid_is_explicit_and_agrees_with_newton() {
    let q0: [f64; 16] = core::array::from_fn(|i| 0.3 * ((i + 1) as f64 * std::f64::consts::PI / 17.0).sin());
    let (worst, fast_iterations, newton) = compare(|| Fpu::<16> { beta: 1.0 }, q0, [0.0; 16], 0.05, 10_000);
    println!(
        "FPU-β N = 16, 1e4 trapezoid steps: explicit path {fast_iterations} Newton iterations, general path \
         {newton:.2} per step; largest difference in q, p {worst:.1e}"
    );
    assert_eq!(fast_iterations, 0);
    assert!(worst < 1e-14, "explicit and Newton paths differ by {worst:e}");
}

#[test]
fn midpoint_on_a_separable_system_still_uses_newton() {
    let mut sim = Integrator::new(Pendulum, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    sim.run(10, |_| {}).unwrap();
    assert!(sim.stats().newton_iterations >= 10);
}
