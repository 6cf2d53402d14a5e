//! Forces and Rayleigh dissipation on run-time-sized systems (the discrete
//! Lagrange–d'Alembert principle of docs/theory.md §6 on the reverse-mode
//! driver): the same states as at a compile-time size, the macro's force
//! over slices against one written by hand, the damped and the driven
//! chain against their analytic solutions with the order fitted, momentum
//! under internal forces, and a force that is not finite.

use lagrangian::prelude::*;
use lagrangian::{DynLagrangian, ForceCoupling, Pattern, Scalar};

/// Eight masses between walls, damped (`R = ½γ Σ v_i² + ½κ Σ (v_{i+1} −
/// v_i)²`) and driven (`Q_0 = a cos Ωt`, a cubic friction `−μ v_i³` on every
/// mass), with their size known at compile time.
#[derive(Clone)]
pub(super) struct Forced;

const GAMMA: f64 = 0.05;
const KAPPA: f64 = 0.02;
const MU: f64 = 0.1;
const DRIVE: f64 = 0.3;
const OMEGA: f64 = 1.3;

#[lagrangian]
impl Forced {
    fn lagrangian(&self, q: [f64; 8], v: [f64; 8]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..8 {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.5 * (q[0] * q[0] + q[7] * q[7]);
        for i in 0..7 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d;
        }
        kinetic - potential
    }

    fn dissipation(&self, _q: [f64; 8], v: [f64; 8]) -> f64 {
        let mut r = 0.0;
        for i in 0..8 {
            r += 0.5 * GAMMA * v[i] * v[i];
        }
        for i in 0..7 {
            let d = v[i + 1] - v[i];
            r += 0.5 * KAPPA * d * d;
        }
        r
    }

    fn force(&self, t: f64, _q: [f64; 8], v: [f64; 8]) -> [f64; 8] {
        let mut f = [0.0; 8];
        for i in 0..8 {
            f[i] = -MU * v[i] * v[i] * v[i];
        }
        f[0] += DRIVE * (OMEGA * t).cos();
        f
    }
}

/// The same chain with its size known at run time, written by hand over
/// slices (force and dissipation banded: bandwidth 0 and 1).
#[derive(Clone, Debug)]
pub(super) struct ForcedDyn {
    pub(super) n: usize,
}

fn chain_lagrangian<D: Scalar>(q: &[D], v: &[D], walls: bool) -> D {
    let n = q.len();
    let mut l = D::from(0.0);
    for i in 0..n {
        l += v[i] * v[i] * 0.5;
    }
    if walls {
        l -= (q[0] * q[0] + q[n - 1] * q[n - 1]) * 0.5;
    }
    for i in 0..n - 1 {
        let d = q[i + 1] - q[i];
        l -= d * d * 0.5;
    }
    l
}

impl DynLagrangian for ForcedDyn {
    const AUTONOMOUS: bool = true;
    const FORCE_COUPLING: ForceCoupling = ForceCoupling { q: Pattern::Diagonal, v: Pattern::Banded { bandwidth: 1 } };
    const HAS_DISSIPATION: bool = true;
    const HAS_FORCE: bool = true;

    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        chain_lagrangian(q, v, true)
    }

    fn dissipation<D: Scalar>(&self, _q: &[D], v: &[D]) -> D {
        let mut r = D::from(0.0);
        for x in v {
            r += *x * *x * (0.5 * GAMMA);
        }
        for i in 0..v.len() - 1 {
            let d = v[i + 1] - v[i];
            r += d * d * (0.5 * KAPPA);
        }
        r
    }

    fn force<D: Scalar>(&self, t: D, _q: &[D], v: &[D], f: &mut [D]) {
        for (f, v) in f.iter_mut().zip(v) {
            *f = -(*v * *v * *v * MU);
        }
        f[0] += (t * OMEGA).cos() * DRIVE;
    }
}

