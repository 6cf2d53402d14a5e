//! Reverse-mode derivatives from a recorded tape: gradients in `O(ops)` and
//! Hessian blocks by compressed second-order adjoints, for systems too large
//! for the array hyper-duals of [`hyperdual`](crate::hyperdual).
//!
//! # API in one example
//!
//! ```
//! use lagrangian_runtime::tape::{Seeds, Tape, Var};
//! use lagrangian_runtime::Scalar;
//!
//! // Any generic body runs on `Var` unchanged (here an FPU-β chain's potential).
//! fn energy<D: Scalar>(q: &[D]) -> D {
//!     let mut e = D::zero();
//!     for i in 0..q.len() - 1 {
//!         let d = q[i + 1] - q[i];
//!         e += d * d * 0.5 + d.powi(4) * 0.25;
//!     }
//!     e
//! }
//!
//! let n = 6;
//! let q: Vec<f64> = (0..n).map(|i| 0.1 * i as f64).collect();
//! let mut tape = Tape::new(); // reuse it: no allocation once warm
//! let value = tape.record(&q, |x| energy(x))?;
//!
//! let mut gradient = vec![0.0; n];
//! tape.gradient(&mut gradient)?; // one reverse sweep
//!
//! // The Hessian is tridiagonal (bandwidth 1): 3 directions instead of n.
//! let seeds = Seeds::banded(0..n, 1);
//! let k = seeds.directions();
//! let mut hs = vec![0.0; n * k]; // H·S, inputs × k, row-major
//! tape.hessian_product(&seeds, &mut gradient, &mut hs)?;
//! let mut band = vec![0.0; n * 3]; // row r: H[r][r − 1], H[r][r], H[r][r + 1]
//! seeds.recover(&hs, 0..n, &mut band)?;
//! assert!((band[3 + 1] - 2.0 * (1.0 + 3.0 * 0.01)).abs() < 1e-12); // ∂²E/∂q₁²
//! # let _ = value;
//! # Ok::<(), lagrangian_runtime::tape::TapeError>(())
//! ```
//!
//! - [`Tape::record`] installs the tape as the thread's current tape, hands
//!   the closure one [`Var`] per input, runs it, and keeps the recording. The
//!   closure may call any generic `D: Scalar` code: the bodies `#[lagrangian]`
//!   generates run on [`Var`] unchanged.
//! - [`Tape::gradient`]: the gradient of the last recording (one reverse sweep).
//! - [`Tape::hessian_product`]: `H·S` for a seed matrix `S` given compactly by
//!   [`Seeds`] (input `j` gets direction `colour(j)`), and the gradient, by
//!   the second-order adjoint method: a forward tangent sweep in `K`
//!   directions and a reverse sweep of the adjoint and the `K` second-order
//!   adjoints, `O(K·ops)` time. Directions are processed in chunks of at
//!   most 8, so the work buffers hold `O(8·ops)` numbers whatever `K` is.
//! - [`Seeds::recover`] reads a block of the Hessian back from `H·S`: a band
//!   for [`Seeds::banded`] (colour of input `j` is `(j − start) mod (2b + 1)`),
//!   the full block for [`Seeds::dense`]. Rows may be any range of inputs, so
//!   one product gives the mixed block `∂²A/∂q_k∂q_{k+1}` (rows `0..N`) and
//!   the block `∂²A/∂q_{k+1}²` (rows `N..2N`) when columns `N..2N` are seeded.
//! - [`Seeds::Along`] seeds one direction with any weights: `H·w`, the
//!   Hessian–vector product a discrete adjoint contracts with, in one sweep.
//!
//! # Why
//!
//! The array hyper-duals carry an `N × N` block in every intermediate value,
//! so a Lagrangian with `O(N)` operations costs `O(N³)` and its values alone
//! overflow the stack near `N = 64`. Here every elementary operation appends
//! one node to a heap tape: the indices of at most two parents and the local
//! partials `∂f/∂a`, `∂f/∂b`, `∂²f/∂a²`, `∂²f/∂a∂b`, `∂²f/∂b²` (48 bytes).
//! A gradient is one reverse sweep; a Hessian whose pattern is banded with
//! bandwidth `b` needs `2b + 1` compressed directions (Curtis, Powell and
//! Reid, "On the estimation of sparse Jacobian matrices"; Griewank and
//! Walther, "Evaluating Derivatives", on second-order adjoints), a dense one
//! `N`.
//!
//! # The number
//!
//! [`Var`] is `Copy` (the generated code is generic over
//! [`Scalar`](crate::Scalar), which requires it): 16 bytes, its value, the
//! index of its node and the generation of the recording that made it. A
//! constant (from `f64`, `zero()`, `one()`, a literal) has no node. Adding or
//! subtracting a constant keeps the node of the variable (the derivatives are
//! unchanged), so `x + 1.0` records nothing.
//!
//! Values are computed exactly as `f64` computes them, and the local partials
//! with the `(f0, f1, f2)` formulas of [`hyperdual`](crate::hyperdual) in the
//! same order of operations, so the value of a recording is bit for bit the
//! `f64` evaluation, and for a single operation the gradient and Hessian are
//! bit for bit those of the hyper-duals. For compositions the sweeps sum the
//! same terms in another order: agreement to a few ulps. Comparisons look at
//! the value only (as in num-dual), so generic code takes the same branches
//! as on `f64`. `x % y` is `x − n·y` with the integer `n` held constant, as in
//! [`hyperdual`](crate::hyperdual).
//!
//! # Misuse
//!
//! - Recording while another recording is active on the same thread (a
//!   [`Tape::record`] inside the closure of another) fails with
//!   [`TapeError::Nested`] without running the inner closure; the outer
//!   recording is unaffected.
//! - A non-constant [`Var`] from another recording (kept from an earlier one,
//!   or made on another thread) used in a recording is detected by its
//!   generation: the operation gives a constant, and [`Tape::record`] fails
//!   with [`TapeError::Stale`]. Generations come from a process-wide 32-bit
//!   counter, so a collision needs a `Var` kept across 2³² recordings.
//! - Arithmetic on [`Var`]s outside any recording computes values only: the
//!   result is a constant.
//! - If the closure panics, the recording is discarded and the thread has no
//!   current tape afterwards.
//! - Each thread that records keeps one small struct (under 100 bytes)
//!   allocated until the process ends: the slot the thread-local points to
//!   (see `Slot` in the source for why).
//!
//! # Stack use
//!
//! The tape is on the heap and the sweeps use `O(1)` stack. The closure gets
//! the inputs as a slice; only `[Var; N]` arrays that generic code builds
//! itself live on the stack (16 bytes per entry).

