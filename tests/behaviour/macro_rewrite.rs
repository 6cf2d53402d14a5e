//! Behaviour of the code `#[lagrangian]` generates, through the facade.
//!
//! For Lagrangians that exercise every supported construct: the trait methods
//! evaluated on `f64` agree bit for bit with the user's own `f64` methods (the
//! rewrite only reorders exactly commuting operations); their derivatives on
//! dual numbers agree with central finite differences and, for the pendulum,
//! with the hand-derived formula; and the constants are right.
#![allow(missing_docs)]

use lagrangian::Lagrangian;
use lagrangian::num_dual::Dual64;
use lagrangian::prelude::*;

// ---------------------------------------------------------------- systems --

/// `L = ½ m l² θ̇² + m g l cos θ`.
pub struct Pendulum {
    pub m: f64,
    pub l: f64,
    pub g: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * self.l * self.l * v[0] * v[0] + self.m * self.g * self.l * q[0].cos()
    }
}

const PENDULUM: Pendulum = Pendulum { m: 1.3, l: 0.8, g: 9.81 };

/// Every construct at once, time-dependent; `q[2]` never appears. It
/// branches on `q` and `t`, so it must be declared discontinuous.
pub struct KitchenSink {
    pub m: f64,
    pub k: [f64; 3],
    pub p: f64,
    pub stiff: bool,
}

#[lagrangian(discontinuous)]
impl KitchenSink {
    fn lagrangian(&self, t: f64, q: [f64; 3], v: [f64; 3]) -> f64 {
        use std::f64::consts::PI;
        const HALF: f64 = 0.5;
        let mut kinetic = 0.0;
        for i in 0..3 {
            kinetic += HALF * self.m * v[i] * v[i];
        }
        let (x, y) = (q[0], q[1]);
        let r: f64 = (x * x + y * y + 1.0).sqrt();
        let angle = q[1].atan2(q[0]) + self.p.atan2(1.0) + 1.0_f64.atan2(q[0]);
        let mut potential = self.k[0] * r.powi(2) + self.k[1] * (1.0 - q[0]).abs().powf(self.p);
        if q[0] > 0.0 {
            potential -= 2.0 / (v[0] * v[0] + 1.0);
        } else if 0.0 < q[1] {
            potential += q[1].powf(1.5 + t);
        } else {
            potential = potential * 2.0 - 0.1;
        }
        let two = 2;
        let scale = if self.stiff { 2.0 } else { 1.0 };
        let drive = if t > 1.0 { (PI * t).sin() } else { 0.0 };
        if r > 100.0 {
            return 0.0;
        }
        kinetic - scale * potential + drive * q[1] + (two as f64) * angle - f64::cos(t)
            + 3.0_f64.powf(v[2]) * 1e-3
            + 2.0f64.log(v[2] * v[2] + 2.0)
            + self.k[2].mul_add(v[1], 1.0).tanh()
    }

    fn force(&self, t: f64, q: [f64; 3], _v: [f64; 3]) -> [f64; 3] {
        [1.0 - q[0], 0.0, 2.0 / (t + 1.0)]
    }
}

const SINK: KitchenSink = KitchenSink { m: 1.7, k: [0.9, 0.4, 0.3], p: 1.3, stiff: true };

/// Two coupled oscillators with Rayleigh damping and a periodic drive.
pub struct Damped {
    pub k: f64,
    pub c: [f64; 2],
    pub amp: f64,
    pub w: f64,
}

#[lagrangian]
impl Damped {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - 0.5 * self.k * (q[0] - q[1]).powi(2)
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        let mut r = 0.0;
        for i in 0..2 {
            r += 0.5 * self.c[i] * v[i] * v[i];
        }
        r
    }

    fn force(&self, t: f64, q: [f64; 2], _v: [f64; 2]) -> [f64; 2] {
        let mut f = [0.0; 2];
        f[0] = self.amp * (self.w * t).cos();
        f[1] -= self.c[1] * q[1];
        f
    }
}

const DAMPED: Damped = Damped { k: 2.0, c: [0.1, 0.3], amp: 0.5, w: 1.7 };

/// A chain of `N` unit masses, generic over `N`: indexing by the loop
/// variable, so nothing is proven cyclic.
pub struct Chain<const N: usize> {
    pub k: f64,
}

#[lagrangian]
impl<const N: usize> Chain<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.0;
        for i in 0..N {
            l += 0.5 * v[i] * v[i];
        }
        for i in 1..N {
            l -= 0.5 * self.k * (q[i] - q[i - 1]).powi(2);
        }
        l
    }
}

/// Generic over `N` with only literal indices into `q`: coordinates other
/// than 0 are cyclic, which the generated constant works out for each `N`.
pub struct Tilted<const N: usize>;