/// The same chain written with `#[lagrangian]` over slices, the force
/// written into `f`: the macro proves the bands of `ForcedDyn`'s
/// hand-written `FORCE_COUPLING`.
#[derive(Clone, Debug)]
struct ForcedMacro {
    n: usize,
}

#[lagrangian]
impl ForcedMacro {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut l = 0.0;
        for i in 0..n {
            l += v[i] * v[i] * 0.5;
        }
        l -= (q[0] * q[0] + q[n - 1] * q[n - 1]) * 0.5;
        for i in 0..n - 1 {
            let d = q[i + 1] - q[i];
            l -= d * d * 0.5;
        }
        l
    }

    fn dissipation(&self, _q: &[f64], v: &[f64]) -> f64 {
        let mut r = 0.0;
        for i in 0..v.len() {
            r += v[i] * v[i] * (0.5 * GAMMA);
        }
        for i in 0..v.len() - 1 {
            let d = v[i + 1] - v[i];
            r += d * d * (0.5 * KAPPA);
        }
        r
    }

    fn force(&self, t: f64, _q: &[f64], v: &[f64], f: &mut [f64]) {
        for i in 0..f.len() {
            f[i] = -(v[i] * v[i] * v[i] * MU);
        }
        f[0] += (t * OMEGA).cos() * DRIVE;
    }
}

const H: f64 = 0.02;

/// The third normal mode's shape `sin(πi/3)`, `i = 1 … 8` (`ω₃ = 1`).
pub(super) fn shape() -> [f64; 8] {
    core::array::from_fn(|i| (std::f64::consts::PI * (i + 1) as f64 / 3.0).sin())
}

fn schemes() -> [(&'static str, Scheme); 4] {
    [
        ("midpoint", Scheme::MIDPOINT),
        ("trapezoid", Scheme::TRAPEZOID),
        ("alpha-beta", Scheme::OnePoint(OnePoint::AlphaBeta(lagrangian::AlphaBeta::new(0.3).unwrap()))),
        ("yoshida 4", Scheme::composition(lagrangian::Composition::YOSHIDA4, OnePoint::Trapezoid)),
    ]
}

#[test]
fn a_forced_run_time_chain_steps_as_the_compile_time_one() {
    let q0 = shape();
    let v0: [f64; 8] = core::array::from_fn(|i| 0.1 * (i as f64 - 3.5));
    let dynamic = Problem::new(ForcedDyn { n: 8 }, 0.0, q0.to_vec(), v0.to_vec());
    let compiled = Problem::new(Forced, 0.0, q0, v0);
    for (name, scheme) in schemes() {
        let mut a = dynamic.stepper(&scheme, H).unwrap();
        let mut b = compiled.stepper(&scheme, H).unwrap();
        a.run(300, |_| {}).unwrap();
        b.run(300, |_| {}).unwrap();
        let (sa, sb) = (a.state(), b.state());
        assert_eq!(sa.t, sb.t, "{name}");
        let mut largest = 0.0f64;
        for i in 0..8 {
            largest = largest.max((sa.q[i] - sb.q[i]).abs()).max((sa.p[i] - sb.p[i]).abs());
        }
        // Round-off of 300 steps: the two sizes sum the same terms in
        // different orders.
        assert!(largest < 1e-12, "{name}: {largest:e}");
        // The motion is damped and driven: far from the start.
        assert!((sa.q[0] - q0[0]).abs() > 1e-2, "{name}");
    }
}

/// [`ForcedMacro`]'s generated Lagrangian, gradient code and dissipation,
/// and [`ForcedDyn`]'s force written by hand: what differs from
/// `ForcedMacro` is the force alone.
#[derive(Clone, Debug)]
struct ForcedByHand(ForcedMacro);

impl DynLagrangian for ForcedByHand {
    const AUTONOMOUS: bool = <ForcedMacro as DynLagrangian>::AUTONOMOUS;
    const SEPARABILITY: lagrangian::Separability = <ForcedMacro as DynLagrangian>::SEPARABILITY;
    const COUPLING: lagrangian::Coupling = <ForcedMacro as DynLagrangian>::COUPLING;
    const FORCE_COUPLING: ForceCoupling = <ForcedDyn as DynLagrangian>::FORCE_COUPLING;
    const HAS_DISSIPATION: bool = true;
    const HAS_FORCE: bool = true;
    const HAS_GRADIENT: bool = <ForcedMacro as DynLagrangian>::HAS_GRADIENT;
    const HAS_GRADIENT_QV: bool = <ForcedMacro as DynLagrangian>::HAS_GRADIENT_QV;

    fn dimension(&self) -> usize {
        self.0.n
    }

    fn lagrangian<D: Scalar>(&self, t: D, q: &[D], v: &[D]) -> D {
        DynLagrangian::lagrangian(&self.0, t, q, v)
    }

    fn gradient_q(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        self.0.gradient_q(t, q, v, out);
    }

    fn value_gradient_q(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) -> f64 {
        self.0.value_gradient_q(t, q, v, out)
    }

    fn gradient_qv_scalar<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) {
        self.0.gradient_qv_scalar(t, q, v, out_q, out_v);
    }

    fn dissipation<D: Scalar>(&self, q: &[D], v: &[D]) -> D {
        DynLagrangian::dissipation(&self.0, q, v)
    }

    fn force<D: Scalar>(&self, t: D, q: &[D], v: &[D], f: &mut [D]) {
        DynLagrangian::force(&ForcedDyn { n: self.0.n }, t, q, v, f);
    }
}

