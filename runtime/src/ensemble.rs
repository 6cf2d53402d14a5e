//! Ensembles: one integration per input (initial conditions, parameters),
//! run in parallel with the feature `rayon`, results in the order of the
//! inputs.
//!
//! Each member is the user's closure `member(index, &input)`, which builds
//! its own integrator and returns its result; members share nothing, so a
//! parallel run returns exactly, bit for bit, what [`run_serial`] returns
//! (`tests/behaviour/ensemble.rs` checks 1000 pendulum runs). A member that fails (an
//! `Err`, or a panic, which is caught) is reported with its index while the
//! others finish.
//!
//! # Sharding over a cluster
//!
//! Built: [`shard`] gives the contiguous range of inputs of job `k` of `n`,
//! [`Shard`] holds one job's results with the index of its first member,
//! and [`merge`] puts the shards of all jobs back into one [`Ensemble`] of
//! a given number of members, refusing shards that leave a member out
//! (between shards, at the head or at the tail), hold one twice or hold one
//! past the end. With the feature `serde`,
//! inputs of the user's types, [`Shard`] and [`Ensemble`] serialise (as JSON
//! through `serde_json`, or any serde format), so each job writes its shard
//! to a file and one last job merges them.
//!
//! A Slurm array job runs the same binary once per shard: each task takes
//! `shard(len, $SLURM_ARRAY_TASK_ID, $SLURM_ARRAY_TASK_COUNT)`, runs those
//! members with [`run`] (rayon uses the task's cores) and writes a [`Shard`];
//! a last step reads the files and calls [`merge`] with the number of
//! members. Every member is independent, so the merged result equals a
//! single-machine run bit for bit. The example `ensemble_shard` is such a
//! binary, and `scripts/slurm/` runs it for real on a single-node cluster
//! (10 000 pendulum runs in 8 array tasks, merged and compared with the serial
//! run bit for bit; `docs/guide/cluster.md` shows the commands, their output
//! and what to change on a real cluster); `tests/behaviour/ensemble.rs` makes
//! the same comparison without a scheduler. MPI (rsmpi) is not offered: array
//! jobs need no communication between members.

use core::ops::Range;
use std::panic::{AssertUnwindSafe, catch_unwind};

/// Why a member has no result.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum MemberError<E> {
    /// The member returned an error.
    #[error("{0}")]
    Failed(E),
    /// The member panicked (a bug in the member's code; the message is the panic's).
    #[error("the member panicked: {0}")]
    Panicked(String),
}

/// The results of an ensemble, in the order of its inputs.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Ensemble<O, E> {
    /// One result per input.
    pub results: Vec<Result<O, MemberError<E>>>,
}

impl<O, E> Ensemble<O, E> {
    /// The number of members.
    pub fn len(&self) -> usize {
        self.results.len()
    }

    /// `true` without members.
    pub fn is_empty(&self) -> bool {
        self.results.is_empty()
    }

    /// The members that failed, with their indices.
    pub fn failures(&self) -> impl Iterator<Item = (usize, &MemberError<E>)> {
        self.results.iter().enumerate().filter_map(|(i, r)| r.as_ref().err().map(|e| (i, e)))
    }

    /// The members that succeeded, with their indices.
    pub fn successes(&self) -> impl Iterator<Item = (usize, &O)> {
        self.results.iter().enumerate().filter_map(|(i, r)| r.as_ref().ok().map(|o| (i, o)))
    }
}

/// One member, its panic caught.
fn one<I, O, E>(
    member: &(impl Fn(usize, &I) -> Result<O, E> + Sync),
    index: usize,
    input: &I,
) -> Result<O, MemberError<E>> {
    match catch_unwind(AssertUnwindSafe(|| member(index, input))) {
        Ok(Ok(o)) => Ok(o),
        Ok(Err(e)) => Err(MemberError::Failed(e)),
        Err(panic) => {
            let text = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "(no message)".to_string());
            Err(MemberError::Panicked(text))
        }
    }
}