#[lagrangian]
impl<const N: usize> Tilted<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        0.5 * v[0] * v[0] - q[0]
    }
}

// ---------------------------------------------------------------- helpers --

/// `L(t, q, v)` through the trait, on `f64`.
fn eval<S: Lagrangian<N>, const N: usize>(s: &S, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
    s.lagrangian::<f64>(t, q, v)
}

/// `(∂L/∂t, ∂L/∂q, ∂L/∂v)` through the trait, on dual numbers.
fn dual_gradient<S: Lagrangian<N>, const N: usize>(
    s: &S,
    t: f64,
    q: [f64; N],
    v: [f64; N],
) -> (f64, [f64; N], [f64; N]) {
    let lift = |x: [f64; N]| x.map(Dual64::from);
    let dt = s.lagrangian(Dual64::from(t).derivative(), lift(q), lift(v)).eps;
    let dq = std::array::from_fn(|i| {
        let mut qd = lift(q);
        qd[i] = qd[i].derivative();
        s.lagrangian(Dual64::from(t), qd, lift(v)).eps
    });
    let dv = std::array::from_fn(|i| {
        let mut vd = lift(v);
        vd[i] = vd[i].derivative();
        s.lagrangian(Dual64::from(t), lift(q), vd).eps
    });
    (dt, dq, dv)
}

/// Central difference of `f` at `x`.
fn central(f: impl Fn(f64) -> f64, x: f64) -> f64 {
    let h = 1e-6 * x.abs().max(1.0);
    (f(x + h) - f(x - h)) / (2.0 * h)
}

/// The same gradient by central finite differences.
fn fd_gradient<S: Lagrangian<N>, const N: usize>(s: &S, t: f64, q: [f64; N], v: [f64; N]) -> (f64, [f64; N], [f64; N]) {
    let dt = central(|t| eval(s, t, q, v), t);
    let dq = std::array::from_fn(|i| {
        central(
            |x| {
                let mut q = q;
                q[i] = x;
                eval(s, t, q, v)
            },
            q[i],
        )
    });
    let dv = std::array::from_fn(|i| {
        central(
            |x| {
                let mut v = v;
                v[i] = x;
                eval(s, t, q, v)
            },
            v[i],
        )
    });
    (dt, dq, dv)
}

fn assert_close(actual: f64, expected: f64, rel: f64, what: &str) {
    let scale = expected.abs().max(1.0);
    assert!((actual - expected).abs() <= rel * scale, "{what}: {actual} vs {expected} (tolerance {rel} relative)");
}

/// Dual-number derivatives agree with finite differences.
fn assert_gradient_matches_fd<S: Lagrangian<N>, const N: usize>(s: &S, t: f64, q: [f64; N], v: [f64; N]) {
    let (dt, dq, dv) = dual_gradient(s, t, q, v);
    let (fdt, fdq, fdv) = fd_gradient(s, t, q, v);
    assert_close(dt, fdt, 1e-7, "dL/dt");
    for i in 0..N {
        assert_close(dq[i], fdq[i], 1e-7, &format!("dL/dq[{i}]"));
        assert_close(dv[i], fdv[i], 1e-7, &format!("dL/dv[{i}]"));
    }
}

/// Sample states, chosen to visit every branch of the kitchen sink.
const SINK_STATES: [(f64, [f64; 3], [f64; 3]); 4] = [
    (0.3, [0.4, -0.7, 2.0], [0.5, -1.2, 0.8]),
    (1.7, [-0.6, 0.9, -1.0], [1.1, 0.3, -0.4]),
    (2.5, [-0.2, -0.5, 0.0], [-0.7, 0.6, 1.9]),
    (0.0, [150.0, 1.0, 0.0], [0.0, 0.0, 0.5]),
];

// ------------------------------------------------------------------ tests --

#[test]
fn pendulum_trait_equals_the_users_method() {
    for (q, v) in [(0.3, -1.1), (2.9, 0.4), (-1.0, 0.0)] {
        assert_eq!(eval(&PENDULUM, 0.0, [q], [v]).to_bits(), PENDULUM.lagrangian([q], [v]).to_bits());
    }
}

#[test]
fn pendulum_derivatives_match_the_hand_formula_and_finite_differences() {
    let Pendulum { m, l, g } = PENDULUM;
    for (q, v) in [(0.3, -1.1), (2.9, 0.4), (-1.0, 0.0)] {
        let (dt, dq, dv) = dual_gradient(&PENDULUM, 0.0, [q], [v]);
        assert_eq!(dt, 0.0);
        assert_close(dq[0], -m * g * l * q.sin(), 1e-13, "dL/dq");
        assert_close(dv[0], m * l * l * v, 1e-13, "dL/dv");
        assert_gradient_matches_fd(&PENDULUM, 0.0, [q], [v]);
    }
}