/// The macro's force over slices steps as the hand-written one: the same
/// operations in the same order, so the same force and, over the same
/// Lagrangian, the same states bit for bit; against the hand-written
/// Lagrangian too to round-off (the macro writes the gradient of `L` as
/// adjoint code, which sums in another order than the tape). The bands
/// proven are those written by hand.
#[test]
fn the_macros_force_over_slices_steps_as_the_hand_written_one() {
    assert_eq!(<ForcedMacro as DynLagrangian>::FORCE_COUPLING, <ForcedDyn as DynLagrangian>::FORCE_COUPLING);
    const { assert!(<ForcedMacro as DynLagrangian>::HAS_FORCE && <ForcedMacro as DynLagrangian>::HAS_DISSIPATION) };
    let q0 = shape();
    let v0: Vec<f64> = (0..8).map(|i| 0.1 * (i as f64 - 3.5)).collect();
    let by_hand = Problem::new(ForcedDyn { n: 8 }, 0.0, q0.to_vec(), v0.clone());
    let force_by_hand = Problem::new(ForcedByHand(ForcedMacro { n: 8 }), 0.0, q0.to_vec(), v0.clone());
    let by_macro = Problem::new(ForcedMacro { n: 8 }, 0.0, q0.to_vec(), v0);
    // The force alone, at a state and a time: bit for bit.
    let (t, q, v) = (0.7, q0.to_vec(), (0..8).map(|i| 0.2 * i as f64 - 0.5).collect::<Vec<f64>>());
    let (mut a, mut b) = (vec![0.0; 8], vec![0.0; 8]);
    <ForcedDyn as DynLagrangian>::force(&ForcedDyn { n: 8 }, t, &q, &v, &mut a);
    <ForcedMacro as DynLagrangian>::force(&ForcedMacro { n: 8 }, t, &q, &v, &mut b);
    assert_eq!(a.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), b.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
    let bits = |s: &PhasePoint| -> Vec<u64> { s.q.iter().chain(&s.p).map(|x| x.to_bits()).collect() };
    for (name, scheme) in schemes() {
        let mut a = by_hand.stepper(&scheme, H).unwrap();
        let mut b = by_macro.stepper(&scheme, H).unwrap();
        let mut c = force_by_hand.stepper(&scheme, H).unwrap();
        a.run(300, |_| {}).unwrap();
        b.run(300, |_| {}).unwrap();
        c.run(300, |_| {}).unwrap();
        let (sa, sb, sc) = (a.state(), b.state(), c.state());
        assert_eq!(bits(sb), bits(sc), "{name}");
        assert_eq!(sa.t, sb.t, "{name}");
        // Measured: 1–2 ulps of the largest entries.
        let largest = (0..8).map(|i| (sa.q[i] - sb.q[i]).abs().max((sa.p[i] - sb.p[i]).abs())).fold(0.0, f64::max);
        assert!(largest < 1e-14, "{name}: {largest:e}");
        assert!((sa.q[0] - q0[0]).abs() > 1e-2, "{name}");
    }
}

