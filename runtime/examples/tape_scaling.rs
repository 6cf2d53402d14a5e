//! Cost of the tape on an FPU-β chain: ns per recorded operation, gradient
//! and banded Hessian for N = 100 … 100 000 with the fitted exponent in N,
//! the array hyper-duals and a hand-written gradient for comparison, and the
//! peak memory.
//!
//! ```text
//! cargo run --release -p lagrangian-runtime --example tape_scaling
//! cargo run --release -p lagrangian-runtime --example tape_scaling -- probe 65536
//! ```
//!
//! `probe N` runs the midpoint discrete Lagrangian of the chain through the
//! `Lagrangian<N>` trait (which takes `[D; N]` by value) on `Var` in a thread
//! with the default 2 MiB stack, to find the largest `N` that fits; a stack
//! overflow aborts the process, so probe one `N` per run.

use std::hint::black_box;
use std::time::Instant;

use lagrangian_runtime::hyperdual::HyperDualArray;
use lagrangian_runtime::structure::{Coupling, Pattern};
use lagrangian_runtime::tape::{Seeds, Tape, Var};
use lagrangian_runtime::{Lagrangian, Scalar};

const BETA: f64 = 0.7;

/// The FPU-β Lagrangian with fixed ends, written like a user's body.
fn fpu<D: Scalar>(q: &[D], v: &[D]) -> D {
    let n = q.len();
    let mut kinetic = D::zero();
    for i in 0..n {
        kinetic += v[i] * v[i] * 0.5;
    }
    let mut potential = D::zero();
    for i in 0..=n {
        let left = if i == 0 { D::zero() } else { q[i - 1] };
        let right = if i == n { D::zero() } else { q[i] };
        let d = right - left;
        potential += d * d * 0.5 + d.powi(4) * (BETA / 4.0);
    }
    kinetic - potential
}

/// The gradient of [`fpu`] by hand (`q` part, then `v` part).
fn fpu_gradient(q: &[f64], v: &[f64], out: &mut [f64]) {
    let n = q.len();
    out.fill(0.0);
    for i in 0..=n {
        let left = if i == 0 { 0.0 } else { q[i - 1] };
        let right = if i == n { 0.0 } else { q[i] };
        let d = right - left;
        let f = d + BETA * d * d * d;
        if i < n {
            out[i] -= f;
        }
        if i > 0 {
            out[i - 1] += f;
        }
    }
    out[n..].copy_from_slice(v);
}

struct Fpu;

impl<const N: usize> Lagrangian<N> for Fpu {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; N] = [false; N];
    const COUPLING: Coupling = Coupling { q_q: Pattern::banded(N, 1), q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };

    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; N], v: [D; N]) -> D {
        fpu(&q, &v)
    }
}

/// Nanoseconds per call of `f`: the best of 5 batches of at least 30 ms.
fn time(mut f: impl FnMut()) -> f64 {
    f();
    let mut reps = 1u64;
    loop {
        let start = Instant::now();
        for _ in 0..reps {
            f();
        }
        if start.elapsed().as_secs_f64() > 0.03 {
            break;
        }
        reps *= 2;
    }
    (0..5)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..reps {
                f();
            }
            start.elapsed().as_secs_f64() * 1e9 / reps as f64
        })
        .fold(f64::INFINITY, f64::min)
}

