//! The pilot: a short run of a candidate at two step sizes, whose
//! difference (Richardson) estimates the global error, its growth in time,
//! and the step that meets the tolerance at the end of the span.
//!
//! Over the pilot `[t0, t0 + Tp]` the method runs with step `h` (or `σ` in
//! the new time of a time transformation) and with `h/2`. The two runs are
//! compared in position at every node they share: every coarse node of a
//! fixed-step method; for a time transformation, whose nodes fall at
//! different times in the two runs, every coarse node `k` against the fine
//! node `2k` at the same new time, moved to the coarse node's time along
//! the fine run's velocity (no landings: a landing step solves for its
//! partial step, and many of them would make the pilot a different method
//! from the final run). The error of the coarse run is
//! `e ≈ ‖Δq‖∞ · 2^p/(2^p − 1)` for a method of order `p`, kept as a running
//! maximum over the nodes: the tolerance is on positions, and an
//! oscillation's position error, which vanishes twice a period, is kept at
//! its peak. Weighing the momentum difference in as well (in units `Q/P`)
//! overestimates the error tenfold on an eccentric orbit, whose momentum
//! error at pericentre is `a δt` for a position error `v δt`; the growth,
//! though, is judged on that phase-space distance, which grows as the
//! phase error does from the start (the position error from a start at rest
//! rises steeply enough over the first checkpoints to look exponential).
//!
//! The growth of `e` between the checkpoints `Tp/64, …, Tp/2, Tp` decides the
//! extrapolation to the end `T`: a power `t^k` with `1 ≤ k ≤ 2`, the lesser
//! exponent the last two intervals measure (on a dissipative system the
//! last interval's `k ≥ 0` where the exponents fall below 1), or
//! exponential when the local exponent
//! `k = Δln e / Δln t` exceeds 3 over two intervals in a row (an
//! exponential `e^{λt}` has `k = λt`, growing without bound), with the
//! measured rate `λ`: the signature of chaos.

use std::sync::Arc;
use std::time::Instant;

use nalgebra::SMatrix;

use crate::error::Error;
use crate::mechanics::DiscreteMechanics;
use crate::solution::Stepping;
use crate::system::Lagrangian;

/// How the global error grows with time, as measured by the pilot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Growth {
    /// As `t^k` (`k = 1`: linear, symplectic methods on integrable motion;
    /// `k < 1` only on a dissipative system, whose errors are damped).
    Power(f64),
    /// As `exp(λ t)`: the pilot's error estimate grows faster than
    /// quadratically; `λ` measured over the second half of the pilot.
    Exponential(f64),
}

/// One recorded node of a pilot run.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sample<const N: usize> {
    pub t: f64,
    pub q: [f64; N],
    pub p: [f64; N],
}

/// What one run of a pilot recorded.
#[derive(Clone, Debug)]
pub(crate) struct Probe<const N: usize> {
    /// The start and the recorded nodes, in time order.
    pub samples: Vec<Sample<N>>,
    /// `max_t ‖q(t)‖∞` over the nodes.
    pub scale: f64,
    /// `max_t ‖p(t)‖∞` over the nodes.
    pub p_scale: f64,
    /// The fastest rate `ρ` of the linearisation at sampled nodes.
    pub rates: Vec<f64>,
    /// Steps taken.
    pub steps: u64,
    /// Whether the run reached the last checkpoint (a survey stops early
    /// once its step density is clearly varying: see [`probe`]).
    pub complete: bool,
    /// Whether the run stopped at a checkpoint where its energy had left
    /// that of the start (see [`probe`]'s `energy_guard`).
    pub lost: bool,
}

/// The change of the energy `E_L`, over its scale, at which a run of a
/// conservative autonomous system has left its orbit: a tenth, as the
/// difference of a tenth of the positions does for a pilot round.
const ENERGY_LOST: f64 = 0.1;

/// Samples of `ρ` a survey takes at least before it may stop early.
const SURVEY_MIN_SAMPLES: usize = 16;