/// A linearly damped chain between walls, `R = ½γ Σ v_i²`, its size known
/// at run time (the macro's rewrite of both bodies over slices).
#[derive(Clone)]
pub(super) struct Damped {
    pub(super) n: usize,
    pub(super) gamma: f64,
}

#[lagrangian]
impl Damped {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.5 * (q[0] * q[0] + q[n - 1] * q[n - 1]);
        for i in 0..n - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d;
        }
        kinetic - potential
    }

    fn dissipation(&self, _q: &[f64], v: &[f64]) -> f64 {
        let mut r = 0.0;
        for i in 0..v.len() {
            r += 0.5 * self.gamma * v[i] * v[i];
        }
        r
    }
}

/// The slope of `log error` against `log h` between successive halvings.
pub(super) fn orders(errors: &[f64]) -> Vec<f64> {
    errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect()
}

/// The third mode of the damped chain is a damped oscillator
/// `a'' + γa' + a = 0`: `q_i = sin(πi/3) a(t)`, `a = e^{−γt/2}(cos ω t +
/// γ/(2ω) sin ω t)`, `ω = √(1 − γ²/4)`, and its energy
/// `E = ½|s|²(a'² + a²)` falls by the work of the dissipation. Both, and
/// the states, converge at order 2 for the second-order rules.
#[test]
fn a_damped_run_time_chain_loses_the_work_of_its_dissipation() {
    let gamma: f64 = 0.2;
    let s = shape();
    let norm2: f64 = s.iter().map(|x| x * x).sum();
    let omega = (1.0 - gamma * gamma / 4.0).sqrt();
    let t_end = 10.0;
    let decay = (-gamma * t_end / 2.0).exp();
    let a = decay * ((omega * t_end).cos() + gamma / (2.0 * omega) * (omega * t_end).sin());
    let da = -decay / omega * (omega * t_end).sin();
    let energy_exact = 0.5 * norm2 * (da * da + a * a);
    let problem = Problem::new(Damped { n: 8, gamma }, 0.0, s.to_vec(), vec![0.0; 8]);
    for (name, scheme) in schemes() {
        if name == "alpha-beta" {
            continue;
        }
        let (mut state_errors, mut energy_errors) = (Vec::new(), Vec::new());
        for h in [0.04, 0.02, 0.01] {
            let mut sim = problem.stepper(&scheme, h).unwrap();
            sim.run_until(t_end).unwrap();
            let q = &sim.state().q;
            state_errors.push((0..8).map(|i| (q[i] - s[i] * a).abs()).fold(0.0, f64::max));
            let e0 = 0.5 * norm2;
            // The energy lost against the work the dissipation did.
            energy_errors.push(((sim.energy().unwrap() - e0) - (energy_exact - e0)).abs());
        }
        let expected = if name == "yoshida 4" { 4.0 } else { 2.0 };
        for (what, errors) in [("state", &state_errors), ("energy", &energy_errors)] {
            for order in orders(errors) {
                assert!((order - expected).abs() < 0.15, "{name}: {what} order {order} from {errors:?}");
            }
        }
    }
}