#[test]
fn kitchen_sink_trait_equals_the_users_method() {
    for (t, q, v) in SINK_STATES {
        assert_eq!(eval(&SINK, t, q, v).to_bits(), SINK.lagrangian(t, q, v).to_bits(), "at {t} {q:?} {v:?}");
        let force = <KitchenSink as Lagrangian<3>>::force::<f64>(&SINK, t, q, v);
        assert_eq!(force, SINK.force(t, q, v));
    }
    // Each `stiff` branch.
    let soft = KitchenSink { stiff: false, ..SINK };
    let (t, q, v) = SINK_STATES[0];
    assert_eq!(eval(&soft, t, q, v).to_bits(), soft.lagrangian(t, q, v).to_bits());
}

#[test]
fn kitchen_sink_derivatives_match_finite_differences() {
    for (t, q, v) in SINK_STATES {
        assert_gradient_matches_fd(&SINK, t, q, v);
    }
}

#[test]
fn force_and_dissipation_are_rewritten_too() {
    let (t, q, v) = (0.8, [0.3, -0.4], [1.2, -0.5]);
    assert_eq!(eval(&DAMPED, t, q, v).to_bits(), DAMPED.lagrangian(q, v).to_bits());
    let r = <Damped as Lagrangian<2>>::dissipation::<f64>(&DAMPED, q, v);
    assert_eq!(r.to_bits(), DAMPED.dissipation(q, v).to_bits());
    let f = <Damped as Lagrangian<2>>::force::<f64>(&DAMPED, t, q, v);
    assert_eq!(f, DAMPED.force(t, q, v));

    // ∂R/∂v_i = c_i v_i, on dual numbers.
    for i in 0..2 {
        let mut vd = v.map(Dual64::from);
        vd[i] = vd[i].derivative();
        let r = <Damped as Lagrangian<2>>::dissipation(&DAMPED, q.map(Dual64::from), vd);
        assert_close(r.eps, DAMPED.c[i] * v[i], 1e-13, "dR/dv");
    }
    // ∂Q/∂t and ∂Q/∂q.
    let f = <Damped as Lagrangian<2>>::force(
        &DAMPED,
        Dual64::from(t).derivative(),
        q.map(Dual64::from),
        v.map(Dual64::from),
    );
    assert_close(f[0].eps, -DAMPED.amp * DAMPED.w * (DAMPED.w * t).sin(), 1e-13, "dQ0/dt");
    assert_eq!(f[1].eps, 0.0);
    let mut qd = q.map(Dual64::from);
    qd[1] = qd[1].derivative();
    let f = <Damped as Lagrangian<2>>::force(&DAMPED, Dual64::from(t), qd, v.map(Dual64::from));
    assert_eq!([f[0].eps, f[1].eps], [0.0, -DAMPED.c[1]]);
}

#[test]
fn generic_systems_expand_for_every_n() {
    let chain = Chain::<4> { k: 3.0 };
    let (q, v) = ([0.1, -0.3, 0.5, 0.2], [1.0, 0.4, -0.6, 0.9]);
    assert_eq!(eval(&chain, 0.0, q, v).to_bits(), chain.lagrangian(q, v).to_bits());
    assert_gradient_matches_fd(&chain, 0.0, q, v);
    let tilted = Tilted::<2>;
    assert_eq!(eval(&tilted, 0.0, [0.5, 0.1], [1.0, 2.0]), tilted.lagrangian([0.5, 0.1], [1.0, 2.0]));
}

/// `(AUTONOMOUS, HAS_DISSIPATION, HAS_FORCE, CYCLIC, DISCONTINUOUS)`.
fn constants<S: Lagrangian<N>, const N: usize>() -> (bool, bool, bool, [bool; N], bool) {
    (S::AUTONOMOUS, S::HAS_DISSIPATION, S::HAS_FORCE, S::CYCLIC, S::DISCONTINUOUS)
}

#[test]
fn constants_describe_the_signature_and_the_cyclic_coordinates() {
    assert_eq!(constants::<Pendulum, 1>(), (true, false, false, [false], false));
    assert_eq!(constants::<KitchenSink, 3>(), (false, false, true, [false, false, true], true));
    // `force` taking `t` does not make the Lagrangian time-dependent.
    assert_eq!(constants::<Damped, 2>(), (true, true, true, [false, false], false));
    assert_eq!(constants::<Chain<3>, 3>(), (true, false, false, [false; 3], false));
    assert_eq!(constants::<Tilted<3>, 3>(), (true, false, false, [false, true, true], false));
}
