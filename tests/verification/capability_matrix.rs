//! The capability matrix of the runtime: every discrete Lagrangian × step
//! policy × number type either integrates with a checked property or is
//! refused with a typed error. `cargo test --test verification capability_matrix:: --
//! --nocapture` prints it; with `LAGRANGIAN_CAPABILITIES=docs/capabilities.md`
//! it also writes it as that page, with the date, the machine and the
//! command. A change of capability (a cell that starts or stops working)
//! fails this test until the expectation here is updated.
use crate::common;

use common::forced::DampedOscillator;
use common::schemes::families;
use lagrangian::prelude::*;
use lagrangian::problem::{Combination, Size, supports};

/// `L = ½ v² + g cos q`, g = 9.81.
pub struct Pendulum;

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + 9.81 * q[0].cos()
    }
}

/// What a cell did: a checked number, or the error it was refused with.
type Outcome = Result<String, String>;

/// A unit pendulum under unit gravity as a point `(x, y)` on the unit circle.
pub struct CartesianPendulum;

#[lagrangian]
impl CartesianPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }
    fn constraints(&self, q: [f64; 2]) -> [f64; 1] {
        [q[0] * q[0] + q[1] * q[1] - 1.0]
    }
}

/// The same pendulum damped by `R = ½ c |v|²`, c = 0.3.
pub struct DampedCartesianPendulum;

#[lagrangian]
impl DampedCartesianPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }
    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.15 * (v[0] * v[0] + v[1] * v[1])
    }
    fn constraints(&self, q: [f64; 2]) -> [f64; 1] {
        [q[0] * q[0] + q[1] * q[1] - 1.0]
    }
}

/// A pendulum whose length grows as `1 + 0.1 t`: a moving constraint.
pub struct GrowingPendulum;

#[lagrangian]
impl GrowingPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }
    fn constraints(&self, t: f64, q: [f64; 2]) -> [f64; 1] {
        let l = 1.0 + 0.1 * t;
        [q[0] * q[0] + q[1] * q[1] - l * l]
    }
}

/// `|x² + y² − l²|`.
fn off_circle(q: [f64; 2], l: f64) -> f64 {
    (q[0] * q[0] + q[1] * q[1] - l * l).abs()
}

/// Constrained fixed steps: the largest `|g|` over 1000 steps of `h` (≤ 1e-14).
fn constrained_fixed<M: Method<f64>>(m: M, h: f64) -> Outcome {
    let q0 = [1f64.sin(), -1f64.cos()];
    let mut sim = Integrator::new(CartesianPendulum, m, h).start(0.0, q0, [0.0; 2]).map_err(|e| e.to_string())?;
    let mut worst = 0.0f64;
    for _ in 0..1000 {
        sim.step().map_err(|e| e.to_string())?;
        worst = worst.max(off_circle(sim.state().q, 1.0));
    }
    assert!(worst <= 1e-14, "{worst:e}");
    Ok(format!("max |g| {worst:.1e}"))
}

/// Constrained fixed steps of the damped pendulum: the largest `|g|` over
/// 1000 steps (≤ 1e-14), and the energy lost (> 0).
fn constrained_forced<M: Method<f64>>(m: M, h: f64) -> Outcome {
    let q0 = [1f64.sin(), -1f64.cos()];
    let mut sim = Integrator::new(DampedCartesianPendulum, m, h).start(0.0, q0, [0.0; 2]).map_err(|e| e.to_string())?;
    // Unit mass: `p = v`, `E = ½|p|² + y`.
    let energy = |s: &State<2>| 0.5 * (s.p[0] * s.p[0] + s.p[1] * s.p[1]) + s.q[1];
    let e0 = energy(sim.state());
    let mut worst = 0.0f64;
    for _ in 0..1000 {
        sim.step().map_err(|e| e.to_string())?;
        worst = worst.max(off_circle(sim.state().q, 1.0));
    }
    let lost = e0 - energy(sim.state());
    assert!(worst <= 1e-14 && lost > 0.0, "{worst:e}, {lost:e}");
    Ok(format!("max |g| {worst:.1e}, energy lost {lost:.2}"))
}