/// The discrete energy balance of the midpoint rule (docs/theory.md §6):
/// for a quadratic `L` under fixed steps the energy of the step ahead of
/// node `k` is that of the step behind it plus the work
/// `W_k = (F_{k−1}^+ + F_k^−)·(v̂_{k−1} + v̂_k)/2` of the forces at the
/// node, to round-off and Newton's tolerance. With `F = −γ v̂`,
/// `F^− = F^+ = (h/2) F`: `W_k = −(hγ/4) |v̂_{k−1} + v̂_k|²`.
#[test]
fn midpoint_balances_the_energy_of_a_damped_run_time_chain_at_every_node() {
    let (n, gamma, h) = (8, 0.2, 0.05);
    let mut sim =
        Problem::new(Damped { n, gamma }, 0.0, shape().to_vec(), vec![0.0; 8]).stepper(&Scheme::MIDPOINT, h).unwrap();
    let (mut q, mut e) = (vec![sim.state().q.clone()], vec![sim.discrete_energy()]);
    for _ in 0..200 {
        sim.step().unwrap();
        q.push(sim.state().q.clone());
        e.push(sim.discrete_energy());
    }
    let mut largest = 0.0f64;
    for k in 1..200 {
        let work: f64 = (0..n)
            .map(|i| {
                let sum = (q[k][i] - q[k - 1][i]) / h + (q[k + 1][i] - q[k][i]) / h;
                -(h * gamma / 4.0) * sum * sum
            })
            .sum();
        largest = largest.max((e[k + 1] - e[k] - work).abs());
    }
    assert!(largest < 1e-13, "largest residual of the balance {largest:e}");
    // The balance is not empty: the chain lost most of its energy.
    assert!(e[200] < 0.5 * e[1], "{} against {}", e[200], e[1]);
}

/// A chain driven in its third mode, `Q_i = sin(πi/3) F cos Ωt`, with
/// `R = ½γ Σ v_i²`: started on the periodic response `a = A cos Ωt +
/// B sin Ωt` (`A = F(1 − Ω²)/D`, `B = FγΩ/D`, `D = (1 − Ω²)² + γ²Ω²`), it
/// stays on it. Written with the macro, the force depending on `t`.
#[derive(Clone, Debug)]
pub(super) struct Driven {
    pub(super) shape: Vec<f64>,
    pub(super) gamma: f64,
    pub(super) amplitude: f64,
    pub(super) frequency: f64,
}

#[lagrangian]
impl Driven {
    fn dimension(&self) -> usize {
        self.shape.len()
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut l = 0.0;
        for i in 0..n {
            l += 0.5 * v[i] * v[i];
        }
        l -= 0.5 * (q[0] * q[0] + q[n - 1] * q[n - 1]);
        for i in 0..n - 1 {
            let d = q[i + 1] - q[i];
            l -= 0.5 * d * d;
        }
        l
    }

    fn dissipation(&self, _q: &[f64], v: &[f64]) -> f64 {
        let mut r = 0.0;
        for i in 0..v.len() {
            r += 0.5 * self.gamma * v[i] * v[i];
        }
        r
    }

    fn force(&self, t: f64, _q: &[f64], _v: &[f64], f: &mut [f64]) {
        let drive = self.amplitude * (self.frequency * t).cos();
        for i in 0..f.len() {
            f[i] = drive * self.shape[i];
        }
    }
}