/// Runs `member(index, &input)` for every input one after the other.
pub fn run_serial<I, O, E>(inputs: &[I], member: impl Fn(usize, &I) -> Result<O, E> + Sync) -> Ensemble<O, E> {
    Ensemble { results: inputs.iter().enumerate().map(|(i, x)| one(&member, i, x)).collect() }
}

/// Runs `member(index, &input)` for every input, in parallel on rayon's
/// global thread pool (feature `rayon`; without it, serially). Results are in
/// the order of the inputs and equal those of [`run_serial`].
///
/// ```
/// use lagrangian_runtime::ensemble::{self, MemberError};
/// use lagrangian_runtime::{Error, Integrator, Lagrangian, Midpoint, Scalar};
///
/// /// `L = ½v² − ½ω²q²`.
/// struct Oscillator(f64);
/// impl Lagrangian<1> for Oscillator {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 1] = [false];
///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
///         (v[0] * v[0] - q[0] * q[0] * (self.0 * self.0)) * 0.5
///     }
/// }
///
/// // One run per frequency; the last one cannot start.
/// let omegas = [0.5, 1.0, 2.0, f64::NAN];
/// let results = ensemble::run(&omegas, |_index, &omega| -> Result<f64, Error> {
///     let mut sim = Integrator::new(Oscillator(omega), Midpoint, 0.01).start(0.0, [1.0], [0.0])?;
///     sim.run_until(1.0, |_| {})?;
///     Ok(sim.state().q[0])
/// });
/// assert_eq!(results.len(), 4);
/// for (i, q) in results.successes() {
///     assert!((q - omegas[i].cos()).abs() < 1e-4);
/// }
/// let failed: Vec<usize> = results.failures().map(|(i, _)| i).collect();
/// assert_eq!(failed, [3]);
/// assert!(matches!(results.results[3], Err(MemberError::Failed(Error::InvalidInitialData { .. }))));
/// ```
pub fn run<I: Sync, O: Send, E: Send>(
    inputs: &[I],
    member: impl Fn(usize, &I) -> Result<O, E> + Sync,
) -> Ensemble<O, E> {
    #[cfg(feature = "rayon")]
    {
        use rayon::prelude::*;
        Ensemble { results: inputs.par_iter().enumerate().map(|(i, x)| one(&member, i, x)).collect() }
    }
    #[cfg(not(feature = "rayon"))]
    run_serial(inputs, member)
}

/// Why a shard or a merge is refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ShardError {
    /// `count` is zero or `index ≥ count`.
    #[error("shard {index} of {count} does not exist")]
    NoSuchShard {
        /// The requested shard.
        index: usize,
        /// The number of shards.
        count: usize,
    },
    /// No shard holds these members (a gap between shards, or a missing
    /// head or tail); the first such range.
    #[error("the shards do not cover the members once: members {}..{} are missing", .members.start, .members.end)]
    Missing {
        /// The members missing.
        members: Range<usize>,
    },
    /// A shard holds members that an earlier one (in order of `start`)
    /// holds too; the first such range.
    #[error("the shards do not cover the members once: members {}..{} are duplicated", .members.start, .members.end)]
    Duplicated {
        /// The members held twice.
        members: Range<usize>,
    },
    /// A shard holds members at or past the end of the ensemble.
    #[error("a shard holds members {}..{}, past the end of the ensemble of {len}", .members.start, .members.end)]
    Beyond {
        /// The members out of range (an empty range for an empty shard
        /// that starts past the end).
        members: Range<usize>,
        /// The number of members of the ensemble.
        len: usize,
    },
}