/// Constrained fixed steps with a moving constraint: the largest `|g(t, q)|`
/// over 1000 steps (≤ 1e-13).
fn constrained_moving<M: Method<f64>>(m: M, h: f64) -> Outcome {
    let mut sim =
        Integrator::new(GrowingPendulum, m, h).start(0.0, [0.0, -1.0], [1.0, -0.1]).map_err(|e| e.to_string())?;
    let mut worst = 0.0f64;
    for _ in 0..1000 {
        sim.step().map_err(|e| e.to_string())?;
        worst = worst.max(off_circle(sim.state().q, 1.0 + 0.1 * sim.state().t));
    }
    assert!(worst <= 1e-13, "{worst:e}");
    Ok(format!("max |g| {worst:.1e}"))
}

/// Constrained energy-preserving steps of the pendulum whirling over the
/// top (from the bottom at speed 3; a swing from rest loses the energy
/// root where the leading coefficient of the energy error changes sign):
/// the largest `|g|` (≤ 1e-14) and relative change of the discrete energy
/// (≤ 1e-13) over 1000 steps after the first, if they start at all.
fn constrained_energy_steps<M: Method<f64>>(m: M, h: f64) -> Outcome {
    let mut sim = Integrator::new(CartesianPendulum, m, h)
        .energy_preserving(StepBounds::around(h))
        .start(0.0, [0.0, -1.0], [3.0, 0.0])
        .map_err(|e| e.to_string())?;
    sim.step().map_err(|e| e.to_string())?;
    let e1 = sim.discrete_energy();
    let (mut worst, mut energy) = (0.0f64, 0.0f64);
    for _ in 0..1000 {
        sim.step().map_err(|e| e.to_string())?;
        worst = worst.max(off_circle(sim.state().q, 1.0));
        energy = energy.max((sim.discrete_energy() - e1).abs() / e1.abs());
    }
    assert!(worst <= 1e-14 && energy <= 1e-13, "{worst:e}, {energy:e}");
    Ok(format!("max |g| {worst:.1e}, energy error {energy:.1e}"))
}

/// A chain of 10 000 links (N = 20 000) under `DynConstrained`: the
/// largest `|g|` over 5 steps of 1e-3 (≤ 8ε·max|q|), and the bandwidth of
/// the saddle-point matrix.
fn constrained_large<R: DiscreteLagrangian>(rule: R) -> Outcome {
    let (g, _, q_max, bandwidth) = common::links::run(10_000, rule, 1e-3, 5).map_err(|e| e.to_string())?;
    assert!(g <= 8.0 * f64::EPSILON * q_max, "{g:e}");
    Ok(format!("N = 20 000: max |g| {g:.1e}, saddle-point bandwidth {bandwidth}"))
}

/// The large-`N` cell of a family `DynConstrained` cannot take (its rule
/// type is not a one-point discrete Lagrangian): no value to refuse.
const NO_LARGE: &str = "no such integrator: `DynConstrained` takes the one-point rules (midpoint, trapezoid, α-β)";

/// One row of the constraints table: fixed, forces, moving constraints,
/// energy-preserving steps, large N.
fn constrained_row<M: Method<f64> + Copy>(m: M, h: f64, large: Outcome) -> [Outcome; 5] {
    [constrained_fixed(m, h), constrained_forced(m, h), constrained_moving(m, h), constrained_energy_steps(m, h), large]
}