#[test]
fn a_driven_run_time_chain_follows_its_periodic_response() {
    let (gamma, amplitude, frequency): (f64, f64, f64) = (0.1, 0.5, 0.7);
    let d = (1.0 - frequency * frequency).powi(2) + (gamma * frequency).powi(2);
    let (a, b) = (amplitude * (1.0 - frequency * frequency) / d, amplitude * gamma * frequency / d);
    let response = |t: f64| a * (frequency * t).cos() + b * (frequency * t).sin();
    let s = shape();
    let system = Driven { shape: s.to_vec(), gamma, amplitude, frequency };
    let q0: Vec<f64> = s.iter().map(|x| x * a).collect();
    let v0: Vec<f64> = s.iter().map(|x| x * b * frequency).collect();
    // Neither the force nor the dissipation couples two masses.
    let diagonal = ForceCoupling { q: Pattern::Diagonal, v: Pattern::Diagonal };
    assert_eq!(<Driven as DynLagrangian>::FORCE_COUPLING, diagonal);
    let problem = Problem::new(system, 0.0, q0, v0);
    let t_end = 12.0;
    for (name, scheme) in schemes() {
        if name == "alpha-beta" {
            continue;
        }
        let mut errors = Vec::new();
        for h in [0.04, 0.02, 0.01] {
            let mut sim = problem.stepper(&scheme, h).unwrap();
            sim.run_until(t_end).unwrap();
            let q = &sim.state().q;
            errors.push((0..8).map(|i| (q[i] - s[i] * response(t_end)).abs()).fold(0.0, f64::max));
        }
        let expected = if name == "yoshida 4" { 4.0 } else { 2.0 };
        for order in orders(&errors) {
            assert!((order - expected).abs() < 0.2, "{name}: order {order} from {errors:?}");
        }
    }
}

/// A free chain (no walls) with internal forces only: a damper between
/// neighbours `R = ½κ Σ (v_{i+1} − v_i)²` and a pair force
/// `g = μ sin(q_{i+1} − q_i)(v_{i+1} − v_i)`, `+g` on `i`, `−g` on `i + 1`.
/// Neither moves the centre of mass: `Σ p` is conserved.
#[derive(Clone, Debug)]
pub(super) struct Internal {
    pub(super) n: usize,
}

#[lagrangian]
impl Internal {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut l = 0.0;
        for i in 0..n {
            l += 0.5 * v[i] * v[i];
        }
        for i in 0..n - 1 {
            let d = q[i + 1] - q[i];
            l -= 0.5 * d * d + 0.25 * d.powi(4);
        }
        l
    }

    fn dissipation(&self, _q: &[f64], v: &[f64]) -> f64 {
        let mut r = 0.0;
        for i in 0..v.len() - 1 {
            let d = v[i + 1] - v[i];
            r += 0.05 * d * d;
        }
        r
    }

    fn force(&self, _t: f64, q: &[f64], v: &[f64], f: &mut [f64]) {
        for i in 0..q.len() - 1 {
            let g = 0.3 * (q[i + 1] - q[i]).sin() * (v[i + 1] - v[i]);
            f[i] += g;
            f[i + 1] -= g;
        }
    }
}

#[test]
fn internal_forces_conserve_the_momentum_of_a_run_time_chain() {
    // The macro proves the pair force and the dampers banded: `O(N)` steps.
    let band = Pattern::Banded { bandwidth: 1 };
    assert_eq!(<Internal as DynLagrangian>::FORCE_COUPLING, ForceCoupling { q: band, v: band });
    let n = 16;
    let q0: Vec<f64> = (0..n).map(|i| 0.3 * (0.9 * i as f64).sin()).collect();
    let v0: Vec<f64> = (0..n).map(|i| 0.5 + 0.4 * (1.7 * i as f64).cos()).collect();
    let problem = Problem::new(Internal { n }, 0.0, q0, v0.clone());
    let total: f64 = v0.iter().sum();
    for (name, scheme) in schemes() {
        let mut sim = problem.stepper(&scheme, 0.05).unwrap();
        sim.run(400, |_| {}).unwrap();
        let p: f64 = sim.momenta().iter().sum();
        // 400 steps of sums of 16 terms of order 1.
        assert!((p - total).abs() < 1e-12, "{name}: Σp {p} against {total}");
        // The dampers worked: the relative velocities are smaller.
        let v = sim.velocity().unwrap();
        let spread = v.iter().map(|x| (x - total / n as f64).abs()).fold(0.0, f64::max);
        assert!(spread < 0.4, "{name}: spread {spread}");
    }
}

