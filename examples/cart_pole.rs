//! Swing-up of a cart-pole as discrete mechanics and optimal control: the
//! force on the cart is a piecewise-linear function of time through 31
//! values on a fixed grid, an array field declared as the parameters of the
//! system (`parameters(u: [f64; CONTROLS])`), and the
//! controls are chosen so that the discrete trajectory ends with the pole
//! upright and the cart back at the origin, at rest.
//!
//! The cart (mass `M`, position `x`) carries a pole of length `ℓ` with a
//! point mass `m` at its tip, at angle `φ` from hanging down:
//! `L = ½ (M + m) ẋ² + m ℓ ẋ φ̇ cos φ + ½ m ℓ² φ̇² + m g ℓ cos φ`, with the
//! force `u(t)` on `x`. The dynamics are the midpoint rule's discrete
//! Lagrange–d'Alembert equations, which the run satisfies to the Newton
//! tolerance whatever the controls: the optimisation only chooses `u`.
//!
//! The terminal residual `r(u) = (x_n, φ_n − π, p_x,n, p_φ,n)` is four
//! equations in 31 unknowns. Each row of its Jacobian is the gradient of
//! one component, one discrete adjoint (`Problem::gradient`, a terminal
//! loss that is that component). The controls are updated by
//! minimum-norm Gauss–Newton steps on `r(u) = 0` with a control-effort
//! regulariser: each step solves the linearised constraint `r + J δ = 0`
//! with the smallest `|δ|² + ρ |u + δ|²` (a 4 × 4 system in the Lagrange
//! multipliers), halved until `|r|` decreases. A penalty `|r|² + ρ|u|²`
//! for a quasi-Newton optimiser would stop at a residual of the order of
//! `ρ`, not at the 1e-8 the terminal condition asks for. While the
//! regulariser acts, `|r|` falls linearly; below 1e-2 it is dropped
//! (`ρ = 0`), and the minimum-norm Newton steps of the terminal condition
//! itself take `|r|` to round-off quadratically. The controls found are a
//! swing-up biased toward small forces, not the minimum of the effort
//! subject to the terminal condition.
//!
//! Run with `cargo run --release --example cart_pole`: it prints the
//! iterations and writes the pole angle, cart position and control against
//! time to `target/example-output/cart_pole/` (or `$LAGRANGIAN_OUT`). Its
//! test (`cargo test -p lagrangian-examples --example cart_pole`) checks the
//! adjoint gradient of a loss against central differences and that the
//! swing-up lands within 1e-8 of the target, on a coarser time step.

#[path = "support/plot.rs"]
mod plot;

use std::error::Error;
use std::f64::consts::PI;

use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};

/// Mass of the cart [kg].
const M_CART: f64 = 1.0;
/// Mass at the tip of the pole [kg].
const M_POLE: f64 = 0.2;
/// Length of the pole [m].
const LENGTH: f64 = 0.5;
/// Gravity [m/s²].
const G: f64 = 9.81;
/// Duration of the manoeuvre [s].
const T_END: f64 = 3.0;
/// Intervals of the control grid.
const INTERVALS: usize = 30;
/// Control values: one at each node of the grid.
const CONTROLS: usize = INTERVALS + 1;
/// Spacing of the control grid [s].
const DT: f64 = T_END / INTERVALS as f64;

/// A cart-pole whose cart is pushed by `u(t)`, linear between the values
/// `u[0], …, u[30]` at the nodes of the control grid: one array parameter,
/// `θ = u`.
#[derive(Clone, Debug, Default)]
pub struct CartPole {
    u: [f64; CONTROLS],
}

#[lagrangian(parameters(u: [f64; CONTROLS]))]
impl CartPole {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let (c, ml) = (q[1].cos(), M_POLE * LENGTH);
        0.5 * (M_CART + M_POLE) * v[0] * v[0] + ml * v[0] * v[1] * c + 0.5 * ml * LENGTH * v[1] * v[1] + ml * G * c
    }

    fn force(&self, t: f64, _q: [f64; 2], _v: [f64; 2]) -> [f64; 2] {
        let u = self.u;
        // The grid interval holding `t` (the last one from `T_END` on). The
        // time step divides the grid spacing (`step`), so no step straddles
        // a node and the force is linear in `t` over each step.
        let mut k = (t / DT) as usize;
        if k > INTERVALS - 1 {
            k = INTERVALS - 1;
        }
        let s = t / DT - k as f64;
        [u[k] + (u[k + 1] - u[k]) * s, 0.0]
    }
}

