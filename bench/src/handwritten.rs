//! Hand-written integrators with analytic derivatives: the baselines the
//! generated code is measured against. Same predictor (linear extrapolation)
//! and the same Newton stopping rule as the runtime, so that the comparison
//! measures the cost of the derivatives and of the generic machinery only.
#![allow(dead_code, missing_docs, unreachable_pub, clippy::too_many_arguments)]

/// The runtime's stopping rule: correction below `tol (1 + |x|)`, or the
/// contraction estimate `θ/(1−θ)|Δ|` below it.
#[derive(Default)]
pub struct Stop {
    previous: Option<f64>,
}

impl Stop {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn done(&mut self, dn: f64, xn: f64) -> bool {
        let target = 1e-12 * (1.0 + xn);
        if dn <= target {
            return true;
        }
        if let Some(prev) = self.previous {
            let theta = dn / prev;
            if theta < 1.0 && theta / (1.0 - theta) * dn <= target {
                return true;
            }
        }
        self.previous = Some(dn);
        false
    }
}

/// `L = ½ a θ̇² + d cos θ` with `a = m l²`, `d = m g l`.
#[derive(Clone, Copy)]
pub struct PendulumParams {
    pub a: f64,
    pub d: f64,
}

/// Midpoint rule for the pendulum, state `(q, p)` plus the previous `q`.
pub struct PendulumMidpoint {
    pub s: PendulumParams,
    pub h: f64,
    pub q: f64,
    pub p: f64,
    pub q_prev: f64,
}

impl PendulumMidpoint {
    pub fn new(s: PendulumParams, h: f64, q0: f64, v0: f64) -> Self {
        Self { s, h, q: q0, p: s.a * v0, q_prev: q0 - h * v0 }
    }

    #[inline(never)]
    pub fn step(&mut self) -> Option<()> {
        let (a, d, h, q, p) = (self.s.a, self.s.d, self.h, self.q, self.p);
        let mut x = 2.0 * q - self.q_prev;
        let mut stop = Stop::new();
        let mut converged = false;
        for _ in 0..25 {
            let qm = 0.5 * (q + x);
            let (s, c) = qm.sin_cos();
            let r = p - 0.5 * h * d * s - a * (x - q) / h;
            let j = -0.25 * h * d * c - a / h;
            let dx = -r / j;
            x += dx;
            if stop.done(dx.abs(), x.abs()) {
                converged = true;
                break;
            }
        }
        if !converged {
            return None;
        }
        let qm = 0.5 * (q + x);
        self.p = -0.5 * h * d * qm.sin() + a * (x - q) / h;
        self.q_prev = q;
        self.q = x;
        Some(())
    }
}

/// Explicit Störmer–Verlet for the pendulum (velocity Verlet in `(q, p)`).
pub struct PendulumVerlet {
    pub s: PendulumParams,
    pub h: f64,
    pub q: f64,
    pub p: f64,
}

impl PendulumVerlet {
    #[inline(never)]
    pub fn step(&mut self) {
        let (a, d, h) = (self.s.a, self.s.d, self.h);
        let half = self.p - 0.5 * h * d * self.q.sin();
        self.q += h * half / a;
        self.p = half - 0.5 * h * d * self.q.sin();
    }
}

/// Double pendulum: `L = ½ a v₁² + ½ b v₂² + c v₁ v₂ cos(q₁ − q₂) + d cos q₁ + e cos q₂`.
#[derive(Clone, Copy)]
pub struct DoubleParams {
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub d: f64,
    pub e: f64,
}

/// `(L_q, L_v, L_qq, L_qv, L_vv)` with `L_qv[i][j] = ∂²L/∂q_i∂v_j`.
#[inline(always)]
#[allow(clippy::type_complexity)]
pub fn double_partials(
    s: &DoubleParams,
    q: [f64; 2],
    v: [f64; 2],
) -> ([f64; 2], [f64; 2], [[f64; 2]; 2], [[f64; 2]; 2], [[f64; 2]; 2]) {
    let (sd, cd) = (q[0] - q[1]).sin_cos();
    let (s1, c1) = q[0].sin_cos();
    let (s2, c2) = q[1].sin_cos();
    let vv = s.c * v[0] * v[1];
    let l_q = [-vv * sd - s.d * s1, vv * sd - s.e * s2];
    let l_v = [s.a * v[0] + s.c * v[1] * cd, s.b * v[1] + s.c * v[0] * cd];
    let l_qq = [[-vv * cd - s.d * c1, vv * cd], [vv * cd, -vv * cd - s.e * c2]];
    let l_qv = [[-s.c * v[1] * sd, -s.c * v[0] * sd], [s.c * v[1] * sd, s.c * v[0] * sd]];
    let l_vv = [[s.a, s.c * cd], [s.c * cd, s.b]];
    (l_q, l_v, l_qq, l_qv, l_vv)
}