/// The constraints table: each constrained family × what it is asked to
/// carry, as markdown, with whether each cell works.
fn constraints_table() -> (String, Vec<Vec<bool>>) {
    let ab = AlphaBeta::new(0.3).unwrap();
    let rows: Vec<(&str, [Outcome; 5])> = vec![
        (
            "constrained midpoint",
            constrained_row(Constrained::<_, 1>::new(Midpoint), 0.01, constrained_large(Midpoint)),
        ),
        (
            "constrained trapezoid",
            constrained_row(Constrained::<_, 1>::new(Trapezoid), 0.01, constrained_large(Trapezoid)),
        ),
        ("constrained α-β (α = 0.3)", constrained_row(Constrained::<_, 1>::new(ab), 0.01, constrained_large(ab))),
        (
            "constrained Galerkin s = 2",
            constrained_row(Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss()), 0.05, Err(NO_LARGE.into())),
        ),
        (
            "constrained Galerkin s = 3",
            constrained_row(Constrained::<_, 1>::galerkin(Galerkin::<3, 3>::gauss()), 0.05, Err(NO_LARGE.into())),
        ),
        (
            "constrained Yoshida 4",
            constrained_row(Constrained::<_, 1>::composition(Composition::YOSHIDA4), 0.01, Err(NO_LARGE.into())),
        ),
    ];
    let columns = [
        "fixed: Cartesian pendulum",
        "forces: damped pendulum",
        "moving constraint: growing pendulum",
        "energy-preserving steps",
        "large N: chain of 10 000 links, run-time-sized",
    ];
    let mut table = format!("| method | {} |\n|---|{}\n", columns.join(" | "), "---|".repeat(columns.len()));
    let mut cells = Vec::new();
    for (name, outcomes) in &rows {
        // `|g|` in a cell would end it: markdown needs the bars escaped.
        let text: Vec<String> = outcomes
            .iter()
            .map(|o| match o {
                Ok(s) => format!("works: {s}"),
                Err(e) => format!("refused: {e}"),
            })
            .map(|cell| cell.replace('|', "\\|"))
            .collect();
        table += &format!("| {name} | {} |\n", text.join(" | "));
        cells.push(outcomes.iter().map(Result::is_ok).collect::<Vec<_>>());
    }
    (table, cells)
}

fn damped() -> DampedOscillator {
    DampedOscillator { m: 1.0, k: 4.0, c: 0.5 }
}

/// Fixed steps on the pendulum from 1 rad: relative spread of the energy over 1000 steps of `h` (≤ `tolerance`).
fn fixed<M: F64Readouts>(m: M, h: f64, tolerance: f64) -> Outcome {
    let mut sim = Integrator::new(Pendulum, m, h).start(0.0, [1.0], [0.0]).map_err(|e| e.to_string())?;
    let e0 = sim.energy().map_err(|e| e.to_string())?;
    let mut worst = 0.0f64;
    for _ in 0..1000 {
        sim.step().map_err(|e| e.to_string())?;
        worst = worst.max(((sim.energy().map_err(|e| e.to_string())? - e0) / e0).abs());
    }
    assert!(worst <= tolerance, "{worst:e}");
    Ok(format!("energy spread {worst:.1e}"))
}

/// Energy-preserving steps on the pendulum: discrete energy over 1000 steps (≤ 1e-12).
fn energy_steps<M: Method<f64>>(m: M, h: f64) -> Outcome {
    let mut sim = Integrator::new(Pendulum, m, h)
        .energy_preserving(StepBounds::around(h))
        .start(0.0, [1.0], [0.0])
        .map_err(|e| e.to_string())?;
    sim.step().map_err(|e| e.to_string())?;
    let e1 = sim.discrete_energy();
    let mut worst = 0.0f64;
    for _ in 0..1000 {
        sim.step().map_err(|e| e.to_string())?;
        worst = worst.max(((sim.discrete_energy() - e1) / e1).abs());
    }
    assert!(worst <= 1e-12, "{worst:e}");
    Ok(format!("discrete energy {worst:.1e}"))
}

/// Forced fixed steps on the damped oscillator: error of q(4) against the exact solution.
fn forced<M: Method<f64>>(m: M, h: f64, tolerance: f64) -> Outcome {
    let mut sim = Integrator::new(damped(), m, h).start(0.0, [1.0], [0.0]).map_err(|e| e.to_string())?;
    sim.run_until(4.0, |_| {}).map_err(|e| e.to_string())?;
    let err = (sim.state().q[0] - damped().exact(1.0, 4.0)[0]).abs();
    assert!(err <= tolerance, "{err:e}");
    Ok(format!("q(4) error {err:.1e}"))
}