use core::cell::{Cell, RefCell};
use core::fmt;
use core::iter::{Product, Sum};
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Range, Rem, RemAssign, Sub, SubAssign};
use std::sync::atomic::{AtomicU32, Ordering};

use num_dual::{DualNum, DualStruct, Mappable};
use num_traits::{FromPrimitive, Inv, Num, One, Signed, Zero};

#[cfg(test)]
mod tests;

/// The parent index of a missing parent and the node index of a constant.
const NONE: u32 = u32::MAX;

/// Directions per chunk of the second-order sweep (the width of the tangent
/// and second-order adjoint of each node in the work buffers).
const CHUNK: usize = 8;

/// What went wrong in a recording or a sweep.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TapeError {
    /// [`Tape::record`] was called while a recording was active on this thread.
    #[error("a recording is already active on this thread (`Tape::record` does not nest)")]
    Nested,
    /// A [`Var`] from another recording was used; the recording is discarded.
    #[error("a `Var` from another recording was used")]
    Stale,
    /// The recording would need more than `u32::MAX − 1` nodes.
    #[error("the recording exceeds `u32::MAX - 1` nodes")]
    TooLarge,
    /// A sweep was asked for before any successful recording.
    #[error("no recording to differentiate")]
    NoRecording,
    /// A slice has the wrong length.
    #[error("`{what}` has length {got}, expected {expected}")]
    Length {
        /// Which argument.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The length it must have.
        expected: usize,
    },
    /// A range of inputs reaches past the last input.
    #[error("the range {start}..{end} of `{what}` is not within the {inputs} inputs")]
    Range {
        /// Which argument.
        what: &'static str,
        /// Start of the range.
        start: usize,
        /// End of the range.
        end: usize,
        /// The number of inputs.
        inputs: usize,
    },
    /// A colour of [`Seeds::Colours`] is not below its number of directions.
    #[error("input {input} has colour {colour}, not below the {directions} directions")]
    Colour {
        /// The input.
        input: usize,
        /// Its colour.
        colour: u32,
        /// The number of directions.
        directions: usize,
    },
    /// [`Seeds::recover`] was called on [`Seeds::Colours`] or
    /// [`Seeds::Along`], whose pattern it does not know.
    #[error("`Seeds::Colours` and `Seeds::Along` have no known pattern to recover a block from")]
    NoPattern,
}

/// One elementary operation: at most two parents and the local partials
/// `[∂f/∂a, ∂f/∂b, ∂²f/∂a², ∂²f/∂a∂b, ∂²f/∂b²]`. A unary node has `b = NONE`
/// (its `b` partials are never read); an input has `a = b = NONE`.
#[derive(Clone, Copy, Debug)]
struct Node {
    a: u32,
    b: u32,
    d: [f64; 5],
}

/// The recording the thread's operations append to.
struct Recording {
    nodes: Vec<Node>,
    generation: u32,
    error: Option<TapeError>,
}

/// A thread's recording slot: allocated at the thread's first recording
/// and kept (leaked, one small struct per thread that ever records) so that
/// the thread-locals below hold only a `Copy` reference. A thread-local
/// without a destructor is a plain address computation, inlined at every
/// operation; one with a destructor (such as a `RefCell` holding the `Vec`)
/// goes through an out-of-line accessor, which measured at about half of
/// the recording time.
type Slot = &'static RefCell<Recording>;

thread_local! {
    /// The recording operations append to, while one is active.
    static CURRENT: Cell<Option<Slot>> = const { Cell::new(None) };
    /// This thread's slot, once allocated.
    static SLOT: Cell<Option<Slot>> = const { Cell::new(None) };
}

/// Generations of recordings, process-wide so that a `Var` sent to another
/// thread is not mistaken for one of that thread's recording. Starts at 1:
/// constants carry generation 0.
static GENERATION: AtomicU32 = AtomicU32::new(1);

/// Uninstalls the current recording when dropped, so that a panicking
/// closure leaves no tape installed.
struct Uninstall;

impl Drop for Uninstall {
    fn drop(&mut self) {
        let _ = CURRENT.try_with(|current| current.set(None));
    }
}

/// A real number recorded on the thread's current [`Tape`]: its value, the
/// index of its node and the generation of its recording.
///
/// `Copy` and 16 bytes, so that generated code generic over
/// [`Scalar`](crate::Scalar) runs on it unchanged. See the [module
/// documentation](self).
#[derive(Clone, Copy, Debug)]
pub struct Var {
    value: f64,
    index: u32,
    generation: u32,
}

impl Var {
    /// A constant: no node, zero derivatives.
    #[inline(always)]
    pub const fn constant(value: f64) -> Self {
        Self { value, index: NONE, generation: 0 }
    }

    /// The value.
    #[inline(always)]
    pub const fn value(&self) -> f64 {
        self.value
    }

    /// Whether this is a constant (has no node on a tape).
    #[inline(always)]
    pub const fn is_constant(&self) -> bool {
        self.index == NONE
    }

    /// The node of a unary function with value `f0`, first derivative `f1`
    /// and second derivative `f2` at `self`.
    #[inline(always)]
    fn unary(self, f0: f64, f1: f64, f2: f64) -> Self {
        if self.index == NONE {
            Self::constant(f0)
        } else {
            push(f0, self, Self::constant(0.0), [f1, 0.0, f2, 0.0, 0.0])
        }
    }

    /// The node of a binary function of `self` and `other` with value `f0`
    /// and partials `d` (see [`Node`]); a variable parent goes first.
    #[inline(always)]
    fn binary(self, other: Self, f0: f64, d: [f64; 5]) -> Self {
        match (self.index == NONE, other.index == NONE) {
            (false, _) => push(f0, self, other, d),
            (true, false) => push(f0, other, self, [d[1], d[0], d[4], d[3], d[2]]),
            (true, true) => Self::constant(f0),
        }
    }
}