/// `(L_q, L_v)` only.
#[inline(always)]
pub fn double_gradient(s: &DoubleParams, q: [f64; 2], v: [f64; 2]) -> ([f64; 2], [f64; 2]) {
    let (sd, cd) = (q[0] - q[1]).sin_cos();
    let vv = s.c * v[0] * v[1];
    (
        [-vv * sd - s.d * q[0].sin(), vv * sd - s.e * q[1].sin()],
        [s.a * v[0] + s.c * v[1] * cd, s.b * v[1] + s.c * v[0] * cd],
    )
}

/// Solves the 2×2 system `j x = r` by Cramer's rule.
#[inline(always)]
fn solve2(j: [[f64; 2]; 2], r: [f64; 2]) -> [f64; 2] {
    let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
    [(r[0] * j[1][1] - r[1] * j[0][1]) / det, (j[0][0] * r[1] - j[1][0] * r[0]) / det]
}

/// Which hand-written discrete Lagrangian a [`DoubleStepper`] uses.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum DoubleMethod {
    /// `A = h L((q₀+q₁)/2, v̂)`.
    Midpoint,
    /// `A = h/2 [L(q₀, v̂) + L(q₁, v̂)]`: Störmer–Verlet in Lagrangian form (implicit, since `M(q)` varies).
    Verlet,
}

/// Hand-written midpoint or Störmer–Verlet step for the double pendulum.
pub struct DoubleStepper {
    pub s: DoubleParams,
    pub method: DoubleMethod,
    pub h: f64,
    pub q: [f64; 2],
    pub p: [f64; 2],
    pub q_prev: [f64; 2],
}

impl DoubleStepper {
    pub fn new(s: DoubleParams, method: DoubleMethod, h: f64, q0: [f64; 2], v0: [f64; 2]) -> Self {
        let (_, p) = double_gradient(&s, q0, v0);
        Self { s, method, h, q: q0, p, q_prev: [q0[0] - h * v0[0], q0[1] - h * v0[1]] }
    }

    /// Residual `p + ∂A/∂q₀` and its Jacobian in `q₁ = x`.
    #[inline(always)]
    fn residual(&self, x: [f64; 2]) -> ([f64; 2], [[f64; 2]; 2]) {
        let (h, q, p, s) = (self.h, self.q, self.p, &self.s);
        let v = [(x[0] - q[0]) / h, (x[1] - q[1]) / h];
        match self.method {
            DoubleMethod::Midpoint => {
                let qm = [0.5 * (q[0] + x[0]), 0.5 * (q[1] + x[1])];
                let (l_q, l_v, l_qq, l_qv, l_vv) = double_partials(s, qm, v);
                let r = [p[0] + 0.5 * h * l_q[0] - l_v[0], p[1] + 0.5 * h * l_q[1] - l_v[1]];
                let j = core::array::from_fn(|i| {
                    core::array::from_fn(|k| 0.25 * h * l_qq[i][k] + 0.5 * (l_qv[i][k] - l_qv[k][i]) - l_vv[i][k] / h)
                });
                (r, j)
            }
            DoubleMethod::Verlet => {
                let (l_q0, l_v0, _, l_qv0, l_vv0) = double_partials(s, q, v);
                let (_, l_v1, _, l_qv1, l_vv1) = double_partials(s, x, v);
                let r = core::array::from_fn(|i| p[i] + 0.5 * h * l_q0[i] - 0.5 * (l_v0[i] + l_v1[i]));
                let j = core::array::from_fn(|i| {
                    core::array::from_fn(|k| {
                        0.5 * l_qv0[i][k] - 0.5 * l_vv0[i][k] / h - 0.5 * (l_qv1[k][i] + l_vv1[i][k] / h)
                    })
                });
                (r, j)
            }
        }
    }

    #[inline(never)]
    pub fn step(&mut self) -> Option<()> {
        let (h, q) = (self.h, self.q);
        let mut x = [2.0 * q[0] - self.q_prev[0], 2.0 * q[1] - self.q_prev[1]];
        let mut stop = Stop::new();
        let mut converged = false;
        for _ in 0..25 {
            let (r, j) = self.residual(x);
            let dx = solve2(j, r);
            x = [x[0] - dx[0], x[1] - dx[1]];
            if stop.done(dx[0].abs().max(dx[1].abs()), x[0].abs().max(x[1].abs())) {
                converged = true;
                break;
            }
        }
        if !converged {
            return None;
        }
        let v = [(x[0] - q[0]) / h, (x[1] - q[1]) / h];
        self.p = match self.method {
            DoubleMethod::Midpoint => {
                let (l_q, l_v) = double_gradient(&self.s, [0.5 * (q[0] + x[0]), 0.5 * (q[1] + x[1])], v);
                [0.5 * h * l_q[0] + l_v[0], 0.5 * h * l_q[1] + l_v[1]]
            }
            DoubleMethod::Verlet => {
                let (_, l_v0) = double_gradient(&self.s, q, v);
                let (l_q1, l_v1) = double_gradient(&self.s, x, v);
                core::array::from_fn(|i| 0.5 * h * l_q1[i] + 0.5 * (l_v0[i] + l_v1[i]))
            }
        };
        self.q_prev = q;
        self.q = x;
        Some(())
    }
}