/// Runs `it` through `checkpoints` (increasing), recording every node when
/// `every_node` (otherwise the checkpoints) and sampling `ρ` with `rates`
/// at every `stride`-th node when `stride > 0` (only for `½ vᵀMv − V(q)`
/// with a constant `M`: see [`Rates`]). With `stop_above`, the run stops
/// once [`SURVEY_MIN_SAMPLES`] samples or more give a
/// [`density_ratio`](super::choice::density_ratio) above it: uniform steps
/// through a strongly varying density are what the survey is there to
/// avoid (on Kepler `e = 0.9` they are 187 steps over an orbit, where the
/// final run takes 9), and the part of the orbit already seen decides.
/// With `energy_guard` (a conservative autonomous system, whose energy
/// `E_L` the flow keeps), the run stops at the first checkpoint where
/// `|E_L − E_L(t0)|` exceeds [`ENERGY_LOST`] of `max(|E_L(t0)|, |p·v|)`,
/// marked [`lost`](Probe::lost): a variational method at a step that
/// resolves the motion keeps the energy to far less, and one at a step that
/// does not can converge to a spurious root of its stage equations and run
/// off (Galerkin `s = 4` on the double pendulum at `ρh = 1` reaches
/// positions of 5 600 rad within six steps).
pub(crate) fn probe<I: Stepping<N>, const N: usize>(
    mut it: I,
    checkpoints: &[f64],
    every_node: bool,
    stride: usize,
    mut rates: Option<&mut Rates<N>>,
    stop_above: Option<f64>,
    energy_guard: bool,
) -> Result<Probe<N>, Error> {
    // `(E_L, |p·v|)` at the current node; `None` where the velocity is not found.
    let energy = |it: &I| {
        let s = it.state();
        let v = it.velocity().ok()?;
        let pv = s.p.iter().zip(&v).map(|(p, v)| p * v).sum::<f64>().abs();
        Some((it.system().energy(s.t, s.q, v), pv))
    };
    let start_energy = if energy_guard { energy(&it) } else { None };
    let start = it.state();
    let norm = |x: &[f64; N]| x.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let mut out = Probe {
        samples: vec![Sample { t: start.t, q: start.q, p: start.p }],
        scale: norm(&start.q),
        p_scale: norm(&start.p),
        rates: Vec::new(),
        steps: 0,
        complete: true,
        lost: false,
    };
    let mut last_h = None;
    let mut k = 0usize;
    for &tc in checkpoints {
        while it.state().t < tc {
            let t = it.state().t;
            it.step_toward(tc, last_h)?;
            let s = it.state();
            if !s.q.iter().chain(&s.p).all(|x| x.is_finite()) {
                return Err(Error::NonFinite { state: s.into(), h: s.t - t, iterations: 0, quantity: "position" });
            }
            last_h = Some(s.t - t);
            out.scale = out.scale.max(norm(&s.q));
            out.p_scale = out.p_scale.max(norm(&s.p));
            if every_node || s.t >= tc {
                out.samples.push(Sample { t: s.t, q: s.q, p: s.p });
            }
            if s.t >= tc
                && let Some((e0, pv0)) = start_energy
                && energy(&it).is_some_and(|(e, pv)| {
                    let drift = (e - e0).abs();
                    drift.is_nan() || drift > ENERGY_LOST * e0.abs().max(pv).max(pv0)
                })
            {
                out.lost = true;
                out.complete = false;
                out.steps = it.stats().steps;
                return Ok(out);
            }
            k += 1;
            if stride > 0
                && k.is_multiple_of(stride)
                && let Some(rate) = rates.as_deref_mut().and_then(|r| r.sample(&it, POWER_ITERATIONS))
            {
                out.rates.push(rate);
                if let Some(limit) = stop_above
                    && out.rates.len() >= SURVEY_MIN_SAMPLES
                    && super::choice::density_ratio(&out.rates).is_some_and(|r| r > limit)
                {
                    out.complete = false;
                    out.steps = it.stats().steps;
                    return Ok(out);
                }
            }
        }
    }
    out.steps = it.stats().steps;
    Ok(out)
}

/// Power iterations per sample of [`Rates::at`] (warm-started from the
/// previous sample's mode).
const POWER_ITERATIONS: usize = 3;

/// The fastest rate `ρ = √|λ|max` of the linearisation of
/// `½ vᵀMv − V(q)` with a constant mass matrix `M`, whose rates are the
/// `√|λ(M⁻¹∇²V)|`: power iteration on central differences of the generated
/// gradient `∂L/∂q` along a mode carried from one sample to the next, with
/// `M⁻¹` formed once. Two gradients and a product with `M⁻¹` per iteration,
/// on the stack, in place of the `4N` accelerations (each solving for `M`
/// again) and the dense eigenvalue problem of
/// [`guidance::linearize`](crate::guidance::linearize), which along a survey
/// of many nodes on 15 coordinates cost 100× a whole calibrated run.
pub(crate) struct Rates<const N: usize> {
    /// `M⁻¹`, shared with the started integrator that formed it.
    /// `None` for a system of any other form: each sample is then the
    /// dense linearisation of [`guidance::linearize`](crate::guidance::linearize)
    /// at the node's `(t, q, v)` (on two coordinates, eight accelerations
    /// and a 4 × 4 eigenvalue problem, a fraction of a Galerkin `s = 6` step).
    inverse_mass: Option<Arc<SMatrix<f64, N, N>>>,
    mode: [f64; N],
}

