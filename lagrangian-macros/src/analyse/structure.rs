//! Structure analysis: what the syntax of the bodies proves about the
//! Hessian of `L` and the Jacobian of the forces, for `SEPARABILITY`,
//! `COUPLING` and `FORCE_COUPLING` (docs/structure.md explains it for users).
//!
//! An abstract interpreter runs each body once, flow-sensitively, on abstract
//! values ([`Abs`]). A scalar carries
//! - the variables it may depend on (`q[i]`, `v[i]`, `t`), with indices that
//!   are literals, offsets `i + c` from a loop variable `i`, or unknown;
//! - for each Hessian block (`q–q`, `q–v`, `v–v`), the largest index distance
//!   of a pair of variables whose mixed second derivative may be non-zero
//!   (or "unknown"): a pair is formed where two dependencies meet in a
//!   product, a quotient or a nonlinear function, and its distance is taken
//!   there, while both indices still refer to the same loop iteration;
//! - its degree structure in `v`: which homogeneous degrees 0, 1, 2 it may
//!   have and what the coefficients of each may depend on (`t`, `q`), or
//!   "not a polynomial of degree ≤ 2 in `v`".
//!
//! Offsets from a loop variable are only meaningful within one iteration:
//! at the end of each iteration, and for values leaving the loop, they
//! become unknown indices. Loops run to a fixpoint of the state at their
//! head, so a value carried from one iteration to the next (`prev = q[i]`)
//! is read with an unknown index. Anything the interpreter cannot follow —
//! a branch on `t`, `q` or `v`, a cast of such a value to an integer — makes
//! it give up on that function: everything general, nothing proven.

use crate::ir::{Block, Class, Expr, ExprKind, Function, LocalId, Math, ParamRef, Stmt, System};
use std::collections::BTreeSet;
use syn::{BinOp, Type, UnOp};

/// What is proven about a system.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Structure {
    /// The form of `L`.
    pub(crate) separability: Separability,
    /// The Hessian blocks of `L`.
    pub(crate) coupling: Coupling,
    /// The Jacobian blocks of the generalised force.
    pub(crate) force: ForceCoupling,
}

/// Mirrors the runtime's `Separability`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Separability {
    /// Nothing proven.
    NotProven,
    /// `L = ½ vᵀM(q)v − V(t, q)`.
    QuadraticKinetic,
    /// `L = ½ vᵀMv − V(t, q)`, `M` constant.
    ConstantMass,
}

/// A block's pattern before `N` is known: the largest distance `|i − j|` of
/// an entry that may be non-zero, or general.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Band {
    /// Entries with `|i − j|` up to this may be non-zero (0: diagonal).
    Width(u64),
    /// Any entry may be non-zero.
    General,
}

/// Mirrors the runtime's `Coupling`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Coupling {
    /// `∂²L/∂q∂q`.
    pub(crate) q_q: Band,
    /// `∂²L/∂q∂v`.
    pub(crate) q_v: Band,
    /// `∂²L/∂v∂v`.
    pub(crate) v_v: Band,
}

/// Mirrors the runtime's `ForceCoupling`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ForceCoupling {
    /// `∂F/∂q`.
    pub(crate) q: Band,
    /// `∂F/∂v`.
    pub(crate) v: Band,
}

impl Structure {
    /// Nothing proven.
    #[cfg(test)]
    pub(crate) const GENERAL: Structure = Structure {
        separability: Separability::NotProven,
        coupling: Coupling { q_q: Band::General, q_v: Band::General, v_v: Band::General },
        force: ForceCoupling { q: Band::General, v: Band::General },
    };
}

/// Analyses the Lagrangian, the dissipation function and the forces.
pub(crate) fn structure(system: &System) -> Structure {
    let lagrangian = Interp::run(&system.lagrangian);
    let (separability, coupling) = match &lagrangian {
        Some(Abs::Num(val)) => (val.poly.separability(), val.pairs.coupling()),
        // A constant of unknown type (`Self::C`).
        Some(Abs::Int(_)) => (Separability::ConstantMass, Pairs::NONE.coupling()),
        _ => (Separability::NotProven, Pairs::GENERAL.coupling()),
    };
    // `F = Q − ∂R/∂v`: row `i` of its Jacobian is row `vᵢ` of the Hessian of `R`.
    let mut force = [Reach::None; 2];
    if let Some(dissipation) = &system.dissipation {
        let pairs = match Interp::run(dissipation) {
            Some(Abs::Num(val)) => val.pairs,
            _ => Pairs::GENERAL,
        };
        force = join2(force, [pairs.0[QV], pairs.0[VV]]);
    }
    if let Some(function) = &system.force {
        let out = match &function.out {
            // Written into `f: &mut [f64]`: the pattern is that of `f` at
            // the end of the body.
            Some(out) => out.local.map_or(Some([Reach::None; 2]), |local| Interp::run_out(function, local)),
            None => match Interp::run(function) {
                Some(Abs::Array { out, .. }) => Some(out),
                _ => None,
            },
        };
        force = join2(force, out.unwrap_or([Reach::General; 2]));
    }
    Structure { separability, coupling, force: ForceCoupling { q: force[0].band(), v: force[1].band() } }
}

/// The join of two `[∂F/∂q, ∂F/∂v]` reaches.
fn join2(a: [Reach; 2], b: [Reach; 2]) -> [Reach; 2] {
    [a[0].max(b[0]), a[1].max(b[1])]
}

/// Beyond this many dependencies a value's indices are forgotten: pairs are
/// formed in `O(deps²)`, and a value depending on hundreds of variables is
/// rarely part of a sparse Hessian.
const MAX_DEPS: usize = 256;

/// Passes over a loop body before giving up; the state at the head only
/// grows and settles in a few passes in practice.
const MAX_PASSES: usize = 64;

/// What an index can be an offset from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Base {
    /// A loop variable (its local's id), in the current iteration.
    Loop(usize),
    /// A constant the macro cannot evaluate (`N`, `self.n`), numbered by
    /// its tokens: it has one value during a call.
    Const(usize),
}

/// An index of `q` or `v`, or the value of an integer expression.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Index {
    /// A known value.
    Lit(i64),
    /// `base + offset`.
    Rel(Base, i64),
    /// Anything.
    Any,
}

impl Index {
    fn add(self, other: Index) -> Index {
        match (self, other) {
            (Index::Lit(a), Index::Lit(b)) => a.checked_add(b).map_or(Index::Any, Index::Lit),
            (Index::Rel(x, a), Index::Lit(b)) | (Index::Lit(b), Index::Rel(x, a)) => {
                a.checked_add(b).map_or(Index::Any, |c| Index::Rel(x, c))
            }
            _ => Index::Any,
        }
    }

    fn sub(self, other: Index) -> Index {
        match (self, other) {
            (Index::Lit(a), Index::Lit(b)) => a.checked_sub(b).map_or(Index::Any, Index::Lit),
            (Index::Rel(x, a), Index::Lit(b)) => a.checked_sub(b).map_or(Index::Any, |c| Index::Rel(x, c)),
            (Index::Rel(x, a), Index::Rel(y, b)) if x == y => a.checked_sub(b).map_or(Index::Any, Index::Lit),
            _ => Index::Any,
        }
    }

    fn literal(self, f: impl FnOnce(i64) -> Option<i64>, other: Index) -> Index {
        match (self, other) {
            (Index::Lit(a), Index::Lit(_)) => f(a).map_or(Index::Any, Index::Lit),
            _ => Index::Any,
        }
    }

    /// An index of `q` or `v`: negative values cannot be one.
    fn as_position(self) -> Index {
        match self {
            Index::Lit(a) if a < 0 => Index::Any,
            other => other,
        }
    }