/// Appends a node with parents `a` (a variable) and `b` (a variable or a
/// constant, whose partials are then never read) to the current recording;
/// a constant when there is none.
///
/// Inlined, with the rare cases out of line: it runs once per operation of
/// the user's code, and a call per operation cost about half of the
/// recording time.
#[inline(always)]
fn push(value: f64, a: Var, b: Var, d: [f64; 5]) -> Var {
    let Some(slot) = CURRENT.try_with(Cell::get).ok().flatten() else { return Var::constant(value) };
    let Ok(mut rec) = slot.try_borrow_mut() else { return Var::constant(value) };
    let generation = rec.generation;
    let index = rec.nodes.len();
    let current = a.generation == generation && (b.index == NONE || b.generation == generation);
    if current && index < NONE as usize {
        rec.nodes.push(Node { a: a.index, b: b.index, d });
        Var { value, index: index as u32, generation }
    } else {
        fail(&mut rec, index);
        Var::constant(value)
    }
}

/// [`push`] when a parent is from another recording or the tape is full:
/// the recording fails, so the result's derivatives no longer matter (it
/// becomes a constant). Takes no partials, so that `push` builds its node in
/// registers: passing them out of line put them in memory and the node copy
/// stalled on store forwarding.
#[cold]
#[inline(never)]
fn fail(rec: &mut Recording, index: usize) {
    let error = if index >= NONE as usize { TapeError::TooLarge } else { TapeError::Stale };
    rec.error.get_or_insert(error);
}

/// A compact seed matrix `S` (inputs × `K`): input `j` gets the unit vector
/// of direction `colour(j)`, or no direction; or one direction `w` with any
/// weights ([`Along`](Seeds::Along)).
#[derive(Clone, Debug, PartialEq)]
pub enum Seeds<'a> {
    /// One direction per input of `columns`: `H·S` holds those columns of
    /// the Hessian exactly.
    Dense {
        /// The seeded inputs.
        columns: Range<usize>,
    },
    /// Compressed seeds for banded blocks: input `columns.start + c` gets
    /// direction `c mod (2·bandwidth + 1)`. A block with rows `rows` (any
    /// range of inputs) read back by [`recover`](Seeds::recover) is exact
    /// when its entry `(rows.start + r, columns.start + c)` vanishes for
    /// `|r − c| > bandwidth`; other rows of `H·S` hold sums of entries.
    Banded {
        /// The seeded inputs.
        columns: Range<usize>,
        /// The bandwidth `b` of the pattern.
        bandwidth: usize,
    },
    /// Any colouring: input `j` gets direction `colour[j]` (`None`: not
    /// seeded). [`recover`](Seeds::recover) does not apply.
    Colours {
        /// One entry per input.
        colour: &'a [Option<u32>],
        /// The number of directions `K`; every colour must be below it.
        directions: usize,
    },
    /// One direction, input `j` weighted `direction[j]`: `H·S` is the
    /// Hessian–vector product `H·w`. [`recover`](Seeds::recover) does not
    /// apply.
    Along {
        /// `w`, one entry per input.
        direction: &'a [f64],
    },
}

impl Seeds<'static> {
    /// Every input of `columns` seeded in its own direction.
    pub fn dense(columns: Range<usize>) -> Self {
        Seeds::Dense { columns }
    }

    /// Inputs of `columns` coloured `(j − columns.start) mod (2·bandwidth + 1)`.
    pub fn banded(columns: Range<usize>, bandwidth: usize) -> Self {
        Seeds::Banded { columns, bandwidth }
    }
}

impl Seeds<'_> {
    /// The number of directions `K`: the number of columns of `H·S`.
    pub fn directions(&self) -> usize {
        match self {
            Seeds::Dense { columns } => columns.len(),
            Seeds::Banded { columns, bandwidth } => columns.len().min(bandwidth.saturating_mul(2).saturating_add(1)),
            Seeds::Colours { directions, .. } => *directions,
            Seeds::Along { .. } => 1,
        }
    }

    /// The direction of input `j` and its weight, if seeded.
    #[inline]
    fn colour(&self, j: usize) -> Option<(usize, f64)> {
        match self {
            Seeds::Dense { columns } => columns.contains(&j).then(|| (j - columns.start, 1.0)),
            Seeds::Banded { columns, bandwidth } => {
                columns.contains(&j).then(|| ((j - columns.start) % (2 * bandwidth + 1), 1.0))
            }
            Seeds::Colours { colour, .. } => colour[j].map(|c| (c as usize, 1.0)),
            Seeds::Along { direction } => Some((0, direction[j])),
        }
    }

    /// Checks the seeds against a recording with `inputs` inputs.
    fn check(&self, inputs: usize) -> Result<(), TapeError> {
        match self {
            Seeds::Dense { columns } | Seeds::Banded { columns, .. } => check_range("columns", columns, inputs),
            Seeds::Colours { colour, directions } => {
                if colour.len() != inputs {
                    return Err(TapeError::Length { what: "colour", got: colour.len(), expected: inputs });
                }
                match colour.iter().enumerate().find(|(_, c)| c.is_some_and(|c| c as usize >= *directions)) {
                    Some((input, c)) => {
                        Err(TapeError::Colour { input, colour: c.unwrap_or(0), directions: *directions })
                    }
                    None => Ok(()),
                }
            }
            Seeds::Along { direction } => expect_len("direction", direction.len(), inputs),
        }
    }

    /// Reads the Hessian block with rows `rows` (inputs) and the seeded
    /// columns back from `hs = H·S` (inputs × [`directions`](Self::directions),
    /// row-major, as [`Tape::hessian_product`] writes it).
    ///
    /// - [`Seeds::Dense`]: `out` is the `rows.len() × columns.len()` block,
    ///   row-major.
    /// - [`Seeds::Banded`] with bandwidth `b`: `out` is `rows.len() × (2b + 1)`,
    ///   row `r` holding the entries `(rows.start + r, columns.start + c)` for
    ///   `c = r − b, …, r + b` in order (the band of row `r` around the
    ///   "diagonal" `c = r`); slots with `c` outside the columns are zero. The
    ///   block must vanish outside that band, which is what the seeds assume.
    /// - [`Seeds::Colours`] and [`Seeds::Along`] fail with [`TapeError::NoPattern`].
    pub fn recover(&self, hs: &[f64], rows: Range<usize>, out: &mut [f64]) -> Result<(), TapeError> {
        let k = self.directions();
        // With no directions (no columns) there is nothing to read and no
        // way to know the number of inputs: only `out`'s length is checked.
        let inputs = hs.len().checked_div(k).unwrap_or(usize::MAX);
        if k != 0 && !hs.len().is_multiple_of(k) {
            return Err(TapeError::Length { what: "hs", got: hs.len(), expected: hs.len().next_multiple_of(k) });
        }
        check_range("rows", &rows, inputs)?;
        match self {
            Seeds::Dense { columns } => {
                check_range("columns", columns, inputs)?;
                let width = columns.len();
                expect_len("out", out.len(), rows.len() * width)?;
                for (r, row) in rows.clone().enumerate() {
                    out[r * width..(r + 1) * width].copy_from_slice(&hs[row * k..row * k + width]);
                }
                Ok(())
            }
            Seeds::Banded { columns, bandwidth } => {
                check_range("columns", columns, inputs)?;
                let b = *bandwidth;
                let width = b.saturating_mul(2).saturating_add(1);
                expect_len("out", out.len(), rows.len().saturating_mul(width))?;
                for r in 0..rows.len() {
                    let row = &hs[(rows.start + r) * k..(rows.start + r + 1) * k];
                    for s in 0..width {
                        // Column c = r − b + s of the block.
                        let c = (r + s).checked_sub(b).filter(|&c| c < columns.len());
                        out[r * width + s] = c.map_or(0.0, |c| row[c % width]);
                    }
                }
                Ok(())
            }
            Seeds::Colours { .. } | Seeds::Along { .. } => Err(TapeError::NoPattern),
        }
    }
}

