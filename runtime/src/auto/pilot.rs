//! The pilot: a short run of a candidate at two step sizes, whose
//! difference (Richardson) estimates the global error, its growth in time,
//! and the step that meets the tolerance at the end of the span.
//!
//! Over the pilot `[t0, t0 + Tp]` the method runs with step `h` (or `σ` in
//! the new time of a time transformation) and with `h/2`; at the
//! checkpoints `Tp/4, Tp/2, Tp` the error of the coarse run is
//! `e ≈ ‖q_h − q_{h/2}‖∞ · 2^p/(2^p − 1)` for a method of order `p`
//! (running maximum). Its growth between checkpoints decides the
//! extrapolation to the end `T`: linear in time (a symplectic method on
//! integrable motion: the phase error grows linearly), a power `t^k` with
//! `1 ≤ k ≤ 2` as the pilot measures it, or exponential when the local
//! exponent `k = Δln e / Δln t` exceeds 3 (an exponential `e^{λt}` has
//! `k = λt`, growing without bound), with the measured rate `λ`: the
//! signature of chaos.

use std::time::Instant;

use crate::error::Error;
use crate::guidance;
use crate::solution::Stepping;

/// How the global error grows with time, as measured by the pilot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Growth {
    /// As `t^k` (`k = 1`: linear, symplectic methods on integrable motion).
    Power(f64),
    /// As `exp(λ t)`: the pilot's error estimate grows faster than
    /// quadratically; `λ` measured over the second half of the pilot.
    Exponential(f64),
}

/// What one run of a pilot recorded.
#[derive(Clone, Debug)]
pub(crate) struct Probe<const N: usize> {
    /// `q` at each checkpoint.
    pub q: Vec<[f64; N]>,
    /// `max_t ‖q(t)‖∞` over the nodes.
    pub scale: f64,
    /// The fastest rate `ρ` of the linearisation at sampled nodes.
    pub rates: Vec<f64>,
    /// Steps taken.
    pub steps: u64,
}

/// Runs `it` through `checkpoints` (increasing), sampling `ρ` at every
/// `stride`-th node when `stride > 0`.
pub(crate) fn probe<I: Stepping<N>, const N: usize>(
    mut it: I,
    checkpoints: &[f64],
    stride: usize,
) -> Result<Probe<N>, Error<N>> {
    let start = it.state();
    let mut out =
        Probe { q: Vec::new(), scale: start.q.iter().fold(0.0f64, |m, x| m.max(x.abs())), rates: Vec::new(), steps: 0 };
    let mut last_h = None;
    let mut k = 0usize;
    for &tc in checkpoints {
        while it.state().t < tc {
            let t = it.state().t;
            it.step_toward(tc, last_h)?;
            let s = it.state();
            if !s.q.iter().all(|x| x.is_finite()) {
                return Err(Error::NonFinite { state: s, h: s.t - t, iterations: 0, quantity: "position" });
            }
            last_h = Some(s.t - t);
            out.scale = s.q.iter().fold(out.scale, |m, x| m.max(x.abs()));
            k += 1;
            if stride > 0 && k.is_multiple_of(stride) {
                let v = it.velocity()?;
                if let Ok(lin) = guidance::linearize(it.system(), s.t, s.q, v) {
                    out.rates.push(lin.fastest);
                }
            }
        }
        out.q.push(it.state().q);
    }
    out.steps = it.stats().steps;
    Ok(out)
}

/// The error estimate of a coarse/fine pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Richardson {
    /// The estimated error of the coarse run at the last checkpoint
    /// (running maximum over the checkpoints).
    pub error: f64,
    /// The growth measured.
    pub growth: Growth,
    /// The round-off level of the difference: an error estimate near it
    /// measures round-off, not the method.
    pub noise: f64,
}

impl Richardson {
    /// From the coarse and fine probes of a method of order `p` at the
    /// checkpoints `times` (each twice as far from `t0` as the one before).
    /// The growth is judged between checkpoints at least `settle` after
    /// `t0` (a period of the fastest mode: before it, the error of an
    /// oscillation can rise by more than any power of `t` as its phase turns).
    pub(crate) fn new<const N: usize>(
        coarse: &Probe<N>,
        fine: &Probe<N>,
        order: u32,
        times: &[f64],
        t0: f64,
        settle: f64,
    ) -> Self {
        let factor = 2f64.powi(order as i32) / (2f64.powi(order as i32) - 1.0);
        let mut running = 0.0f64;
        let e: Vec<f64> = coarse
            .q
            .iter()
            .zip(&fine.q)
            .map(|(a, b)| {
                let d = a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
                running = running.max(d * factor);
                running
            })
            .collect();
        let scale = coarse.scale.max(fine.scale).max(f64::MIN_POSITIVE);
        let noise = 10.0 * f64::EPSILON * scale * (fine.steps.max(1) as f64).sqrt();
        let error = e[e.len() - 1];
        let mut growth = Growth::Power(1.0);
        // An oscillation's error sampled at one instant can sit near a zero
        // of its phase (a turning point moves by a phase error to second
        // order only), so one steep interval is no proof: exponential growth
        // is two steep intervals in a row, as `e^{λt}` keeps them.
        let mut steep_before = false;
        for i in 1..e.len() {
            let (a, b) = (e[i - 1], e[i]);
            // Above round-off, below saturation, after the first period.
            if times[i - 1] - t0 < 0.99 * settle || a <= 100.0 * noise || b >= 1e-2 * scale {
                continue;
            }
            let k = (b / a).ln() / ((times[i] - t0) / (times[i - 1] - t0)).ln();
            let steep = k > 3.0;
            growth = if steep && steep_before {
                Growth::Exponential((b / a).ln() / (times[i] - times[i - 1]))
            } else {
                match growth {
                    Growth::Exponential(rate) => Growth::Exponential(rate),
                    Growth::Power(_) => Growth::Power(k.clamp(1.0, 2.0)),
                }
            };
            steep_before = steep;
        }
        // An error that saturates before two checkpoints show its growth:
        // judged from the first measurable checkpoint to the last.
        if matches!(growth, Growth::Power(_)) && error >= 1e-2 * scale {
            let n = e.len() - 1;
            if let Some(i) = (0..n).find(|&i| times[i] - t0 >= 0.99 * settle && e[i] > 10.0 * noise) {
                let k = (error / e[i]).ln() / ((times[n] - t0) / (times[i] - t0)).ln();
                if k > 3.0 {
                    growth = Growth::Exponential((error / e[i]).ln() / (times[n] - times[i]));
                }
            }
        }
        Self { error, growth, noise }
    }

    /// The error extrapolated from the pilot's end `tp` to `t_end`.
    pub(crate) fn at(&self, t0: f64, tp: f64, t_end: f64) -> f64 {
        self.error * amplification(self.growth, t0, tp, t_end)
    }
}

/// The factor by which an error at `tp` grows until `t_end`.
pub(crate) fn amplification(growth: Growth, t0: f64, tp: f64, t_end: f64) -> f64 {
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