impl<const N: usize> Rates<N> {
    /// From `M⁻¹`, which an explicit integrator forms at its start.
    pub(crate) fn new(inverse_mass: Arc<SMatrix<f64, N, N>>) -> Self {
        Self { inverse_mass: Some(inverse_mass), mode: core::array::from_fn(|i| 1.0 + 0.1 * i as f64) }
    }

    /// For a system not proven `½ vᵀMv − V(q)` with a constant `M`: the
    /// fastest rate of the whole linearisation at each sampled node.
    pub(crate) fn linearised() -> Self {
        Self { inverse_mass: None, mode: [0.0; N] }
    }

    /// `ρ` at the current node of `it`.
    fn sample<I: Stepping<N>>(&mut self, it: &I, iterations: usize) -> Option<f64> {
        let s = it.state();
        if self.inverse_mass.is_some() {
            return self.at(it.system(), s.t, &s.q, iterations);
        }
        let v = it.velocity().ok()?;
        crate::guidance::linearize(it.system(), s.t, s.q, v)
            .ok()
            .map(|l| l.fastest)
            .filter(|r| r.is_finite() && *r > 0.0)
    }

    /// `ρ` at `(t, q)` after `iterations` power iterations (`None` for
    /// [`linearised`](Self::linearised) rates).
    pub(crate) fn at<S: Lagrangian<N> + ?Sized>(
        &mut self,
        system: &S,
        t: f64,
        q: &[f64; N],
        iterations: usize,
    ) -> Option<f64> {
        let delta = f64::EPSILON.cbrt() * q.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        let m = self.inverse_mass.clone()?;
        let zero = [0.0; N];
        let (mut plus, mut minus) = ([0.0; N], [0.0; N]);
        let mut lambda = 0.0;
        for _ in 0..iterations {
            let norm = self.mode.iter().map(|x| x * x).sum::<f64>().sqrt();
            if !(norm > 0.0 && norm.is_finite()) {
                return None;
            }
            let u = self.mode.map(|x| x / norm);
            system.gradient_q(t, &core::array::from_fn(|i| q[i] + delta * u[i]), &zero, &mut plus);
            system.gradient_q(t, &core::array::from_fn(|i| q[i] - delta * u[i]), &zero, &mut minus);
            let force: [f64; N] = core::array::from_fn(|i| (plus[i] - minus[i]) / (2.0 * delta));
            let m = &*m;
            self.mode = core::array::from_fn(|i| (0..N).map(|j| m[(i, j)] * force[j]).sum());
            lambda = self.mode.iter().map(|x| x * x).sum::<f64>().sqrt();
        }
        (lambda.is_finite() && lambda > 0.0).then(|| lambda.sqrt())
    }
}

/// The error estimate of a coarse/fine pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Richardson {
    /// The estimated error of the coarse run at the pilot's end (running
    /// maximum over the shared nodes).
    pub error: f64,
    /// The growth measured.
    pub growth: Growth,
    /// The round-off level of the difference: an error estimate near it
    /// measures round-off, not the method.
    pub noise: f64,
}

