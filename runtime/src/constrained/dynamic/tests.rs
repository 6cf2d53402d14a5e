//! The run-time-sized constrained integrator: the same steps as the
//! const-size (dense) one, a saddle-point band that does not grow with the
//! chain, and the typed errors of bad input. The chain of 10 000 links in a
//! 2 MiB thread is `tests/constraints/large_chain.rs`.

use super::*;
use crate::structure::{Coupling, Pattern, Separability};
use crate::system::{Lagrangian, Scalar};
use crate::{Constrained, Integrator, Midpoint};

/// A chain of `links` unit links with unit point masses at the joints,
/// hanging from a pivot at the origin under unit gravity, in Cartesian
/// coordinates `(x₁, y₁, …, x_n, y_n)`; `nan_above` makes the constraints
/// NaN when a joint rises above that height.
#[derive(Clone, Debug)]
struct Chain {
    links: usize,
    nan_above: f64,
    /// Repeat the first constraint in place of the last (redundant).
    redundant: bool,
    /// The number of constraints declared (`links` but for bad input).
    count: usize,
}

impl Chain {
    fn new(links: usize) -> Self {
        Self { links, nan_above: f64::INFINITY, redundant: false, count: links }
    }

    fn lagrangian_of<D: Scalar>(q: &[D], v: &[D]) -> D {
        let mut l = D::zero();
        for i in 0..q.len() / 2 {
            l += (v[2 * i] * v[2 * i] + v[2 * i + 1] * v[2 * i + 1]) * 0.5 - q[2 * i + 1];
        }
        l
    }

    fn constraints_of<D: Scalar>(&self, q: &[D], g: &mut [D]) {
        let (mut x, mut y) = (D::zero(), D::zero());
        for r in 0..self.links {
            let (dx, dy) = (q[2 * r] - x, q[2 * r + 1] - y);
            g[r] = dx * dx + dy * dy - 1.0;
            if q[2 * r + 1].re() > self.nan_above {
                g[r] += (-q[2 * r + 1]).sqrt();
            }
            x = q[2 * r];
            y = q[2 * r + 1];
        }
        if self.redundant {
            g[self.links - 1] = g[0] * 2.0;
        }
    }
}

/// `L = ½|v|² − Σ yᵢ`: diagonal Hessian, constant mass (what
/// `#[lagrangian]` proves for this body).
const CHAIN_COUPLING: Coupling = Coupling { q_q: Pattern::Diagonal, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };

impl DynLagrangian for Chain {
    const AUTONOMOUS: bool = true;
    const SEPARABILITY: Separability = Separability::ConstantMass;
    const COUPLING: Coupling = CHAIN_COUPLING;

    fn dimension(&self) -> usize {
        2 * self.links
    }

    fn lagrangian<D: Scalar>(&self, _: D, q: &[D], v: &[D]) -> D {
        Self::lagrangian_of(q, v)
    }

    fn constraint_count(&self) -> usize {
        self.count
    }

    fn constraints<D: Scalar>(&self, _: D, q: &[D], g: &mut [D]) {
        self.constraints_of(q, g);
    }
}

/// The same chain of five links as a const-size system.
#[derive(Clone, Debug)]
struct Five;

impl Lagrangian<10> for Five {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 10] = [false; 10];
    const CONSTRAINTS: usize = 5;
    fn lagrangian<D: Scalar>(&self, _: D, q: [D; 10], v: [D; 10]) -> D {
        Chain::lagrangian_of(&q, &v)
    }
    fn constraints<D: Scalar>(&self, _: D, q: &[D; 10], g: &mut [D]) {
        Chain::new(5).constraints_of(q, g);
    }
}

/// A folded chain: link `r` goes sideways by `±c` and down by `s`, so that
/// the joints stay within `|x| ≤ 1` and `|y| ≤ s·links`.
fn folded(links: usize, s: f64) -> Vec<f64> {
    let c = (1.0 - s * s).sqrt();
    let mut q = vec![0.0; 2 * links];
    for r in 0..links {
        q[2 * r] = if r % 2 == 0 { c } else { 0.0 };
        q[2 * r + 1] = -s * (r + 1) as f64;
    }
    q
}

#[test]
fn the_banded_path_takes_the_dense_paths_steps() {
    let q0 = folded(5, 0.6);
    let q0a: [f64; 10] = core::array::from_fn(|i| q0[i]);
    let h = 0.01;
    let mut dense = Integrator::new(Five, Constrained::<_, 5>::new(Midpoint), h).start(0.0, q0a, [0.0; 10]).unwrap();
    let mut banded = DynConstrained::start(Chain::new(5), Midpoint, h, 0.0, &q0, &[0.0; 10]).unwrap();
    let mut worst = 0.0f64;
    for _ in 0..200 {
        dense.step().unwrap();
        banded.step().unwrap();
        let (a, b) = (dense.state(), banded.state());
        for i in 0..10 {
            worst = worst.max((a.q[i] - b.q[i]).abs()).max((a.p[i] - b.p[i]).abs());
        }
    }
    println!("five links, 200 midpoint steps: largest difference of q and p {worst:.2e}");
    // Two solvers of the same equations, both converged to round-off: the
    // differences are the round-off of the solves, amplified by the
    // chaotic motion over 200 steps.
    assert!(worst < 1e-10, "largest difference {worst:e}");
}

