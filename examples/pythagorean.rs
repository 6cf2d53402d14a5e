//! The Pythagorean three-body problem (Burrau 1913; Szebehely & Peters
//! 1967): masses 3, 4 and 5 at rest at the corners (1, 3), (−2, −1), (1, −1)
//! of a 3-4-5 right triangle, G = 1, t ∈ [0, 70]. Close encounters come
//! down to distances of ~1e-4; at the end masses 4 and 5 form a binary and
//! mass 3 escapes the other way.
//!
//! Integrated with the explicit time-transformed splitting
//! (docs/time-transformation.md, "Explicit splitting for separable
//! systems"): the logarithmic Hamiltonian `Γ = ln(T + p_t) − ln(−V)`, so
//! `dt/ds = 1/(−V)`, drift–kick–drift leapfrog composed to order 8
//! (Kahan & Li), uniform steps `σ` in `s`. Prints the relative energy
//! error, the steps and the smallest `dt`, the final state against the same
//! run at `σ/2` and against double-double runs at `σ` and `σ/2`, the end-state check (which
//! pair is bound), and fixed steps of the same count and of 10× more, which
//! fail. Writes the three paths (equal axes), `dt` and the energy error
//! against `t` into `target/example-output/pythagorean/` (or
//! `$LAGRANGIAN_OUT`).
//!
//! Run with `cargo run --release --example pythagorean`.

#[path = "support/plot.rs"]
mod plot;

use std::error::Error;
use std::time::Instant;

use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};

/// Three point masses 3, 4, 5 in the plane, G = 1; `q = (x1, y1, x2, y2, x3, y3)`.
#[derive(Clone, Copy, Debug)]
struct Pythagorean;

#[lagrangian]
impl Pythagorean {
    fn lagrangian(&self, q: [f64; 6], v: [f64; 6]) -> f64 {
        let kinetic = 0.5 * (3.0 * (v[0] * v[0] + v[1] * v[1]) + 4.0 * (v[2] * v[2] + v[3] * v[3]))
            + 0.5 * 5.0 * (v[4] * v[4] + v[5] * v[5]);
        let r12 = ((q[0] - q[2]) * (q[0] - q[2]) + (q[1] - q[3]) * (q[1] - q[3])).sqrt();
        let r13 = ((q[0] - q[4]) * (q[0] - q[4]) + (q[1] - q[5]) * (q[1] - q[5])).sqrt();
        let r23 = ((q[2] - q[4]) * (q[2] - q[4]) + (q[3] - q[5]) * (q[3] - q[5])).sqrt();
        kinetic + 12.0 / r12 + 15.0 / r13 + 20.0 / r23
    }
}

const MASSES: [f64; 3] = [3.0, 4.0, 5.0];
const Q0: [f64; 6] = [1.0, 3.0, -2.0, -1.0, 1.0, -1.0];
const T_END: f64 = 70.0;
/// The step in `s`; `σ/2` is the convergence check.
const SIGMA: f64 = 0.02;

/// One run: final state, steps, smallest and largest `dt`, the largest
/// relative energy error, and (optionally) the paths, `dt` and energy error.
struct Record<T> {
    end: State<6, T>,
    steps: u64,
    gradients: u64,
    dt_min: f64,
    energy_max: f64,
    seconds: f64,
    /// Per body: the path, thinned to points 2e-3 apart.
    paths: [Vec<(f64, f64)>; 3],
    /// `(t, log10 dt)` and `(t, log10 |ΔE/E0|)`, every 20th step.
    dt: Vec<(f64, f64)>,
    energy: Vec<(f64, f64)>,
}