fn check_range(what: &'static str, range: &Range<usize>, inputs: usize) -> Result<(), TapeError> {
    if range.start <= range.end && range.end <= inputs {
        Ok(())
    } else {
        Err(TapeError::Range { what, start: range.start, end: range.end, inputs })
    }
}

fn expect_len(what: &'static str, got: usize, expected: usize) -> Result<(), TapeError> {
    if got == expected { Ok(()) } else { Err(TapeError::Length { what, got, expected }) }
}

/// A reusable recording of one scalar function of `inputs` variables, and
/// the work buffers of its sweeps. See the [module documentation](self).
#[derive(Debug, Default)]
pub struct Tape {
    /// Inputs first (no parents), then one node per operation.
    nodes: Vec<Node>,
    /// The input variables handed to the closure.
    vars: Vec<Var>,
    inputs: usize,
    /// The node of the result (`NONE` for a constant result).
    output: u32,
    value: f64,
    recorded: bool,
    adjoint: Vec<f64>,
    /// Tangents and second-order adjoints of the second-order sweep.
    lanes: Vec<f64>,
}

impl Tape {
    /// An empty tape.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty tape with room for `nodes` nodes (inputs included), so that
    /// even the first recording of that size does not reallocate.
    pub fn with_capacity(nodes: usize) -> Self {
        Self { nodes: Vec::with_capacity(nodes), ..Self::default() }
    }

    /// Records `f` at `inputs` and returns its value.
    ///
    /// The closure gets one [`Var`] per input and runs with this tape as the
    /// thread's current tape. The previous recording is replaced; buffers are
    /// reused. Fails (and leaves no recording to sweep) with
    /// [`TapeError::Nested`] when another recording is active on this thread
    /// (the closure is not run), [`TapeError::Stale`] when the closure used a
    /// [`Var`] of another recording, [`TapeError::TooLarge`] past
    /// `u32::MAX − 1` nodes.
    pub fn record(&mut self, inputs: &[f64], f: impl FnOnce(&[Var]) -> Var) -> Result<f64, TapeError> {
        self.recorded = false;
        if CURRENT.with(Cell::get).is_some() {
            return Err(TapeError::Nested);
        }
        if inputs.len() >= NONE as usize {
            return Err(TapeError::TooLarge);
        }
        let generation = GENERATION.fetch_add(1, Ordering::Relaxed).max(1);
        let mut nodes = core::mem::take(&mut self.nodes);
        nodes.clear();
        nodes.resize(inputs.len(), Node { a: NONE, b: NONE, d: [0.0; 5] });
        let mut vars = core::mem::take(&mut self.vars);
        vars.clear();
        vars.extend(inputs.iter().enumerate().map(|(j, &value)| Var { value, index: j as u32, generation }));
        let slot = SLOT.with(|spare| {
            spare.get().unwrap_or_else(|| {
                let new: Slot =
                    Box::leak(Box::new(RefCell::new(Recording { nodes: Vec::new(), generation: 0, error: None })));
                spare.set(Some(new));
                new
            })
        });
        // Not borrowed: only `push` borrows it, and never across user code.
        *slot.borrow_mut() = Recording { nodes, generation, error: None };
        CURRENT.with(|current| current.set(Some(slot)));
        let guard = Uninstall;
        let out = f(&vars);
        drop(guard);
        self.vars = vars;
        let rec =
            core::mem::replace(&mut *slot.borrow_mut(), Recording { nodes: Vec::new(), generation: 0, error: None });
        self.nodes = rec.nodes;
        if let Some(error) = rec.error {
            return Err(error);
        }
        if out.index != NONE && out.generation != generation {
            return Err(TapeError::Stale);
        }
        self.inputs = inputs.len();
        self.output = out.index;
        self.value = out.value;
        self.recorded = true;
        Ok(out.value)
    }

    /// The number of inputs of the last recording.
    pub fn inputs(&self) -> usize {
        self.inputs
    }

    /// The number of nodes of the last recording (inputs included).
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether the tape holds no nodes.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The value of the last successful recording.
    pub fn value(&self) -> Option<f64> {
        self.recorded.then_some(self.value)
    }