/// Forced variable steps of a one-point rule in f64 (energy-balance steps) on
/// the damped oscillator up to t = 3: the balance `E_{k+1} − E_k − W_k` at every
/// node (≤ 1e-13 relative).
fn forced_balance<M: DiscreteLagrangian>(m: M) -> Outcome {
    let mut sim = Integrator::new(damped(), m, 0.01)
        .energy_preserving(StepBounds::around(0.01))
        .start(0.0, [1.0], [0.0])
        .map_err(|e| e.to_string())?;
    let mut worst = 0.0f64;
    while sim.state().t < 3.0 {
        sim.step().map_err(|e| e.to_string())?;
        if let Some(b) = sim.energy_balance() {
            let scale = b.energy_before.abs() + b.energy_after.abs() + b.variational_work.abs();
            worst = worst.max(b.variational_residual().abs() / scale);
        }
    }
    assert!(worst <= 1e-13, "{worst:e}");
    Ok(format!("energy balance {worst:.1e}"))
}

/// Forced energy-preserving steps where they are refused: only `start`.
fn forced_variable<T: Real, M: Method<T>>(m: M, h: f64) -> Outcome {
    Integrator::new(damped(), m, T::from(h))
        .energy_preserving(StepBounds::around(h))
        .start(T::from(0.0), [T::from(1.0)], [T::from(0.0)])
        .map(|_| "started".to_string())
        .map_err(|e| e.to_string())
}

type Dd = DoubleDouble;

fn dd(x: f64) -> Dd {
    Dd::from(x)
}

/// Double-double fixed steps on the pendulum: q after 100 steps agrees with
/// the f64 run of the same method to f64 round-off.
fn double_double<M: Method<f64>, D: Method<Dd>>(m: M, m_dd: D, h: f64) -> Outcome {
    let mut sim =
        Integrator::new(Pendulum, m_dd, dd(h)).start(dd(0.0), [dd(1.0)], [dd(0.0)]).map_err(|e| e.to_string())?;
    let mut reference = Integrator::new(Pendulum, m, h).start(0.0, [1.0], [0.0]).map_err(|e| e.to_string())?;
    sim.run(100, |_| {}).map_err(|e| e.to_string())?;
    reference.run(100, |_| {}).map_err(|e| e.to_string())?;
    let diff = (sim.state().q[0].to_f64() - reference.state().q[0]).abs();
    assert!(diff <= 1e-12, "{diff:e}");
    Ok(format!("agrees with f64 to {diff:.1e}"))
}

/// Double-double energy-preserving steps on the pendulum: discrete energy over 300 steps (≤ 1e-27).
fn double_double_energy_steps<D: Method<Dd>>(m: D, h: f64) -> Outcome {
    let mut sim = Integrator::new(Pendulum, m, dd(h))
        .energy_preserving(StepBounds::around(h))
        .newton(NewtonOptions { rtol: 1e-30, ..NewtonOptions::default() })
        .start(dd(0.0), [dd(1.0)], [dd(0.0)])
        .map_err(|e| e.to_string())?;
    sim.step().map_err(|e| e.to_string())?;
    let e1 = sim.discrete_energy();
    let mut worst = 0.0f64;
    for _ in 0..300 {
        sim.step().map_err(|e| e.to_string())?;
        worst = worst.max(((sim.discrete_energy() - e1) / e1).abs().to_f64());
    }
    assert!(worst <= 1e-27, "{worst:e}");
    Ok(format!("discrete energy {worst:.1e}"))
}

/// Double-double forced fixed steps on the damped oscillator: error of q(4).
fn double_double_forced<D: Method<Dd>>(m: D, h: f64, tolerance: f64) -> Outcome {
    let mut sim =
        Integrator::new(damped(), m, dd(h)).start(dd(0.0), [dd(1.0)], [dd(0.0)]).map_err(|e| e.to_string())?;
    sim.run_until(dd(4.0), |_| {}).map_err(|e| e.to_string())?;
    let err = (sim.state().q[0].to_f64() - damped().exact(1.0, 4.0)[0]).abs();
    assert!(err <= tolerance, "{err:e}");
    Ok(format!("q(4) error {err:.1e}"))
}

/// One row: every cell for one method, given in f64 and in double-double.
fn row<M: F64Readouts + Copy, D: Method<Dd> + Copy>(
    m: M,
    m_dd: D,
    h: f64,
    tol: [f64; 2],
    forced_variable_f64: Outcome,
) -> [Outcome; 8] {
    [
        fixed(m, h, tol[0]),
        energy_steps(m, h),
        forced(m, h, tol[1]),
        forced_variable_f64,
        double_double(m, m_dd, h),
        double_double_energy_steps(m_dd, h),
        double_double_forced(m_dd, h, tol[1]),
        forced_variable::<Dd, D>(m_dd, h),
    ]
}