    /// Forgets the offsets from loop variable `var` (from every loop
    /// variable for `None`).
    fn escape(self, var: Option<usize>) -> Index {
        match self {
            Index::Rel(Base::Loop(x), _) if var.is_none_or(|var| var == x) => Index::Any,
            other => other,
        }
    }
}

/// How far apart two indices are, as the distance of a Hessian entry: known
/// for two literals or two offsets from the same base.
fn distance(a: Index, b: Index) -> Reach {
    match (a, b) {
        (Index::Lit(a), Index::Lit(b)) => Reach::Width(a.abs_diff(b)),
        (Index::Rel(x, a), Index::Rel(y, b)) if x == y => Reach::Width(a.abs_diff(b)),
        _ => Reach::General,
    }
}

/// The largest distance of the entries of a block that may be non-zero.
/// Ordered so that `max` is the join.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Reach {
    /// No entry: the block is zero.
    None,
    /// Entries up to this distance.
    Width(u64),
    /// Any entry.
    General,
}

impl Reach {
    fn band(self) -> Band {
        match self {
            Reach::None => Band::Width(0),
            Reach::Width(width) => Band::Width(width),
            Reach::General => Band::General,
        }
    }
}

/// A variable a value can depend on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Atom {
    /// `t`.
    T,
    /// `q[index]`.
    Q(Index),
    /// `v[index]`.
    V(Index),
}

impl Atom {
    /// The same kind of variable at an unknown index.
    fn widen(self) -> Atom {
        match self {
            Atom::T => Atom::T,
            Atom::Q(_) => Atom::Q(Index::Any),
            Atom::V(_) => Atom::V(Index::Any),
        }
    }

    /// Forgets offsets from loop variable `var` (every one for `None`).
    fn escape(self, var: Option<usize>) -> Atom {
        match self {
            Atom::T => Atom::T,
            Atom::Q(index) => Atom::Q(index.escape(var)),
            Atom::V(index) => Atom::V(index.escape(var)),
        }
    }
}

/// The Hessian blocks, indices into [`Pairs`].
const QQ: usize = 0;
const QV: usize = 1;
const VV: usize = 2;

/// For each Hessian block, how far apart the pairs of variables with a
/// possibly non-zero mixed second derivative are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Pairs([Reach; 3]);

impl Pairs {
    const NONE: Pairs = Pairs([Reach::None; 3]);
    const GENERAL: Pairs = Pairs([Reach::General; 3]);

    fn join(self, other: Pairs) -> Pairs {
        Pairs([0, 1, 2].map(|b| self.0[b].max(other.0[b])))
    }

    /// Adds every pair of a dependency of `a` with one of `b`.
    fn cross(&mut self, a: &BTreeSet<Atom>, b: &BTreeSet<Atom>) {
        for x in a {
            for y in b {
                let (block, i, j) = match (*x, *y) {
                    (Atom::Q(i), Atom::Q(j)) => (QQ, i, j),
                    (Atom::Q(i), Atom::V(j)) | (Atom::V(j), Atom::Q(i)) => (QV, i, j),
                    (Atom::V(i), Atom::V(j)) => (VV, i, j),
                    // The Hessian is in `(q, v)`.
                    _ => continue,
                };
                self.0[block] = self.0[block].max(distance(i, j));
            }
        }
    }

    fn coupling(self) -> Coupling {
        Coupling { q_q: self.0[QQ].band(), q_v: self.0[QV].band(), v_v: self.0[VV].band() }
    }
}

/// What the coefficients of one homogeneous part (in `v`) depend on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Coef {
    t: bool,
    q: bool,
}

impl Coef {
    fn join(self, other: Coef) -> Coef {
        Coef { t: self.t || other.t, q: self.q || other.q }
    }
}

/// The degree structure of a value in `v`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Poly {
    /// `P₀ + P₁ + P₂`, `Pₖ` homogeneous of degree `k` in `v`; `None` where
    /// the part is absent.
    Parts([Option<Coef>; 3]),
    /// Not proven a polynomial of degree ≤ 2 in `v`.
    Other,
}

impl Poly {
    const CONST: Poly = Poly::Parts([Some(Coef { t: false, q: false }), None, None]);

    fn join(self, other: Poly) -> Poly {
        match (self, other) {
            (Poly::Parts(a), Poly::Parts(b)) => Poly::Parts([0, 1, 2].map(|k| join_part(a[k], b[k]))),
            _ => Poly::Other,
        }
    }

    fn mul(self, other: Poly) -> Poly {
        let (Poly::Parts(a), Poly::Parts(b)) = (self, other) else { return Poly::Other };
        let mut out = [None; 3];
        for (i, a) in a.iter().enumerate() {
            for (j, b) in b.iter().enumerate() {
                if let (Some(a), Some(b)) = (a, b) {
                    if i + j > 2 {
                        return Poly::Other;
                    }
                    out[i + j] = join_part(out[i + j], Some(a.join(*b)));
                }
            }
        }
        Poly::Parts(out)
    }

    /// The coefficient when the value is free of `v` (degree 0 only).
    fn free_of_v(self) -> Option<Coef> {
        match self {
            Poly::Parts([c, None, None]) => Some(c.unwrap_or_default()),
            _ => None,
        }
    }

    /// A nonlinear function of values: free of `v` if they all are.
    fn nonlinear(operands: impl IntoIterator<Item = Poly>) -> Poly {
        let mut coef = Coef::default();
        for poly in operands {
            match poly.free_of_v() {
                Some(c) => coef = coef.join(c),
                None => return Poly::Other,
            }
        }
        Poly::Parts([Some(coef), None, None])
    }

    fn separability(self) -> Separability {
        match self {
            Poly::Parts([_, None, None]) => Separability::ConstantMass,
            Poly::Parts([_, None, Some(Coef { t: false, q: false })]) => Separability::ConstantMass,
            Poly::Parts([_, None, Some(Coef { t: false, q: true })]) => Separability::QuadraticKinetic,
            _ => Separability::NotProven,
        }
    }
}

fn join_part(a: Option<Coef>, b: Option<Coef>) -> Option<Coef> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.join(b)),
        (a, None) => a,
        (None, b) => b,
    }
}

/// The abstract value of a scalar (or `bool`).
#[derive(Clone, Debug, PartialEq, Eq)]
struct Val {
    deps: BTreeSet<Atom>,
    pairs: Pairs,
    poly: Poly,
}

impl Val {
    fn constant() -> Val {
        Val { deps: BTreeSet::new(), pairs: Pairs::NONE, poly: Poly::CONST }
    }

    /// `0.0`: no part of any degree, so that `0.0 + v[0]` is homogeneous.
    fn zero() -> Val {
        Val { poly: Poly::Parts([None; 3]), ..Val::constant() }
    }

    fn atom(atom: Atom) -> Val {
        let poly = match atom {
            Atom::T => Poly::Parts([Some(Coef { t: true, q: false }), None, None]),
            Atom::Q(_) => Poly::Parts([Some(Coef { t: false, q: true }), None, None]),
            Atom::V(_) => Poly::Parts([None, Some(Coef::default()), None]),
        };
        Val { deps: BTreeSet::from([atom]), pairs: Pairs::NONE, poly }
    }

    /// A value that may depend on anything in any way.
    fn top() -> Val {
        let deps = BTreeSet::from([Atom::T, Atom::Q(Index::Any), Atom::V(Index::Any)]);
        Val { deps, pairs: Pairs::GENERAL, poly: Poly::Other }
    }

    fn join(&self, other: &Val) -> Val {
        let mut deps = self.deps.clone();
        deps.extend(other.deps.iter().copied());
        Val { deps: normalise(deps), pairs: self.pairs.join(other.pairs), poly: self.poly.join(other.poly) }
    }

    fn add(&self, other: &Val) -> Val {
        self.join(other)
    }