fn run<T: Real>(sigma: f64, record: bool) -> Result<Record<T>, Box<dyn Error>> {
    let clock = Instant::now();
    let mut sim = ExplicitTimeTransformed::new(Pythagorean, TimeFunction::Logarithmic, T::from(sigma))
        .composition(Composition::KAHAN_LI8)
        .form(LeapfrogForm::DriftKickDrift)
        .start(T::from(0.0), Q0.map(T::from), [T::from(0.0); 6])?;
    let e0 = sim.energy().to_f64();
    let mut rec = Record {
        end: sim.state(),
        steps: 0,
        gradients: 0,
        dt_min: f64::INFINITY,
        energy_max: 0.0,
        seconds: 0.0,
        paths: [vec![(Q0[0], Q0[1])], vec![(Q0[2], Q0[3])], vec![(Q0[4], Q0[5])]],
        dt: Vec::new(),
        energy: Vec::new(),
    };
    sim.run_until(T::from(T_END), |s| {
        let state = s.state().to_f64();
        let dt = s.last_time_step().map_or(f64::NAN, |dt| dt.to_f64());
        // The last (landing) step is partial: not a step size of the method.
        if state.t < T_END {
            rec.dt_min = rec.dt_min.min(dt);
        }
        let de = ((s.energy().to_f64() - e0) / e0).abs();
        rec.energy_max = rec.energy_max.max(de);
        if record {
            for (b, path) in rec.paths.iter_mut().enumerate() {
                let p = (state.q[2 * b], state.q[2 * b + 1]);
                let last = path[path.len() - 1];
                if (p.0 - last.0).hypot(p.1 - last.1) > 2e-3 {
                    path.push(p);
                }
            }
            if state.step % 20 == 0 {
                rec.dt.push((state.t, dt.log10()));
                rec.energy.push((state.t, de.max(1e-17).log10()));
            }
        }
    })?;
    rec.end = sim.state();
    rec.steps = sim.stats().steps;
    rec.gradients = sim.stats().gradient_evaluations;
    rec.seconds = clock.elapsed().as_secs_f64();
    Ok(rec)
}