#[test]
fn every_cell_integrates_with_its_property_or_is_refused_typed() {
    let ab = AlphaBeta::new(0.3).unwrap();
    let rows: Vec<(&str, [Outcome; 8])> = vec![
        ("midpoint", row(Midpoint, Midpoint, 0.01, [1e-3, 1e-4], forced_balance(Midpoint))),
        ("trapezoid", row(Trapezoid, Trapezoid, 0.01, [1e-3, 1e-4], forced_balance(Trapezoid))),
        ("α-β (α = 0.3)", row(ab, ab, 0.01, [2e-2, 1e-2], forced_balance(ab))),
        (
            "Galerkin s = 2",
            row(
                Galerkin::<2, 2>::gauss(),
                Galerkin::<2, 2, Dd>::gauss(),
                0.05,
                [1e-4, 1e-5],
                forced_variable::<f64, _>(Galerkin::<2, 2>::gauss(), 0.05),
            ),
        ),
        (
            "Galerkin s = 4",
            row(
                Galerkin::<4, 4>::gauss(),
                Galerkin::<4, 4, Dd>::gauss(),
                0.05,
                [1e-4, 1e-5],
                forced_variable::<f64, _>(Galerkin::<4, 4>::gauss(), 0.05),
            ),
        ),
    ];
    let columns = [
        "fixed (f64)",
        "energy-preserving (f64)",
        "forced fixed (f64)",
        "forced variable (f64)",
        "fixed (DoubleDouble)",
        "energy-preserving (DoubleDouble)",
        "forced fixed (DoubleDouble)",
        "forced variable (DoubleDouble)",
    ];
    let mut table = format!("| method | {} |\n|---|{}\n", columns.join(" | "), "---|".repeat(columns.len()));
    let mut cells = Vec::new();
    for (name, outcomes) in &rows {
        let text: Vec<String> = outcomes
            .iter()
            .map(|o| match o {
                Ok(s) => format!("works: {s}"),
                Err(e) => format!("refused: {}", e.chars().take(90).collect::<String>()),
            })
            .collect();
        table += &format!("| {name} | {} |\n", text.join(" | "));
        cells.push(outcomes.iter().map(Result::is_ok).collect::<Vec<_>>());
    }
    print!("{table}");
    let (schemes, defined) = scheme_table();
    print!("{schemes}");
    let (constraints, constrained_cells) = constraints_table();
    print!("{constraints}");
    if let Some(page) = std::env::var_os("LAGRANGIAN_CAPABILITIES") {
        std::fs::write(&page, capabilities_page(&table, &schemes, &constraints))
            .expect("the capabilities page is writable");
    }
    // Constraints: every family carries them with fixed steps, forces and
    // moving constraints; the one-point and Galerkin rules take
    // energy-preserving steps, the compositions not (as without
    // constraints); the run-time-sized chain runs under the one-point rules.
    let one_point = vec![true, true, true, true, true];
    let galerkin = vec![true, true, true, true, false];
    let composition = vec![true, true, true, false, false];
    assert_eq!(
        constrained_cells,
        vec![one_point.clone(), one_point.clone(), one_point, galerkin.clone(), galerkin, composition],
        "constraints table:\n{constraints}"
    );
    // What `supports` defines: every family with fixed steps at compile-time
    // size; energy steps for the one-point and Galerkin rules (balance
    // steps, of a forced system, for the one-point rules); forces with
    // fixed steps but for the splitting; no compile-time size above 1024;
    // at run-time size fixed steps and `solve` of the one-point rules, the
    // Galerkin rules, the compositions and the implicit time
    // transformation, forced or not, of the splitting, unforced,
    // energy-preserving steps of the one-point and Galerkin rules and
    // energy-balance steps of the one-point rules;
    // sensitivities and the adjoint for fixed steps of
    // the one-point rules, the Galerkin rules, the trapezoid compositions and the
    // implicit time transformation, forced or not, for energy-preserving
    // steps of the one-point and Galerkin rules, for energy-balance steps
    // of the one-point rules, and for the splitting, unforced.
    let one_point = [true, true, true, true, false, true, true, true, true, true, true, true, true, true];
    let galerkin = [true, true, false, true, false, true, true, true, true, false, true, true, true, false];
    let composition = [true, false, false, true, false, true, true, true, false, false, true, true, false, false];
    let transformed = [true, false, false, true, false, true, true, true, false, false, true, true, false, false];
    let splitting = [true, false, false, false, false, true, true, false, false, false, true, false, false, false];
    // Compositions of midpoint and Galerkin sub-steps: fixed steps at both
    // sizes, forced or not; no sensitivities.
    let composed = [true, false, false, true, false, true, true, true, false, false, false, false, false, false];
    let expected = [
        one_point,
        one_point,
        one_point,
        galerkin,
        galerkin,
        galerkin,
        composition,
        composition,
        composition,
        transformed,
        transformed,
        splitting,
        composed,
        composed,
    ];
    assert_eq!(defined, expected);
    // The expectation: what works today. Energy-preserving trapezoid, α-β
    // (α ≠ ½) and Galerkin s = 4 lose the root of the energy equation on the
    // pendulum from rest within a fraction of a swing (typed NoEnergyStep;
    // docs/energy-steps.md says why), in either number type, forced or not;
    // forced variable (energy-balance) steps exist for the one-point rules in
    // f64 and are refused (`Unsupported`) for Galerkin rules and in
    // double-double.
    let expected = [
        [true, true, true, true, true, true, true, false],
        [true, false, true, false, true, false, true, false],
        [true, false, true, false, true, false, true, false],
        [true, true, true, false, true, true, true, false],
        [true, false, true, false, true, false, true, false],
    ];
    for (row, (cells, expected)) in cells.iter().zip(expected).enumerate() {
        assert_eq!(cells.as_slice(), expected.as_slice(), "row {} ({})", row, rows[row].0);
    }
}