    /// Heap bytes held by the tape and its work buffers (capacities).
    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * size_of::<Node>()
            + self.vars.capacity() * size_of::<Var>()
            + (self.adjoint.capacity() + self.lanes.capacity()) * size_of::<f64>()
    }

    /// The number of nodes the sweeps visit: up to the output's.
    fn live(&self) -> Result<usize, TapeError> {
        if !self.recorded {
            return Err(TapeError::NoRecording);
        }
        Ok(if self.output == NONE { 0 } else { self.output as usize + 1 })
    }

    /// Writes the gradient of the last recording (one entry per input) to
    /// `out` by one reverse sweep.
    pub fn gradient(&mut self, out: &mut [f64]) -> Result<(), TapeError> {
        let live = self.live()?;
        expect_len("out", out.len(), self.inputs)?;
        out.fill(0.0);
        if live == 0 {
            return Ok(());
        }
        let adjoint = &mut self.adjoint;
        adjoint.clear();
        adjoint.resize(live, 0.0);
        adjoint[live - 1] = 1.0;
        for i in (self.inputs..live).rev() {
            let w = adjoint[i];
            if w == 0.0 {
                continue;
            }
            let node = self.nodes[i];
            adjoint[node.a as usize] += w * node.d[0];
            if node.b != NONE {
                adjoint[node.b as usize] += w * node.d[1];
            }
        }
        let n = self.inputs.min(live);
        out[..n].copy_from_slice(&adjoint[..n]);
        Ok(())
    }

    /// Writes the gradient to `gradient` (one entry per input) and `H·S` to
    /// `hs` (inputs × `K` row-major, `K = seeds.directions()`): entry
    /// `(i, c)` is `Σ_{j : colour(j) = c} ∂²f/∂x_i∂x_j`.
    ///
    /// Second-order adjoints, `O(K·ops)` time and `O(min(K, 8)·ops)` work
    /// memory; see the [module documentation](self).
    pub fn hessian_product(
        &mut self,
        seeds: &Seeds<'_>,
        gradient: &mut [f64],
        hs: &mut [f64],
    ) -> Result<(), TapeError> {
        let live = self.live()?;
        let n = self.inputs;
        seeds.check(n)?;
        let k = seeds.directions();
        expect_len("gradient", gradient.len(), n)?;
        expect_len("hs", hs.len(), n.saturating_mul(k))?;
        gradient.fill(0.0);
        // Each sweep writes its directions of the rows of the inputs it
        // reaches; only an output that precedes some inputs leaves rows out.
        if live < n {
            hs.fill(0.0);
        }
        if live == 0 {
            return Ok(());
        }
        if k == 0 {
            return self.gradient(gradient);
        }
        let mut first = 0;
        while first < k {
            let width = (k - first).min(CHUNK);
            let g = if first == 0 { Some(&mut *gradient) } else { None };
            let sweep = Sweep { nodes: &self.nodes[..live], inputs: n, seeds, first, k };
            let (adjoint, lanes) = (&mut self.adjoint, &mut self.lanes);
            match width {
                1 => sweep.run::<1>(adjoint, lanes, g, hs),
                2 => sweep.run::<2>(adjoint, lanes, g, hs),
                3 => sweep.run::<3>(adjoint, lanes, g, hs),
                4 => sweep.run::<4>(adjoint, lanes, g, hs),
                5 => sweep.run::<5>(adjoint, lanes, g, hs),
                6 => sweep.run::<6>(adjoint, lanes, g, hs),
                7 => sweep.run::<7>(adjoint, lanes, g, hs),
                _ => sweep.run::<CHUNK>(adjoint, lanes, g, hs),
            }
            first += width;
        }
        Ok(())
    }

    /// For each of `outputs` (values computed during the last recording, or
    /// constants), the smallest and largest input it depends on through the
    /// recorded operations, `None` for a constant: one forward pass over the
    /// nodes, each taking the union of its parents' ranges.
    ///
    /// The ranges are structural, not numerical: an operation whose partial
    /// happens to be zero at the recorded point still counts, so the ranges
    /// hold wherever the function takes the same operations (a body without
    /// branches on its inputs). This is how the runtime finds the band of a
    /// constraint Jacobian (`constrained/sparsity.rs`). A `Var` of another
    /// recording is [`TapeError::Stale`].
    pub fn input_ranges(&self, outputs: &[Var], ranges: &mut [Option<(usize, usize)>]) -> Result<(), TapeError> {
        if !self.recorded {
            return Err(TapeError::NoRecording);
        }
        expect_len("ranges", ranges.len(), outputs.len())?;
        let generation = self.vars.first().map_or(0, |v| v.generation);
        if outputs
            .iter()
            .any(|v| v.index != NONE && (v.generation != generation || v.index as usize >= self.nodes.len()))
        {
            return Err(TapeError::Stale);
        }
        let mut span: Vec<(u32, u32)> = Vec::new();
        span.try_reserve_exact(self.nodes.len()).map_err(|_| TapeError::TooLarge)?;
        for (i, node) in self.nodes.iter().enumerate() {
            let own = if i < self.inputs {
                (i as u32, i as u32)
            } else {
                let a = span[node.a as usize];
                if node.b == NONE {
                    a
                } else {
                    let b = span[node.b as usize];
                    (a.0.min(b.0), a.1.max(b.1))
                }
            };
            span.push(own);
        }
        for (range, v) in ranges.iter_mut().zip(outputs) {
            *range = (v.index != NONE).then(|| {
                let (lo, hi) = span[v.index as usize];
                (lo as usize, hi as usize)
            });
        }
        Ok(())
    }
}

/// One chunk of directions `first..first + W` of a second-order sweep.
struct Sweep<'a, 's> {
    nodes: &'a [Node],
    inputs: usize,
    seeds: &'a Seeds<'s>,
    first: usize,
    k: usize,
}