/// An oscillator whose force is not finite beyond `q_0 = 0.3`.
#[derive(Clone, Debug)]
pub(super) struct Breaking;

impl DynLagrangian for Breaking {
    const AUTONOMOUS: bool = true;
    const FORCE_COUPLING: ForceCoupling = ForceCoupling::NONE;
    const HAS_FORCE: bool = true;

    fn dimension(&self) -> usize {
        2
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        chain_lagrangian(q, v, true)
    }

    fn force<D: Scalar>(&self, _t: D, q: &[D], v: &[D], f: &mut [D]) {
        f[0] = (-q[0] + 0.3).sqrt() * 0.0 - v[0] * 0.01;
    }
}

#[test]
fn a_force_that_is_not_finite_is_a_typed_error_and_changes_nothing() {
    for (name, scheme) in schemes() {
        let problem = Problem::new(Breaking, 0.0, vec![0.0, 0.0], vec![1.0, 0.0]);
        let mut sim = problem.stepper(&scheme, 0.05).unwrap();
        let failure = loop {
            let before = sim.clone();
            match sim.step() {
                Ok(_) => assert!(sim.state().t < 2.0, "{name}: never failed"),
                Err(error) => break (before, error),
            }
        };
        let (before, error) = failure;
        match &error {
            lagrangian::Error::NonFinite { state, quantity, .. } => {
                assert_eq!(*quantity, "force", "{name}");
                assert_eq!(state, before.state(), "{name}: the error carries the state the step started from");
            }
            other => panic!("{name}: {other:?}"),
        }
        let bits = |s: &PhasePoint| {
            let mut b: Vec<u64> = s.q.iter().chain(&s.p).map(|x| x.to_bits()).collect();
            b.extend([s.t.to_bits(), s.step]);
            b
        };
        assert_eq!(bits(sim.state()), bits(before.state()), "{name}: the stepper is unchanged");
        // And again: the same failure from the same state.
        let again = sim.step().unwrap_err();
        assert_eq!(format!("{again:?}"), format!("{error:?}"), "{name}");
    }
    // At the initial data: refused at the start.
    let problem = Problem::new(Breaking, 0.0, vec![0.5, 0.0], vec![0.0, 0.0]);
    assert!(matches!(problem.stepper(&Scheme::MIDPOINT, 0.05), Err(lagrangian::Error::InvalidInitialData { .. })));
}

/// A damped pendulum as a point on the unit circle, sized at run time.
#[derive(Clone, Debug)]
struct DampedCircle;

impl DynLagrangian for DampedCircle {
    const AUTONOMOUS: bool = true;
    const HAS_DISSIPATION: bool = true;

    fn dimension(&self) -> usize {
        2
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        (v[0] * v[0] + v[1] * v[1]) * 0.5 - q[1]
    }

    fn dissipation<D: Scalar>(&self, _q: &[D], v: &[D]) -> D {
        (v[0] * v[0] + v[1] * v[1]) * 0.05
    }

    fn constraint_count(&self) -> usize {
        1
    }

    fn constraints<D: Scalar>(&self, _t: D, q: &[D], g: &mut [D]) {
        g[0] = q[0] * q[0] + q[1] * q[1] - 1.0;
    }
}

/// `DynConstrained`'s saddle-point steps carry no forces: a forced system
/// is refused at the start, not stepped without its forces.
#[test]
fn constrained_run_time_steps_refuse_forces() {
    let started = DynConstrained::start(DampedCircle, Midpoint, 0.01, 0.0, &[1.0, 0.0], &[0.0, 0.0]);
    assert!(
        matches!(&started, Err(lagrangian::Error::Unsupported { what }) if what.contains("forces or dissipation")),
        "{:?}",
        started.err()
    );
}