/// The terminal residual `(x, φ − π, p_x, p_φ)`: zero with the pole
/// upright and the cart at the origin, at rest.
fn residual<D: Scalar>(q: [D; 2], p: [D; 2]) -> [D; 4] {
    [q[0], q[1] - PI, p[0], p[1]]
}

/// One component of the terminal residual as a loss: its adjoint gradient
/// is that row of the Jacobian `∂r/∂u`.
struct Component(usize);

impl Loss<2, CONTROLS> for Component {
    fn terminal<D: Scalar>(&self, _t: D, q: [D; 2], p: [D; 2], _u: &[D; CONTROLS]) -> D {
        residual(q, p)[self.0]
    }
}

/// `∫ u² dt` of the piecewise-linear control through the values `u`.
fn effort<D: Scalar>(u: &[D; CONTROLS]) -> D {
    u.windows(2).fold(D::zero(), |sum, w| sum + (w[0] * w[0] + w[0] * w[1] + w[1] * w[1]) * (DT / 3.0))
}

/// `½ |r|² + ½ ρ ∫ u² dt`: the scalar loss whose adjoint gradient the test
/// compares with central differences.
#[cfg(test)]
struct Misfit {
    rho: f64,
}

#[cfg(test)]
impl Loss<2, CONTROLS> for Misfit {
    fn terminal<D: Scalar>(&self, _t: D, q: [D; 2], p: [D; 2], u: &[D; CONTROLS]) -> D {
        let misfit = residual(q, p).iter().fold(D::zero(), |sum, &r| sum + r * r * 0.5);
        misfit + effort(u) * (0.5 * self.rho)
    }
}

/// The problem with controls `u`: from rest, hanging down.
fn problem(u: [f64; CONTROLS]) -> Problem<CartPole, Dim<2>> {
    Problem::new(CartPole::default().with_parameters(u), 0.0, [0.0, 0.0], [0.0, 0.0])
}

/// The time step with `steps` midpoint steps per interval of the control
/// grid.
fn step(steps: usize) -> f64 {
    DT / steps as f64
}

/// The run with controls `u` at time step `h`.
fn trajectory(u: [f64; CONTROLS], h: f64) -> Result<Solution, Box<dyn Error>> {
    let sol = problem(u).solve(&Scheme::MIDPOINT, h, Plan::until(T_END))?;
    if let Some(e) = sol.error {
        return Err(e.into());
    }
    Ok(sol)
}

/// The terminal residual of the run with controls `u`.
fn terminal(u: [f64; CONTROLS], h: f64) -> Result<[f64; 4], Box<dyn Error>> {
    let sol = trajectory(u, h)?;
    let last = sol.len() - 1;
    Ok(residual(sol.q[last].try_into()?, sol.p[last].try_into()?))
}

/// The checkpoints of an adjoint over `T_END` at step `h`: about `√n`.
fn checkpoints(h: f64) -> Checkpoints {
    Checkpoints::Budget(((T_END / h).sqrt().ceil() as usize).max(1))
}

/// The terminal residual `r` and its Jacobian `∂r/∂u` (rows).
type Linearised = ([f64; 4], [[f64; CONTROLS]; 4]);

/// The terminal residual and its Jacobian `∂r/∂u`, one adjoint per row.
fn jacobian(u: [f64; CONTROLS], h: f64) -> Result<Linearised, Box<dyn Error>> {
    let (mut r, mut jac) = ([0.0; 4], [[0.0; CONTROLS]; 4]);
    for i in 0..4 {
        let g = problem(u).gradient(&Scheme::MIDPOINT, h, T_END, &Component(i), checkpoints(h))?;
        r[i] = g.value;
        jac[i] = g.theta;
    }
    Ok((r, jac))
}