/// `(t, running maximum of the position difference, running maximum of the
/// phase-space difference)` at the nodes the two probes share; the phase
/// space weighs the momentum difference in units of the positions (`Q/P`),
/// so that an oscillation's growth is seen before its position error has
/// turned through a period (the position error alone, rising from a start
/// at rest, looks exponential over the first checkpoints). Fixed steps: the nodes at equal times (to a few ulps of
/// the span). A time transformation (`by_index`): coarse node `k` and fine
/// node `2k` lie at the same new time `s` but at different physical times,
/// so the fine position is moved to the coarse node's time along the fine
/// run's velocity (central difference of its neighbours), `Δq − v Δt`; both
/// runs land only at the pilot's end, where they are compared directly.
fn distances<const N: usize>(coarse: &Probe<N>, fine: &Probe<N>, by_index: bool) -> Vec<(f64, f64, f64)> {
    let (first, last) = (coarse.samples[0].t, coarse.samples[coarse.samples.len() - 1].t);
    let tol = 64.0 * f64::EPSILON * first.abs().max(last.abs()).max(last - first);
    let (scale, p_scale) = (coarse.scale.max(fine.scale), coarse.p_scale.max(fine.p_scale));
    // Momenta in units of the positions; a run at rest weighs positions only.
    let weight = if p_scale > 0.0 { scale / p_scale } else { 0.0 };
    let mut out = Vec::with_capacity(coarse.samples.len());
    let (mut running, mut running_phase) = (0.0f64, 0.0f64);
    let mut push = |t: f64, (dq, dp): (f64, f64)| {
        running = running.max(dq);
        running_phase = running_phase.max(dq.max(dp * weight));
        out.push((t, running, running_phase));
    };
    // `(‖Δq‖∞, ‖Δp‖∞)` with `b` moved to `a.t` along the rates `(v, f)`.
    let diff = |a: &Sample<N>, b: &Sample<N>, (v, f): ([f64; N], [f64; N])| {
        let dt = a.t - b.t;
        (
            (0..N).fold(0.0f64, |m, i| m.max((a.q[i] - b.q[i] - v[i] * dt).abs())),
            (0..N).fold(0.0f64, |m, i| m.max((a.p[i] - b.p[i] - f[i] * dt).abs())),
        )
    };
    let still = ([0.0; N], [0.0; N]);
    if by_index {
        let (nc, nf) = (coarse.samples.len(), fine.samples.len());
        // The fine run's velocity at its node `j` (central difference).
        let velocity = |j: usize| -> [f64; N] {
            let (l, r) = (&fine.samples[j - 1], &fine.samples[j + 1]);
            core::array::from_fn(|i| (r.q[i] - l.q[i]) / (r.t - l.t))
        };
        // The largest speed along the pilot: where the orbit is fastest, a
        // time shift `τ` is a position error `τ ‖v‖∞`.
        let norm = |x: &[f64; N]| x.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let fastest = (1..nf.saturating_sub(1)).map(|j| norm(&velocity(j))).fold(0.0f64, f64::max);
        // `‖Δq‖∞`, or the along-track time shift `τ = Δq·v / v·v` at the
        // fastest speed where that is larger: over part of an eccentric orbit
        // the pilot meets its phase error where the body is slow, and the
        // run passes pericentre with it (Kepler `e = 0.9` over half an orbit
        // from pericentre: the position difference alone estimated 1.0e-4
        // for an error of 6.5e-4 at the end).
        let along = |dq: f64, d: &[f64; N], v: &[f64; N]| {
            let vv = v.iter().map(|x| x * x).sum::<f64>();
            let shift = d.iter().zip(v).map(|(d, v)| d * v).sum::<f64>() / vv;
            if vv > 0.0 && shift.is_finite() { dq.max(shift.abs() * fastest) } else { dq }
        };
        for (k, a) in coarse.samples.iter().enumerate().take(nc - 1) {
            let j = 2 * k;
            if j + 1 >= nf - 1 {
                break;
            }
            let b = &fine.samples[j];
            let (dq, dp) = if j == 0 {
                diff(a, b, still)
            } else {
                let (l, r) = (&fine.samples[j - 1], &fine.samples[j + 1]);
                let v = velocity(j);
                let f = core::array::from_fn(|i| (r.p[i] - l.p[i]) / (r.t - l.t));
                let (dq, dp) = diff(a, b, (v, f));
                let d: [f64; N] = core::array::from_fn(|i| a.q[i] - b.q[i] - v[i] * (a.t - b.t));
                (along(dq, &d, &v), dp)
            };
            push(a.t, (dq, dp));
        }
        let (a, b) = (&coarse.samples[nc - 1], &fine.samples[nf - 1]);
        if (a.t - b.t).abs() <= tol {
            let (dq, dp) = diff(a, b, still);
            let d: [f64; N] = core::array::from_fn(|i| a.q[i] - b.q[i]);
            // The velocity at the end over the fine run's last step.
            let dq = match nf {
                2.. => {
                    let l = &fine.samples[nf - 2];
                    let v: [f64; N] = core::array::from_fn(|i| (b.q[i] - l.q[i]) / (b.t - l.t));
                    along(dq, &d, &v)
                }
                _ => dq,
            };
            push(a.t, (dq, dp));
        }
        return out;
    }
    let mut j = 0;
    for a in &coarse.samples {
        while j < fine.samples.len() && fine.samples[j].t < a.t - tol {
            j += 1;
        }
        let Some(b) = fine.samples.get(j).filter(|b| (b.t - a.t).abs() <= tol) else { continue };
        push(a.t, diff(a, b, still));
    }
    out
}