impl Sweep<'_, '_> {
    /// `lanes` holds, per node, its tangent then its second-order adjoint
    /// (`W` numbers each, side by side so that a node's reads and writes
    /// share cache lines).
    fn run<const W: usize>(
        &self,
        adjoint: &mut Vec<f64>,
        lanes: &mut Vec<f64>,
        gradient: Option<&mut [f64]>,
        hs: &mut [f64],
    ) {
        let live = self.nodes.len();
        let n = self.inputs.min(live);
        // Sized, not cleared: the forward pass below writes every node's
        // tangent and zeroes its second-order adjoint as it goes, in the
        // cache lines it touches anyway (a separate clear of the lanes was
        // the largest single cost of a sweep on a long tape).
        if lanes.len() < 2 * live * W {
            lanes.resize(2 * live * W, 0.0);
        }
        adjoint.clear();
        adjoint.resize(live, 0.0);
        let (lane, _) = lanes[..2 * live * W].as_chunks_mut::<W>();
        let tan = |i: usize| 2 * i;
        let sec = |i: usize| 2 * i + 1;

        // Forward: the tangent of every node in the W directions.
        for j in 0..n {
            lane[tan(j)] = [0.0; W];
            lane[sec(j)] = [0.0; W];
            if let Some((c, weight)) = self.seeds.colour(j)
                && (self.first..self.first + W).contains(&c)
            {
                lane[tan(j)][c - self.first] = weight;
            }
        }
        for i in n..live {
            let node = &self.nodes[i];
            let ta = lane[tan(node.a as usize)];
            let mut t = [0.0; W];
            if node.b == NONE {
                for c in 0..W {
                    t[c] = node.d[0] * ta[c];
                }
            } else {
                let tb = lane[tan(node.b as usize)];
                for c in 0..W {
                    t[c] = node.d[0] * ta[c] + node.d[1] * tb[c];
                }
            }
            lane[tan(i)] = t;
            lane[sec(i)] = [0.0; W];
        }

        // Reverse: the adjoint and the W second-order adjoints.
        adjoint[live - 1] = 1.0;
        for i in (n..live).rev() {
            let w = adjoint[i];
            let s = lane[sec(i)];
            if w == 0.0 && s.iter().all(|&x| x == 0.0) {
                continue;
            }
            let node = &self.nodes[i];
            let (a, d) = (node.a as usize, &node.d);
            let ta = lane[tan(a)];
            adjoint[a] += w * d[0];
            if node.b == NONE {
                let sa = &mut lane[sec(a)];
                for c in 0..W {
                    sa[c] += s[c] * d[0] + w * (d[2] * ta[c]);
                }
            } else {
                let b = node.b as usize;
                let tb = lane[tan(b)];
                adjoint[b] += w * d[1];
                let sa = &mut lane[sec(a)];
                for c in 0..W {
                    sa[c] += s[c] * d[0] + w * (d[2] * ta[c] + d[3] * tb[c]);
                }
                let sb = &mut lane[sec(b)];
                for c in 0..W {
                    sb[c] += s[c] * d[1] + w * (d[3] * ta[c] + d[4] * tb[c]);
                }
            }
        }
        for j in 0..n {
            hs[j * self.k + self.first..j * self.k + self.first + W].copy_from_slice(&lane[sec(j)]);
        }
        if let Some(g) = gradient {
            g[..n].copy_from_slice(&adjoint[..n]);
        }
    }
}

// ---------------------------------------------------------------------------
// Arithmetic. Partials follow `hyperdual.rs` (and so num-dual) formula by
// formula; see the module documentation.

impl fmt::Display for Var {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.index == NONE { write!(f, "{}", self.value) } else { write!(f, "{} (node {})", self.value, self.index) }
    }
}

impl From<f64> for Var {
    #[inline(always)]
    fn from(value: f64) -> Self {
        Self::constant(value)
    }
}

impl Zero for Var {
    #[inline(always)]
    fn zero() -> Self {
        Self::constant(0.0)
    }

    #[inline(always)]
    fn is_zero(&self) -> bool {
        self.value == 0.0
    }
}

impl One for Var {
    #[inline(always)]
    fn one() -> Self {
        Self::constant(1.0)
    }

    #[inline(always)]
    fn is_one(&self) -> bool {
        self.value == 1.0
    }
}

impl Neg for Var {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.unary(-self.value, -1.0, 0.0)
    }
}

impl Neg for &Var {
    type Output = Var;
    #[inline(always)]
    fn neg(self) -> Var {
        -*self
    }
}

impl Add for Var {
    type Output = Self;
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        let value = self.value + other.value;
        // A constant term leaves the derivatives unchanged: keep the node.
        if other.index == NONE {
            Self { value, ..self }
        } else if self.index == NONE {
            Self { value, ..other }
        } else {
            push(value, self, other, [1.0, 1.0, 0.0, 0.0, 0.0])
        }
    }
}

impl Sub for Var {
    type Output = Self;
    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        let value = self.value - other.value;
        if other.index == NONE { Self { value, ..self } } else { self.binary(other, value, [1.0, -1.0, 0.0, 0.0, 0.0]) }
    }
}

impl Mul for Var {
    type Output = Self;
    #[inline(always)]
    fn mul(self, other: Self) -> Self {
        let (a, b) = (self.value, other.value);
        self.binary(other, a * b, [b, a, 0.0, 1.0, 0.0])
    }
}

impl Div for Var {
    type Output = Self;
    /// Partials of `hyperdual.rs`'s quotient rule seeded on one operand at
    /// a time, e.g. `∂/∂a = (1·b − 0·a)·inv² = b·inv²`.
    #[inline(always)]
    fn div(self, other: Self) -> Self {
        let (a, b) = (self.value, other.value);
        let inv = b.recip();
        let inv2 = inv * inv;
        let c = a * 2.0 * inv2 * inv;
        self.binary(other, a * inv, [b * inv2, -a * inv2, 0.0, -inv2, c])
    }
}

/// `x − n·y` with `n = (x − x % y)/y` an integer held constant: the value is
/// `x % y` and the derivatives are those of `x − n·y`.
impl Rem for Var {
    type Output = Self;
    #[inline(always)]
    fn rem(self, other: Self) -> Self {
        let r = self.value % other.value;
        // Rounded: an integer quotient, exact below 2^53.
        let n = ((self.value - r) / other.value).round();
        let mut out = self - other * n;
        out.value = r;
        out
    }
}

macro_rules! forward_ops {
    ($($op:ident $method:ident $assign:ident $assign_method:ident),*) => {$(
        impl<'a> $op<&'a Var> for Var {
            type Output = Var;
            #[inline(always)]
            fn $method(self, other: &'a Var) -> Var {
                $op::$method(self, *other)
            }
        }

        impl<'a> $op<Var> for &'a Var {
            type Output = Var;
            #[inline(always)]
            fn $method(self, other: Var) -> Var {
                $op::$method(*self, other)
            }
        }

        impl<'a, 'b> $op<&'b Var> for &'a Var {
            type Output = Var;
            #[inline(always)]
            fn $method(self, other: &'b Var) -> Var {
                $op::$method(*self, *other)
            }
        }

        impl $assign for Var {
            #[inline(always)]
            fn $assign_method(&mut self, other: Var) {
                *self = $op::$method(*self, other);
            }
        }

        impl $assign<f64> for Var {
            #[inline(always)]
            fn $assign_method(&mut self, c: f64) {
                *self = $op::$method(*self, c);
            }
        }
    )*};
}