/// Solves the symmetric positive definite `a x = b` by Cholesky; `None`
/// when `a` is not positive definite (a rank-deficient Jacobian).
fn cholesky_solve(mut a: [[f64; 4]; 4], mut b: [f64; 4]) -> Option<[f64; 4]> {
    for j in 0..4 {
        let d = a[j][j] - (0..j).map(|k| a[j][k] * a[j][k]).sum::<f64>();
        if !(d.is_finite() && d > 0.0) {
            return None;
        }
        a[j][j] = d.sqrt();
        for i in j + 1..4 {
            a[i][j] = (a[i][j] - (0..j).map(|k| a[i][k] * a[j][k]).sum::<f64>()) / a[j][j];
        }
    }
    for i in 0..4 {
        b[i] = (b[i] - (0..i).map(|k| a[i][k] * b[k]).sum::<f64>()) / a[i][i];
    }
    for i in (0..4).rev() {
        b[i] = (b[i] - (i + 1..4).map(|k| a[k][i] * b[k]).sum::<f64>()) / a[i][i];
    }
    Some(b)
}

/// The step `δ` with the smallest `|δ|² + ρ |u + δ|²` subject to
/// `r + J δ = 0`: `δ = −(ρ u + Jᵀμ)/(1 + ρ)` with
/// `J Jᵀ μ = (1 + ρ) r − ρ J u`.
fn newton_step(u: &[f64; CONTROLS], r: &[f64; 4], jac: &[[f64; CONTROLS]; 4], rho: f64) -> Option<[f64; CONTROLS]> {
    let dot = |a: &[f64; CONTROLS], b: &[f64; CONTROLS]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let jjt: [[f64; 4]; 4] = core::array::from_fn(|i| core::array::from_fn(|k| dot(&jac[i], &jac[k])));
    let rhs: [f64; 4] = core::array::from_fn(|i| (1.0 + rho) * r[i] - rho * dot(&jac[i], u));
    let mu = cholesky_solve(jjt, rhs)?;
    Some(core::array::from_fn(|j| -(rho * u[j] + (0..4).map(|i| jac[i][j] * mu[i]).sum::<f64>()) / (1.0 + rho)))
}