impl Richardson {
    /// From the coarse and fine probes of a method of order `p`, with the
    /// growth judged at the checkpoints `times` (each twice as far from `t0`
    /// as the one before) from `settle` after `t0` on (a period of the
    /// fastest mode: within it, the error of an oscillation is still turning
    /// with its phase); `by_index` pairs the nodes of a time transformation
    /// (see [`distances`]); `dissipative` for a system with a dissipation
    /// function, whose error may grow less than linearly (see
    /// [`scaled`](Self::scaled)).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new<const N: usize>(
        coarse: &Probe<N>,
        fine: &Probe<N>,
        order: u32,
        times: &[f64],
        t0: f64,
        settle: f64,
        by_index: bool,
        dissipative: bool,
    ) -> Self {
        let factor = 2f64.powi(order as i32) / (2f64.powi(order as i32) - 1.0);
        Self::scaled(coarse, fine, factor, times, t0, settle, by_index, dissipative)
    }

    /// The error of `run` measured against `companion`, a run of a method
    /// of higher order at the same step whose error is far smaller (fixed
    /// steps, the same nodes): the difference itself, with its growth
    /// judged as in [`new`](Self::new).
    pub(crate) fn companion<const N: usize>(
        run: &Probe<N>,
        companion: &Probe<N>,
        times: &[f64],
        t0: f64,
        settle: f64,
    ) -> Self {
        Self::scaled(run, companion, 1.0, times, t0, settle, false, false)
    }

    /// The difference of `coarse` and `fine` times `factor` as the error of
    /// `coarse`. A power law grows at least linearly, except on a
    /// `dissipative` system whose last interval measures less: the
    /// dissipation damps the errors the steps make, and the error's
    /// envelope levels off (the sensor, whose circuit settles in a tenth of
    /// the span, measures `k = 0.3` at `rtol = 1e-3`: extrapolated
    /// linearly, its estimate was 3.5 times the largest error along the
    /// run; as `t^0.3`, 0.95 times).
    #[allow(clippy::too_many_arguments)]
    fn scaled<const N: usize>(
        coarse: &Probe<N>,
        fine: &Probe<N>,
        factor: f64,
        times: &[f64],
        t0: f64,
        settle: f64,
        by_index: bool,
        dissipative: bool,
    ) -> Self {
        let scale = coarse.scale.max(fine.scale).max(f64::MIN_POSITIVE);
        let d = distances(coarse, fine, by_index);
        // The running maximum at each checkpoint: the last shared node not after it.
        let e: Vec<f64> = times
            .iter()
            .map(|&tc| {
                let i = d.partition_point(|&(t, _, _)| t <= tc + 64.0 * f64::EPSILON * tc.abs());
                if i == 0 { 0.0 } else { d[i - 1].2 * factor }
            })
            .collect();
        let noise = roundoff(scale, fine.steps as f64, Growth::Power(1.0), 0.0);
        // The growth is judged on the phase-space distance (see `distances`),
        // the error on the positions.
        let phase_error = d.last().map_or(0.0, |x| x.2 * factor);
        let error = d.last().map_or(0.0, |x| x.1 * factor);
        let mut growth = Growth::Power(1.0);
        // Exponential growth keeps every interval steep; a bend of a power
        // law (an error rising as a resonance is crossed) makes one. A power
        // law takes the lesser exponent of the last two intervals: the
        // running maximum of an oscillation's error rises in jumps when its
        // peaks grow past the last one, and one interval that holds a jump
        // (the pendulum's and the outer planets' errors over their first
        // period) would extrapolate as `t²`, tenfold over a tenth of the span.
        let mut steep_before = false;
        let mut k_before: Option<f64> = None;
        for i in 1..e.len() {
            let (a, b) = (e[i - 1], e[i]);
            // Above round-off, below saturation, after the first period.
            if times[i - 1] - t0 < 0.99 * settle || a <= ABOVE_ROUNDOFF * noise || b >= 1e-2 * scale {
                steep_before = false;
                k_before = None;
                continue;
            }
            let k = (b / a).ln() / ((times[i] - t0) / (times[i - 1] - t0)).ln();
            let steep = k > 3.0;
            growth = if steep && steep_before {
                Growth::Exponential((b / a).ln() / (times[i] - times[i - 1]))
            } else {
                match growth {
                    Growth::Exponential(rate) => Growth::Exponential(rate),
                    Growth::Power(_) => {
                        let lesser = k_before.map_or(k, |kb| kb.min(k));
                        Growth::Power(match lesser {
                            l if l >= 1.0 => l.min(2.0),
                            // Below linear: the last interval's exponent,
                            // where dissipation damps the errors.
                            _ if dissipative => k.clamp(0.0, 1.0),
                            _ => 1.0,
                        })
                    }
                }
            };
            steep_before = steep;
            k_before = Some(k);
        }
        // An error that saturates before two checkpoints show its growth:
        // judged from the first measurable checkpoint to the last.
        if matches!(growth, Growth::Power(_)) && phase_error >= 1e-2 * scale {
            let n = e.len() - 1;
            if let Some(i) = (0..n).find(|&i| times[i] - t0 >= 0.99 * settle && e[i] > 0.1 * ABOVE_ROUNDOFF * noise) {
                let k = (phase_error / e[i]).ln() / ((times[n] - t0) / (times[i] - t0)).ln();
                if k > 3.0 {
                    growth = Growth::Exponential((phase_error / e[i]).ln() / (times[n] - times[i]));
                }
            }
        }
        Self { error, growth, noise }
    }

    /// The error extrapolated from the pilot's end `tp` to `t_end`.
    pub(crate) fn at(&self, t0: f64, tp: f64, t_end: f64) -> f64 {
        self.error * amplification(self.growth, t0, tp, t_end)
    }

    /// Whether the difference of the two runs is round-off rather than the
    /// method's error (see [`ABOVE_ROUNDOFF`]).
    pub(crate) fn is_roundoff(&self) -> bool {
        self.error <= ABOVE_ROUNDOFF * self.noise
    }
}