    fn mul(&self, other: &Val) -> Val {
        let mut out = self.join(other);
        out.pairs.cross(&self.deps, &other.deps);
        out.poly = self.poly.mul(other.poly);
        out
    }

    fn div(&self, other: &Val) -> Val {
        let mut out = self.join(other);
        out.pairs.cross(&self.deps, &other.deps);
        out.pairs.cross(&other.deps, &other.deps);
        out.poly = match (self.poly, other.poly.free_of_v()) {
            (Poly::Parts(parts), Some(coef)) => Poly::Parts(parts.map(|part| part.map(|c| c.join(coef)))),
            _ => Poly::Other,
        };
        out
    }

    /// A nonlinear function of the operands.
    fn nonlinear(operands: &[&Val]) -> Val {
        let mut out = Val::constant();
        for operand in operands {
            out = out.join(operand);
        }
        let deps = out.deps.clone();
        out.pairs.cross(&deps, &deps);
        out.poly = Poly::nonlinear(operands.iter().map(|operand| operand.poly));
        out
    }

    /// A `bool` computed from the operands: only its dependencies matter.
    fn condition(operands: &[&Val]) -> Val {
        let mut out = Val::constant();
        for operand in operands {
            out.deps.extend(operand.deps.iter().copied());
        }
        out.deps = normalise(out.deps);
        out
    }

    fn escape(&self, var: Option<usize>) -> Val {
        Val { deps: normalise(self.deps.iter().map(|atom| atom.escape(var)).collect()), ..self.clone() }
    }
}

/// Keeps dependency sets small: an unknown index of `q` subsumes the known
/// ones (every pair with it is general anyway), and very large sets forget
/// their indices.
fn normalise(mut deps: BTreeSet<Atom>) -> BTreeSet<Atom> {
    if deps.len() > MAX_DEPS {
        deps = deps.into_iter().map(Atom::widen).collect();
    }
    if deps.contains(&Atom::Q(Index::Any)) {
        deps.retain(|atom| !matches!(atom, Atom::Q(index) if *index != Index::Any));
    }
    if deps.contains(&Atom::V(Index::Any)) {
        deps.retain(|atom| !matches!(atom, Atom::V(index) if *index != Index::Any));
    }
    deps
}

/// An abstract value.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Abs {
    /// No value: a statement, or an expression that diverges.
    Unit,
    /// A scalar or a `bool`.
    Num(Val),
    /// An integer.
    Int(Index),
    /// An array: `elems` covers every element (what a read may return), `out`
    /// how far the dependencies of each element on `q` and on `v` are from
    /// its own position (the Jacobian pattern of a returned force).
    Array { elems: Val, out: [Reach; 2] },
}

impl Abs {
    fn escape(&self, var: Option<usize>) -> Abs {
        match self {
            Abs::Unit => Abs::Unit,
            Abs::Num(val) => Abs::Num(val.escape(var)),
            Abs::Int(index) => Abs::Int(index.escape(var)),
            Abs::Array { elems, out } => Abs::Array { elems: elems.escape(var), out: *out },
        }
    }

    fn as_index(&self) -> Index {
        match self {
            Abs::Int(index) => *index,
            _ => Index::Any,
        }
    }
}

/// The abstract value of every local, `None` before its first assignment.
type Env = Vec<Option<Abs>>;

/// How far the dependencies `deps` of a value stored at `position` are from it.
fn out_of(position: Index, deps: &BTreeSet<Atom>) -> [Reach; 2] {
    let mut out = [Reach::None; 2];
    for atom in deps {
        let (k, index) = match *atom {
            Atom::Q(index) => (0, index),
            Atom::V(index) => (1, index),
            Atom::T => continue,
        };
        out[k] = out[k].max(distance(position, index));
    }
    out
}

/// The interpreter of one body.
struct Interp {
    /// The constants used as index bases, by their tokens.
    consts: Vec<String>,
    /// Whether paths name one value throughout the body: not when it
    /// declares items (two blocks may each declare their own `const K`).
    paths_fixed: bool,
    /// The join of the values of `return`s.
    ret: Abs,
    /// For each enclosing loop, innermost last, the join of the states at its
    /// `break`s and `continue`s.
    jumps: Vec<Option<Env>>,
    /// Set when the body does something the analysis does not follow.
    gave_up: bool,
}

impl Interp {
    /// The abstract value of `function`, `None` if the analysis gave up.
    fn run(function: &Function) -> Option<Abs> {
        let mut interp = Interp {
            consts: Vec::new(),
            paths_fixed: !declares_items(&function.body),
            ret: Abs::Unit,
            jumps: Vec::new(),
            gave_up: false,
        };
        let mut env: Env = vec![None; function.locals.len()];
        let value = interp.block(&function.body, &mut env);
        let ret = std::mem::replace(&mut interp.ret, Abs::Unit);
        let value = interp.join(&value.escape(None), &ret);
        (!interp.gave_up).then_some(value)
    }

    /// How far the entries of the out-parameter `local` of `function` depend
    /// on `q` and `v` from their own positions once the body has run, from
    /// zeros; `None` if the analysis gave up. A `return` leaves the body
    /// with a state the analysis does not keep, so it gives up on one.
    fn run_out(function: &Function, local: LocalId) -> Option<[Reach; 2]> {
        let mut returns = false;
        function.body.visit(&mut |expr| {
            returns |= matches!(expr.kind, ExprKind::Return(_));
            !returns
        });
        if returns {
            return None;
        }
        let mut interp = Interp {
            consts: Vec::new(),
            paths_fixed: !declares_items(&function.body),
            ret: Abs::Unit,
            jumps: Vec::new(),
            gave_up: false,
        };
        let mut env: Env = vec![None; function.locals.len()];
        env[local.0] = Some(Abs::Array { elems: Val::constant(), out: [Reach::None; 2] });
        interp.block(&function.body, &mut env);
        match env[local.0].take() {
            Some(Abs::Array { out, .. }) if !interp.gave_up => Some(out),
            _ => None,
        }
    }

    /// The number of the constant named `key`.
    fn intern(&mut self, key: String) -> usize {
        match self.consts.iter().position(|k| *k == key) {
            Some(id) => id,
            None => {
                self.consts.push(key);
                self.consts.len() - 1
            }
        }
    }

    fn give_up(&mut self) -> Abs {
        self.gave_up = true;
        Abs::Num(Val::top())
    }

    fn join(&mut self, a: &Abs, b: &Abs) -> Abs {
        match (a, b) {
            (Abs::Unit, other) | (other, Abs::Unit) => other.clone(),
            (Abs::Num(a), Abs::Num(b)) => Abs::Num(a.join(b)),
            (Abs::Int(a), Abs::Int(b)) => Abs::Int(if a == b { *a } else { Index::Any }),
            // An integer and an opaque constant (`self.n`), or a constant
            // that is a float and a number.
            (Abs::Int(_), Abs::Num(val)) | (Abs::Num(val), Abs::Int(_)) => {
                if val.deps.is_empty() {
                    Abs::Int(Index::Any)
                } else {
                    Abs::Num(val.join(&Val::constant()))
                }
            }
            (Abs::Array { elems: a, out: oa }, Abs::Array { elems: b, out: ob }) => {
                Abs::Array { elems: a.join(b), out: join2(*oa, *ob) }
            }
            _ => self.give_up(),
        }
    }

    fn join_env(&mut self, a: &Env, b: &Env) -> Env {
        a.iter()
            .zip(b)
            .map(|(a, b)| match (a, b) {
                (Some(a), Some(b)) => Some(self.join(a, b)),
                (a, None) => a.clone(),
                (None, b) => b.clone(),
            })
            .collect()
    }

