//! Ensembles: 1000 pendulum runs in parallel equal the serial runs bit for
//! bit, in input order; failing members are reported with their index while
//! the others finish; shards serialise and merge back into the whole, bit
//! for bit the serial run (what `scripts/slurm/run.sh` checks on a cluster).

use lagrangian::ensemble::{self, Ensemble, MemberError, Shard};
use lagrangian::prelude::*;
use lagrangian::{Plan, Solution};

#[derive(Clone)]
struct Pendulum {
    omega2: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + self.omega2 * q[0].cos()
    }
}

/// An initial angle and a gravity per member.
fn inputs() -> Vec<(f64, f64)> {
    (0..1000).map(|i| (0.1 + 2.9 * i as f64 / 1000.0, 9.0 + (i % 7) as f64 * 0.25)).collect()
}

/// 400 midpoint steps; the final state and the largest energy change.
fn member(_: usize, &(theta0, omega2): &(f64, f64)) -> Result<(State<1>, f64), Error> {
    let mut sim = Integrator::new(Pendulum { omega2 }, Midpoint, 0.01).start(0.0, [theta0], [0.0])?;
    let e0 = sim.energy()?;
    let mut worst: f64 = 0.0;
    sim.run(400, |s| worst = worst.max((s.energy().unwrap() - e0).abs()))?;
    Ok((*sim.state(), worst))
}

#[test]
fn parallel_runs_equal_serial_runs_bit_for_bit() {
    let inputs = inputs();
    let serial = ensemble::run_serial(&inputs, member);
    let parallel = ensemble::run(&inputs, member);
    assert_eq!(parallel.len(), 1000);
    assert_eq!(parallel.failures().count(), 0);
    for (i, (s, p)) in serial.results.iter().zip(&parallel.results).enumerate() {
        let (s, p) = (s.as_ref().unwrap(), p.as_ref().unwrap());
        assert_eq!(s.0.q[0].to_bits(), p.0.q[0].to_bits(), "member {i}");
        assert_eq!(s.0.p[0].to_bits(), p.0.p[0].to_bits(), "member {i}");
        assert_eq!(s.1.to_bits(), p.1.to_bits(), "member {i}");
    }
    // In input order: member i is the run from input i.
    let (theta, omega2) = inputs[617];
    let alone = member(617, &(theta, omega2)).unwrap();
    assert_eq!(parallel.results[617].as_ref().unwrap(), &alone);
}

#[test]
fn failing_members_are_reported_with_their_index() {
    let mut inputs = inputs();
    inputs[3].0 = f64::NAN;
    inputs[998].1 = f64::INFINITY;
    let result = ensemble::run(&inputs, member);
    let failed: Vec<usize> = result.failures().map(|(i, _)| i).collect();
    assert_eq!(failed, vec![3, 998]);
    assert!(matches!(result.results[3], Err(MemberError::Failed(Error::InvalidInitialData { .. }))));
    assert_eq!(result.successes().count(), 998);
}

/// Each shard solved and written as JSON, read back and merged: the same as one run.
#[test]
fn sharded_ensembles_serialise_and_merge() {
    let inputs: Vec<(f64, f64)> = inputs().into_iter().step_by(50).collect();
    let solve = |_: usize, &(theta0, omega2): &(f64, f64)| -> Result<Solution, String> {
        let mut sim = Integrator::new(Pendulum { omega2 }, Midpoint, 0.01)
            .start(0.0, [theta0], [0.0])
            .map_err(|e| e.to_string())?;
        let sol = sim.solve(Plan::until(1.0).every(20)).map_err(|e| e.to_string())?;
        sol.into_result().map_err(|e| e.to_string())
    };
    let whole = ensemble::run(&inputs, solve);
    let mut files = Vec::new();
    for k in 0..3 {
        let range = ensemble::shard(inputs.len(), k, 3).unwrap();
        let shard = Shard { start: range.start, results: ensemble::run(&inputs[range], solve) };
        files.push(serde_json::to_string(&shard).unwrap());
    }
    let shards: Vec<Shard<Solution, String>> = files.iter().rev().map(|f| serde_json::from_str(f).unwrap()).collect();
    let merged: Ensemble<Solution, String> = ensemble::merge(shards, inputs.len()).unwrap();
    assert_eq!(merged, whole);
    assert_eq!(merged.len(), 20);
}

/// 1000 members in 8 shards, as the tasks of an array job write them (JSON
/// files, read back in another order), merged: every number the serial run's
/// bits.
#[test]
fn merged_shards_equal_the_serial_run_bit_for_bit() {
    // `(t, q, p, max |E − E0|)`, the error as text: what a task writes to its file.
    let flat = |i: usize, x: &(f64, f64)| {
        member(i, x).map(|(s, worst)| [s.t, s.q[0], s.p[0], worst]).map_err(|e| e.to_string())
    };
    let inputs = inputs();
    let serial = ensemble::run_serial(&inputs, flat);
    let files: Vec<String> = (0..8)
        .map(|k| {
            let range = ensemble::shard(inputs.len(), k, 8).unwrap();
            let shard = Shard { start: range.start, results: ensemble::run(&inputs[range], flat) };
            serde_json::to_string(&shard).unwrap()
        })
        .collect();
    let shards: Vec<Shard<[f64; 4], String>> = files.iter().rev().map(|f| serde_json::from_str(f).unwrap()).collect();
    let merged = ensemble::merge(shards, inputs.len()).unwrap();
    assert_eq!(merged.len(), serial.len());
    for (i, (m, s)) in merged.results.iter().zip(&serial.results).enumerate() {
        let (m, s) = (m.as_ref().unwrap(), s.as_ref().unwrap());
        assert_eq!(m.map(f64::to_bits), s.map(f64::to_bits), "member {i}");
    }
    // Not vacuous: the members differ from one another.
    assert_ne!(merged.results[0], merged.results[999]);
}
