//! An ensemble of pendulum runs split over the tasks of a cluster array job,
//! merged back and checked against one serial run bit for bit.
//!
//! Member `i` starts at `θ0 = 0.1 + 2.9 i/M` with gravity `ω² = 9 + (i mod 7)/4`
//! and takes 10 000 midpoint steps of `h = 0.01`; its result is `(q, p)` at
//! the end and the largest energy change on the way. The inputs follow from
//! the index, so every task knows its members without an input file.
//!
//! ```text
//! ensemble_shard shard --members M --shard K --shards N --out FILE
//!     runs members shard(M, K, N) and writes them as a JSON `Shard`
//! ensemble_shard merge --members M --shards N --dir DIR
//!     merges DIR/shard-0.json … DIR/shard-(N−1).json, runs all M members
//!     serially in this process and compares every number bit for bit
//!     (exit status 1 when one differs)
//! ```
//!
//! `scripts/slurm/run.sh` runs it as a Slurm array job (`docs/guide/cluster.md`);
//! without a scheduler, the same steps by hand:
//! `cargo run --release --example ensemble_shard -- shard --members 1000 --shard 0 --shards 2 --out /tmp/shard-0.json`
//! (and shard 1), then `… -- merge --members 1000 --shards 2 --dir /tmp`.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use lagrangian::ensemble::{self, Ensemble, Shard};
use lagrangian::prelude::*;

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

/// Steps per member.
const STEPS: usize = 10_000;

/// `(q(T), p(T), max |E − E0|)` of one member.
type Outcome = [f64; 3];

/// The results of some members; a failed member carries its error's text.
type Results = Ensemble<Outcome, String>;

/// The input of member `index` of `members`: `(θ0, ω²)`.
fn input(index: usize, members: usize) -> (f64, f64) {
    (0.1 + 2.9 * index as f64 / members as f64, 9.0 + (index % 7) as f64 * 0.25)
}

fn member(_: usize, &(theta0, omega2): &(f64, f64)) -> Result<Outcome, String> {
    let mut sim =
        Integrator::new(Pendulum { omega2 }, Midpoint, 0.01).start(0.0, [theta0], [0.0]).map_err(|e| e.to_string())?;
    let e0 = sim.energy().map_err(|e| e.to_string())?;
    let mut worst: f64 = 0.0;
    sim.run(STEPS, |s| worst = worst.max((s.energy().unwrap_or(f64::NAN) - e0).abs())).map_err(|e| e.to_string())?;
    let state = sim.state();
    Ok([state.q[0], state.p[0], worst])
}

fn inputs(members: usize) -> Vec<(f64, f64)> {
    (0..members).map(|i| input(i, members)).collect()
}

/// The command line: `--name value` pairs after the subcommand.
struct Args {
    command: String,
    pairs: Vec<(String, String)>,
}

impl Args {
    fn parse() -> Result<Args, String> {
        let mut it = std::env::args().skip(1);
        let command = it.next().ok_or("a subcommand: `shard` or `merge` (see the example's docs)")?;
        let mut pairs = Vec::new();
        while let Some(name) = it.next() {
            let value = it.next().ok_or_else(|| format!("`{name}` needs a value"))?;
            pairs.push((name, value));
        }
        Ok(Args { command, pairs })
    }

    fn text(&self, name: &str) -> Result<&str, String> {
        self.pairs
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
            .ok_or_else(|| format!("`{name}` is missing"))
    }

    fn count(&self, name: &str) -> Result<usize, String> {
        let v = self.text(name)?;
        v.parse().map_err(|_| format!("`{name}`: `{v}` is not a count"))
    }
}

/// Runs one shard and writes it.
fn shard(args: &Args) -> Result<(), String> {
    let (members, k, n) = (args.count("--members")?, args.count("--shard")?, args.count("--shards")?);
    let out = PathBuf::from(args.text("--out")?);
    let range = ensemble::shard(members, k, n).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let all = inputs(members);
    let shard = Shard { start: range.start, results: ensemble::run(&all[range.clone()], member) };
    let file = std::fs::File::create(&out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    serde_json::to_writer(std::io::BufWriter::new(file), &shard)
        .map_err(|e| format!("cannot write {}: {e}", out.display()))?;
    println!(
        "shard {k} of {n}: members {}..{} in {:.2} s, {} failed, written to {}",
        range.start,
        range.end,
        start.elapsed().as_secs_f64(),
        shard.results.failures().count(),
        out.display()
    );
    Ok(())
}

/// Whether two member results are the same bits (an error is the same text).
fn same_bits(
    a: &Result<Outcome, ensemble::MemberError<String>>,
    b: &Result<Outcome, ensemble::MemberError<String>>,
) -> bool {
    match (a, b) {
        (Ok(x), Ok(y)) => x.iter().zip(y).all(|(x, y)| x.to_bits() == y.to_bits()),
        (Err(x), Err(y)) => x == y,
        _ => false,
    }
}

/// Merges the shards, runs the serial ensemble and compares them.
fn merge(args: &Args) -> Result<bool, String> {
    let (members, n) = (args.count("--members")?, args.count("--shards")?);
    let dir = PathBuf::from(args.text("--dir")?);
    let mut shards = Vec::with_capacity(n);
    for k in 0..n {
        let path = dir.join(format!("shard-{k}.json"));
        let file = std::fs::File::open(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let shard: Shard<Outcome, String> = serde_json::from_reader(std::io::BufReader::new(file))
            .map_err(|e| format!("{} is not a shard: {e}", path.display()))?;
        shards.push(shard);
    }
    let merged: Results = ensemble::merge(shards, members).map_err(|e| e.to_string())?;
    println!("merged {n} shards: {} members, {} failed", merged.len(), merged.failures().count());
    let start = Instant::now();
    let serial: Results = ensemble::run_serial(&inputs(members), member);
    println!("serial run of the {members} members in this process: {:.2} s", start.elapsed().as_secs_f64());
    let differ: Vec<usize> = merged
        .results
        .iter()
        .zip(&serial.results)
        .enumerate()
        .filter(|(_, (a, b))| !same_bits(a, b))
        .map(|(i, _)| i)
        .collect();
    let largest = merged.successes().map(|(_, o)| o[2]).fold(0.0, f64::max);
    println!("largest energy change of a member over {STEPS} steps: {largest:.3e}");
    if differ.is_empty() {
        println!("merged == serial: all {members} members bit for bit (q, p, energy change)");
        Ok(true)
    } else {
        println!("merged != serial: {} members differ, the first {:?}", differ.len(), &differ[..differ.len().min(10)]);
        Ok(false)
    }
}

fn main() -> ExitCode {
    let result = Args::parse().and_then(|args| match args.command.as_str() {
        "shard" => shard(&args).map(|()| true),
        "merge" => merge(&args),
        other => Err(format!("unknown subcommand `{other}`: `shard` or `merge`")),
    });
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::from(2)
        }
    }
}