    fn block(&mut self, block: &Block, env: &mut Env) -> Abs {
        let mut value = Abs::Unit;
        for stmt in &block.stmts {
            value = match stmt {
                Stmt::Let { bindings, inits, .. } => {
                    // All initializers first: `let (a, b) = (b, a);`.
                    let values: Vec<Abs> = inits.iter().map(|init| self.expr(init, env)).collect();
                    for (binding, value) in bindings.iter().zip(values) {
                        if let Some(local) = binding.local {
                            env[local.0] = Some(value);
                        }
                    }
                    Abs::Unit
                }
                Stmt::Expr { expr, .. } => self.expr(expr, env),
                Stmt::Item(_) => Abs::Unit,
            };
        }
        match block.stmts.last() {
            Some(Stmt::Expr { semi: false, .. }) => value,
            _ => Abs::Unit,
        }
    }

    /// The value of `expr`, in the shape its class says it has.
    fn expr(&mut self, expr: &Expr, env: &mut Env) -> Abs {
        let value = self.kind(expr, env);
        match (expr.class, value) {
            (Class::Unit, _) => Abs::Unit,
            (_, Abs::Unit) => Abs::Unit,
            // A constant of unknown type (`self.n`) may be an integer.
            (Class::Int | Class::Const, Abs::Int(index)) => Abs::Int(index),
            (Class::Int, Abs::Num(val)) if val.deps.is_empty() => Abs::Int(Index::Any),
            (Class::Bool | Class::Const | Class::Active, Abs::Num(val)) => Abs::Num(val),
            // A constant that turned out to be a float (`let mut x = PI;`,
            // later `x += q[0]`).
            (Class::Bool | Class::Active, Abs::Int(_)) => Abs::Num(Val::constant()),
            (Class::ConstArray | Class::ActiveArray, value @ Abs::Array { .. }) => value,
            // Indexing opaque constant data gives constants of any shape.
            (Class::ConstArray, Abs::Int(_)) => Abs::Array { elems: Val::constant(), out: [Reach::None; 2] },
            (Class::ConstArray, Abs::Num(val)) if val.deps.is_empty() => {
                Abs::Array { elems: Val::constant(), out: [Reach::None; 2] }
            }
            _ => self.give_up(),
        }
    }

    fn kind(&mut self, expr: &Expr, env: &mut Env) -> Abs {
        match &expr.kind {
            ExprKind::Lit(syn::Lit::Int(lit)) if !matches!(lit.suffix(), "f32" | "f64") => {
                Abs::Int(lit.base10_parse::<i64>().map_or(Index::Any, Index::Lit))
            }
            ExprKind::Lit(syn::Lit::Float(lit)) if lit.base10_parse::<f64>().is_ok_and(|x| x == 0.0) => {
                Abs::Num(Val::zero())
            }
            ExprKind::Lit(_) | ExprKind::SelfValue(_) => Abs::Num(Val::constant()),
            // Possibly an integer, fixed during the call: a base for indices.
            ExprKind::Path(_) if !self.paths_fixed => Abs::Num(Val::constant()),
            ExprKind::Path(_) | ExprKind::Field { .. } => match constant_key(expr) {
                Some(key) => Abs::Int(Index::Rel(Base::Const(self.intern(key)), 0)),
                None => Abs::Num(Val::constant()),
            },
            ExprKind::Param(ParamRef::Time, _) => Abs::Num(Val::atom(Atom::T)),
            ExprKind::Param(param, _) => {
                // The whole array: element `k` is the variable `k`.
                let (atom, out) = match param {
                    ParamRef::Q => (Atom::Q(Index::Any), [Reach::Width(0), Reach::None]),
                    _ => (Atom::V(Index::Any), [Reach::None, Reach::Width(0)]),
                };
                Abs::Array { elems: Val::atom(atom), out }
            }
            ExprKind::Local(local, _) => match env[local.0].clone() {
                Some(value) => value,
                None => self.give_up(),
            },
            ExprKind::Index { base, index, .. } => {
                let param = match base.kind {
                    ExprKind::Param(ParamRef::Q, _) => Some(Atom::Q as fn(Index) -> Atom),
                    ExprKind::Param(ParamRef::V, _) => Some(Atom::V as fn(Index) -> Atom),
                    _ => None,
                };
                let array = if param.is_none() { Some(self.expr(base, env)) } else { None };
                let index = self.expr(index, env).as_index();
                match (param, array) {
                    (Some(atom), _) => Abs::Num(Val::atom(atom(index.as_position()))),
                    (None, Some(Abs::Array { elems, .. })) => Abs::Num(elems),
                    (None, Some(Abs::Num(val))) if val.deps.is_empty() => Abs::Num(Val::constant()),
                    (None, Some(Abs::Int(_))) => Abs::Num(Val::constant()),
                    _ => self.give_up(),
                }
            }
            ExprKind::Unary { op, expr: inner } => {
                let value = self.expr(inner, env);
                match (op, value) {
                    (UnOp::Neg(_), Abs::Int(Index::Lit(a))) => Abs::Int(a.checked_neg().map_or(Index::Any, Index::Lit)),
                    // `!` on an integer is the bitwise complement.
                    (UnOp::Neg(_) | UnOp::Not(_), Abs::Int(_)) => Abs::Int(Index::Any),
                    (UnOp::Not(_), Abs::Num(val)) => Abs::Num(Val::condition(&[&val])),
                    (_, value) => value,
                }
            }
            ExprKind::Binary { lhs, op, rhs } => {
                let (a, b) = (self.expr(lhs, env), self.expr(rhs, env));
                self.binary(*op, expr.class, a, b)
            }
            ExprKind::Cast { expr: inner, ty } => {
                let value = self.expr(inner, env);
                if crate::parse::is_f64(ty) {
                    return match value {
                        Abs::Int(_) => Abs::Num(Val::constant()),
                        other => other,
                    };
                }
                match value {
                    // A jump in `L`: its derivatives say nothing across it.
                    Abs::Num(val) if !val.deps.is_empty() => self.give_up(),
                    // `self.x as usize` and `self.x as i64` differ for a
                    // negative `f64` field: the cast names a new constant.
                    Abs::Int(Index::Rel(Base::Const(id), 0)) if keeps_indices(ty) => {
                        let key = format!("{} as {}", self.consts[id], quote::ToTokens::to_token_stream(ty));
                        Abs::Int(Index::Rel(Base::Const(self.intern(key)), 0))
                    }
                    // An offset makes it an integer already (`self.x + 1`
                    // does not compile for a float).
                    Abs::Int(index) if keeps_indices(ty) => Abs::Int(index),
                    _ => Abs::Int(Index::Any),
                }
            }
            ExprKind::Paren(inner) => self.expr(inner, env),
            ExprKind::Block(block) => self.block(block, env),
            ExprKind::If { cond, then_branch, else_branch } => {
                if let Abs::Num(cond) = self.expr(cond, env)
                    && !cond.deps.is_empty()
                {
                    // A branch on `t`, `q` or `v`: `L` is piecewise.
                    return self.give_up();
                }
                let mut then_env = env.clone();
                let then_value = self.block(then_branch, &mut then_env);
                let else_value = match else_branch {
                    Some(else_branch) => self.expr(else_branch, env),
                    None => Abs::Unit,
                };
                *env = self.join_env(&then_env, env);
                self.join(&then_value, &else_value)
            }
            ExprKind::For { var, start, end, body, .. } => {
                self.expr(start, env);
                self.expr(end, env);
                self.for_loop(var.as_ref().map(|(local, _)| local.0), body, env);
                Abs::Unit
            }
            // Fixed during a call, the same for `q` and `v`: a base for
            // indices (`q[q.len() - 1]`). The key is no path's tokens.
            ExprKind::MethodCall { receiver, math: Math::Len, .. } => match receiver.kind {
                ExprKind::Param(..) => Abs::Int(Index::Rel(Base::Const(self.intern("<len>".to_owned())), 0)),
                // A local may hold `q` or an array of another length.
                _ => Abs::Int(Index::Any),
            },
            ExprKind::MethodCall { receiver, method, math, args, .. } => {
                let receiver = self.expr(receiver, env);
                let args: Vec<Abs> = args.iter().map(|arg| self.expr(arg, env)).collect();
                if expr.class == Class::Int {
                    return Abs::Int(Index::Any);
                }
                self.method(&method.to_string(), *math, receiver, &args)
            }
            ExprKind::Array(elems) => {
                let mut summary: Option<Val> = None;
                let mut out = [Reach::None; 2];
                for (k, elem) in elems.iter().enumerate() {
                    let Some(val) = self.element(elem, env) else { return self.give_up() };
                    let position = i64::try_from(k).map_or(Index::Any, Index::Lit);
                    out = join2(out, out_of(position, &val.deps));
                    summary = Some(summary.map_or_else(|| val.clone(), |s| s.join(&val)));
                }
                Abs::Array { elems: summary.unwrap_or_else(Val::constant), out }
            }
            ExprKind::Repeat { elem, .. } => {
                let Some(val) = self.element(elem, env) else { return self.give_up() };
                Abs::Array { out: out_of(Index::Any, &val.deps), elems: val }
            }
            ExprKind::Assign { place, op, value } => {
                let value = self.expr(value, env);
                self.assign(place, *op, value, env);
                Abs::Unit
            }
            ExprKind::Return(value) => {
                if let Some(value) = value {
                    let value = self.expr(value, env).escape(None);
                    let ret = std::mem::replace(&mut self.ret, Abs::Unit);
                    self.ret = self.join(&ret, &value);
                }
                Abs::Unit
            }
            ExprKind::Break(_) | ExprKind::Continue(_) => {
                if let Some(jumps) = self.jumps.pop() {
                    let joined = match jumps {
                        Some(jumps) => self.join_env(&jumps, env),
                        None => env.clone(),
                    };
                    self.jumps.push(Some(joined));
                }
                Abs::Unit
            }
        }
    }