/// The inputs of job `index` of `count` over `len` members: contiguous
/// ranges whose sizes differ by at most one.
///
/// Each job of an array (one Slurm task, say) runs its range and writes a
/// [`Shard`]; [`merge`] puts the shards back together:
///
/// ```
/// use lagrangian_runtime::ensemble::{self, Shard};
///
/// let squares = |_index: usize, x: &f64| -> Result<f64, String> { Ok(x * x) };
/// let inputs: Vec<f64> = (0..10).map(f64::from).collect();
/// let shards: Vec<Shard<f64, String>> = (0..3)
///     .map(|job| {
///         let range = ensemble::shard(inputs.len(), job, 3).expect("job < 3");
///         Shard { start: range.start, results: ensemble::run_serial(&inputs[range], squares) }
///     })
///     .collect();
/// assert_eq!(ensemble::shard(10, 0, 3)?, 0..4);
/// let merged = ensemble::merge(shards, inputs.len())?;
/// assert_eq!(merged, ensemble::run_serial(&inputs, squares));
/// // A missing job is refused, not a silently shorter ensemble.
/// assert!(ensemble::merge::<f64, String>(Vec::new(), 10).is_err());
/// # Ok::<(), ensemble::ShardError>(())
/// ```
pub fn shard(len: usize, index: usize, count: usize) -> Result<Range<usize>, ShardError> {
    if count == 0 || index >= count {
        return Err(ShardError::NoSuchShard { index, count });
    }
    let (base, extra) = (len / count, len % count);
    let start = index * base + index.min(extra);
    Ok(start..start + base + usize::from(index < extra))
}

/// The results of one job: members `start …` of the whole ensemble.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Shard<O, E> {
    /// The index of the first member.
    pub start: usize,
    /// Its members' results.
    pub results: Ensemble<O, E>,
}