forward_ops!(
    Add add AddAssign add_assign,
    Sub sub SubAssign sub_assign,
    Mul mul MulAssign mul_assign,
    Div div DivAssign div_assign,
    Rem rem RemAssign rem_assign
);

impl Add<f64> for Var {
    type Output = Self;
    #[inline(always)]
    fn add(self, c: f64) -> Self {
        Self { value: self.value + c, ..self }
    }
}

impl Sub<f64> for Var {
    type Output = Self;
    #[inline(always)]
    fn sub(self, c: f64) -> Self {
        Self { value: self.value - c, ..self }
    }
}

impl Mul<f64> for Var {
    type Output = Self;
    #[inline(always)]
    fn mul(self, c: f64) -> Self {
        self.unary(self.value * c, c, 0.0)
    }
}

impl Div<f64> for Var {
    type Output = Self;
    #[inline(always)]
    fn div(self, c: f64) -> Self {
        self.unary(self.value / c, c.recip(), 0.0)
    }
}

/// `x % c` for a constant `c`: the derivatives of `x` are unchanged.
impl Rem<f64> for Var {
    type Output = Self;
    #[inline(always)]
    fn rem(self, c: f64) -> Self {
        Self { value: self.value % c, ..self }
    }
}

impl Inv for Var {
    type Output = Self;
    #[inline(always)]
    fn inv(self) -> Self {
        self.recip()
    }
}

impl Sum for Var {
    #[inline(always)]
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::zero(), |acc, x| acc + x)
    }
}

impl<'a> Sum<&'a Var> for Var {
    #[inline(always)]
    fn sum<I: Iterator<Item = &'a Var>>(iter: I) -> Self {
        iter.fold(Self::zero(), |acc, x| acc + x)
    }
}

impl Product for Var {
    #[inline(always)]
    fn product<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::one(), |acc, x| acc * x)
    }
}

impl<'a> Product<&'a Var> for Var {
    #[inline(always)]
    fn product<I: Iterator<Item = &'a Var>>(iter: I) -> Self {
        iter.fold(Self::one(), |acc, x| acc * x)
    }
}

macro_rules! from_primitive {
    ($($method:ident $prim:ty),*) => {$(
        #[inline(always)]
        fn $method(n: $prim) -> Option<Self> {
            f64::$method(n).map(Self::constant)
        }
    )*};
}

impl FromPrimitive for Var {
    from_primitive!(from_isize isize, from_i8 i8, from_i16 i16, from_i32 i32, from_i64 i64, from_i128 i128,
        from_usize usize, from_u8 u8, from_u16 u16, from_u32 u32, from_u64 u64, from_u128 u128, from_f32 f32,
        from_f64 f64);
}

impl Num for Var {
    type FromStrRadixErr = <f64 as Num>::FromStrRadixErr;
    /// Parses a constant.
    #[inline(always)]
    fn from_str_radix(s: &str, radix: u32) -> Result<Self, Self::FromStrRadixErr> {
        <f64 as Num>::from_str_radix(s, radix).map(Self::constant)
    }
}

impl Signed for Var {
    #[inline(always)]
    fn abs(&self) -> Self {
        if self.is_positive() { *self } else { -self }
    }

    #[inline(always)]
    fn abs_sub(&self, other: &Self) -> Self {
        if self.value > other.value { self - other } else { Self::zero() }
    }

    #[inline(always)]
    fn signum(&self) -> Self {
        if self.is_positive() {
            Self::one()
        } else if self.is_zero() {
            Self::zero()
        } else {
            -Self::one()
        }
    }

    #[inline(always)]
    fn is_positive(&self) -> bool {
        Signed::is_positive(&self.value)
    }

    #[inline(always)]
    fn is_negative(&self) -> bool {
        Signed::is_negative(&self.value)
    }
}

impl DualStruct for Var {
    type Real = f64;
    type Inner = f64;

    #[inline(always)]
    fn re(&self) -> f64 {
        self.value
    }

    #[inline(always)]
    fn from_inner(inner: &f64) -> Self {
        Self::constant(*inner)
    }
}

impl Mappable<Self> for Var {
    type Output<O> = O;

    #[inline(always)]
    fn map_dual<M: Fn(Self) -> O, O>(self, f: M) -> O {
        f(self)
    }
}

/// Equal when the values are (as in num-dual), so generic code branches as
/// it would on `f64`.
impl PartialEq for Var {
    #[inline(always)]
    fn eq(&self, other: &Self) -> bool {
        self.value == other.value
    }
}

impl PartialEq<f64> for Var {
    #[inline(always)]
    fn eq(&self, other: &f64) -> bool {
        self.value == *other
    }
}

/// Ordered by the values (as in num-dual).
impl PartialOrd for Var {
    #[inline(always)]
    fn partial_cmp(&self, other: &Self) -> Option<core::cmp::Ordering> {
        self.value.partial_cmp(&other.value)
    }
}

impl PartialOrd<f64> for Var {
    #[inline(always)]
    fn partial_cmp(&self, other: &f64) -> Option<core::cmp::Ordering> {
        self.value.partial_cmp(other)
    }
}

impl DualNum for Var {
    type Primitive = f64;
    /// First and second derivatives are exact, as for a hyper-dual.
    const NDERIV: usize = 2;
    type InnerDual = f64;

    #[inline(always)]
    fn from_re(re: f64) -> Self {
        Self::constant(re)
    }

    #[inline(always)]
    fn scale(self, factor: &f64) -> Self {
        self * *factor
    }

    #[inline(always)]
    fn recip(&self) -> Self {
        let rec = self.value.recip();
        let f1 = -rec * rec;
        self.unary(rec, f1, -f1 * rec * 2.0)
    }

    #[inline(always)]
    fn powi(&self, n: i32) -> Self {
        match n {
            0 => Self::one(),
            1 => *self,
            2 => self * self,
            _ => {
                let x = self.value;
                let pow3 = x.powi(n - 3);
                let n1 = n as f64;
                let n2 = (i64::from(n) * (i64::from(n) - 1)) as f64;
                self.unary(pow3 * x * x * x, pow3 * x * x * n1, pow3 * x * n2)
            }
        }
    }