    /// The value of an array element: a scalar, or an integer (a constant).
    fn element(&mut self, elem: &Expr, env: &mut Env) -> Option<Val> {
        match self.expr(elem, env) {
            Abs::Num(val) => Some(val),
            Abs::Int(_) => Some(Val::constant()),
            _ => None,
        }
    }

    /// Runs a loop body to a fixpoint of the state at its head; leaves in
    /// `env` the state after the loop (after any number of iterations).
    fn for_loop(&mut self, var: Option<usize>, body: &Block, env: &mut Env) {
        let mut head = env.clone();
        for _ in 0..MAX_PASSES {
            let mut state = head.clone();
            if let Some(var) = var {
                state[var] = Some(Abs::Int(Index::Rel(Base::Loop(var), 0)));
            }
            self.jumps.push(None);
            self.block(body, &mut state);
            if let Some(Some(jumps)) = self.jumps.pop() {
                state = self.join_env(&state, &jumps);
            }
            // The next iteration has another value of `var`.
            let state: Env = state.iter().map(|value| value.as_ref().map(|value| value.escape(var))).collect();
            let next = self.join_env(&head, &state);
            if next == head {
                *env = head;
                return;
            }
            head = next;
        }
        self.give_up();
        *env = head;
    }

    fn assign(&mut self, place: &Expr, op: Option<BinOp>, value: Abs, env: &mut Env) {
        match &place.kind {
            ExprKind::Local(local, _) => {
                let value = match (op, env[local.0].clone()) {
                    (Some(op), Some(old)) => self.binary(op, place.class, old, value),
                    (None, _) => value,
                    (Some(_), None) => self.give_up(),
                };
                env[local.0] = Some(value);
            }
            ExprKind::Index { base, index, .. } => {
                let position = self.expr(index, env).as_index();
                let ExprKind::Local(local, _) = base.kind else {
                    self.give_up();
                    return;
                };
                let Some(Abs::Array { elems, out }) = env[local.0].clone() else {
                    self.give_up();
                    return;
                };
                let Abs::Num(val) = value else {
                    self.give_up();
                    return;
                };
                // The element's old dependencies are already in `out`,
                // relative to the same position.
                let new_out = join2(out, out_of(position.as_position(), &val.deps));
                let element = match op {
                    Some(op) => match self.binary(op, Class::Active, Abs::Num(elems.clone()), Abs::Num(val)) {
                        Abs::Num(element) => element,
                        _ => Val::top(),
                    },
                    None => val,
                };
                env[local.0] = Some(Abs::Array { elems: elems.join(&element), out: new_out });
            }
            _ => {
                self.give_up();
            }
        }
    }

    fn binary(&mut self, op: BinOp, class: Class, a: Abs, b: Abs) -> Abs {
        let (a, b) = match (a, b) {
            // A diverging operand.
            (Abs::Unit, other) | (other, Abs::Unit) => return other,
            pair => pair,
        };
        // Integers, or constants that may be (`self.n - 1` has class `Const`).
        let integers = matches!((&a, &b), (Abs::Int(_), Abs::Int(_))) && class != Class::Bool;
        if class == Class::Int || integers {
            let (a, b) = (a.as_index(), b.as_index());
            return Abs::Int(match op {
                BinOp::Add(_) | BinOp::AddAssign(_) => a.add(b),
                BinOp::Sub(_) | BinOp::SubAssign(_) => a.sub(b),
                BinOp::Mul(_) | BinOp::MulAssign(_) => {
                    a.literal(|x| if let Index::Lit(y) = b { x.checked_mul(y) } else { None }, b)
                }
                BinOp::Div(_) | BinOp::DivAssign(_) => {
                    a.literal(|x| if let Index::Lit(y) = b { x.checked_div(y) } else { None }, b)
                }
                BinOp::Rem(_) | BinOp::RemAssign(_) => {
                    a.literal(|x| if let Index::Lit(y) = b { x.checked_rem(y) } else { None }, b)
                }
                _ => Index::Any,
            });
        }
        let num = |abs: &Abs| match abs {
            Abs::Num(val) => val.clone(),
            _ => Val::constant(),
        };
        let (x, y) = (num(&a), num(&b));
        if matches!(a, Abs::Array { .. }) || matches!(b, Abs::Array { .. }) {
            // Comparing whole arrays of constants.
            return Abs::Num(Val::condition(&[&x, &y]));
        }
        Abs::Num(match op {
            BinOp::Add(_) | BinOp::Sub(_) | BinOp::AddAssign(_) | BinOp::SubAssign(_) => x.add(&y),
            BinOp::Mul(_) | BinOp::MulAssign(_) => x.mul(&y),
            BinOp::Div(_) | BinOp::DivAssign(_) => x.div(&y),
            // Only of constants (`analyse` refuses it on the others).
            BinOp::Rem(_) | BinOp::RemAssign(_) => Val::nonlinear(&[&x, &y]),
            // Comparisons and logic.
            _ => Val::condition(&[&x, &y]),
        })
    }

    fn method(&mut self, name: &str, math: Math, receiver: Abs, args: &[Abs]) -> Abs {
        let num = |abs: &Abs| match abs {
            Abs::Num(val) => Some(val.clone()),
            Abs::Int(_) => Some(Val::constant()),
            _ => None,
        };
        let Some(x) = num(&receiver) else { return self.give_up() };
        if name == "signum" && !x.deps.is_empty() {
            // A jump, like a branch.
            return self.give_up();
        }
        if math == Math::Powi {
            return match args.first().map(Abs::as_index) {
                Some(Index::Lit(0)) => Abs::Num(Val::constant()),
                Some(Index::Lit(1)) => Abs::Num(x),
                Some(Index::Lit(2)) => Abs::Num(x.mul(&x)),
                _ => Abs::Num(Val::nonlinear(&[&x])),
            };
        }
        let Some(args) = args.iter().map(num).collect::<Option<Vec<Val>>>() else { return self.give_up() };
        if name == "mul_add"
            && let [a, b] = args.as_slice()
        {
            return Abs::Num(x.mul(a).add(b));
        }
        let operands: Vec<&Val> = std::iter::once(&x).chain(&args).collect();
        Abs::Num(Val::nonlinear(&operands))
    }
}