/// A column of the scheme table: its name, the policy from a step, the
/// size, whether the system is forced, and what is asked.
type Column = (&'static str, fn(f64) -> Policy, Size, bool, Capability);

/// The columns of the scheme table.
const SCHEME_COLUMNS: [Column; 14] = [
    ("fixed, N = 2", Policy::fixed, Size::Const(2), false, Capability::Solve),
    ("energy-preserving, N = 2", Policy::energy_preserving, Size::Const(2), false, Capability::Solve),
    ("energy-balance, forced, N = 2", Policy::energy_balance, Size::Const(2), true, Capability::Solve),
    ("fixed, forced, N = 2", Policy::fixed, Size::Const(2), true, Capability::Solve),
    ("fixed, N = 1025", Policy::fixed, Size::Const(1025), false, Capability::Solve),
    ("fixed, run-time N: step, `run_until`", Policy::fixed, Size::Dynamic, false, Capability::Step),
    ("fixed, run-time N: `solve`, files", Policy::fixed, Size::Dynamic, false, Capability::Solve),
    ("fixed, forced, run-time N: step, `solve`", Policy::fixed, Size::Dynamic, true, Capability::Solve),
    (
        "energy-preserving, run-time N: step, `solve`",
        Policy::energy_preserving,
        Size::Dynamic,
        false,
        Capability::Solve,
    ),
    ("energy-balance, forced, run-time N", Policy::energy_balance, Size::Dynamic, true, Capability::Solve),
    ("sensitivities, adjoint: fixed, N = 2", Policy::fixed, Size::Const(2), false, Capability::Sensitivities),
    ("sensitivities, adjoint: fixed, forced, N = 2", Policy::fixed, Size::Const(2), true, Capability::Sensitivities),
    (
        "sensitivities, adjoint: energy-preserving, N = 2",
        Policy::energy_preserving,
        Size::Const(2),
        false,
        Capability::Sensitivities,
    ),
    (
        "sensitivities, adjoint: energy-balance, forced, N = 2",
        Policy::energy_balance,
        Size::Const(2),
        true,
        Capability::Sensitivities,
    ),
];

/// Every method family × step policy × size through `Problem` (arrays or
/// vectors): what `lagrangian::problem::supports` answers, the
/// markdown table and whether each cell is defined.
fn scheme_table() -> (String, Vec<[bool; 14]>) {
    let names: Vec<&str> = SCHEME_COLUMNS.iter().map(|c| c.0).collect();
    let mut table = format!("| scheme | {} |\n|---|{}\n", names.join(" | "), "---|".repeat(names.len()));
    let mut defined = Vec::new();
    for (name, scheme, _) in families() {
        let mut row = [false; 14];
        let cells: Vec<String> = SCHEME_COLUMNS
            .iter()
            .zip(&mut row)
            .map(|(&(_, policy, size, forced, capability), cell)| {
                let query =
                    Combination { scheme: &scheme, policy: policy(0.01), size, forced, constraints: 0, capability };
                match supports(&query) {
                    Ok(()) => {
                        *cell = true;
                        "defined".to_string()
                    }
                    Err(why) => format!("refused: {why}"),
                }
            })
            .collect();
        table += &format!("| {name} | {} |\n", cells.join(" | "));
        defined.push(row);
    }
    (table, defined)
}

/// The generated page `docs/capabilities.md`: the matrices with where and
/// how they were made.
fn capabilities_page(table: &str, schemes: &str, constraints: &str) -> String {
    let days = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs() / 86_400);
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!(
        "# Capabilities\n\n\
         Generated by the capability-matrix test on {} ({}/{}, {cores} cores): \
         `LAGRANGIAN_CAPABILITIES=docs/capabilities.md cargo test --test verification capability_matrix::`. \
         Do not edit by hand.\n\n\
         Every discrete Lagrangian × step policy × number type on the pendulum from 1 rad (forced: a damped \
         oscillator) either integrates with the property named, checked, or is refused with a typed error, \
         quoted. The test fails when a cell changes.\n\n{table}\n\
         ## One way in: `Problem`, `Scheme` and `Policy`\n\n\
         What `lagrangian::problem::supports` answers for each method family as a `Scheme` value, each step \
         `Policy` and each size (compile-time `N`, `Problem<S, Dim<N>>` stated with arrays, and run-time, `Problem<S, Dyn>` stated \
         with vectors); a refused cell is the `Error::Unsupported` that `Problem::stepper` and `Problem::solve` \
         return at construction, with this text. A defined cell may still be refused by its driver for the \
         values of a system (a mass matrix that is not constant for the splitting; the energy equation without \
         a root, as above). The behaviour test `method_matrix` steps, lands, solves and writes every defined \
         fixed-step cell.\n\n{schemes}\n\
         ## Holonomic constraints\n\n\
         Each constrained family (`Constrained`) on a pendulum written as a point on the unit circle, from 1 rad at \
         rest: fixed steps (largest `|g|` over 1000 steps), with Rayleigh damping (largest `|g|` and the energy \
         lost), with a constraint that moves (a length growing as `1 + 0.1 t`), with energy-preserving steps (whirling over \
         the top from the bottom at speed 3, largest `|g|` and relative change of the discrete energy over 1000 \
         steps: a swing from rest has no energy root where the leading coefficient of the energy error changes \
         sign, at 0.795 rad for the midpoint rule); and a \
         hanging chain of 10 000 planar links in Cartesian coordinates (N = 20 000, M = 10 000) under the \
         run-time-sized `DynConstrained`, whose saddle-point systems are banded (largest `|g|` over 5 steps). A \
         refused cell quotes the typed error; `no such integrator` marks a combination that has no type to \
         refuse it.\n\n{constraints}",
        civil_date(days as i64),
        std::env::consts::OS,
        std::env::consts::ARCH,
    )
}

/// `YYYY-MM-DD` of a day count from 1970-01-01 (Howard Hinnant's `civil_from_days`).
fn civil_date(days: i64) -> String {
    let z = days + 719_468;
    let (era, doe) = (z.div_euclid(146_097), z.rem_euclid(146_097));
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let (d, m) = (doy - (153 * mp + 2) / 5 + 1, if mp < 10 { mp + 3 } else { mp - 9 });
    format!("{:04}-{m:02}-{d:02}", yoe + era * 400 + i64::from(m <= 2))
}

#[test]
fn day_counts_become_calendar_dates() {
    assert_eq!(civil_date(0), "1970-01-01");
    assert_eq!(civil_date(11_016), "2000-02-29");
    assert_eq!(civil_date(20_785), "2026-11-28");
}