/// The largest component of `r`.
fn norm(r: &[f64; 4]) -> f64 {
    r.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// An optimised swing-up.
#[derive(Clone, Debug)]
pub struct SwingUp {
    /// The control values at the nodes of the grid [N].
    pub controls: [f64; CONTROLS],
    /// The terminal residual `(x, φ − π, p_x, p_φ)` of the run with them.
    pub residual: [f64; 4],
    /// The largest component of the residual after each iteration.
    pub history: Vec<f64>,
}

/// Regulariser of the control effort in the Gauss–Newton steps.
const RHO: f64 = 0.3;
/// Below this terminal residual the regulariser is dropped.
const POLISH: f64 = 1e-2;
/// The terminal residual the optimisation stops at.
const TARGET: f64 = 1e-10;

/// Swings the pole up with `steps` midpoint steps per interval of the
/// control grid, from the controls `start`.
pub fn swing_up(start: [f64; CONTROLS], steps: usize) -> Result<SwingUp, Box<dyn Error>> {
    let h = step(steps);
    let mut u = start;
    let mut history = Vec::new();
    for _ in 0..100 {
        let (r, jac) = jacobian(u, h)?;
        let size = norm(&r);
        if size <= TARGET {
            return Ok(SwingUp { controls: u, residual: r, history });
        }
        let rho = if size > POLISH { RHO } else { 0.0 };
        let delta = newton_step(&u, &r, &jac, rho).ok_or("the terminal state's Jacobian is rank deficient")?;
        // Halve the step until the terminal residual decreases (a run that
        // fails, its Newton iteration diverging, counts as no decrease).
        let mut alpha = 1.0;
        loop {
            let trial: [f64; CONTROLS] = core::array::from_fn(|j| u[j] + alpha * delta[j]);
            if let Ok(r) = terminal(trial, h)
                && norm(&r) < size
            {
                u = trial;
                history.push(norm(&r));
                break;
            }
            alpha *= 0.5;
            if alpha < 1e-6 {
                return Err("no step along the Gauss–Newton direction decreases the terminal residual".into());
            }
        }
    }
    Err("the swing-up did not converge in 100 iterations".into())
}

fn main() -> Result<(), Box<dyn Error>> {
    let steps = 10;
    let h = step(steps);
    println!(
        "cart-pole swing-up: M = {M_CART} kg, m = {M_POLE} kg, ℓ = {LENGTH} m, {CONTROLS} control values over \
         {T_END} s, midpoint rule h = {h}"
    );
    let swing = swing_up([0.0; CONTROLS], steps)?;
    println!("max |r| after each of {} Gauss–Newton iterations:", swing.history.len());
    for row in swing.history.chunks(8) {
        println!("  {}", row.iter().map(|r| format!("{r:.2e}")).collect::<Vec<_>>().join(" "));
    }
    let r = swing.residual;
    println!("terminal residual (x, φ − π, p_x, p_φ) = ({:.1e}, {:.1e}, {:.1e}, {:.1e})", r[0], r[1], r[2], r[3]);
    let peak = swing.controls.iter().fold(0.0f64, |m, u| m.max(u.abs()));
    println!("control effort ∫u² dt = {:.3} N²s, peak |u| = {peak:.2} N", effort(&swing.controls));

    let sol = trajectory(swing.controls, h)?;
    let angle: Vec<(f64, f64)> = sol.t.iter().zip(&sol.q).map(|(&t, q)| (t, q[1])).collect();
    let cart: Vec<(f64, f64)> = sol.t.iter().zip(&sol.q).map(|(&t, q)| (t, q[0])).collect();
    let control: Vec<(f64, f64)> = swing.controls.iter().enumerate().map(|(j, &u)| (j as f64 * DT, u)).collect();
    let dir = plot::output_dir("cart_pole")?;
    Figure {
        title: "Cart-pole swing-up: controls by Gauss–Newton with adjoint Jacobians, midpoint rule",
        x_label: "t [s]",
        x_range: (0.0, T_END),
        equal_axes: false,
        panels: vec![
            Panel {
                y_label: "pole angle φ [rad]", series: vec![Series { label: "", points: &angle, markers: false }]
            },
            Panel { y_label: "cart position x [m]", series: vec![Series { label: "", points: &cart, markers: false }] },
            Panel { y_label: "force u [N]", series: vec![Series { label: "", points: &control, markers: true }] },
        ],
    }
    .save(&dir.join("cart_pole"), 1000)?;
    println!("plots: {}", dir.join("cart_pole.png").display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Steps per control interval in the tests: coarse, so that the
    /// unoptimised test runs in seconds; the terminal condition holds for
    /// the discrete trajectory at any step.
    const STEPS: usize = 2;

    #[test]
    fn the_adjoint_gradient_matches_central_differences_at_the_start() {
        // θ is the array `u`, entry by entry.
        assert_eq!((CartPole::NAMES[0], CartPole::NAMES[CONTROLS - 1]), ("u[0]", "u[30]"));
        let h = step(STEPS);
        // A start away from rest, so that the loss sees the nonlinear terms.
        let u: [f64; CONTROLS] = core::array::from_fn(|j| 3.0 * (j as f64 * 0.7).sin());
        let loss = Misfit { rho: 0.1 };
        let g = problem(u).gradient(&Scheme::MIDPOINT, h, T_END, &loss, checkpoints(h)).unwrap();
        let value = |u: [f64; CONTROLS]| {
            let r = terminal(u, h).unwrap();
            0.5 * r.iter().map(|r| r * r).sum::<f64>() + 0.5 * loss.rho * effort(&u)
        };
        assert!((g.value - value(u)).abs() <= 1e-12 * g.value);
        let scale = g.theta.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        // Central differences: truncation `ε² J'''/6` and rounding
        // `1e-16 J/ε`, about 2e-10 of the largest component here at
        // ε = 1e-5.
        let eps = 1e-5;
        let mut worst = 0.0f64;
        for j in 0..CONTROLS {
            let (mut up, mut down) = (u, u);
            up[j] += eps;
            down[j] -= eps;
            let fd = (value(up) - value(down)) / (2.0 * eps);
            worst = worst.max((g.theta[j] - fd).abs() / scale);
            assert!((g.theta[j] - fd).abs() <= 1e-8 * scale, "control {j}: adjoint {} vs differences {fd}", g.theta[j]);
        }
        eprintln!("loss {:.6e}, max |dJ/du| {scale:.3e}, adjoint vs differences {worst:.1e} of it", g.value);
    }

    #[test]
    fn the_swing_up_lands_within_1e_8_of_upright_at_rest() {
        let swing = swing_up([0.0; CONTROLS], STEPS).unwrap();
        eprintln!("{} iterations: {:?}", swing.history.len(), swing.history);
        assert!(norm(&swing.residual) <= 1e-8, "terminal residual {:?}", swing.residual);
        // The residual is that of an independent forward run.
        let r = terminal(swing.controls, step(STEPS)).unwrap();
        assert!(norm(&r) <= 1e-8, "terminal residual {r:?}");
    }
}
