//! The cost of choosing the method at run time: a pendulum midpoint step
//! through `Problem` and a `Scheme` value (one `match` on the driver per
//! call) against `Integrator::new(…, Midpoint, h)` named directly. Each
//! iteration is one step of a user's loop, `let state = sim.step()?`,
//! reading the new state from what the step returns.
//!
//! Run with `cargo bench -p lagrangian-bench --bench dispatch`.
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use lagrangian::prelude::*;
use std::hint::black_box;

/// The tests' pendulum (`m = 1.3`, `l = 0.8`), cloneable for `Problem`.
#[derive(Clone)]
struct Pendulum {
    m: f64,
    l: f64,
    g: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * self.l * self.l * v[0] * v[0] + self.m * self.g * self.l * q[0].cos()
    }
}

const P: Pendulum = Pendulum { m: 1.3, l: 0.8, g: 9.81 };
const H: f64 = 0.01;

fn dispatch(c: &mut Criterion) {
    let mut group = c.benchmark_group("dispatch");
    let mut direct = Integrator::new(P, Midpoint, H).start(0.0, [1.0], [0.0]).unwrap();
    group.bench_function("pendulum midpoint: Integrator", |b| {
        b.iter(|| {
            let state = direct.step().unwrap();
            black_box(state.q[0])
        })
    });
    let mut chosen = Problem::new(P, 0.0, [1.0], [0.0]).stepper(&Scheme::MIDPOINT, H).unwrap();
    group.bench_function("pendulum midpoint: Problem + Scheme", |b| {
        b.iter(|| {
            let state = chosen.step().unwrap();
            black_box(state.q[0])
        })
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(50);
    targets = dispatch
}
criterion_main!(benches);