/// Least-squares slope of `ln t` against `ln n`.
fn exponent(points: &[(f64, f64)]) -> f64 {
    let xs: Vec<f64> = points.iter().map(|p| p.0.ln()).collect();
    let ys: Vec<f64> = points.iter().map(|p| p.1.ln()).collect();
    let (mx, my) = (xs.iter().sum::<f64>() / xs.len() as f64, ys.iter().sum::<f64>() / ys.len() as f64);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

fn state(n: usize) -> Vec<f64> {
    (0..2 * n).map(|i| ((i * 7919) % 1000) as f64 * 1e-3 - 0.5).collect()
}

/// The peak resident set of the process (Linux), in MB.
fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

fn scaling() {
    println!("FPU-β chain, L(q, v) with 2N inputs; times are the best of 5 batches (release)");
    println!(
        "{:>8} {:>9} {:>10} {:>12} {:>12} {:>14} {:>12} {:>10}",
        "N", "nodes", "ns/op rec", "record µs", "gradient µs", "banded H µs", "by hand µs", "tape MB"
    );
    let mut tape = Tape::new();
    let mut rows = Vec::new();
    for n in [100, 1_000, 10_000, 100_000] {
        let x = state(n);
        let mut g = vec![0.0; 2 * n];
        let seeds = Seeds::banded(0..2 * n, 1);
        let k = seeds.directions();
        let mut hs = vec![0.0; 2 * n * k];
        let mut band = vec![0.0; 2 * n * 3];
        let record = time(|| {
            tape.record(black_box(&x), |v| fpu(&v[..n], &v[n..])).unwrap();
        });
        let nodes = tape.len() - 2 * n;
        let gradient = time(|| tape.gradient(&mut g).unwrap());
        let hessian = time(|| {
            tape.hessian_product(&seeds, &mut g, &mut hs).unwrap();
            seeds.recover(&hs, 0..2 * n, &mut band).unwrap();
        });
        let mut gh = vec![0.0; 2 * n];
        let by_hand = time(|| fpu_gradient(black_box(&x[..n]), &x[n..], &mut gh));
        tape.gradient(&mut g).unwrap();
        let err = g.iter().zip(&gh).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(err < 1e-12, "tape and hand-written gradients differ by {err:e}");
        println!(
            "{n:>8} {nodes:>9} {:>10.2} {:>12.1} {:>12.1} {:>14.1} {:>12.1} {:>10.1}",
            record / nodes as f64,
            record * 1e-3,
            gradient * 1e-3,
            hessian * 1e-3,
            by_hand * 1e-3,
            tape.memory_bytes() as f64 / 1e6
        );
        rows.push((n as f64, record, gradient, hessian, by_hand));
    }
    let fit =
        |f: fn(&(f64, f64, f64, f64, f64)) -> f64| exponent(&rows.iter().map(|r| (r.0, f(r))).collect::<Vec<_>>());
    println!(
        "fitted exponent in N: record {:.3}, gradient {:.3}, record + gradient {:.3}, banded Hessian {:.3}, \
         record + banded Hessian {:.3}",
        fit(|r| r.1),
        fit(|r| r.2),
        fit(|r| r.1 + r.2),
        fit(|r| r.3),
        fit(|r| r.1 + r.3)
    );
    println!(
        "tape at N = 100 000: {:.1} MB (nodes {} B each, Var {} B); process peak RSS {:.1} MB",
        tape.memory_bytes() as f64 / 1e6,
        48,
        size_of::<Var>(),
        peak_rss_mb().unwrap_or(f64::NAN)
    );
}

/// The `q–q` Hessian block of `L` at one point: array hyper-dual (one
/// evaluation) against the tape (record + banded product + recovery).
fn against_hyper_duals<const N: usize>() -> (f64, f64, f64) {
    type Hd<const N: usize> = HyperDualArray<[f64; N], [f64; N]>;
    let x = state(N);
    let hyper = time(|| {
        let q: [Hd<N>; N] = core::array::from_fn(|i| {
            let mut y = Hd::<N>::from_re(x[i]);
            y.eps1[i] = 1.0;
            y.eps2[i] = 1.0;
            y
        });
        let v: [Hd<N>; N] = core::array::from_fn(|i| Hd::<N>::from_re(x[N + i]));
        black_box(Fpu.lagrangian(Hd::<N>::from_re(0.0), black_box(q), v));
    });
    let mut tape = Tape::new();
    let seeds = Seeds::banded(0..N, 1);
    let mut g = vec![0.0; 2 * N];
    let mut hs = vec![0.0; 2 * N * 3];
    let mut band = vec![0.0; N * 3];
    let taped = time(|| {
        tape.record(black_box(&x), |v| {
            let q: [Var; N] = core::array::from_fn(|i| v[i]);
            let w: [Var; N] = core::array::from_fn(|i| v[N + i]);
            Fpu.lagrangian(Var::from(0.0), q, w)
        })
        .unwrap();
        tape.hessian_product(&seeds, &mut g, &mut hs).unwrap();
        seeds.recover(&hs, 0..N, &mut band).unwrap();
    });
    let gradient = time(|| {
        tape.record(black_box(&x), |v| fpu(&v[..N], &v[N..])).unwrap();
        tape.gradient(&mut g).unwrap();
    });
    (hyper, taped, gradient)
}

fn small() {
    println!();
    println!("q–q Hessian block of L (value, gradient and Hessian from one call), ns:");
    println!(
        "{:>4} {:>16} {:>22} {:>8} {:>22}",
        "N", "HyperDualArray", "tape record + band H", "ratio", "tape record + grad"
    );
    for (n, (hyper, taped, gradient)) in
        [(8, against_hyper_duals::<8>()), (16, against_hyper_duals::<16>()), (32, against_hyper_duals::<32>())]
    {
        println!("{n:>4} {hyper:>16.0} {taped:>22.0} {:>8.2} {gradient:>22.0}", hyper / taped);
    }
}

/// The midpoint discrete Lagrangian through the trait, `[Var; N]` by value,
/// in a 2 MiB thread.
fn probe<const N: usize>() {
    let ok = std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(|| {
            let x = state(N);
            let mut tape = Tape::new();
            let h = 0.01;
            tape.record(&x, |v| {
                let q: [Var; N] = core::array::from_fn(|i| (v[i] + v[N + i]) * 0.5);
                let w: [Var; N] = core::array::from_fn(|i| (v[N + i] - v[i]) / h);
                Fpu.lagrangian(Var::from(0.0), q, w) * h
            })
            .unwrap();
            tape.len()
        })
        .unwrap()
        .join()
        .is_ok();
    println!(
        "N = {N}: `[Var; N]` through `Lagrangian::lagrangian` in a 2 MiB thread: {}",
        if ok { "fits" } else { "fails" }
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("probe") {
        match args.get(2).and_then(|s| s.parse::<usize>().ok()) {
            Some(16_384) => probe::<16_384>(),
            Some(24_576) => probe::<24_576>(),
            Some(32_768) => probe::<32_768>(),
            Some(49_152) => probe::<49_152>(),
            Some(65_536) => probe::<65_536>(),
            Some(100_000) => probe::<100_000>(),
            _ => eprintln!("probe one of 16384, 24576, 32768, 49152, 65536, 100000"),
        }
        return;
    }
    small();
    println!();
    scaling();
}
