//! The pilot: a short run of a candidate at two step sizes, whose
//! difference (Richardson) estimates the global error, its growth in time,
//! and the step that meets the tolerance at the end of the span.
//!
//! Over the pilot `[t0, t0 + Tp]` the method runs with step `h` (or `σ` in
//! the new time of a time transformation) and with `h/2`. The two runs are
//! compared in phase space at every node they share (every coarse node of a
//! fixed-step method; the checkpoints of a time transformation, whose nodes
//! fall at different times): the distance
//! `d = max(‖Δq‖∞, ‖Δp‖∞ · Q/P)`, with `Q` and `P` the largest `|q_i|` and
//! `|p_i|` met, measures the momentum difference in units of the positions.
//! The error of the coarse run is `e ≈ d · 2^p/(2^p − 1)` for a method of
//! order `p`, kept as a running maximum. An oscillation's position error
//! alone vanishes twice a period (the phase error moves the turning points
//! only to second order), so sampled at a few instants it can look as if it
//! grew by orders of magnitude between them; its phase-space error, maximal
//! over the nodes, grows as the phase error does: linearly in time for a
//! symplectic method on integrable motion.
//!
//! The growth of `e` between the checkpoints `Tp/64, …, Tp/2, Tp` decides the
//! extrapolation to the end `T`: a power `t^k` with `1 ≤ k ≤ 2` as the pilot
//! measures it, or exponential when the local exponent
//! `k = Δln e / Δln t` exceeds 3 over two intervals in a row (an
//! exponential `e^{λt}` has `k = λt`, growing without bound), with the
//! measured rate `λ`: the signature of chaos.

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
}

/// Runs `it` through `checkpoints` (increasing), recording every node when
/// `every_node` (otherwise the checkpoints) and sampling `ρ` at every
/// `stride`-th node when `stride > 0`.
pub(crate) fn probe<I: Stepping<N>, const N: usize>(
    mut it: I,
    checkpoints: &[f64],
    every_node: bool,
    stride: usize,
) -> Result<Probe<N>, Error<N>> {
    let start = it.state();
    let norm = |x: &[f64; N]| x.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let mut out = Probe {
        samples: vec![Sample { t: start.t, q: start.q, p: start.p }],
        scale: norm(&start.q),
        p_scale: norm(&start.p),
        rates: Vec::new(),
        steps: 0,
    };
    let mut last_h = None;
    let mut k = 0usize;
    for &tc in checkpoints {
        while it.state().t < tc {
            let t = it.state().t;
            it.step_toward(tc, last_h)?;
            let s = it.state();
            if !s.q.iter().chain(&s.p).all(|x| x.is_finite()) {
                return Err(Error::NonFinite { state: s, h: s.t - t, iterations: 0, quantity: "position" });
            }
            last_h = Some(s.t - t);
            out.scale = out.scale.max(norm(&s.q));
            out.p_scale = out.p_scale.max(norm(&s.p));
            if every_node || s.t >= tc {
                out.samples.push(Sample { t: s.t, q: s.q, p: s.p });
            }
            k += 1;
            if stride > 0 && k.is_multiple_of(stride) {
                let v = it.velocity()?;
                if let Ok(lin) = guidance::linearize(it.system(), s.t, s.q, v) {
                    out.rates.push(lin.fastest);
                }
            }
        }
    }
    out.steps = it.stats().steps;
    Ok(out)
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

/// `(t, running maximum of the phase-space distance)` at the nodes both
/// probes recorded (times equal to a few ulps of the span).
fn distances<const N: usize>(coarse: &Probe<N>, fine: &Probe<N>, scale: f64) -> Vec<(f64, f64)> {
    // Momenta in units of the positions; a run at rest weighs positions only.
    let weight = if coarse.p_scale.max(fine.p_scale) > 0.0 { scale / coarse.p_scale.max(fine.p_scale) } else { 0.0 };
    let (first, last) = (coarse.samples[0].t, coarse.samples[coarse.samples.len() - 1].t);
    let tol = 64.0 * f64::EPSILON * first.abs().max(last.abs()).max(last - first);
    let mut out = Vec::with_capacity(coarse.samples.len());
    let mut running = 0.0f64;
    let mut j = 0;
    for a in &coarse.samples {
        while j < fine.samples.len() && fine.samples[j].t < a.t - tol {
            j += 1;
        }
        let Some(b) = fine.samples.get(j).filter(|b| (b.t - a.t).abs() <= tol) else { continue };
        let dq = a.q.iter().zip(&b.q).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        let dp = a.p.iter().zip(&b.p).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        running = running.max(dq.max(dp * weight));
        out.push((a.t, running));
    }
    out
}

impl Richardson {
    /// From the coarse and fine probes of a method of order `p`, with the
    /// growth judged at the checkpoints `times` (each twice as far from `t0`
    /// as the one before) from `settle` after `t0` on (a period of the
    /// fastest mode: within it, the error of an oscillation is still turning
    /// with its phase).
    pub(crate) fn new<const N: usize>(
        coarse: &Probe<N>,
        fine: &Probe<N>,
        order: u32,
        times: &[f64],
        t0: f64,
        settle: f64,
    ) -> Self {
        let factor = 2f64.powi(order as i32) / (2f64.powi(order as i32) - 1.0);
        let scale = coarse.scale.max(fine.scale).max(f64::MIN_POSITIVE);
        let d = distances(coarse, fine, scale);
        // The running maximum at each checkpoint: the last shared node not after it.
        let e: Vec<f64> = times
            .iter()
            .map(|&tc| {
                let i = d.partition_point(|&(t, _)| t <= tc + 64.0 * f64::EPSILON * tc.abs());
                if i == 0 { 0.0 } else { d[i - 1].1 * factor }
            })
            .collect();
        let noise = 10.0 * f64::EPSILON * scale * (fine.steps.max(1) as f64).sqrt();
        let error = d.last().map_or(0.0, |x| x.1 * factor);
        let mut growth = Growth::Power(1.0);
        // Exponential growth keeps every interval steep; a bend of a power
        // law (an error rising as a resonance is crossed) makes one.
        let mut steep_before = false;
        for i in 1..e.len() {
            let (a, b) = (e[i - 1], e[i]);
            // Above round-off, below saturation, after the first period.
            if times[i - 1] - t0 < 0.99 * settle || a <= 100.0 * noise || b >= 1e-2 * scale {
                steep_before = false;
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