/// Whether `block` or a block inside it declares an item (`const`, `use`).
fn declares_items(block: &Block) -> bool {
    let has_item = |block: &Block| block.stmts.iter().any(|stmt| matches!(stmt, Stmt::Item(_)));
    let mut found = has_item(block);
    block.visit(&mut |expr| {
        found |= match &expr.kind {
            ExprKind::Block(block) | ExprKind::If { then_branch: block, .. } | ExprKind::For { body: block, .. } => {
                has_item(block)
            }
            _ => false,
        };
        !found
    });
    found
}

/// The tokens naming a constant path or a field of `self` (`N`,
/// `Self::N`, `self.chain.n`).
fn constant_key(expr: &Expr) -> Option<String> {
    match &expr.kind {
        ExprKind::Path(path) => Some(quote::ToTokens::to_token_stream(path).to_string()),
        ExprKind::SelfValue(_) => Some("self".to_owned()),
        ExprKind::Field { base, member } => {
            Some(format!("{}.{}", constant_key(base)?, quote::ToTokens::to_token_stream(member)))
        }
        ExprKind::Paren(inner) => constant_key(inner),
        _ => None,
    }
}

/// Whether a cast to `ty` keeps every index value the loops of a body can
/// produce: the pointer-sized and 64-bit integer types.
fn keeps_indices(ty: &Type) -> bool {
    match ty {
        Type::Path(path) => ["usize", "isize", "u64", "i64"].iter().any(|name| path.path.is_ident(name)),
        Type::Paren(inner) => keeps_indices(&inner.elem),
        Type::Group(inner) => keeps_indices(&inner.elem),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ctxt::Ctxt;
    use crate::parse::Input;
    use syn::{ItemImpl, parse_quote};

    const W0: Band = Band::Width(0);
    const W1: Band = Band::Width(1);
    const G: Band = Band::General;

    fn analysed(item: &ItemImpl) -> Structure {
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(item)).expect("valid");
        let analysis = crate::analyse::analyse(&cx, &mut system);
        // Some bodies here are discontinuous on purpose: only `analyse`'s own
        // errors are checked.
        cx.check().expect("no errors");
        assert!(analysis.consistent);
        analysis.structure
    }

    /// The structure of `L = body` with `N` coordinates and a time argument.
    fn lagrangian(body: syn::Block) -> Structure {
        analysed(&parse_quote! {
            impl P { fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 #body }
        })
    }

    fn coupling(q_q: Band, q_v: Band, v_v: Band) -> Coupling {
        Coupling { q_q, q_v, v_v }
    }

    #[test]
    fn pendulum_is_separable_with_constant_mass_and_diagonal() {
        let s = lagrangian(parse_quote!({ 0.5 * self.m * self.l * self.l * v[0] * v[0] + self.k * q[0].cos() }));
        assert_eq!(s.separability, Separability::ConstantMass);
        assert_eq!(s.coupling, coupling(W0, W0, W0));
        // No force, no dissipation: a zero Jacobian.
        assert_eq!(s.force, ForceCoupling { q: W0, v: W0 });
    }

    #[test]
    fn degree_in_v_and_what_the_mass_matrix_depends_on() {
        let sep = |body: syn::Block| lagrangian(body).separability;
        use Separability::{ConstantMass, NotProven, QuadraticKinetic};
        // Quadratic in `v`, not constant.
        assert_eq!(sep(parse_quote!({ v[0] * v[0] * q[0].cos() })), QuadraticKinetic);
        assert_eq!(sep(parse_quote!({ 0.5 * v[0] * v[0] / q[0] - q[0].powi(2) })), QuadraticKinetic);
        // Not quadratic.
        assert_eq!(sep(parse_quote!({ v[0].powi(3) })), NotProven);
        assert_eq!(sep(parse_quote!({ v[0] * v[0] * v[1] })), NotProven);
        assert_eq!(sep(parse_quote!({ -(1.0 - v[0] * v[0]).sqrt() })), NotProven);
        assert_eq!(sep(parse_quote!({ q[0] / v[0] })), NotProven);
        assert_eq!(sep(parse_quote!({ v[0].powf(2.0) })), NotProven);
        // A term linear in `v` (a magnetic field): not homogeneous.
        assert_eq!(sep(parse_quote!({ 0.5 * v[0] * v[0] + q[0] * v[1] })), NotProven);
        assert_eq!(sep(parse_quote!({ 0.5 * v[0] * v[0] + 3.0 * v[1] })), NotProven);
        // A mass depending on time.
        assert_eq!(sep(parse_quote!({ (1.0 + t) * v[0] * v[0] })), NotProven);
        // A potential depending on time is fine.
        assert_eq!(sep(parse_quote!({ v[0] * v[0] - q[0] * t.sin() })), ConstantMass);
        // `powi(2)`, `mul_add` and constant factors keep the degree.
        assert_eq!(sep(parse_quote!({ (self.a * v[0] - 2.0 * v[1]).powi(2) + q[0].powi(0) })), ConstantMass);
        assert_eq!(sep(parse_quote!({ v[0].mul_add(v[0] * self.m, q[0].cos()) })), ConstantMass);
        assert_eq!(sep(parse_quote!({ v[0].mul_add(q[0], v[0]) * v[0] })), QuadraticKinetic);
        assert_eq!(sep(parse_quote!({ v[0].mul_add(q[0], 1.0) * v[0] })), NotProven);
        // A sum started at `0.0` has no degree-0 part.
        assert_eq!(
            sep(parse_quote!({
                let mut x = 0.0;
                x += v[0];
                x *= q[0];
                x * v[1]
            })),
            QuadraticKinetic
        );
        // No kinetic energy: `M = 0`, constant.
        assert_eq!(sep(parse_quote!({ -q[0] * q[0] })), ConstantMass);
    }

    #[test]
    fn a_local_mixing_q_and_v_is_followed_through_lets() {
        let s = lagrangian(parse_quote!({
            let x = v[0] + q[0];
            let y = x;
            0.5 * y * x
        }));
        assert_eq!(s.separability, Separability::NotProven);
        assert_eq!(s.coupling, coupling(W0, W0, W0));
        let s = lagrangian(parse_quote!({
            let mut k = 0.5 * v[0] * v[0];
            k *= 1.0 + q[1] * q[1];
            let (a, b) = (k, -self.g * q[0]);
            let (a, b) = (b, a);
            a + b
        }));
        assert_eq!(s.separability, Separability::QuadraticKinetic);
        assert_eq!(s.coupling, coupling(W0, W1, W0));
    }

    #[test]
    fn literal_indices_give_their_distances() {
        let s = lagrangian(parse_quote!({ (q[0] - q[3]).cos() + v[2] * v[2] * q[2] + v[1] * v[4] }));
        assert_eq!(s.coupling, coupling(Band::Width(3), W0, Band::Width(3)));
        // A sum alone couples nothing; products of sums couple everything in them.
        let s = lagrangian(parse_quote!({ q[0] + q[5] + (q[1] + q[2]) * (q[1] - q[2]) }));
        assert_eq!(s.coupling.q_q, W1);
    }

    #[test]
    fn constants_the_macro_cannot_evaluate_are_index_bases() {
        let s = lagrangian(parse_quote!({ q[N - 1] * q[N - 2] + q[self.n] * q[self.n] + v[Self::K] * v[Self::K] }));
        assert_eq!(s.coupling, coupling(W1, W0, W0));
        // Different constants, or a constant and a literal: unknown distance.
        assert_eq!(lagrangian(parse_quote!({ q[self.n] * q[N] })).coupling.q_q, G);
        assert_eq!(lagrangian(parse_quote!({ q[N - 1] * q[0] })).coupling.q_q, G);
        assert_eq!(lagrangian(parse_quote!({ q[self.a.n] * q[self.b.n] })).coupling.q_q, G);
        // Through casts: the same cast of the same constant is the same index;
        // a float field cast two ways may not be.
        let s = lagrangian(parse_quote!({ q[self.x as usize] * q[self.x as usize + 1] }));
        assert_eq!(s.coupling.q_q, W1);
        assert_eq!(lagrangian(parse_quote!({ q[self.x as usize] * q[(self.x as i64) as usize] })).coupling.q_q, G);
        let s = lagrangian(parse_quote!({ q[(self.n - 1) as usize] * q[self.n - 1] }));
        assert_eq!(s.coupling.q_q, W0);
        // Items declared in the body can give one name two values.
        let s = lagrangian(parse_quote!({
            let a = {
                const K: usize = 1;
                q[K]
            };
            let b = {
                const K: usize = 2;
                q[K]
            };
            a * b
        }));
        assert_eq!(s.coupling.q_q, G);
        // A float constant that starts a sum.
        let s = lagrangian(parse_quote!({
            let mut x = Self::OFFSET;
            for i in 0..N {
                x += v[i] * v[i];
            }
            x
        }));
        assert_eq!((s.separability, s.coupling), (Separability::ConstantMass, coupling(W0, W0, W0)));
    }

    #[test]
    fn neighbour_loops_give_a_band() {
        // The FPU-β chain with fixed ends, `d` declared outside the loop.
        let s = lagrangian(parse_quote!({
            let mut kinetic = 0.0;
            for i in 0..N {
                kinetic += 0.5 * v[i] * v[i];
            }
            let mut potential = 0.5 * q[0] * q[0] + 0.25 * self.beta * q[0].powi(4);
            let mut d = 0.0;
            for i in 0..N - 1 {
                d = q[i + 1] - q[i];
                potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
            }
            let last = q[N - 1];
            kinetic - potential - 0.5 * last * last
        }));
        assert_eq!(s.separability, Separability::ConstantMass);
        assert_eq!(s.coupling, coupling(W1, W0, W0));

        // Offsets on both sides, through an integer local.
        let s = lagrangian(parse_quote!({
            let mut s = 0.0;
            for i in 2..N {
                let j = i - 2;
                s += q[j] * q[i + 1] * v[i];
            }
            s
        }));
        assert_eq!(s.coupling, coupling(Band::Width(3), Band::Width(2), W0));

        // A chain of pendula coupled in the kinetic energy.
        let s = lagrangian(parse_quote!({
            let mut l = 0.0;
            for i in 0..N - 1 {
                l += v[i] * v[i + 1] * (q[i] - q[i + 1]).cos() + v[i] * v[i] - q[i].cos();
            }
            l
        }));
        assert_eq!(s.separability, Separability::QuadraticKinetic);
        assert_eq!(s.coupling, coupling(W1, W1, W1));
    }

    #[test]
    fn what_loops_cannot_prove_is_general() {
        let general_q_q = |body: syn::Block| {
            let s = lagrangian(body);
            s.coupling.q_q == G
        };
        // A value carried to the next iteration: `prev` is `q[i − 1]`, not `q[i]`.
        assert!(general_q_q(parse_quote!({
            let mut s = 0.0;
            let mut prev = q[0];
            for i in 1..N {
                s += (q[i] - prev).powi(2);
                prev = q[i];
            }
            s
        })));
        // A product over the chain couples everything.
        assert!(general_q_q(parse_quote!({
            let mut s = 1.0;
            for i in 0..N {
                s = s * q[i];
            }
            s
        })));
        // A computed index.
        assert!(general_q_q(parse_quote!({
            let mut s = 0.0;
            for i in 0..N / 2 {
                s += q[2 * i] * q[i];
            }
            s
        })));
        // Two loop variables.
        assert!(general_q_q(parse_quote!({
            let mut s = 0.0;
            for i in 0..N {
                for j in 0..N {
                    s += (q[i] - q[j]).cos();
                }
            }
            s
        })));
        // A loop variable against a literal: a star, not a band.
        assert!(general_q_q(parse_quote!({
            let mut s = 0.0;
            for i in 1..N {
                s += q[i] * q[0];
            }
            s
        })));
        // The sum leaves the loop with unknown indices.
        assert!(general_q_q(parse_quote!({
            let mut s = 0.0;
            for i in 0..N {
                s += q[i];
            }
            s * q[0]
        })));
        // The state at a `continue` reaches the next iteration: there `x` is
        // `q[i − 1]`, although the end of the body resets it.
        assert!(general_q_q(parse_quote!({
            let mut x = 0.0;
            let mut s = 0.0;
            for i in 0..N {
                s += x * q[i];
                x = q[i];
                if self.skip {
                    continue;
                }
                x = 1.0;
            }
            s
        })));
        // An index counted across iterations.
        assert!(general_q_q(parse_quote!({
            let mut s = 0.0;
            let mut k = 0;
            for i in 0..N {
                s += q[k] * q[i];
                k += 1;
            }
            s
        })));
    }

    #[test]
    fn inner_loops_over_their_own_variable_stay_precise() {
        let s = lagrangian(parse_quote!({
            let mut s = 0.0;
            for _ in 0..3 {
                for k in 0..N {
                    s += v[k] * v[k] * self.m;
                }
            }
            for i in 0..N - 1 {
                let mut inner = 0.0;
                for k in 0..2 {
                    inner += (k as f64) * q[i];
                }
                s += inner * q[i + 1];
            }
            s
        }));
        assert_eq!(s.separability, Separability::ConstantMass);
        assert_eq!(s.coupling, coupling(W1, W0, W0));
    }

    #[test]
    fn branches_on_constants_join_and_branches_on_q_give_up() {
        let s = lagrangian(parse_quote!({
            if self.flag { v[0] * v[0] } else { 2.0 * v[0] * v[0] * q[0].cos() + q[1] * q[0] }
        }));
        assert_eq!(s.separability, Separability::QuadraticKinetic);
        assert_eq!(s.coupling, coupling(W1, W0, W0));
        for body in [
            parse_quote!({ if q[0] > 0.0 { v[0] * v[0] } else { 2.0 * v[0] * v[0] } }),
            parse_quote!({
                let b = t > 1.0;
                if b { v[0] * v[0] } else { 0.0 }
            }),
            parse_quote!({ v[0] * v[0] * (q[0] as i32 as f64) }),
            parse_quote!({ v[0] * v[0] * q[0].signum() }),
        ] {
            let s = lagrangian(body);
            assert_eq!((s.separability, s.coupling), (Structure::GENERAL.separability, Structure::GENERAL.coupling));
        }
    }

    #[test]
    fn returns_and_arrays_are_covered() {
        let s = lagrangian(parse_quote!({
            for i in 0..N - 1 {
                if self.early {
                    return q[i] * q[i + 1];
                }
            }
            0.0
        }));
        assert_eq!(s.coupling.q_q, W1);
        // Arrays are summarised: sound, not tight (`x[0] * x[0]` is `q[0]²`).
        let s = lagrangian(parse_quote!({
            let x = [q[0], q[1], 0.5];
            let mut y = [0.0; 3];
            y[2] = v[2];
            x[0] * x[0] + y[1] * y[1]
        }));
        assert_eq!(s.coupling, coupling(W1, W0, W0));
        // An element written in one iteration and read in the next.
        let s = lagrangian(parse_quote!({
            let mut x = [0.0; N];
            let mut s = 0.0;
            for i in 0..N - 1 {
                x[i] = q[i];
                s += x[i] * q[i + 1];
            }
            s
        }));
        assert_eq!(s.coupling.q_q, G);
    }

    #[test]
    fn forces_and_dissipation() {
        let s = analysed(&parse_quote! {
            impl P {
                fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 { v[0] * v[0] }
                fn dissipation(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
                    0.5 * self.c * ((v[1] - v[0]).powi(2) + (v[2] - v[1]).powi(2)) * (1.0 + q[0] * q[0])
                }
                fn force(&self, t: f64, q: [f64; 3], v: [f64; 3]) -> [f64; 3] {
                    [-q[0] * t.cos(), self.k * v[1], 0.0]
                }
            }
        });
        // `∂R/∂v₁` depends on `q₀`, `v₀`, `v₂`; `∂R/∂v₂` on `q₀`.
        assert_eq!(s.force, ForceCoupling { q: Band::Width(2), v: Band::Width(1) });

        let force = |body: syn::Block| {
            analysed(&parse_quote! {
                impl P {
                    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 { v[0] * v[0] }
                    fn force(&self, q: [f64; N], v: [f64; N]) -> [f64; N] #body
                }
            })
            .force
        };
        // Built in a loop over neighbours.
        assert_eq!(
            force(parse_quote!({
                let mut f = [0.0; N];
                for i in 1..N - 1 {
                    f[i] = q[i + 1] - 2.0 * q[i] + q[i - 1];
                    f[i] -= self.c * v[i];
                }
                f
            })),
            ForceCoupling { q: W1, v: W0 }
        );
        // Each element reads the previous one: lower triangular, general.
        assert_eq!(
            force(parse_quote!({
                let mut f = [0.0; N];
                for i in 1..N {
                    f[i] = f[i - 1] + q[i];
                }
                f
            })),
            ForceCoupling { q: G, v: W0 }
        );
        // Every element the same function of `q[0]`.
        assert_eq!(force(parse_quote!({ [q[0].sin(); N] })), ForceCoupling { q: G, v: W0 });
        assert_eq!(force(parse_quote!({ q })), ForceCoupling { q: W0, v: W0 });
    }

    #[test]
    fn forces_written_into_a_slice() {
        let force = |body: syn::Block| {
            analysed(&parse_quote! {
                impl P {
                    fn dimension(&self) -> usize { self.n }
                    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 { v[0] * v[0] }
                    fn force(&self, t: f64, q: &[f64], v: &[f64], f: &mut [f64]) #body
                }
            })
            .force
        };
        // A pair force between neighbours, and a drive on the first mass.
        assert_eq!(
            force(parse_quote!({
                for i in 0..q.len() - 1 {
                    let g = (q[i + 1] - q[i]).sin() * (v[i + 1] - v[i]);
                    f[i] += g;
                    f[i + 1] -= g;
                }
                f[0] += t.cos();
            })),
            ForceCoupling { q: W1, v: W1 }
        );
        // Nothing written: a zero Jacobian.
        assert_eq!(force(parse_quote!({})), ForceCoupling { q: W0, v: W0 });
        assert_eq!(
            force(parse_quote!({
                f[q.len() - 1] = -v[q.len() - 1];
            })),
            ForceCoupling { q: W0, v: W0 }
        );
        // Each entry reads the previous one: general.
        assert_eq!(
            force(parse_quote!({
                f[0] = q[0];
                for i in 1..f.len() {
                    f[i] = f[i - 1] + q[i];
                }
            })),
            ForceCoupling { q: G, v: W0 }
        );
        // An early `return` leaves a state the analysis does not keep.
        assert_eq!(
            force(parse_quote!({
                f[0] = v[0];
                if t.sin() > 0.0 {
                    return;
                }
                f[1] = v[1];
            })),
            ForceCoupling { q: G, v: G }
        );
    }

    #[test]
    fn long_sums_stay_cheap_and_sound() {
        // A 300-term sum nests 300 deep. The macro runs on rustc's thread
        // (8 MiB of stack); the test harness gives 2 MiB, too little for
        // the unoptimised build, so the test takes rustc's.
        let run = || {
            // More dependencies than `MAX_DEPS`: indices are forgotten.
            let terms = (0..300).map(|i| quote::quote!(+ q[#i]));
            let body: syn::Block = syn::parse2(quote::quote!({ (0.0 #(#terms)*).sin() })).unwrap();
            let s = lagrangian(body);
            assert_eq!(s.coupling.q_q, G);
            let terms = (0..300).map(|i| quote::quote!(+ q[#i] * q[#i]));
            let body: syn::Block = syn::parse2(quote::quote!({ 0.0 #(#terms)* })).unwrap();
            assert_eq!(lagrangian(body).coupling.q_q, W0);
        };
        std::thread::Builder::new().stack_size(8 << 20).spawn(run).unwrap().join().unwrap();
    }

    /// The structure of a run-time-sized `L = body` (slices, `fn dimension`).
    fn slices(body: syn::Block) -> Structure {
        analysed(&parse_quote! {
            impl P {
                fn dimension(&self) -> usize { self.n }
                fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 #body
            }
        })
    }

    #[test]
    fn slice_bodies_give_bands_from_their_lengths() {
        // The FPU-β chain bounded by `q.len()`, the last link through
        // `q[q.len() - 1]`.
        let s = slices(parse_quote!({
            let n = q.len();
            let mut l = 0.0;
            for i in 0..v.len() {
                l += 0.5 * v[i] * v[i];
            }
            for i in 0..n - 1 {
                let d = q[i + 1] - q[i];
                l -= 0.5 * d * d + 0.25 * self.beta * d.powi(4);
            }
            l - q[0].powi(2) - q[q.len() - 1].powi(4)
        }));
        assert_eq!(s.separability, Separability::ConstantMass);
        assert_eq!(s.coupling, coupling(W1, W0, W0));
        // `q.len()` and `v.len()` are one constant; offsets from it are a band.
        assert_eq!(slices(parse_quote!({ q[q.len() - 1] * q[v.len() - 3] })).coupling.q_q, Band::Width(2));
        // Loops bounded by a field.
        let s = slices(parse_quote!({
            let mut l = 0.0;
            for i in 1..self.n {
                l += v[i - 1] * v[i] * (q[i - 1] - q[i]).cos();
            }
            l
        }));
        assert_eq!((s.separability, s.coupling), (Separability::QuadraticKinetic, coupling(W1, W1, W1)));
    }

    #[test]
    fn slice_bodies_that_are_not_bands_are_general() {
        let q_q = |body: syn::Block| slices(body).coupling.q_q;
        // The ends of the chain: the length against a literal.
        assert_eq!(q_q(parse_quote!({ q[q.len() - 1] * q[0] })), G);
        // The length against another constant.
        assert_eq!(q_q(parse_quote!({ q[q.len() - 1] * q[self.n - 1] })), G);
        // A ring: `(i + 1) % n` is not an offset.
        assert_eq!(
            q_q(parse_quote!({
                let mut l = 0.0;
                for i in 0..q.len() {
                    l += (q[(i + 1) % q.len()] - q[i]).powi(4);
                }
                l
            })),
            G
        );
        // Indices from data.
        assert_eq!(
            q_q(parse_quote!({
                let mut l = 0.0;
                for i in 1..q.len() {
                    l += q[self.order[i]] * q[i];
                }
                l
            })),
            G
        );
        // The length of a local is not known to be the dimension.
        assert_eq!(
            q_q(parse_quote!({
                let a = [1.0, 2.0];
                q[a.len() - 1] * q[q.len() - 1]
            })),
            G
        );
    }
}