/// The ensemble of `len` members from the shards of all jobs, in member
/// order. Refused unless the shards hold every member `0 … len` exactly once:
/// a member no shard holds (between shards, before the first or after the
/// last) is [`ShardError::Missing`], one held twice
/// [`ShardError::Duplicated`], one at or past `len` [`ShardError::Beyond`].
/// Empty shards are allowed anywhere within `0 ..= len`.
pub fn merge<O, E>(mut shards: Vec<Shard<O, E>>, len: usize) -> Result<Ensemble<O, E>, ShardError> {
    shards.sort_by_key(|s| s.start);
    let mut results = Vec::new();
    for s in shards {
        // Saturating: a start near `usize::MAX` read from a file must not overflow.
        let end = s.start.saturating_add(s.results.len());
        if end > len || s.start > len {
            return Err(ShardError::Beyond { members: s.start.max(len)..end.max(len), len });
        }
        if s.results.is_empty() {
            continue;
        }
        if s.start > results.len() {
            return Err(ShardError::Missing { members: results.len()..s.start });
        }
        if s.start < results.len() {
            return Err(ShardError::Duplicated { members: s.start..end.min(results.len()) });
        }
        results.extend(s.results.results);
    }
    if results.len() < len {
        return Err(ShardError::Missing { members: results.len()..len });
    }
    Ok(Ensemble { results })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cover_every_member_once() {
        for len in [0, 1, 7, 100, 1001] {
            for count in [1, 2, 3, 64] {
                let ranges: Vec<_> = (0..count).map(|k| shard(len, k, count).unwrap()).collect();
                assert_eq!(ranges[0].start, 0);
                assert_eq!(ranges.last().unwrap().end, len);
                assert!(ranges.windows(2).all(|w| w[0].end == w[1].start));
                assert!(ranges.iter().all(|r| r.len() == len / count || r.len() == len / count + 1));
            }
        }
        assert_eq!(shard(10, 3, 3), Err(ShardError::NoSuchShard { index: 3, count: 3 }));
        assert_eq!(shard(10, 0, 0), Err(ShardError::NoSuchShard { index: 0, count: 0 }));
    }

    #[test]
    fn merging_checks_coverage_and_restores_the_order() {
        let inputs: Vec<u32> = (0..10).collect();
        let square = |_: usize, x: &u32| if *x == 7 { Err("seven") } else { Ok(x * x) };
        let whole = run_serial(&inputs, square);
        let part = |k: usize| {
            let r = shard(10, k, 3).unwrap();
            Shard { start: r.start, results: run_serial(&inputs[r], square) }
        };
        assert_eq!(merge(vec![part(2), part(0), part(1)], 10), Ok(whole.clone()));
        assert_eq!(merge(vec![part(0), part(2)], 10), Err(ShardError::Missing { members: 4..7 }));
        assert_eq!(merge(vec![part(0), part(0), part(1), part(2)], 10), Err(ShardError::Duplicated { members: 0..4 }));
        assert_eq!(whole.failures().map(|(i, _)| i).collect::<Vec<_>>(), vec![7]);
    }

    /// Shards of `0 … 10` in three jobs, the members' results their indices.
    fn shards_of_ten() -> Vec<Shard<usize, ()>> {
        (0..3)
            .map(|k| {
                let r = shard(10, k, 3).unwrap();
                Shard { start: r.start, results: Ensemble { results: r.map(Ok).collect() } }
            })
            .collect()
    }

    #[test]
    fn a_missing_tail_or_head_is_refused_with_the_missing_members() {
        let [s0, s1, s2]: [Shard<usize, ()>; 3] = shards_of_ten().try_into().unwrap();
        // Shards 0 and 1 of 3 hold 7 of the 10 members.
        assert_eq!(merge(vec![s0.clone(), s1.clone()], 10), Err(ShardError::Missing { members: 7..10 }));
        assert_eq!(merge(vec![s1.clone(), s2.clone()], 10), Err(ShardError::Missing { members: 0..4 }));
        assert_eq!(merge(Vec::<Shard<usize, ()>>::new(), 10), Err(ShardError::Missing { members: 0..10 }));
        let message = merge(vec![s0.clone(), s1.clone()], 10).unwrap_err().to_string();
        assert_eq!(message, "the shards do not cover the members once: members 7..10 are missing");
        let all = merge(vec![s2, s0, s1], 10).unwrap();
        assert_eq!(all.results, (0..10).map(Ok).collect::<Vec<_>>());
    }

    #[test]
    fn members_past_the_end_and_overlaps_are_refused() {
        let shards = shards_of_ten();
        // The whole ensemble is 10 members, not 9.
        assert_eq!(merge(shards.clone(), 9), Err(ShardError::Beyond { members: 9..10, len: 9 }));
        // Shard 1 moved to start at 3: member 3 is held twice.
        let mut overlapping = shards.clone();
        overlapping[1].start = 3;
        assert_eq!(merge(overlapping, 10), Err(ShardError::Duplicated { members: 3..4 }));
        // A start read from a file near `usize::MAX` neither overflows nor passes.
        let mut far = shards.clone();
        far[2].start = usize::MAX - 1;
        assert_eq!(merge(far, 10), Err(ShardError::Beyond { members: usize::MAX - 1..usize::MAX, len: 10 }));
        // Empty shards are fine within the ensemble, refused past its end.
        let empty = |start| Shard { start, results: Ensemble { results: Vec::new() } };
        let mut with_empty = shards.clone();
        with_empty.extend([empty(0), empty(5), empty(10)]);
        assert_eq!(merge(with_empty, 10).map(|e| e.len()), Ok(10));
        let mut with_far_empty = shards;
        with_far_empty.push(empty(11));
        assert_eq!(merge(with_far_empty, 10), Err(ShardError::Beyond { members: 11..11, len: 10 }));
        // An empty ensemble from no shards or one empty shard.
        assert_eq!(merge(Vec::<Shard<usize, ()>>::new(), 0).map(|e| e.len()), Ok(0));
        assert_eq!(merge(vec![empty(0)], 0).map(|e| e.len()), Ok(0));
    }

    #[test]
    fn a_panicking_member_is_reported_and_the_others_finish() {
        let inputs = [1, 2, 3];
        let e = run(&inputs, |_, &x| if x == 2 { panic!("member two") } else { Ok::<_, ()>(x) });
        assert_eq!(e.results[0], Ok(1));
        assert_eq!(e.results[1], Err(MemberError::Panicked("member two".to_string())));
        assert_eq!(e.results[2], Ok(3));
    }
}