#[test]
fn the_saddle_point_band_does_not_grow_with_the_chain() {
    for links in [10, 100, 1000] {
        let sim =
            DynConstrained::start(Chain::new(links), Midpoint, 1e-3, 0.0, &folded(links, 0.1), &vec![0.0; 2 * links])
                .unwrap();
        // Rows of 4 columns at stride 2, a diagonal step Jacobian: each
        // multiplier sits within 3 places of its coordinates.
        assert!(sim.saddle_point_bandwidth() <= 3, "{links} links: {}", sim.saddle_point_bandwidth());
    }
}

#[test]
fn bad_input_is_a_typed_error_with_the_state_kept() {
    let q0 = folded(6, 0.6);
    let zero = vec![0.0; 12];
    // Redundant constraints (the last row twice the first): refused at the
    // start.
    let redundant = Chain { redundant: true, ..Chain::new(6) };
    let r = DynConstrained::start(redundant, Midpoint, 0.01, 0.0, &q0, &zero);
    assert!(matches!(r, Err(Error::SingularConstraints { rcond, .. }) if rcond < 1e-13), "{r:?}");
    // Inconsistent data.
    let mut off = q0.clone();
    off[3] += 0.1;
    let r = DynConstrained::start(Chain::new(6), Midpoint, 0.01, 0.0, &off, &zero);
    assert!(matches!(r, Err(Error::InconsistentConstraints { position, .. }) if position > 1e-3), "{r:?}");
    // Newton failure: state kept.
    let options = NewtonOptions { max_iterations: 1, ..NewtonOptions::default() };
    let mut sim = DynConstrained::start_with(Chain::new(6), Midpoint, 0.1, options, 0.0, &q0, &zero).unwrap();
    let before = sim.state().clone();
    let r = sim.step();
    assert!(matches!(r, Err(Error::NewtonDidNotConverge { .. })), "{r:?}");
    assert_eq!(sim.state(), &before);
    assert_eq!(sim.stats().failed_steps, 1);
    // NaN constraints above y = −0.5, reached by a joint thrown upwards.
    let nan = Chain { nan_above: -0.5, ..Chain::new(1) };
    let r = DynConstrained::start(nan.clone(), Midpoint, 0.05, 0.0, &[0.0, 1.0], &[1.0, 0.0]);
    assert!(matches!(r, Err(Error::NonFiniteConstraints { .. })), "{r:?}");
    let mut sim = DynConstrained::start(
        Chain { links: 2, count: 2, ..nan },
        Midpoint,
        0.05,
        0.0,
        &[0.0, -1.0, 0.0, -2.0],
        &[3.0, 0.0, 6.0, 0.0],
    )
    .unwrap();
    let error = loop {
        let before = sim.state().clone();
        match sim.step() {
            Ok(_) => assert!(sim.state().t < 5.0),
            Err(e) => {
                assert_eq!(sim.state(), &before);
                break e;
            }
        }
    };
    assert!(matches!(error, Error::NonFiniteConstraints { .. }), "{error:?}");
    // M = 0 or M ≥ N, and the unconstrained integrator: refused.
    for count in [0, 12] {
        let r = DynConstrained::start(Chain { count, ..Chain::new(6) }, Midpoint, 0.01, 0.0, &q0, &zero);
        assert!(matches!(r, Err(Error::Unsupported { .. })), "M = {count}: {r:?}");
    }
    let r = crate::DynIntegrator::new(Chain::new(6), Midpoint, 0.01).start(0.0, &q0, &zero);
    assert!(matches!(r, Err(Error::Unsupported { .. })), "{r:?}");
}

/// `LINKS` links, `STEPS` steps (environment variables; 1000 and 10 by
/// default): what `scripts/constrained-chain-instructions.sh` counts the
/// instructions of under callgrind, for the cost per step against `N`.
#[test]
#[ignore = "a measurement: scripts/constrained-chain-instructions.sh runs it under callgrind"]
fn steps_of_a_chain_for_callgrind() {
    let read = |name: &str, default: usize| std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default);
    let (links, steps) = (read("LINKS", 1000), read("STEPS", 10));
    let q0 = folded(links, 0.01);
    let mut sim = DynConstrained::start(Chain::new(links), Midpoint, 1e-3, 0.0, &q0, &vec![0.0; 2 * links]).unwrap();
    sim.run(steps, |_| {}).unwrap();
    assert_eq!(sim.state().step, steps as u64);
}