    #[inline(always)]
    fn powf(&self, n: f64) -> Self {
        if n == 0.0 {
            Self::one()
        } else if n == 1.0 {
            *self
        } else if (n - 1.0 - 1.0).abs() < f64::EPSILON {
            self * self
        } else {
            let x = self.value;
            let n1 = n - 1.0;
            let pow3 = x.powf(n1 - 1.0 - 1.0);
            self.unary(pow3 * x * x * x, pow3 * x * x * n, pow3 * x * n * n1)
        }
    }

    #[inline(always)]
    fn sqrt(&self) -> Self {
        let rec = self.value.recip();
        let f0 = self.value.sqrt();
        let f1 = f0 * rec * 0.5;
        self.unary(f0, f1, -f1 * rec * 0.5)
    }

    #[inline(always)]
    fn cbrt(&self) -> Self {
        const THIRD: f64 = 1.0 / 3.0;
        let rec = self.value.recip();
        let f0 = self.value.cbrt();
        let f1 = f0 * rec * THIRD;
        self.unary(f0, f1, f1 * rec * (THIRD - 1.0))
    }

    #[inline(always)]
    fn exp(&self) -> Self {
        let f = self.value.exp();
        self.unary(f, f, f)
    }

    #[inline(always)]
    fn exp2(&self) -> Self {
        let ln2 = 2.0f64.ln();
        let f0 = self.value.exp2();
        let f1 = f0 * ln2;
        self.unary(f0, f1, f1 * ln2)
    }

    #[inline(always)]
    fn exp_m1(&self) -> Self {
        let f1 = self.value.exp();
        self.unary(self.value.exp_m1(), f1, f1)
    }

    #[inline(always)]
    fn ln(&self) -> Self {
        let rec = self.value.recip();
        self.unary(self.value.ln(), rec, -rec * rec)
    }

    #[inline(always)]
    fn log(&self, base: f64) -> Self {
        let rec = self.value.recip();
        let f1 = rec / base.ln();
        self.unary(self.value.log(base), f1, -f1 * rec)
    }

    #[inline(always)]
    fn log2(&self) -> Self {
        let rec = self.value.recip();
        let f1 = rec / 2.0f64.ln();
        self.unary(self.value.log2(), f1, -f1 * rec)
    }

    #[inline(always)]
    fn log10(&self) -> Self {
        let rec = self.value.recip();
        let f1 = rec / core::f64::consts::LN_10;
        self.unary(self.value.log10(), f1, -f1 * rec)
    }

    #[inline(always)]
    fn ln_1p(&self) -> Self {
        let rec = (self.value + 1.0).recip();
        self.unary(self.value.ln_1p(), rec, -rec * rec)
    }

    #[inline(always)]
    fn sin(&self) -> Self {
        let (s, c) = self.value.sin_cos();
        self.unary(s, c, -s)
    }

    #[inline(always)]
    fn cos(&self) -> Self {
        let (s, c) = self.value.sin_cos();
        self.unary(c, -s, -c)
    }

    #[inline(always)]
    fn sin_cos(&self) -> (Self, Self) {
        let (s, c) = self.value.sin_cos();
        (self.unary(s, c, -s), self.unary(c, -s, -c))
    }

    #[inline(always)]
    fn tan(&self) -> Self {
        let (s, c) = self.sin_cos();
        s / c
    }

    #[inline(always)]
    fn asin(&self) -> Self {
        let x = self.value;
        let rec = (1.0 - x * x).recip();
        let f1 = rec.sqrt();
        self.unary(x.asin(), f1, x * f1 * rec)
    }

    #[inline(always)]
    fn acos(&self) -> Self {
        let x = self.value;
        let rec = (1.0 - x * x).recip();
        let f1 = -rec.sqrt();
        self.unary(x.acos(), f1, x * f1 * rec)
    }

    #[inline(always)]
    fn atan(&self) -> Self {
        let x = self.value;
        let rec = (1.0 + x * x).recip();
        self.unary(x.atan(), rec, -x * rec * rec * 2.0)
    }

    #[inline(always)]
    fn atan2(&self, other: Self) -> Self {
        let mut out = (self / other).atan();
        out.value = self.value.atan2(other.value);
        out
    }

    #[inline(always)]
    fn sinh(&self) -> Self {
        let (s, c) = (self.value.sinh(), self.value.cosh());
        self.unary(s, c, s)
    }

    #[inline(always)]
    fn cosh(&self) -> Self {
        let (s, c) = (self.value.sinh(), self.value.cosh());
        self.unary(c, s, c)
    }

    #[inline(always)]
    fn tanh(&self) -> Self {
        self.sinh() / self.cosh()
    }

    #[inline(always)]
    fn asinh(&self) -> Self {
        let x = self.value;
        let rec = (1.0 + x * x).recip();
        let f1 = rec.sqrt();
        self.unary(x.asinh(), f1, -x * f1 * rec)
    }

    #[inline(always)]
    fn acosh(&self) -> Self {
        let x = self.value;
        let rec = (x * x - 1.0).recip();
        let f1 = rec.sqrt();
        self.unary(x.acosh(), f1, -x * f1 * rec)
    }

    #[inline(always)]
    fn atanh(&self) -> Self {
        let x = self.value;
        let rec = (1.0 - x * x).recip();
        self.unary(x.atanh(), rec, x * rec * rec * 2.0)
    }

    #[inline(always)]
    fn sph_j0(&self) -> Self {
        if self.value.abs() < f64::EPSILON { Self::one() - self * self / 6.0 } else { self.sin() / self }
    }

    #[inline(always)]
    fn sph_j1(&self) -> Self {
        if self.value.abs() < f64::EPSILON {
            *self / 3.0
        } else {
            let (s, c) = self.sin_cos();
            (s - self * c) / (self * self)
        }
    }

    #[inline(always)]
    fn sph_j2(&self) -> Self {
        if self.value.abs() < f64::EPSILON {
            self * self / 15.0
        } else {
            let (s, c) = self.sin_cos();
            let s2 = self * self;
            ((s - self * c) * 3.0 - s2 * s) / (s2 * self)
        }
    }
}