/// `max_i |a_i − b_i|` over positions and momenta.
fn distance(a: &State<6>, b: &State<6>) -> f64 {
    a.q.iter().zip(&b.q).chain(a.p.iter().zip(&b.p)).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

fn to_f64<T: Real>(s: &State<6, T>) -> State<6> {
    State { step: s.step, t: s.t.to_f64(), q: s.q.map(|x| x.to_f64()), p: s.p.map(|x| x.to_f64()) }
}

/// The two-body energy of bodies `i`, `j` in their centre-of-mass frame,
/// and the energy of the third body relative to the pair's centre of mass
/// (negative: bound).
fn end_state(s: &State<6>) -> [(usize, usize, f64, f64); 3] {
    let pos = |b: usize| [s.q[2 * b], s.q[2 * b + 1]];
    let vel = |b: usize| [s.p[2 * b] / MASSES[b], s.p[2 * b + 1] / MASSES[b]];
    [(0, 1, 2), (0, 2, 1), (1, 2, 0)].map(|(i, j, k)| {
        let (mi, mj, mk) = (MASSES[i], MASSES[j], MASSES[k]);
        let (m, mu) = (mi + mj, mi * mj / (mi + mj));
        let (dq, dv) = ([pos(i)[0] - pos(j)[0], pos(i)[1] - pos(j)[1]], [vel(i)[0] - vel(j)[0], vel(i)[1] - vel(j)[1]]);
        let pair = 0.5 * mu * (dv[0] * dv[0] + dv[1] * dv[1]) - mi * mj / dq[0].hypot(dq[1]);
        let cq = [(mi * pos(i)[0] + mj * pos(j)[0]) / m, (mi * pos(i)[1] + mj * pos(j)[1]) / m];
        let cv = [(mi * vel(i)[0] + mj * vel(j)[0]) / m, (mi * vel(i)[1] + mj * vel(j)[1]) / m];
        let mu3 = mk * m / (mk + m);
        let (rq, rv) = ([pos(k)[0] - cq[0], pos(k)[1] - cq[1]], [vel(k)[0] - cv[0], vel(k)[1] - cv[1]]);
        let third = 0.5 * mu3 * (rv[0] * rv[0] + rv[1] * rv[1]) - mk * m / rq[0].hypot(rq[1]);
        (i, j, pair, third)
    })
}

/// Fixed steps of the same order (Kahan–Li 8 of explicit Störmer–Verlet),
/// `n` of them over [0, 70]: the largest relative energy error, or the
/// error that stopped it.
fn fixed(n: u64) -> String {
    let h = T_END / n as f64;
    let mut sim = match Integrator::new(Pythagorean, Composition::KAHAN_LI8, h).start(0.0, Q0, [0.0; 6]) {
        Ok(sim) => sim,
        Err(e) => return format!("failed to start: {e}"),
    };
    let e0 = match sim.energy() {
        Ok(e) => e,
        Err(e) => return format!("no energy: {e}"),
    };
    let mut worst = 0.0f64;
    let result = sim.run_until(T_END, |s| {
        worst = worst.max(((s.energy().unwrap_or(f64::NAN) - e0) / e0).abs());
    });
    match result {
        Ok(()) => format!("ran to t = {T_END}: largest relative energy error {worst:.1e}"),
        Err(e) => format!("stopped at t = {:.4} (largest energy error before it {worst:.1e}): {e}", sim.state().t),
    }
}

fn main() -> Result<(), Box<dyn Error>> {
    println!("Pythagorean three-body problem, t ∈ [0, {T_END}], logH + Kahan–Li 8 (DKD), uniform σ in s");
    let main = run::<f64>(SIGMA, true)?;
    let half = run::<f64>(SIGMA / 2.0, false)?;
    let dd = run::<DoubleDouble>(SIGMA, false)?;
    let dd_half = run::<DoubleDouble>(SIGMA / 2.0, false)?;
    let end = to_f64(&main.end);
    println!(
        "σ = {SIGMA}: {} steps ({} gradient evaluations, {:.0} ms), smallest dt {:.2e}, largest relative energy error {:.1e}",
        main.steps,
        main.gradients,
        main.seconds * 1e3,
        main.dt_min,
        main.energy_max
    );
    println!(
        "σ/2: {} steps, largest relative energy error {:.1e}; final state differs from σ's by {:.1e} (max over q, p)",
        half.steps,
        half.energy_max,
        distance(&end, &to_f64(&half.end))
    );
    println!(
        "double-double, σ = {SIGMA}: {:.0} ms, largest relative energy error {:.1e}; final state differs from f64's by {:.1e}",
        dd.seconds * 1e3,
        dd.energy_max,
        distance(&end, &to_f64(&dd.end))
    );
    println!(
        "double-double, σ/2: largest relative energy error {:.1e}; final state differs from double-double σ's by {:.1e}",
        dd_half.energy_max,
        distance(&to_f64(&dd.end), &to_f64(&dd_half.end))
    );
    println!(
        "(the encounters amplify differences: f64 rounding of the absolute coordinates, not the step, limits the f64 runs)"
    );
    println!("end state at t = {T_END} (pair energy in its centre-of-mass frame; third body against the pair):");
    for (i, j, pair, third) in end_state(&end) {
        println!(
            "  masses {} and {}: pair energy {pair:+.4}, mass {} against them {third:+.4}",
            MASSES[i],
            MASSES[j],
            MASSES[3 - i - j]
        );
    }
    println!("fixed steps, same order (Kahan–Li 8 of Störmer–Verlet):");
    for n in [main.steps, 10 * main.steps] {
        println!("  {n} steps (h = {:.2e}): {}", T_END / n as f64, fixed(n));
    }

    let dir = plot::output_dir("pythagorean")?;
    let all = main.paths.iter().flatten();
    let (x0, x1) = all.clone().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let labels = ["mass 3", "mass 4", "mass 5"];
    Figure {
        title: "Pythagorean three-body problem, t ∈ [0, 70] (equal axes)",
        x_label: "x",
        x_range: (x0, x1),
        panels: vec![Panel {
            y_label: "y",
            series: (0..3).map(|b| Series { label: labels[b], points: &main.paths[b], markers: false }).collect(),
        }],
        equal_axes: true,
    }
    .save(&dir.join("paths"), 900)?;
    Figure {
        title: &format!("Adaptive step and energy error, σ = {SIGMA} ({} steps)", main.steps),
        x_label: "t",
        x_range: (0.0, T_END),
        panels: vec![
            Panel { y_label: "log10 dt", series: vec![Series { label: "", points: &main.dt, markers: false }] },
            Panel {
                y_label: "log10 |ΔE/E0|",
                series: vec![Series { label: "", points: &main.energy, markers: false }],
            },
        ],
        equal_axes: false,
    }
    .save(&dir.join("steps"), 1000)?;
    println!("plots: {}", dir.display());
    Ok(())
}