/// The round-off of a run of `steps` steps, `ROUNDOFF · ε · Q · √N` (a
/// random walk of the rounding, `Q` the scale of the positions), amplified
/// over `span` as `exp(λ span)` where the error grows exponentially: the
/// pilot's level of a difference of its runs (with the finer run's steps)
/// and the floor of the final run (with its steps), which a tolerance below
/// it cannot reach in `f64`.
pub(crate) fn roundoff(scale: f64, steps: f64, growth: Growth, span: f64) -> f64 {
    let amplified = match growth {
        Growth::Exponential(rate) => (rate * span).exp(),
        Growth::Power(_) => 1.0,
    };
    ROUNDOFF * f64::EPSILON * scale * steps.max(1.0).sqrt() * amplified
}

/// The coefficient of [`roundoff`]: the root mean square of the errors the
/// fixed-point Galerkin steps measure where their truncation error is far
/// below (`CALLGRIND_ERROR=1 auto_solve PROBLEM galerkin-fp-S steps=N`):
/// Kepler in polar coordinates over 1 000 orbits (`Q = 628` over the pilot)
/// 2.1 for `s = 6` at 68 k to 543 k steps (single runs 0.06 to 6.8) and 1.4
/// for `s = 8` at 48 k to 160 k (at most 2.7); the pendulum and Kepler
/// `e = 0.5` at most 0.65 and 0.32 at 128 k steps, where the errors no
/// longer grow with `N`.
pub(crate) const ROUNDOFF: f64 = 2.0;

/// A difference of two pilot runs above this multiple of the finer run's
/// [`roundoff`] measures the method: single runs scatter to 3.4 times the
/// model (6.8 against its 2), and the round-off of both runs is then at most
/// a percent of the difference. Below it the difference is round-off, and
/// neither the step it asks for nor its growth is taken from it (the growth
/// is judged from a tenth of it up, where a power law still shows).
pub(crate) const ABOVE_ROUNDOFF: f64 = 500.0;

/// The factor by which an error at `tp` grows until `t_end`.
fn amplification(growth: Growth, t0: f64, tp: f64, t_end: f64) -> f64 {
    match growth {
        Growth::Power(k) => ((t_end - t0) / (tp - t0)).powf(k),
        Growth::Exponential(rate) => (rate * (t_end - tp)).exp(),
    }
}

/// The pilot's cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cost {
    /// Steps of all pilot runs.
    pub steps: u64,
    /// Wall-clock seconds of the pilot (choice included).
    pub seconds: f64,
}

/// A stopwatch for the pilot's cost.
pub(crate) struct Clock(Instant);

impl Clock {
    pub(crate) fn start() -> Self {
        Self(Instant::now())
    }

    pub(crate) fn seconds(&self) -> f64 {
        self.0.elapsed().as_secs_f64()
    }
}
