//! The gradient `∂L/∂q` written out in plain `f64`: a reverse-mode (adjoint)
//! source transformation of the analysed body of `fn lagrangian`.
//!
//! The explicit Störmer–Verlet path of the runtime needs only `∂L/∂q` per
//! step. Evaluated on an array dual number, every operation of the body
//! carries `N` derivative components (`O(N²)` for a body of `O(N)`
//! operations); the adjoint code here costs a small multiple of one plain
//! evaluation, as reverse mode does, without a tape.
//!
//! The code is a forward sweep that binds every active intermediate to a
//! temporary, then a reverse sweep that propagates adjoints from the value of
//! `L` down to the leaves `q[i]`. Expression trees need no accumulation (each
//! node has one parent); locals and `q[i]` accumulate. Loops are handled
//! without a tape by what the accepted subset guarantees: a loop body only
//! binds its own immutable locals and adds to accumulators declared outside
//! every loop (`s += e`, `s -= e`), which it never reads. Its iterations
//! are then independent, and the adjoint of an accumulator is the same at
//! every iteration (the update is linear), so the reverse sweep is one more
//! loop over the same range that recomputes the body's intermediates and
//! propagates their adjoints. The forward loop is kept only when the
//! reverse sweep reads the value of one of its accumulators (`s * s`), not
//! when the Lagrangian only returns it.
//!
//! A product chain (`0.25 * β * d * d * d * d`, `x * y * x`, `d * d / c`,
//! `c * d.powi(4)`) is differentiated as one product `C · Π bⱼ^kⱼ`, not node
//! by node: each distinct active factor gets `kⱼ · C · bⱼ^(kⱼ−1) · Π_{i≠j}
//! bᵢ^kᵢ`, powers by squaring, the constants multiplied once. Written out
//! by the user's association, the chain's reverse sweep would pay every
//! partial product. This rounds the derivative differently, by ulps.
//!
//! Anything outside the subset — `if`, blocks, `return`, arrays of active
//! values, assignments other than accumulation, an accumulator read inside a
//! loop, an active `powf` exponent — yields no gradient code, and the
//! runtime keeps its dual-number path. Nothing is ever approximated.

use crate::ir::{Block, Expr, ExprKind, Function, LetBinding, LocalId, Math, ParamRef, Stmt};
use proc_macro2::{Span, TokenStream};
use quote::{ToTokens, format_ident, quote};
use std::collections::HashMap;
use syn::{BinOp, Type, UnOp};

/// The statements of `gradient_q(&self, __t, __q, __v, __out)`: they write
/// `∂L/∂q(t, q, v)` into `__out`. `None` when the body is outside the
/// subset this stage differentiates.
pub(crate) fn gradient_q(function: &Function) -> Option<TokenStream> {
    let mut adjoint = Adjoint::new(function);
    adjoint.function_body(&function.body)
}

/// The statements of `value_gradient_q(&self, __t, __q, __v, __out) -> f64`:
/// those of [`gradient_q`], every forward loop kept, then the value of `L`
/// the forward sweep computed. `None` outside the subset.
pub(crate) fn value_gradient_q(function: &Function) -> Option<TokenStream> {
    let mut adjoint = Adjoint::new(function);
    adjoint.value = true;
    adjoint.function_body(&function.body)
}

/// The statements of `add_gradient_q_at_rest(&self, __t, __q, __out)`,
/// ending with a value of `L(t, q, 0)` whose only use is its finiteness:
/// those of [`value_gradient_q`] with every `v[i]` the constant `0.0` (the
/// terms of the velocities alone then fold away at compile time), `∂L/∂q`
/// added to `__out` (not cleared first), and the forward loops that only
/// the value reads summed in [`PARTIAL_SUMS`] interleaved partial sums (see
/// [`Adjoint::reassociated_loop`]). `None` outside the subset, or where
/// the body reads `v` other than by index or length.
pub(crate) fn add_gradient_q_at_rest(function: &Function) -> Option<TokenStream> {
    let mut adjoint = Adjoint::new(function);
    adjoint.value = true;
    adjoint.finite = true;
    adjoint.function_body(&function.body)
}

/// How many partial sums a loop [`add_gradient_q_at_rest`] reassociates
/// keeps: iterations `4c + k` add to sum `k`, so that the four chains of
/// additions are independent and the compiler vectorises them (two lanes
/// of `f64` per SSE2 register, twice).
const PARTIAL_SUMS: usize = 4;
// The sums are combined pairwise by name, `(s₀ + s₁) + (s₂ + s₃)`.
const _: () = assert!(PARTIAL_SUMS == 4);

/// The statements of `gradient_qv(&self, __t, __q, __v, __out, __out_v)`:
/// `∂L/∂q` into `__out` and `∂L/∂v` into `__out_v`, by the same
/// transformation with the velocities as leaves too. `None` outside the
/// subset.
pub(crate) fn gradient_qv(function: &Function) -> Option<TokenStream> {
    let mut adjoint = Adjoint::new(function);
    adjoint.with_v = true;
    adjoint.function_body(&function.body)
}

/// The statements of `gradient_qv_scalar<__D>(&self, __t, __q, __v,
/// __out, __out_v)`: the transformation of [`gradient_qv`] printed generic
/// over the scalar `__D` (`f64`, a dual number), on slices. Constants stay
/// `f64`; where an `f64` would meet a `__D` on the wrong side of an
/// operator it becomes `__D::from(c)`, and `f64::sin(x)` becomes
/// `x.sin()`. At `__D = f64` it performs the same IEEE operations as the
/// `f64` code (operands of `+` and `*` may swap sides, which is exact).
/// `None` outside the subset.
pub(crate) fn gradient_qv_generic(function: &Function) -> Option<TokenStream> {
    let mut adjoint = Adjoint::new(function);
    adjoint.with_v = true;
    adjoint.generic = true;
    adjoint.function_body(&function.body)
}

/// The statements of `value_gradient_qv_scalar<__D>(&self, __t, __q, __v,
/// __out, __out_v) -> __D`: those of [`gradient_qv_generic`], every forward
/// loop kept (also those whose sums only the value of `L` reads), then the
/// value of `L` the forward sweep computed. `None` outside the subset.
pub(crate) fn value_gradient_qv_generic(function: &Function) -> Option<TokenStream> {
    let mut adjoint = Adjoint::new(function);
    adjoint.with_v = true;
    adjoint.generic = true;
    adjoint.value = true;
    adjoint.function_body(&function.body)
}

/// `const HAS_GRADIENT` and `fn gradient_q` for the trait impl, with
/// `HAS_GRADIENT_QV` and `gradient_qv_scalar` (generic over the scalar), and
/// `gradient_qv` in `f64` for a system of known size; nothing when the body
/// is outside the subset. `n` is `None` for a run-time-sized system
/// (slices).
pub(crate) fn method(function: &Function, n: Option<&TokenStream>) -> Option<TokenStream> {
    let body = gradient_q(function)?;
    let [t, q, v, out, out_v] = [name("t"), name("q"), name("v"), name("out"), name("out_v")];
    let (state, gradient) = match n {
        Some(n) => (quote!(&[f64; #n]), quote!(&mut [f64; #n])),
        None => (quote!(&[f64]), quote!(&mut [f64])),
    };
    let self_token = syn::Token![self](function.self_span);
    // Slices: `out` as long as `q` (as the trait asks), which lets the
    // compiler drop the bounds checks of `out[i + 1]` in a loop over `q`
    // (and vectorise it) whatever the order of the body's terms.
    let reslice = n.is_none().then(|| quote!(let #out = &mut #out[..#q.len()];));
    // Both derivatives in `f64`, for the implicit steps' residuals:
    // size-known systems (the slice trait has only the generic method).
    let both = n.and_then(|_| gradient_qv(function)).map(|body| {
        quote! {
            #[inline]
            fn gradient_qv(&#self_token, #t: f64, #q: #state, #v: #state, #out: #gradient, #out_v: #gradient) {
                #body
            }
        }
    });
    // Both derivatives on any scalar: on dual numbers, the Hessian-vector
    // products of the implicit steps' Jacobians (forward over reverse).
    let generic = gradient_qv_generic(function).map(|body| {
        let d = scalar();
        // And with the value of `L`, which the implicit steps check at
        // their last Newton iterate: size-known systems (the slice trait
        // has no such method).
        let value = n.and_then(|_| value_gradient_qv_generic(function)).map(|body| {
            quote! {
                #[inline]
                fn value_gradient_qv_scalar<#d: ::lagrangian::__private::Scalar>(
                    &#self_token,
                    #t: #d,
                    #q: &[#d],
                    #v: &[#d],
                    #out: &mut [#d],
                    #out_v: &mut [#d],
                ) -> #d {
                    #body
                }
            }
        });
        quote! {
            const HAS_GRADIENT_QV: bool = true;
            #[inline]
            fn gradient_qv_scalar<#d: ::lagrangian::__private::Scalar>(
                &#self_token,
                #t: #d,
                #q: &[#d],
                #v: &[#d],
                #out: &mut [#d],
                #out_v: &mut [#d],
            ) {
                #body
            }
            #value
        }
    });
    // With the value of `L`, which the explicit steps check at the node
    // they reach.
    let valued = value_gradient_q(function).map(|body| {
        quote! {
            #[inline]
            fn value_gradient_q(&#self_token, #t: f64, #q: #state, #v: #state, #out: #gradient) -> f64 {
                #reslice
                #body
            }
        }
    });
    // At rest, added to `out`, with the finiteness of `L`: the force and
    // the check the explicit steps of large systems need at the node they
    // reach.
    let finite = add_gradient_q_at_rest(function).map(|body| {
        quote! {
            #[inline]
            fn add_gradient_q_at_rest(&#self_token, #t: f64, #q: #state, #out: #gradient) -> bool {
                #reslice
                let __l: f64 = { #body };
                __l.is_finite()
            }
        }
    });
    Some(quote! {
        const HAS_GRADIENT: bool = true;
        #[inline]
        fn gradient_q(&#self_token, #t: f64, #q: #state, #v: #state, #out: #gradient) {
            #reslice
            #body
        }
        #valued
        #finite
        #both
        #generic
    })
}

/// The scalar type parameter of the generic gradient (the name the user's
/// methods are printed with too).
fn scalar() -> proc_macro2::Ident {
    format_ident!("__D", span = Span::call_site())
}

fn name(s: &str) -> proc_macro2::Ident {
    format_ident!("__{}", s, span = Span::call_site())
}

/// The state of one transformation.
struct Adjoint<'a> {
    function: &'a Function,
    /// Whether each version of a local depends on `q` (conservatively).
    depends: HashMap<(usize, usize), bool>,
    /// The accumulators: mutable active locals declared outside every loop,
    /// only ever changed by `+=` and `-=`.
    accumulator: Vec<bool>,
    /// The scratch variables: mutable active locals only ever changed by
    /// `=`. Each assignment is a new version, a `let` of its own.
    scratch: Vec<bool>,
    /// The version each read of a scratch variable sees, and the version each
    /// assignment creates, by node address.
    versions: HashMap<*const Expr, usize>,
    /// Accumulators whose value the reverse sweep reads, directly or
    /// through the locals defined from them.
    needed: Vec<bool>,
    /// The expressions each version of a local is defined by (its `let`
    /// initialiser, or the value of the assignment that makes the version),
    /// through which a read of the local reads the accumulators they read.
    definitions: HashMap<(usize, usize), Vec<&'a Expr>>,
    /// The temporary of each active node, by address (stable: the IR is not
    /// moved while this runs).
    temps: HashMap<*const Expr, usize>,
    /// The next adjoint temporary.
    next_adjoint: usize,
    /// Adjoints of locals declared in the current scope of the reverse
    /// sweep and not yet printed: the first contribution binds them
    /// (`let mut __a = g`, not `0 + g`, which IEEE does not fold).
    pending: Vec<(LocalId, usize)>,
    /// Differentiate in `v` too (`gradient_qv`), not only in `q`.
    with_v: bool,
    /// Print generic over the scalar `__D` instead of in `f64`.
    generic: bool,
    /// End with the value of `L` (`value_gradient_qv_scalar`): every
    /// forward loop is kept, also where only that value reads its sums.
    value: bool,
    /// The velocities are zero and only the finiteness of the value is
    /// read ([`add_gradient_q_at_rest`]): `v[i]` is `0.0`, `__out` is added
    /// to, and the forward loops whose sums only that value reads are
    /// reassociated.
    finite: bool,
    /// The loops whose sums their reverse loop carries
    /// ([`fused_loop`](Self::fused_loop)), by body, with the sum of their
    /// partial sums.
    fused: Vec<(*const Block, TokenStream)>,
    /// The sums of the fused loops the forward sweep skipped, which the
    /// value adds.
    witnesses: Vec<TokenStream>,
    /// While a reassociated loop's body is printed: the partial sum its
    /// accumulations go to.
    lane: Option<usize>,
    /// How many loops the reverse sweep is inside.
    loop_depth: usize,
    /// Straight-line bodies whose `q[i]` (and `v[i]`) are read at integer
    /// literals only: the first contribution to `__out[i]` assigns it
    /// (`0 + g` would put one more addition after `g`, which IEEE does not
    /// fold), and these are the indices assigned so far.
    assigned: Option<Vec<(bool, u32)>>,
    /// Adjoint temporaries whose value is a constant (the seed negated, or
    /// times constants): products with them fold at compile time, and in
    /// generic code they are `f64`, so that a product with an active value
    /// scales its lanes instead of paying the dual product rule.
    constants: Vec<String>,
    /// Adjoints of locals whose only contribution so far is a constant:
    /// the local's adjoint is that constant until a second contribution
    /// (or a loop that may add to it) makes it a variable.
    aliases: Vec<((LocalId, usize), TokenStream)>,
}

impl<'a> Adjoint<'a> {
    fn new(function: &'a Function) -> Self {
        let n = function.locals.len();
        Adjoint {
            function,
            depends: HashMap::new(),
            accumulator: vec![false; n],
            scratch: vec![false; n],
            versions: HashMap::new(),
            needed: vec![false; n],
            definitions: HashMap::new(),
            temps: HashMap::new(),
            next_adjoint: 0,
            pending: Vec::new(),
            with_v: false,
            generic: false,
            value: false,
            finite: false,
            fused: Vec::new(),
            witnesses: Vec::new(),
            lane: None,
            loop_depth: 0,
            assigned: None,
            constants: Vec::new(),
            aliases: Vec::new(),
        }
    }

    /// The type of active values: `f64`, or the generic scalar.
    fn ty(&self) -> TokenStream {
        if self.generic { scalar().into_token_stream() } else { quote!(f64) }
    }

    /// An `f64` constant `c` as an active value: `c`, or `__D::from(c)`.
    fn active(&self, c: TokenStream) -> TokenStream {
        if self.generic {
            let d = scalar();
            quote!(#d::from(#c))
        } else {
            c
        }
    }

    /// Zero as an active value.
    fn zero(&self) -> TokenStream {
        self.active(quote!(0.0f64))
    }

    fn function_body(&mut self, block: &'a Block) -> Option<TokenStream> {
        let (stmts, tail) = match block.stmts.split_last() {
            Some((Stmt::Expr { expr, semi: false }, rest)) if !matches!(expr.kind, ExprKind::For { .. }) => {
                (rest, expr)
            }
            _ => return None,
        };
        // Which locals are accumulators or scratch variables, and that the
        // statements are of the subset (expressions are checked while they
        // are printed).
        let (mut plain, mut accumulated) = (vec![false; self.accumulator.len()], vec![false; self.accumulator.len()]);
        block.visit(&mut |e: &Expr| {
            if let ExprKind::Assign { place, op, .. } = &e.kind
                && let ExprKind::Local(id, _) = place.kind
            {
                match op {
                    None => plain[id.0] = true,
                    Some(_) => accumulated[id.0] = true,
                }
            }
            true
        });
        for stmt in stmts {
            self.check_stmt(stmt, true, &plain, &accumulated)?;
        }
        if self.reads_accumulator_in_loop(stmts) {
            return None;
        }
        let mut current = HashMap::new();
        self.resolve(stmts, &mut Vec::new(), &mut current, &mut HashMap::new())?;
        self.resolve_expr(tail, &[], &current)?;
        // Dependence on `q`, to a fixed point: an accumulator may be read
        // before a later accumulation makes it depend on `q`.
        loop {
            let before = self.depends.clone();
            self.dependence(stmts);
            if before == self.depends {
                break;
            }
        }

        // The reverse sweep first, so that it says which accumulators the
        // forward sweep must compute.
        // Added to `__out`, every contribution is an addition.
        self.assigned = (!self.finite && literal_leaves_only(block)).then(Vec::new);
        let mut reverse = Vec::new();
        self.declare_adjoints(stmts);
        if tail.class.is_active() && self.depends_on_q(tail) {
            let seed = self.one();
            self.reverse(tail, seed, &mut reverse)?;
        }
        for stmt in stmts.iter().rev() {
            self.reverse_stmt(stmt, &mut reverse)?;
        }

        let mut forward = Vec::new();
        let mut items = Vec::new();
        for stmt in stmts {
            match stmt {
                Stmt::Item(item) => items.push(item.to_token_stream()),
                _ => self.forward_stmt(stmt, true, &mut forward)?,
            }
        }
        // The value of `L` bound before the reverse sweep, whose names it
        // cannot then shadow.
        let value = match self.value {
            true => {
                let (value, ty, name) = (self.forward_active(tail, &mut forward)?, self.ty(), name("value"));
                forward.push(quote!(let #name: #ty = #value;));
                Some(name)
            }
            false => self.forward(tail, &mut forward).map(|_| None)?,
        };
        let out = name("out");
        let zero = self.zero();
        let clear_v = self.with_v.then(|| {
            let out_v = name("out_v");
            quote!(for __x in #out_v.iter_mut() {
                *__x = #zero;
            })
        });
        let clear = (!self.finite).then(|| {
            quote!(for __x in #out.iter_mut() {
                *__x = #zero;
            })
        });
        let witnesses = &self.witnesses;
        let value = value.map(|value| quote!(#value #(+ #witnesses)*));
        Some(quote! {
            #(#items)*
            #clear
            #clear_v
            #(#forward)*
            #(#reverse)*
            #value
        })
    }

    /// Checks that `stmt` is of the subset; marks accumulators and scratch
    /// variables (`plain`, `accumulated`: how each local is ever assigned).
    fn check_stmt(&mut self, stmt: &Stmt, top: bool, plain: &[bool], accumulated: &[bool]) -> Option<()> {
        match stmt {
            Stmt::Let { bindings, inits, .. } => {
                if bindings.len() != inits.len() {
                    return None;
                }
                for binding in bindings {
                    let Some(local) = binding.local else { continue };
                    let class = self.function.locals[local.0].class;
                    if class.is_array() && class.is_active() {
                        return None;
                    }
                    if binding.mutable {
                        // Only active scalars may be mutated, by
                        // accumulation outside loops, or by assignment.
                        match (plain[local.0], accumulated[local.0]) {
                            _ if !class.is_active() => return None,
                            (true, true) => return None,
                            (false, true) if !top => return None,
                            (false, true) => self.accumulator[local.0] = true,
                            (true, false) => self.scratch[local.0] = true,
                            (false, false) => {}
                        }
                    }
                }
                Some(())
            }
            Stmt::Item(_) => top.then_some(()),
            Stmt::Expr { expr, .. } => match &expr.kind {
                ExprKind::For { body, .. } => {
                    body.stmts.iter().try_for_each(|stmt| self.check_stmt(stmt, false, plain, accumulated))
                }
                ExprKind::Assign { place, op: Some(BinOp::AddAssign(_) | BinOp::SubAssign(_)), .. } => {
                    match place.kind {
                        ExprKind::Local(id, _) if self.accumulator[id.0] => Some(()),
                        _ => None,
                    }
                }
                ExprKind::Assign { place, op: None, .. } => match place.kind {
                    ExprKind::Local(id, _) if self.scratch[id.0] => Some(()),
                    _ => None,
                },
                _ => None,
            },
        }
    }

    /// Gives every read of a scratch variable the version it sees, and every
    /// assignment its new version. `None` when a read may see a value from
    /// an earlier iteration of a loop (`left = q[i]` read at the next
    /// iteration), or one assigned inside a loop that has ended.
    /// `current`: the visible version of each scratch variable and the loop
    /// depth of its definition (`None`: invalid); `next`: the next version.
    fn resolve(
        &mut self,
        stmts: &[Stmt],
        loops: &mut Vec<Vec<bool>>,
        current: &mut HashMap<usize, Option<(usize, usize)>>,
        next: &mut HashMap<usize, usize>,
    ) -> Option<()> {
        for stmt in stmts {
            match stmt {
                Stmt::Let { bindings, inits, .. } => {
                    for (binding, init) in bindings.iter().zip(inits) {
                        self.resolve_expr(init, loops, current)?;
                        if let Some(local) = binding.local
                            && self.scratch[local.0]
                        {
                            current.insert(local.0, Some((0, loops.len())));
                            next.insert(local.0, 1);
                        }
                    }
                }
                Stmt::Expr { expr, .. } => match &expr.kind {
                    ExprKind::For { body, .. } => {
                        // The scratch variables the loop assigns, anywhere in it.
                        let mut assigned = vec![false; self.scratch.len()];
                        body.visit(&mut |e: &Expr| {
                            if let ExprKind::Assign { place, op: None, .. } = &e.kind
                                && let ExprKind::Local(id, _) = place.kind
                            {
                                assigned[id.0] = true;
                            }
                            true
                        });
                        loops.push(assigned);
                        self.resolve(&body.stmts, loops, current, next)?;
                        let assigned = loops.pop()?;
                        for (local, _) in assigned.iter().enumerate().filter(|(_, a)| **a) {
                            current.insert(local, None);
                        }
                    }
                    ExprKind::Assign { place, op, value } => {
                        self.resolve_expr(value, loops, current)?;
                        let ExprKind::Local(id, _) = place.kind else { return None };
                        if op.is_none() {
                            let version = next.get(&id.0).copied()?;
                            next.insert(id.0, version + 1);
                            current.insert(id.0, Some((version, loops.len())));
                            self.versions.insert(std::ptr::from_ref(expr), version);
                        }
                    }
                    _ => return None,
                },
                Stmt::Item(_) => {}
            }
        }
        Some(())
    }

    /// Resolves the reads of scratch variables in `expr` (see `resolve`).
    fn resolve_expr(
        &mut self,
        expr: &Expr,
        loops: &[Vec<bool>],
        current: &HashMap<usize, Option<(usize, usize)>>,
    ) -> Option<()> {
        let mut ok = true;
        let mut found = Vec::new();
        expr.visit(&mut |e: &Expr| {
            if let ExprKind::Local(id, _) = e.kind
                && self.scratch[id.0]
            {
                match current.get(&id.0).copied().flatten() {
                    // No loop entered since the definition assigns it.
                    Some((version, depth)) if loops[depth..].iter().all(|assigned| !assigned[id.0]) => {
                        found.push((std::ptr::from_ref(e), version));
                    }
                    _ => ok = false,
                }
            }
            true
        });
        self.versions.extend(found);
        ok.then_some(())
    }

    /// The version of a local a read or an assignment refers to (0 but for
    /// scratch variables).
    fn version(&self, expr: &Expr) -> usize {
        self.versions.get(&std::ptr::from_ref(expr)).copied().unwrap_or(0)
    }

    fn local_depends(&self, id: LocalId, version: usize) -> bool {
        self.depends.get(&(id.0, version)).copied().unwrap_or(false)
    }

    /// Whether a loop body reads an accumulator (its iterations would not be
    /// independent).
    fn reads_accumulator_in_loop(&self, stmts: &[Stmt]) -> bool {
        let mut found = false;
        for stmt in stmts {
            let Stmt::Expr { expr, .. } = stmt else { continue };
            let ExprKind::For { body, .. } = &expr.kind else { continue };
            body.visit(&mut |e: &Expr| {
                match &e.kind {
                    // The place of an accumulation is written, not read.
                    ExprKind::Assign { value, .. } => {
                        value.visit(&mut |e: &Expr| {
                            found |= matches!(e.kind, ExprKind::Local(id, _) if self.accumulator[id.0]);
                            true
                        });
                        return false;
                    }
                    ExprKind::Local(id, _) if self.accumulator[id.0] => found = true,
                    _ => {}
                }
                true
            });
        }
        found
    }

    /// One pass of the dependence analysis over `stmts`.
    fn dependence(&mut self, stmts: &'a [Stmt]) {
        for stmt in stmts {
            match stmt {
                Stmt::Let { bindings, inits, .. } => {
                    for (binding, init) in bindings.iter().zip(inits) {
                        if let Some(local) = binding.local {
                            let depends = self.depends_on_q(init);
                            *self.depends.entry((local.0, 0)).or_default() |= depends;
                            self.define((local.0, 0), init);
                        }
                    }
                }
                Stmt::Expr { expr, .. } => match &expr.kind {
                    ExprKind::For { body, .. } => self.dependence(&body.stmts),
                    ExprKind::Assign { place, value, op } => {
                        if let ExprKind::Local(id, _) = place.kind {
                            let depends = self.depends_on_q(value);
                            *self.depends.entry((id.0, self.version(expr))).or_default() |= depends;
                            // An accumulation is the accumulator's own.
                            if op.is_none() {
                                self.define((id.0, self.version(expr)), value);
                            }
                        }
                    }
                    _ => {}
                },
                Stmt::Item(_) => {}
            }
        }
    }

    /// Records `init` as a definition of the version `key` of a local (once:
    /// [`dependence`](Self::dependence) runs to a fixed point).
    fn define(&mut self, key: (usize, usize), init: &'a Expr) {
        let definitions = self.definitions.entry(key).or_default();
        if !definitions.iter().any(|d| std::ptr::eq(*d, init)) {
            definitions.push(init);
        }
    }

    /// Marks as needed the accumulators `expr` reads, directly or through
    /// the definitions of the locals it reads (`let e = s; e.exp()` reads
    /// the value of the accumulator `s`).
    fn mark_needed(&mut self, expr: &Expr) {
        let mut reads = Vec::new();
        self.local_reads(expr, &mut reads);
        let mut seen = Vec::new();
        while let Some((id, version)) = reads.pop() {
            if seen.contains(&(id, version)) {
                continue;
            }
            seen.push((id, version));
            if self.accumulator[id.0] {
                self.needed[id.0] = true;
            } else if let Some(definitions) = self.definitions.get(&(id.0, version)) {
                for &definition in definitions {
                    self.local_reads(definition, &mut reads);
                }
            }
        }
    }

    /// The versions of the locals `expr` reads, pushed to `reads`.
    fn local_reads(&self, expr: &Expr, reads: &mut Vec<(LocalId, usize)>) {
        expr.visit(&mut |e: &Expr| {
            if let ExprKind::Local(id, _) = e.kind {
                reads.push((id, self.version(e)));
            }
            true
        });
    }

    /// Whether `expr` may depend on `q`.
    fn depends_on_q(&self, expr: &Expr) -> bool {
        if !expr.class.is_active() {
            return false;
        }
        let mut depends = false;
        expr.visit(&mut |e: &Expr| {
            match &e.kind {
                ExprKind::Param(ParamRef::Q, _) => depends = true,
                ExprKind::Param(ParamRef::V, _) => depends |= self.with_v,
                ExprKind::Local(id, _) => depends |= self.local_depends(*id, self.version(e)),
                _ => {}
            }
            !depends
        });
        depends
    }

    /// Makes the adjoints of the active locals `stmts` declare that depend
    /// on `q` pending: printed at their first contribution, or as zero where
    /// they are read (or may be written in a loop) before it.
    fn declare_adjoints(&mut self, stmts: &[Stmt]) {
        for stmt in stmts {
            let defined: Vec<(LocalId, usize)> = match stmt {
                Stmt::Let { bindings, .. } => {
                    bindings.iter().filter_map(|binding| binding.local).map(|l| (l, 0)).collect()
                }
                Stmt::Expr { expr, .. } => match &expr.kind {
                    ExprKind::Assign { place, op: None, .. } => match place.kind {
                        ExprKind::Local(id, _) => vec![(id, self.version(expr))],
                        _ => continue,
                    },
                    _ => continue,
                },
                Stmt::Item(_) => continue,
            };
            for (local, version) in defined {
                if self.function.locals[local.0].class.is_active() && self.local_depends(local, version) {
                    self.pending.push((local, version));
                }
            }
        }
    }

    /// Prints a pending adjoint as zero (`let mut __a = 0.0`).
    fn declare_zero(&mut self, local: LocalId, version: usize, out: &mut Vec<TokenStream>) {
        if let Some(position) = self.pending.iter().position(|p| *p == (local, version)) {
            self.pending.remove(position);
            let (adjoint, ty, zero) = (adjoint_name(local, version), self.ty(), self.zero());
            out.push(quote!(let mut #adjoint: #ty = #zero;));
        }
    }

    /// The adjoint of a local where it is read: declared as zero first if
    /// nothing contributed to it yet.
    fn read_adjoint(&mut self, local: LocalId, version: usize, out: &mut Vec<TokenStream>) -> TokenStream {
        if let Some((_, constant)) = self.aliases.iter().find(|(key, _)| *key == (local, version)) {
            return constant.clone();
        }
        self.declare_zero(local, version, out);
        adjoint_name(local, version).into_token_stream()
    }

    /// Turns the adjoint of a local that is a constant so far into a
    /// variable holding it (`let mut __a = c`), before something adds to it.
    fn materialize(&mut self, local: LocalId, version: usize, out: &mut Vec<TokenStream>) {
        if let Some(position) = self.aliases.iter().position(|(key, _)| *key == (local, version)) {
            let (_, constant) = self.aliases.remove(position);
            let (adjoint, ty, value) = (adjoint_name(local, version), self.ty(), self.as_active(&constant));
            out.push(quote!(let mut #adjoint: #ty = #value;));
        }
    }

    /// The forward code of one statement. `top`: outside every loop (loops
    /// there are run only when an accumulator they add to is needed).
    fn forward_stmt(&mut self, stmt: &Stmt, top: bool, out: &mut Vec<TokenStream>) -> Option<()> {
        match stmt {
            Stmt::Let { bindings, tuple, ty, inits, .. } => {
                for (i, (binding, init)) in bindings.iter().zip(inits).enumerate() {
                    let ty = match (ty.as_deref(), tuple) {
                        (Some(Type::Tuple(types)), true) => types.elems.iter().nth(i),
                        (Some(ty), false) => Some(ty),
                        _ => None,
                    };
                    self.forward_let(*binding, ty, init, out)?;
                }
                Some(())
            }
            Stmt::Expr { expr, .. } => match &expr.kind {
                ExprKind::For { var, start, limits, end, body } => {
                    if top && !self.value && !self.adds_to_needed(body) {
                        return Some(());
                    }
                    if top && self.finite && !self.adds_to_needed(body) {
                        // Carried by its reverse loop (`fused_loop`): the
                        // value adds the partial sums at the end.
                        if let Some(k) = self.fused.iter().position(|(b, _)| std::ptr::eq(*b, body)) {
                            let (_, total) = &self.fused[k];
                            self.witnesses.push(total.clone());
                            return Some(());
                        }
                    }
                    if top && self.finite && !self.adds_to_needed(body) && reassociable(limits, body) {
                        return self.reassociated_loop(var.as_ref().map(|(id, _)| *id), start, end, body, out);
                    }
                    let mut inner = Vec::new();
                    for stmt in &body.stmts {
                        self.forward_stmt(stmt, false, &mut inner)?;
                    }
                    let var = loop_var(var.as_ref().map(|(id, _)| *id));
                    let (start, end) = (self.constant(start)?, self.constant(end)?);
                    out.push(quote!(for #var in #start #limits #end { #(#inner)* }));
                    Some(())
                }
                ExprKind::Assign { place, op, value } => {
                    let ExprKind::Local(id, _) = place.kind else { return None };
                    let local = local_name(id, self.version(expr));
                    match op {
                        Some(op) => {
                            let value = self.forward(value, out)?;
                            let place = match self.lane {
                                Some(lane) => partial_name(id, lane).into_token_stream(),
                                None => local.into_token_stream(),
                            };
                            out.push(quote!(#place #op #value;));
                        }
                        // A new version of a scratch variable.
                        None => {
                            let (value, ty) = (self.forward_active(value, out)?, self.ty());
                            out.push(quote!(let #local: #ty = #value;));
                        }
                    }
                    Some(())
                }
                _ => None,
            },
            Stmt::Item(_) => None,
        }
    }

    /// `let` of one binding: the value of `init` under the local's name.
    fn forward_let(
        &mut self,
        binding: LetBinding,
        ty: Option<&Type>,
        init: &Expr,
        out: &mut Vec<TokenStream>,
    ) -> Option<()> {
        let Some(local) = binding.local else {
            // `_`: nothing is bound; a constant is still checked to print.
            return if init.class.is_active() { self.forward(init, out).map(drop) } else { Some(()) };
        };
        let name = local_name(local, 0);
        // Scratch variables get a new name at each assignment instead.
        let mutability = self.accumulator[local.0].then(|| quote!(mut));
        if self.function.locals[local.0].class.is_active() {
            let (value, ty) = (self.forward_active(init, out)?, self.ty());
            out.push(quote!(let #mutability #name: #ty = #value;));
        } else {
            let value = self.constant(init)?;
            let ty = ty.map(|ty| quote!(: #ty));
            out.push(quote!(let #mutability #name #ty = #value;));
        }
        Some(())
    }

    /// The forward code of a top-level loop `for var in start..end` whose
    /// sums only the value of `L` reads, for [`add_gradient_q_at_rest`]:
    /// iteration `start + 4c + k` adds to the `k`-th of [`PARTIAL_SUMS`]
    /// partial sums of each accumulator (the body printed once per sum, so
    /// that the sums are independent chains the compiler vectorises), the
    /// remaining iterations to the first, and the accumulator then adds
    /// `(s₀ + s₁) + (s₂ + s₃)`. Each iteration's terms are the same
    /// operations as in order; only the order of the additions changes,
    /// which rounds the sum differently but leaves it finite exactly when
    /// the ordered one is, but where a partial sum overflows and the
    /// ordered one does not, or the other way round.
    fn reassociated_loop(
        &mut self,
        var: Option<LocalId>,
        start: &Expr,
        end: &Expr,
        body: &Block,
        out: &mut Vec<TokenStream>,
    ) -> Option<()> {
        let accumulators = self.accumulations(body);
        let var = loop_var(var);
        let (start, end) = (self.constant(start)?, self.constant(end)?);
        let (ty, zero) = (self.ty(), self.zero());
        let mut partials = Vec::new();
        for &id in &accumulators {
            for lane in 0..PARTIAL_SUMS {
                let partial = partial_name(id, lane);
                partials.push(quote!(let mut #partial: #ty = #zero;));
            }
        }
        let mut lanes = Vec::new();
        for lane in 0..PARTIAL_SUMS {
            self.lane = Some(lane);
            let mut inner = Vec::new();
            let printed = body.stmts.iter().try_for_each(|stmt| self.forward_stmt(stmt, false, &mut inner));
            self.lane = None;
            printed?;
            lanes.push(quote!(#(#inner)*));
        }
        self.lane = Some(0);
        let mut rest = Vec::new();
        let printed = body.stmts.iter().try_for_each(|stmt| self.forward_stmt(stmt, false, &mut rest));
        self.lane = None;
        printed?;
        let totals = accumulators.iter().map(|&id| {
            let (local, [s0, s1, s2, s3]) = (local_name(id, 0), [0, 1, 2, 3].map(|lane| partial_name(id, lane)));
            quote!(#local += (#s0 + #s1) + (#s2 + #s3);)
        });
        let chunked = chunked_loop(&var, (&start, &end), &lanes, &quote!(#(#rest)*));
        out.push(quote! {
            #(#partials)*
            #chunked
            #(#totals)*
        });
        Some(())
    }

    /// The reverse loop of a top-level loop whose sums only the value of
    /// `L` reads, at rest ([`add_gradient_q_at_rest`]): `inner`, the
    /// iteration's recomputed intermediates and adjoints, which add each
    /// term of the sums to `__w` instead of to its accumulator, run for
    /// `start + 4c + k` with `__w` the `k`-th of [`PARTIAL_SUMS`] partial
    /// sums (the chunk's four iterations in order, so the adjoints are
    /// added as in the plain loop), the remaining iterations with the
    /// first. The forward sweep then skips the loop
    /// ([`forward_stmt`](Self::forward_stmt)) and the value ends with
    /// `+ (w₀ + w₁) + (w₂ + w₃)`: one pass over the coordinates instead of
    /// two. The sums enter `L` linearly (the reverse sweep reads no value
    /// of theirs), so the value so formed is finite exactly when `L` is,
    /// but where a sum overflows in one order and not in the other.
    fn fused_loop(
        &mut self,
        body: &Block,
        var: TokenStream,
        (start, end): (TokenStream, TokenStream),
        inner: Vec<TokenStream>,
        out: &mut Vec<TokenStream>,
    ) {
        let index = self.fused.len();
        let partials = (0..PARTIAL_SUMS).map(|lane| format_ident!("__w{}_{}", index, lane)).collect::<Vec<_>>();
        let into = |partial: &proc_macro2::Ident| {
            quote! {
                let mut __w: f64 = #partial;
                #(#inner)*
                #partial = __w;
            }
        };
        let lanes = partials.iter().map(into).collect::<Vec<_>>();
        let chunked = chunked_loop(&var, (&start, &end), &lanes, &into(&partials[0]));
        out.push(quote! {
            #(let mut #partials: f64 = 0.0f64;)*
            #chunked
        });
        let [w0, w1, w2, w3] = [0, 1, 2, 3].map(|lane| &partials[lane]);
        self.fused.push((std::ptr::from_ref(body), quote!(((#w0 + #w1) + (#w2 + #w3)))));
    }

    /// The accumulators a loop body adds to.
    fn accumulations(&self, body: &Block) -> Vec<LocalId> {
        let mut accumulators = Vec::new();
        body.visit(&mut |e: &Expr| {
            if let ExprKind::Assign { place, op: Some(_), .. } = &e.kind
                && let ExprKind::Local(id, _) = place.kind
                && !accumulators.contains(&id)
            {
                accumulators.push(id);
            }
            true
        });
        accumulators
    }

    /// Whether a loop body adds to an accumulator the reverse sweep reads.
    fn adds_to_needed(&self, body: &Block) -> bool {
        let mut found = false;
        body.visit(&mut |e: &Expr| {
            if let ExprKind::Assign { place, .. } = &e.kind
                && let ExprKind::Local(id, _) = place.kind
            {
                found |= self.needed[id.0];
            }
            true
        });
        found
    }

    /// The reverse code of one statement.
    fn reverse_stmt(&mut self, stmt: &Stmt, out: &mut Vec<TokenStream>) -> Option<()> {
        match stmt {
            Stmt::Let { bindings, inits, .. } => {
                for (binding, init) in bindings.iter().zip(inits).rev() {
                    let Some(local) = binding.local else { continue };
                    if self.local_depends(local, 0) && self.depends_on_q(init) {
                        let adjoint = self.read_adjoint(local, 0, out);
                        self.reverse(init, adjoint, out)?;
                    }
                }
                Some(())
            }
            Stmt::Expr { expr, .. } => match &expr.kind {
                ExprKind::For { var, start, limits, end, body } => {
                    if !self.loop_depends_on_q(body) {
                        return Some(());
                    }
                    // At rest, a loop whose sums only the value of `L` reads
                    // and enter it (something after the loop reads them)
                    // carries them here instead of in a forward loop of its
                    // own (see `fused_loop`).
                    let fuse = self.finite
                        && self.loop_depth == 0
                        && !self.adds_to_needed(body)
                        && reassociable(limits, body)
                        && self.accumulations(body).iter().all(|&id| {
                            self.aliases.iter().any(|(key, _)| *key == (id, 0)) || !self.pending.contains(&(id, 0))
                        });
                    // Adjoints the loop may add to exist before it, as zero
                    // if nothing contributed yet; the loop's own are pending
                    // in its body.
                    let mut read = Vec::new();
                    body.visit(&mut |e: &Expr| {
                        if let ExprKind::Local(id, _) = e.kind {
                            read.push(id);
                        }
                        true
                    });
                    for (local, version) in self.pending.clone() {
                        if read.contains(&local) {
                            self.declare_zero(local, version, out);
                        }
                    }
                    // A constant adjoint the loop may add to becomes a
                    // variable first (an accumulator's adjoint is only read
                    // in a loop, never added to).
                    let aliased: Vec<(LocalId, usize)> = self.aliases.iter().map(|(key, _)| *key).collect();
                    for (local, version) in aliased {
                        if read.contains(&local) && !self.accumulator[local.0] {
                            self.materialize(local, version, out);
                        }
                    }
                    let outer = std::mem::take(&mut self.pending);
                    // Recompute the body's intermediates, then propagate.
                    let mut inner = Vec::new();
                    for stmt in &body.stmts {
                        match stmt {
                            Stmt::Let { .. } => self.forward_stmt(stmt, false, &mut inner)?,
                            Stmt::Expr { expr, .. } => match &expr.kind {
                                ExprKind::Assign { op: None, .. } => self.forward_stmt(stmt, false, &mut inner)?,
                                ExprKind::Assign { value, op: Some(op), .. } if fuse => {
                                    let value = self.forward(value, &mut inner)?;
                                    inner.push(quote!(__w #op #value;));
                                }
                                ExprKind::Assign { value, .. } => drop(self.forward(value, &mut inner)?),
                                ExprKind::For { .. } => {}
                                _ => return None,
                            },
                            Stmt::Item(_) => return None,
                        }
                    }
                    self.declare_adjoints(&body.stmts);
                    self.loop_depth += 1;
                    for stmt in body.stmts.iter().rev() {
                        self.reverse_stmt(stmt, &mut inner)?;
                    }
                    self.loop_depth -= 1;
                    // Adjoints nothing contributed to are not printed.
                    self.pending = outer;
                    let var = loop_var(var.as_ref().map(|(id, _)| *id));
                    let (start, end) = (self.constant(start)?, self.constant(end)?);
                    if fuse {
                        self.fused_loop(body, var, (start, end), inner, out);
                    } else {
                        out.push(quote!(for #var in #start #limits #end { #(#inner)* }));
                    }
                    Some(())
                }
                ExprKind::Assign { place, op: None, value } => {
                    let ExprKind::Local(id, _) = place.kind else { return None };
                    let version = self.version(expr);
                    if self.local_depends(id, version) && self.depends_on_q(value) {
                        let adjoint = self.read_adjoint(id, version, out);
                        self.reverse(value, adjoint, out)?;
                    }
                    Some(())
                }
                ExprKind::Assign { place, op: Some(op), value } => {
                    let ExprKind::Local(id, _) = place.kind else { return None };
                    if !self.depends_on_q(value) {
                        return Some(());
                    }
                    let adjoint = self.read_adjoint(id, 0, out);
                    let g = match op {
                        BinOp::AddAssign(_) => adjoint.into_token_stream(),
                        BinOp::SubAssign(_) => self.negate(&adjoint, out),
                        _ => return None,
                    };
                    self.reverse(value, g, out)
                }
                _ => None,
            },
            Stmt::Item(_) => Some(()),
        }
    }

    /// Whether anything a loop body adds or binds depends on `q`.
    fn loop_depends_on_q(&self, body: &Block) -> bool {
        body.stmts.iter().any(|stmt| match stmt {
            Stmt::Let { inits, .. } => inits.iter().any(|init| self.depends_on_q(init)),
            Stmt::Expr { expr, .. } => match &expr.kind {
                ExprKind::For { body, .. } => self.loop_depends_on_q(body),
                ExprKind::Assign { value, .. } => self.depends_on_q(value),
                _ => false,
            },
            Stmt::Item(_) => false,
        })
    }

    /// `let __g{k} = value;`, returning `__g{k}`.
    fn bind(&mut self, value: TokenStream, out: &mut Vec<TokenStream>) -> TokenStream {
        let g = format_ident!("__g{}", self.next_adjoint);
        self.next_adjoint += 1;
        let ty = self.ty();
        out.push(quote!(let #g: #ty = #value;));
        g.into_token_stream()
    }

    /// The seed of the reverse sweep, the adjoint of `L`: one.
    fn one(&self) -> TokenStream {
        quote!(1.0f64)
    }

    /// `g · x` bound to an adjoint temporary; `x` alone when `g` is the
    /// seed (`x · 1` is `x`, and on dual numbers the product would not be
    /// free). `active`: whether `x` is an active value (a constant is made
    /// one in generic code).
    fn times(&mut self, g: &TokenStream, x: TokenStream, active: bool, out: &mut Vec<TokenStream>) -> TokenStream {
        let seed = g.to_string() == self.one().to_string();
        match (self.is_constant(g), active) {
            // A constant: `f64` in generic code too.
            (true, false) => self.bind_constant(if seed { x } else { quote!(#g * #x) }, out),
            (true, true) if seed => self.bind(x, out),
            // `D · f64`: the lanes scaled (IEEE `*` commutes).
            (true, true) if self.generic => self.bind(quote!(#x * #g), out),
            _ => self.bind(quote!(#g * #x), out),
        }
    }

    /// `let __g{k}: f64 = value;` for a constant adjoint, returning `__g{k}`.
    fn bind_constant(&mut self, value: TokenStream, out: &mut Vec<TokenStream>) -> TokenStream {
        let g = format_ident!("__g{}", self.next_adjoint);
        self.next_adjoint += 1;
        out.push(quote!(let #g: f64 = #value;));
        self.constants.push(g.to_string());
        g.into_token_stream()
    }

    /// `−g` bound to an adjoint temporary.
    fn negate(&mut self, g: &TokenStream, out: &mut Vec<TokenStream>) -> TokenStream {
        if self.is_constant(g) { self.bind_constant(quote!(-#g), out) } else { self.bind(quote!(-#g), out) }
    }

    /// The adjoint `g` as an active value: a constant one made active in
    /// generic code.
    fn as_active(&self, g: &TokenStream) -> TokenStream {
        if self.generic && self.is_constant(g) { self.active(g.clone()) } else { g.clone() }
    }

    /// Whether the adjoint `g` is a constant: the seed, or made from it by
    /// negation and products with constants.
    fn is_constant(&self, g: &TokenStream) -> bool {
        let g = g.to_string();
        g == self.one().to_string() || self.constants.contains(&g)
    }

    /// The names of `sin` and `cos` of the receiver of the active `sin` or
    /// `cos` node `expr`, which its forward code binds together.
    fn sin_cos(&mut self, expr: &Expr) -> (proc_macro2::Ident, proc_macro2::Ident) {
        let temp = self.temp(expr);
        (format_ident!("{}_sin", temp), format_ident!("{}_cos", temp))
    }

    /// The temporary of an active node.
    fn temp(&mut self, expr: &Expr) -> proc_macro2::Ident {
        let next = self.temps.len();
        let k = *self.temps.entry(std::ptr::from_ref(expr)).or_insert(next);
        format_ident!("__t{}", k)
    }

    /// Emits the forward code of `expr` into `out`; returns its value: a
    /// temporary when active, the constant expression otherwise.
    fn forward(&mut self, expr: &Expr, out: &mut Vec<TokenStream>) -> Option<TokenStream> {
        if !expr.class.is_active() {
            return self.constant(expr);
        }
        let value = match &expr.kind {
            ExprKind::Paren(inner) => return self.forward(inner, out),
            ExprKind::Cast { expr: inner, .. } if inner.class.is_active() => {
                // An active value is only ever cast to `f64` here: a cast to
                // an integer is constant.
                return self.forward(inner, out);
            }
            ExprKind::Param(ParamRef::Time, _) => return Some(name("t").into_token_stream()),
            ExprKind::Index { base, index, .. } => {
                let param = match base.kind {
                    ExprKind::Param(ParamRef::Q, _) => name("q"),
                    ExprKind::Param(ParamRef::V, _) => name("v"),
                    _ => return None,
                };
                let index = self.constant(index)?;
                match base.kind {
                    // At rest: a constant the compiler folds.
                    ExprKind::Param(ParamRef::V, _) if self.finite => quote!(0.0f64),
                    _ => quote!(#param[#index]),
                }
            }
            ExprKind::Local(id, _) => local_name(*id, self.version(expr)).into_token_stream(),
            ExprKind::Unary { op: UnOp::Neg(_), expr: inner } => {
                let inner = self.forward(inner, out)?;
                quote!(-#inner)
            }
            ExprKind::Binary { lhs: lhs_expr, op, rhs: rhs_expr } => {
                if !matches!(op, BinOp::Add(_) | BinOp::Sub(_) | BinOp::Mul(_) | BinOp::Div(_)) {
                    return None;
                }
                let (lhs, rhs) = (self.forward(lhs_expr, out)?, self.forward(rhs_expr, out)?);
                match op {
                    // `D` has `D op f64` but not `f64 op D`: `c + x` → `x + c`
                    // (exact: IEEE `+` and `*` commute), `c - x` →
                    // `D::from(c) - x`.
                    _ if !self.generic || lhs_expr.class.is_active() => quote!(#lhs #op #rhs),
                    BinOp::Add(_) | BinOp::Mul(_) => quote!(#rhs #op #lhs),
                    _ => {
                        let lhs = self.active(lhs);
                        quote!(#lhs #op #rhs)
                    }
                }
            }
            ExprKind::MethodCall { receiver, method, math, args, .. } => {
                let receiver_value = self.forward(receiver, out)?;
                let mut values = Vec::with_capacity(args.len());
                for arg in args {
                    values.push(self.forward(arg, out)?);
                }
                let rule = Rule::of(&method.to_string(), *math, args)?;
                // `sin` and `cos` as a pair: the reverse sweep's partial is
                // the other half (on dual numbers each of them is a
                // `sin_cos` of the real part). Where everything inlines the
                // compiler merges the two calls itself (measured: the same
                // instructions per step); the generated code does not rely
                // on it.
                if let Rule::Unary(f @ (Unary::Sin | Unary::Cos)) = rule {
                    let (temp, (sin, cos), ty) = (self.temp(expr), self.sin_cos(expr), self.ty());
                    let pair = match self.generic {
                        true => quote!(#receiver_value.sin_cos()),
                        false => quote!(f64::sin_cos(#receiver_value)),
                    };
                    out.push(quote!(let (#sin, #cos): (#ty, #ty) = #pair;));
                    let value = if matches!(f, Unary::Sin) { sin } else { cos };
                    out.push(quote!(let #temp: #ty = #value;));
                    return Some(temp.into_token_stream());
                }
                // At rest, for the finiteness of the value only: a small
                // constant power as products, which vectorise (`powi` is
                // a call the compiler keeps scalar); they round as the
                // compiler expands `powi`, and overflow where it does but
                // at the threshold.
                if self.finite
                    && method == "powi"
                    && let Some(k) = args.first().and_then(integer_literal).filter(|k| (1..=16).contains(k))
                {
                    let (temp, power) = (self.temp(expr), power_by_squaring(&receiver_value, k));
                    out.push(quote!(let #temp: f64 = #power;));
                    return Some(temp.into_token_stream());
                }
                let method = format_ident!("{}", method.to_string());
                if self.generic {
                    // `atan2` and `mul_add` take active operands throughout.
                    let uniform = matches!(rule, Rule::Atan2 | Rule::MulAdd);
                    let receiver_value = self.active_if(!receiver.class.is_active(), receiver_value);
                    let values: Vec<TokenStream> = (args.iter().zip(values))
                        .map(|(arg, value)| self.active_if(uniform && !arg.class.is_active(), value))
                        .collect();
                    quote!(#receiver_value.#method(#(#values),*))
                } else {
                    quote!(f64::#method(#receiver_value #(, #values)*))
                }
            }
            _ => return None,
        };
        let temp = self.temp(expr);
        let ty = self.ty();
        out.push(quote!(let #temp: #ty = #value;));
        Some(temp.into_token_stream())
    }

    /// [`forward`](Self::forward) of a value bound to an active local: a
    /// constant becomes an active value.
    fn forward_active(&mut self, expr: &Expr, out: &mut Vec<TokenStream>) -> Option<TokenStream> {
        let value = self.forward(expr, out)?;
        Some(self.active_if(!expr.class.is_active(), value))
    }

    /// `value` as an active value when `constant` (generic code only).
    fn active_if(&self, constant: bool, value: TokenStream) -> TokenStream {
        if constant { self.active(value) } else { value }
    }

    /// The value of an active node forward code has bound, for a partial
    /// derivative; marks the accumulators it reads as needed.
    fn value(&mut self, expr: &Expr) -> Option<TokenStream> {
        if !expr.class.is_active() {
            return self.constant(expr);
        }
        self.mark_needed(expr);
        Some(match &expr.kind {
            ExprKind::Paren(inner) => return self.value(inner),
            ExprKind::Cast { expr: inner, .. } if inner.class.is_active() => return self.value(inner),
            ExprKind::Param(ParamRef::Time, _) => name("t").into_token_stream(),
            _ => self.temp(expr).into_token_stream(),
        })
    }

    /// Emits code adding `g · ∂expr/∂(leaf)` to the adjoint of every leaf of
    /// `expr` that depends on `q`; `g` is a name or a literal.
    fn reverse(&mut self, expr: &Expr, g: TokenStream, out: &mut Vec<TokenStream>) -> Option<()> {
        if !self.depends_on_q(expr) {
            return Some(());
        }
        if let Some(chain) = self.product_chain(expr) {
            return self.reverse_chain(&chain, g, out);
        }
        match &expr.kind {
            ExprKind::Paren(inner) => self.reverse(inner, g, out),
            ExprKind::Cast { expr: inner, .. } => self.reverse(inner, g, out),
            ExprKind::Index { base, index, .. } => {
                let adjoint = match base.kind {
                    ExprKind::Param(ParamRef::Q, _) => name("out"),
                    ExprKind::Param(ParamRef::V, _) if self.with_v => name("out_v"),
                    _ => return Some(()),
                };
                let literal = integer_literal(index);
                let index = self.constant(index)?;
                let key = (matches!(base.kind, ExprKind::Param(ParamRef::V, _)), literal.unwrap_or(u32::MAX));
                let g = self.as_active(&g);
                match self.assigned.as_mut() {
                    Some(assigned) if literal.is_some() && !assigned.contains(&key) => {
                        assigned.push(key);
                        out.push(quote!(#adjoint[#index] = #g;));
                    }
                    _ => out.push(quote!(#adjoint[#index] += #g;)),
                }
                Some(())
            }
            ExprKind::Local(id, _) => {
                let version = self.version(expr);
                let adjoint = adjoint_name(*id, version);
                match self.pending.iter().position(|p| *p == (*id, version)) {
                    // A first contribution that is a constant: the adjoint
                    // is that constant until another one arrives.
                    Some(position) if self.is_constant(&g) => {
                        self.pending.remove(position);
                        self.aliases.push(((*id, version), g));
                    }
                    Some(position) => {
                        self.pending.remove(position);
                        let ty = self.ty();
                        out.push(quote!(let mut #adjoint: #ty = #g;));
                    }
                    None => {
                        self.materialize(*id, version, out);
                        let g = self.as_active(&g);
                        out.push(quote!(#adjoint += #g;));
                    }
                }
                Some(())
            }
            ExprKind::Unary { op: UnOp::Neg(_), expr: inner } => {
                let g = self.negate(&g, out);
                self.reverse(inner, g, out)
            }
            ExprKind::Binary { lhs, op, rhs } => {
                let (a, b) = (self.depends_on_q(lhs), self.depends_on_q(rhs));
                match op {
                    BinOp::Add(_) => {
                        self.reverse(lhs, g.clone(), out)?;
                        self.reverse(rhs, g, out)
                    }
                    BinOp::Sub(_) => {
                        self.reverse(lhs, g.clone(), out)?;
                        if b {
                            let g = self.negate(&g, out);
                            self.reverse(rhs, g, out)?;
                        }
                        Some(())
                    }
                    BinOp::Mul(_) => {
                        if a {
                            let y = self.value(rhs)?;
                            let g = self.times(&g, y, rhs.class.is_active(), out);
                            self.reverse(lhs, g, out)?;
                        }
                        if b {
                            let x = self.value(lhs)?;
                            let g = self.times(&g, x, lhs.class.is_active(), out);
                            self.reverse(rhs, g, out)?;
                        }
                        Some(())
                    }
                    // `c / √s` (a potential `μ / r`): the adjoint of `s` is
                    // `−c·g / (2 s √s)`, one division instead of the
                    // quotient's and the square root's one each.
                    BinOp::Div(_) if !lhs.class.is_active() && self.square_root(rhs).is_some() => {
                        let (root, s) = (self.value(rhs)?, self.square_root(rhs)?);
                        let (c, s_value) = (self.constant(lhs)?, self.value(s)?);
                        let scaled = self.times(&g, quote!((-0.5f64 * #c)), false, out);
                        let scaled = self.as_active(&scaled);
                        let g = self.bind(quote!(#scaled / (#s_value * #root)), out);
                        self.reverse(s, g, out)
                    }
                    BinOp::Div(_) => {
                        let y = self.value(rhs)?;
                        if a {
                            // `g / c` of a constant `c` is a constant too.
                            let g = match (self.is_constant(&g), rhs.class.is_active()) {
                                (true, false) => self.bind_constant(quote!(#g / #y), out),
                                _ => {
                                    let g = self.as_active(&g);
                                    self.bind(quote!(#g / #y), out)
                                }
                            };
                            self.reverse(lhs, g, out)?;
                        }
                        if b {
                            let quotient = self.value(expr)?;
                            let product = match self.is_constant(&g) && self.generic {
                                true => quote!(#quotient * #g),
                                false => quote!(#g * #quotient),
                            };
                            let g = self.bind(quote!(-(#product) / #y), out);
                            self.reverse(rhs, g, out)?;
                        }
                        Some(())
                    }
                    _ => None,
                }
            }
            ExprKind::MethodCall { receiver, method, math, args, .. } => {
                let rule = Rule::of(&method.to_string(), *math, args)?;
                // Generic code: the operands of `atan2` and `mul_add` as
                // active values, as the forward code passed them.
                let uniform = self.generic && matches!(rule, Rule::Atan2 | Rule::MulAdd);
                let x = self.value(receiver)?;
                let x = self.active_if(uniform && !receiver.class.is_active(), x);
                let y = self.value(expr)?;
                let mut operands = Vec::with_capacity(args.len());
                for arg in args {
                    let value = self.value(arg)?;
                    operands.push(self.active_if(uniform && !arg.class.is_active(), value));
                }
                let partials = match rule {
                    // The other half of the forward sweep's `sin_cos`.
                    Rule::Unary(Unary::Sin) => vec![Some(self.sin_cos(expr).1.to_token_stream())],
                    Rule::Unary(Unary::Cos) => {
                        let sin = self.sin_cos(expr).0;
                        vec![Some(quote!(-#sin))]
                    }
                    _ if self.generic => rule.generic_partials(&x, &y, &operands),
                    _ => rule.partials(&x, &y, &operands),
                };
                let operands = std::iter::once(&**receiver).chain(args);
                for (operand, partial) in operands.zip(partials) {
                    if let Some(partial) = partial
                        && self.depends_on_q(operand)
                    {
                        let g = self.times(&g, quote!((#partial)), true, out);
                        self.reverse(operand, g, out)?;
                    }
                }
                Some(())
            }
            _ => None,
        }
    }

    /// `s` when `expr` is `s.sqrt()` (in parentheses or not).
    fn square_root<'e>(&self, expr: &'e Expr) -> Option<&'e Expr> {
        match &expr.kind {
            ExprKind::Paren(inner) => self.square_root(inner),
            ExprKind::MethodCall { receiver, method, math, args, .. }
                if matches!(Rule::of(&method.to_string(), *math, args), Some(Rule::Unary(Unary::Sqrt))) =>
            {
                Some(receiver)
            }
            _ => None,
        }
    }

    /// The product chain rooted at `expr` (`c * d * d / k`, any association
    /// of `*` and of `/` by constants) when folding it into one rule per
    /// distinct active factor pays: three factors or more, or an active
    /// factor that repeats. `None` otherwise (the node's own rule is as
    /// cheap: `c * x`, `x * y`, `x / c`).
    fn product_chain<'e>(&self, expr: &'e Expr) -> Option<Chain<'e>> {
        if !matches!(expr.kind, ExprKind::Binary { op: BinOp::Mul(_) | BinOp::Div(_), .. }) {
            return None;
        }
        let mut chain = Chain { numerator: Vec::new(), denominator: Vec::new(), bases: Vec::new() };
        self.flatten(expr, &mut chain);
        let factors =
            chain.numerator.len() + chain.denominator.len() + chain.bases.iter().map(|b| b.1 as usize).sum::<usize>();
        (factors >= 3 || chain.bases.iter().any(|b| b.1 > 1)).then_some(chain)
    }

    /// Collects the factors of a product into `chain`.
    fn flatten<'e>(&self, expr: &'e Expr, chain: &mut Chain<'e>) {
        match &expr.kind {
            _ if !expr.class.is_active() => chain.numerator.push(expr),
            ExprKind::Paren(inner) => self.flatten(inner, chain),
            ExprKind::Binary { lhs, op: BinOp::Mul(_), rhs } => {
                self.flatten(lhs, chain);
                self.flatten(rhs, chain);
            }
            ExprKind::Binary { lhs, op: BinOp::Div(_), rhs } if !rhs.class.is_active() => {
                self.flatten(lhs, chain);
                chain.denominator.push(rhs);
            }
            // `x.powi(4)` in a product is `x` four times (its own rule would
            // multiply by `4` and by the chain's constants separately).
            ExprKind::MethodCall { receiver, math: Math::Powi, args, .. }
                if let Some(n) = args.first().and_then(integer_literal).filter(|n| *n >= 1) =>
            {
                add_base(self, chain, receiver, n);
            }
            _ => add_base(self, chain, expr, 1),
        }

        /// Reads of the same value (a local's version, `q[i]` at the same
        /// index) are one factor with a multiplicity.
        fn add_base<'e>(this: &Adjoint<'_>, chain: &mut Chain<'e>, expr: &'e Expr, n: u32) {
            let key = this.leaf_key(expr);
            match chain.bases.iter_mut().find(|(base, _)| key.is_some() && this.leaf_key(base) == key) {
                Some((_, k)) => *k += n,
                None => chain.bases.push((expr, n)),
            }
        }
    }

    /// What identifies the value of a leaf: a local's version, `q[i]` or
    /// `v[i]` at an index printed the same, `t`. `None` for other nodes.
    fn leaf_key(&self, expr: &Expr) -> Option<String> {
        match &expr.kind {
            ExprKind::Paren(inner) => self.leaf_key(inner),
            ExprKind::Local(id, _) => Some(format!("l{}_{}", id.0, self.version(expr))),
            ExprKind::Param(ParamRef::Time, _) => Some("t".into()),
            ExprKind::Index { base, index, .. } => {
                let param = match base.kind {
                    ExprKind::Param(ParamRef::Q, _) => "q",
                    ExprKind::Param(ParamRef::V, _) => "v",
                    _ => return None,
                };
                Some(format!("{param}[{}]", self.constant(index)?))
            }
            _ => None,
        }
    }

    /// The reverse code of a product chain `C · Π bⱼ^kⱼ` (`C` the constant
    /// factors): the adjoint of `bⱼ` gets `g · (kⱼ·C) · bⱼ^(kⱼ−1) · Π_{i≠j}
    /// bᵢ^kᵢ`, with powers by squaring (`d³ = d²·d`), the constant product
    /// formed once (a loop invariant) and no partial product of the chain
    /// as written. The derivative may differ from the node-by-node rule by
    /// rounding (a few ulps), not the primal value, which the forward code
    /// computes as written where it is read.
    fn reverse_chain(&mut self, chain: &Chain<'_>, g: TokenStream, out: &mut Vec<TokenStream>) -> Option<()> {
        let numerator = chain.numerator.iter().map(|c| self.constant(c)).collect::<Option<Vec<_>>>()?;
        let denominator = chain.denominator.iter().map(|c| self.constant(c)).collect::<Option<Vec<_>>>()?;
        let mut values = Vec::with_capacity(chain.bases.len());
        for (base, _) in &chain.bases {
            values.push(self.value(base)?);
        }
        let mut powers = HashMap::new();
        // `Π_{i≠j} bᵢ^kᵢ` from products of the powers before and after `j`.
        let m = chain.bases.len();
        let (mut before, mut after): (Vec<Option<TokenStream>>, Vec<Option<TokenStream>>) =
            (vec![None; m + 1], vec![None; m + 1]);
        for (j, &(base, k)) in chain.bases.iter().enumerate() {
            if !self.depends_on_q(base) {
                continue;
            }
            let constant = chain_constant(k, &numerator, &denominator);
            let mut actives = Vec::new();
            if let Some(power) = self.power(j, &values[j], k - 1, &mut powers, out) {
                actives.push(power);
            }
            actives.extend(
                [self.prefix(j, chain, &values, &mut before, &mut powers, out), {
                    self.suffix(j + 1, chain, &values, &mut after, &mut powers, out)
                }]
                .into_iter()
                .flatten(),
            );
            let factor = if self.loop_depth > 0 || self.is_constant(&g) {
                // In a loop `g` is usually an accumulator's adjoint, the
                // same at every iteration: `g · C` is then formed once; a
                // constant `g` (`−1` of a subtraction) folds into `C`.
                let mut factor = g.clone();
                if let Some(constant) = constant {
                    factor = self.times(&factor, constant, false, out);
                }
                for x in actives {
                    factor = self.times(&factor, x, true, out);
                }
                factor
            } else {
                // Straight-line code: `g` arrives last (the reverse sweep
                // runs after the forward one), so the partial derivative is
                // formed from the values first and `g` multiplies it once,
                // one product on the path from `L` to the gradient instead
                // of one per factor.
                let product = actives.into_iter().reduce(|p, x| self.bind(quote!(#p * #x), out));
                match (product, constant) {
                    (Some(p), Some(c)) => {
                        let p = self.bind(quote!(#p * #c), out);
                        self.times(&g, p, true, out)
                    }
                    (Some(p), None) => self.times(&g, p, true, out),
                    (None, Some(c)) => self.times(&g, c, false, out),
                    (None, None) => g.clone(),
                }
            };
            self.reverse(base, factor, out)?;
        }
        Some(())
    }

    /// `Π_{i<j} bᵢ^kᵢ` (`None`: empty), bound once per chain.
    fn prefix(
        &mut self,
        j: usize,
        chain: &Chain<'_>,
        values: &[TokenStream],
        memo: &mut [Option<TokenStream>],
        powers: &mut HashMap<(usize, u32), TokenStream>,
        out: &mut Vec<TokenStream>,
    ) -> Option<TokenStream> {
        if j == 0 {
            return None;
        }
        if memo[j].is_none() {
            let last = self.power(j - 1, &values[j - 1], chain.bases[j - 1].1, powers, out)?;
            memo[j] = Some(match self.prefix(j - 1, chain, values, memo, powers, out) {
                Some(rest) => self.bind(quote!(#rest * #last), out),
                None => last,
            });
        }
        memo[j].clone()
    }

    /// `Π_{i≥j} bᵢ^kᵢ` (`None`: empty), bound once per chain.
    fn suffix(
        &mut self,
        j: usize,
        chain: &Chain<'_>,
        values: &[TokenStream],
        memo: &mut [Option<TokenStream>],
        powers: &mut HashMap<(usize, u32), TokenStream>,
        out: &mut Vec<TokenStream>,
    ) -> Option<TokenStream> {
        if j >= chain.bases.len() {
            return None;
        }
        if memo[j].is_none() {
            let first = self.power(j, &values[j], chain.bases[j].1, powers, out)?;
            memo[j] = Some(match self.suffix(j + 1, chain, values, memo, powers, out) {
                Some(rest) => self.bind(quote!(#first * #rest), out),
                None => first,
            });
        }
        memo[j].clone()
    }

    /// `x^n` for the chain's base `j` (`None` for `n = 0`), by squaring,
    /// each power bound once per chain.
    fn power(
        &mut self,
        j: usize,
        x: &TokenStream,
        n: u32,
        powers: &mut HashMap<(usize, u32), TokenStream>,
        out: &mut Vec<TokenStream>,
    ) -> Option<TokenStream> {
        match n {
            0 => None,
            1 => Some(x.clone()),
            _ => {
                if let Some(power) = powers.get(&(j, n)) {
                    return Some(power.clone());
                }
                let power = if n.is_multiple_of(2) {
                    let half = self.power(j, x, n / 2, powers, out)?;
                    self.bind(quote!(#half * #half), out)
                } else {
                    let lower = self.power(j, x, n - 1, powers, out)?;
                    self.bind(quote!(#lower * #x), out)
                };
                powers.insert((j, n), power.clone());
                Some(power)
            }
        }
    }

    /// A constant (or integer) expression, printed as the user wrote it in
    /// `f64`, in parentheses; locals by their generated names.
    fn constant(&self, expr: &Expr) -> Option<TokenStream> {
        if expr.class.is_active() {
            return None;
        }
        let (q, v) = (name("q"), name("v"));
        let printed = match &expr.kind {
            ExprKind::Lit(lit) => lit.to_token_stream(),
            ExprKind::Path(path) => path.to_token_stream(),
            ExprKind::SelfValue(token) => token.to_token_stream(),
            ExprKind::Param(ParamRef::Q, _) => name("q").into_token_stream(),
            // At rest there is no `v` to pass.
            ExprKind::Param(ParamRef::V, _) if self.finite => return None,
            ExprKind::Param(ParamRef::V, _) => name("v").into_token_stream(),
            ExprKind::Param(ParamRef::Time, _) => return None,
            ExprKind::Local(id, _) => local_name(*id, 0).into_token_stream(),
            ExprKind::Field { base, member } => {
                let base = self.constant(base)?;
                quote!(#base.#member)
            }
            ExprKind::Index { base, index, .. } => {
                let (base, index) = (self.constant(base)?, self.constant(index)?);
                quote!(#base[#index])
            }
            ExprKind::Unary { op, expr } => {
                let expr = self.constant(expr)?;
                quote!(#op #expr)
            }
            ExprKind::Binary { lhs, op, rhs } => {
                let (lhs, rhs) = (self.constant(lhs)?, self.constant(rhs)?);
                quote!(#lhs #op #rhs)
            }
            ExprKind::Cast { expr, ty } => {
                let expr = self.constant(expr)?;
                quote!(#expr as #ty)
            }
            ExprKind::Paren(inner) => return self.constant(inner),
            // `q.len()`: the receiver is an (active) array, the length is not.
            ExprKind::MethodCall { receiver, math: Math::Len, .. } => match receiver.kind {
                ExprKind::Param(ParamRef::Q, _) => quote!(#q.len()),
                // At rest `v` is not passed; it is as long as `q`.
                ExprKind::Param(ParamRef::V, _) if self.finite => quote!(#q.len()),
                ExprKind::Param(ParamRef::V, _) => quote!(#v.len()),
                // `self.u.len()`, a field's.
                ExprKind::Field { .. } => {
                    let receiver = self.constant(receiver)?;
                    quote!(#receiver.len())
                }
                _ => return None,
            },
            ExprKind::MethodCall { receiver, method, args, path, .. } => {
                let receiver = self.constant(receiver)?;
                let args = args.iter().map(|arg| self.constant(arg)).collect::<Option<Vec<_>>>()?;
                match path {
                    Some(path) => quote!(#path(#receiver #(, #args)*)),
                    None => quote!(#receiver.#method(#(#args),*)),
                }
            }
            _ => return None,
        };
        Some(quote!((#printed)))
    }
}

/// A product `C · Π bⱼ^kⱼ` read off a chain of `*` and of `/` by
/// constants.
struct Chain<'e> {
    /// The constant factors, multiplied.
    numerator: Vec<&'e Expr>,
    /// The constant divisors.
    denominator: Vec<&'e Expr>,
    /// The distinct active factors with their multiplicities, in the order
    /// they appear.
    bases: Vec<(&'e Expr, u32)>,
}

/// Whether `block` has no loop and reads `q` and `v` only at integer
/// literals: then every `__out[i]` the reverse sweep writes is known by its
/// literal, and a first write may assign.
fn literal_leaves_only(block: &Block) -> bool {
    let mut only = true;
    block.visit(&mut |e: &Expr| {
        match &e.kind {
            ExprKind::For { .. } => only = false,
            ExprKind::Index { base, index, .. }
                if matches!(base.kind, ExprKind::Param(ParamRef::Q | ParamRef::V, _))
                    && integer_literal(index).is_none() =>
            {
                only = false;
            }
            _ => {}
        }
        only
    });
    only
}

/// The value of an integer literal (in parentheses or not): the exponent
/// of `powi`, an index.
fn integer_literal(expr: &Expr) -> Option<u32> {
    match &expr.kind {
        ExprKind::Paren(inner) => integer_literal(inner),
        ExprKind::Lit(syn::Lit::Int(int)) => int.base10_parse().ok(),
        _ => None,
    }
}

/// `x^k` for `k ≥ 1` as products by squaring: `x^2j = x^j · x^j`,
/// `x^(2j+1) = x^2j · x` (the repeated `x^j` the compiler computes once).
fn power_by_squaring(x: &TokenStream, k: u32) -> TokenStream {
    match k {
        1 => x.clone(),
        _ if k.is_multiple_of(2) => {
            let half = power_by_squaring(x, k / 2);
            quote!((#half * #half))
        }
        _ => {
            let even = power_by_squaring(x, k - 1);
            quote!((#even * #x))
        }
    }
}

/// `k · C` as one constant expression (`None` when it is one: `k = 1`, no
/// constant factor): `(k · c₁ · c₂ …) / (d₁ · d₂ …)`, the literal `k` first
/// so that `4.0 * 0.25` folds at compile time.
fn chain_constant(k: u32, numerator: &[TokenStream], denominator: &[TokenStream]) -> Option<TokenStream> {
    let k = (k > 1).then(|| {
        let k = proc_macro2::Literal::f64_suffixed(f64::from(k));
        quote!(#k)
    });
    let factors: Vec<TokenStream> = k.into_iter().chain(numerator.iter().cloned()).collect();
    let product = factors.split_first().map(|(first, rest)| quote!(#first #(* #rest)*));
    let divisor = denominator.split_first().map(|(first, rest)| quote!(#first #(* #rest)*));
    match (product, divisor) {
        (None, None) => None,
        (Some(product), None) => Some(quote!((#product))),
        (product, Some(divisor)) => {
            let product = product.unwrap_or_else(|| quote!(1.0f64));
            Some(quote!((#product / (#divisor))))
        }
    }
}

/// The derivative rule of a supported method.
#[derive(Clone, Copy)]
enum Rule {
    /// `f(x)` with `f'` a function of `x` and `y = f(x)`.
    Unary(Unary),
    /// `x.powi(n)`, `x.powf(c)`, `x.log(b)` with a constant second operand.
    Powi,
    Powf,
    Log,
    /// `y.atan2(x)`.
    Atan2,
    /// `x.mul_add(a, b)`.
    MulAdd,
}

#[derive(Clone, Copy)]
enum Unary {
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    Sinh,
    Cosh,
    Tanh,
    Asinh,
    Acosh,
    Atanh,
    Exp,
    Exp2,
    ExpM1,
    Ln,
    Ln1p,
    Log2,
    Log10,
    Sqrt,
    Cbrt,
    Abs,
    Recip,
}

impl Rule {
    /// The rule for `receiver.method(args)`, or `None` when this stage does
    /// not differentiate it (an active exponent, `signum`).
    fn of(method: &str, math: Math, args: &[Expr]) -> Option<Rule> {
        let constant_args = args.iter().all(|arg| !arg.class.is_active());
        Some(match (math, method) {
            (Math::Powi, _) if constant_args => Rule::Powi,
            (Math::Powf, _) if constant_args => Rule::Powf,
            (Math::Log, _) if constant_args => Rule::Log,
            (Math::Uniform, "atan2") => Rule::Atan2,
            (Math::Uniform, "mul_add") => Rule::MulAdd,
            (Math::Plain, name) => Rule::Unary(match name {
                "sin" => Unary::Sin,
                "cos" => Unary::Cos,
                "tan" => Unary::Tan,
                "asin" => Unary::Asin,
                "acos" => Unary::Acos,
                "atan" => Unary::Atan,
                "sinh" => Unary::Sinh,
                "cosh" => Unary::Cosh,
                "tanh" => Unary::Tanh,
                "asinh" => Unary::Asinh,
                "acosh" => Unary::Acosh,
                "atanh" => Unary::Atanh,
                "exp" => Unary::Exp,
                "exp2" => Unary::Exp2,
                "exp_m1" => Unary::ExpM1,
                "ln" => Unary::Ln,
                "ln_1p" => Unary::Ln1p,
                "log2" => Unary::Log2,
                "log10" => Unary::Log10,
                "sqrt" => Unary::Sqrt,
                "cbrt" => Unary::Cbrt,
                "abs" => Unary::Abs,
                "recip" => Unary::Recip,
                _ => return None,
            }),
            _ => return None,
        })
    }

    /// The partial derivatives of `y = x.method(args)` with respect to `x`
    /// and each argument (`None`: a constant operand).
    fn partials(self, x: &TokenStream, y: &TokenStream, args: &[TokenStream]) -> Vec<Option<TokenStream>> {
        let unary = |d: TokenStream| vec![Some(d)];
        match self {
            Rule::Unary(f) => unary(match f {
                Unary::Sin => quote!(f64::cos(#x)),
                Unary::Cos => quote!(-f64::sin(#x)),
                Unary::Tan => quote!(1.0f64 + #y * #y),
                Unary::Asin => quote!(1.0f64 / f64::sqrt(1.0f64 - #x * #x)),
                Unary::Acos => quote!(-1.0f64 / f64::sqrt(1.0f64 - #x * #x)),
                Unary::Atan => quote!(1.0f64 / (1.0f64 + #x * #x)),
                Unary::Sinh => quote!(f64::cosh(#x)),
                Unary::Cosh => quote!(f64::sinh(#x)),
                Unary::Tanh => quote!(1.0f64 - #y * #y),
                Unary::Asinh => quote!(1.0f64 / f64::sqrt(#x * #x + 1.0f64)),
                Unary::Acosh => quote!(1.0f64 / f64::sqrt(#x * #x - 1.0f64)),
                Unary::Atanh => quote!(1.0f64 / (1.0f64 - #x * #x)),
                Unary::Exp => quote!(#y),
                Unary::Exp2 => quote!(#y * ::core::f64::consts::LN_2),
                Unary::ExpM1 => quote!(#y + 1.0f64),
                Unary::Ln => quote!(1.0f64 / #x),
                Unary::Ln1p => quote!(1.0f64 / (1.0f64 + #x)),
                Unary::Log2 => quote!(1.0f64 / (#x * ::core::f64::consts::LN_2)),
                Unary::Log10 => quote!(1.0f64 / (#x * ::core::f64::consts::LN_10)),
                Unary::Sqrt => quote!(0.5f64 / #y),
                Unary::Cbrt => quote!(1.0f64 / (3.0f64 * #y * #y)),
                // num-dual's `abs` takes the sign of the value, `+1` at zero.
                Unary::Abs => quote!(f64::signum(#x)),
                Unary::Recip => quote!(-(#y * #y)),
            }),
            Rule::Powi => {
                let n = &args[0];
                // `0 · x⁻¹` would be NaN at `x = 0`.
                vec![
                    Some(quote!(match #n { 0 => 0.0f64, 1 => 1.0f64, n => f64::from(n) * f64::powi(#x, n - 1) })),
                    None,
                ]
            }
            Rule::Powf => {
                let c = &args[0];
                vec![Some(quote!(if #c == 0.0f64 { 0.0f64 } else { #c * f64::powf(#x, #c - 1.0f64) })), None]
            }
            Rule::Log => {
                let base = &args[0];
                vec![Some(quote!(1.0f64 / (#x * f64::ln(#base)))), None]
            }
            Rule::Atan2 => {
                // `y = x.atan2(r)` is the angle of the point `(r, x)`.
                let r = &args[0];
                vec![Some(quote!(#r / (#x * #x + #r * #r))), Some(quote!(-#x / (#x * #x + #r * #r)))]
            }
            Rule::MulAdd => {
                vec![Some(args[0].clone()), Some(x.clone()), Some(quote!(1.0f64))]
            }
        }
    }

    /// [`partials`](Self::partials) generic over the scalar `__D`: the same
    /// IEEE operations at `__D = f64` (`1 + y²` written `y² + 1`, which is
    /// exact), methods called on the value, `f64` constants made active
    /// where they would stand left of an active operand. `x` and the
    /// arguments of `atan2` and `mul_add` are active values.
    fn generic_partials(self, x: &TokenStream, y: &TokenStream, args: &[TokenStream]) -> Vec<Option<TokenStream>> {
        let d = scalar();
        let one = quote!(#d::from(1.0f64));
        let unary = |d: TokenStream| vec![Some(d)];
        match self {
            Rule::Unary(f) => unary(match f {
                Unary::Sin => quote!(#x.cos()),
                Unary::Cos => quote!(-#x.sin()),
                Unary::Tan => quote!(#y * #y + 1.0f64),
                Unary::Asin => quote!(#one / (#one - #x * #x).sqrt()),
                Unary::Acos => quote!(-#one / (#one - #x * #x).sqrt()),
                Unary::Atan => quote!(#one / (#x * #x + 1.0f64)),
                Unary::Sinh => quote!(#x.cosh()),
                Unary::Cosh => quote!(#x.sinh()),
                Unary::Tanh => quote!(#one - #y * #y),
                Unary::Asinh => quote!(#one / (#x * #x + 1.0f64).sqrt()),
                Unary::Acosh => quote!(#one / (#x * #x - 1.0f64).sqrt()),
                Unary::Atanh => quote!(#one / (#one - #x * #x)),
                Unary::Exp => quote!(#y),
                Unary::Exp2 => quote!(#y * ::core::f64::consts::LN_2),
                Unary::ExpM1 => quote!(#y + 1.0f64),
                Unary::Ln => quote!(#one / #x),
                Unary::Ln1p => quote!(#one / (#x + 1.0f64)),
                Unary::Log2 => quote!(#one / (#x * ::core::f64::consts::LN_2)),
                Unary::Log10 => quote!(#one / (#x * ::core::f64::consts::LN_10)),
                Unary::Sqrt => quote!(#d::from(0.5f64) / #y),
                Unary::Cbrt => quote!(#one / (#d::from(3.0f64) * #y * #y)),
                // The sign of the value, a constant: `abs` is linear away
                // from zero (num-dual's `abs` takes `+1` at zero too).
                Unary::Abs => quote!(#d::from(f64::signum(#x.re()))),
                Unary::Recip => quote!(-(#y * #y)),
            }),
            Rule::Powi => {
                let n = &args[0];
                vec![
                    Some(quote!(match #n { 0 => #d::from(0.0f64), 1 => #one, n => #x.powi(n - 1) * f64::from(n) })),
                    None,
                ]
            }
            Rule::Powf => {
                let c = &args[0];
                vec![Some(quote!(if #c == 0.0f64 { #d::from(0.0f64) } else { #x.powf(#c - 1.0f64) * #c })), None]
            }
            Rule::Log => {
                let base = &args[0];
                vec![Some(quote!(#one / (#x * f64::ln(#base)))), None]
            }
            Rule::Atan2 => {
                let r = &args[0];
                vec![Some(quote!(#r / (#x * #x + #r * #r))), Some(quote!(-#x / (#x * #x + #r * #r)))]
            }
            Rule::MulAdd => {
                vec![Some(args[0].clone()), Some(x.clone()), Some(one)]
            }
        }
    }
}

/// The name of one version of a local in the generated code.
fn local_name(id: LocalId, version: usize) -> proc_macro2::Ident {
    format_ident!("__l{}_{}", id.0, version)
}

/// The name of the `lane`-th partial sum of an accumulator in a
/// reassociated loop ([`Adjoint::reassociated_loop`]).
fn partial_name(id: LocalId, lane: usize) -> proc_macro2::Ident {
    format_ident!("__s{}_{}", id.0, lane)
}

/// Whether [`Adjoint::reassociated_loop`] can print a loop: a half-open
/// range and a body of `let`s and accumulations without nested loops (a
/// nested loop's iterations would be reassociated with the outer ones').
fn reassociable(limits: &syn::RangeLimits, body: &Block) -> bool {
    matches!(limits, syn::RangeLimits::HalfOpen(_))
        && body.stmts.iter().all(|stmt| match stmt {
            Stmt::Let { .. } => true,
            Stmt::Expr { expr, .. } => matches!(expr.kind, ExprKind::Assign { .. }),
            Stmt::Item(_) => false,
        })
}

/// The name of the adjoint of one version of a local.
fn adjoint_name(id: LocalId, version: usize) -> proc_macro2::Ident {
    format_ident!("__a{}_{}", id.0, version)
}

/// `for var in start..end { … }` as chunks of [`PARTIAL_SUMS`] iterations,
/// the `k`-th of a chunk running `lanes[k]` with `var` bound to its index,
/// then the iterations left over, each running `rest`. A chunk runs while
/// `end − base ≥ 4`: the compiler reads that condition and drops the bounds
/// checks of `q[i + 1]` in the chunk at a run-time size `end = q.len() − 1`,
/// which it could not from a count of chunks `(end − start) / 4` (the FPU-β
/// chain's force at `N = 1000`, on slices: 23 800 instructions with the
/// checks, 13 600 without, as many as on arrays).
fn chunked_loop(
    var: &TokenStream,
    (start, end): (&TokenStream, &TokenStream),
    lanes: &[TokenStream],
    rest: &TokenStream,
) -> TokenStream {
    let lanes = lanes.iter().enumerate().map(|(lane, body)| {
        // Unsuffixed: the loop variable keeps the type the range gives it.
        let offset = proc_macro2::Literal::usize_unsuffixed(lane);
        let index = if lane == 0 { quote!(__base) } else { quote!(__base + #offset) };
        quote!({
            let #var = #index;
            #body
        })
    });
    let width = proc_macro2::Literal::usize_unsuffixed(PARTIAL_SUMS);
    quote! {
        let (__start, __end) = (#start, #end);
        let mut __base = __start;
        while __base < __end && __end - __base >= #width {
            #(#lanes)*
            __base += #width;
        }
        for #var in __base..__end {
            #rest
        }
    }
}

fn loop_var(id: Option<LocalId>) -> TokenStream {
    match id {
        Some(id) => local_name(id, 0).into_token_stream(),
        None => quote!(_),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ctxt::Ctxt;
    use crate::parse::Input;
    use syn::{ItemImpl, parse_quote};

    /// The generated `gradient_q` body for `item`'s Lagrangian, as a string.
    fn gradient(item: &ItemImpl) -> Option<String> {
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(item)).unwrap();
        let _ = crate::analyse::analyse(&cx, &mut system);
        cx.check().unwrap();
        gradient_q(&system.lagrangian).map(|body| body.to_string())
    }

    fn lagrangian(body: syn::Block) -> Option<String> {
        gradient(&parse_quote! {
            impl P { fn lagrangian(&self, t: f64, q: [f64; 3], v: [f64; 3]) -> f64 #body }
        })
    }

    #[test]
    fn straight_line_code_propagates_to_every_coordinate_it_reads() {
        let out = lagrangian(parse_quote!({
            let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
            0.5 * self.m * v[0] * v[0] + self.k / r - t * q[2].cos()
        }))
        .unwrap();
        // One contribution each: assigned, not added to the zero.
        for write in ["__out [(0)] =", "__out [(1)] =", "__out [(2)] ="] {
            assert!(out.contains(write), "{write}: {out}");
        }
        assert!(!out.contains("+="), "{out}");
        // The velocity term does not depend on `q`: its value is computed
        // (it is part of `L`), but no adjoint goes through it.
        let reverse = &out[out.find("let mut __a0_0").unwrap()..];
        assert!(!reverse.contains(". m"), "{out}");
        assert!(out.contains("f64 :: sqrt"), "{out}");
        // `cos` and its partial from one `sin_cos`.
        assert!(out.contains("f64 :: sin_cos (__t2)"), "{out}");
        assert!(out.contains("(- __t3_sin)"), "{out}");
        assert!(!out.contains("f64 :: sin ("), "{out}");
    }

    #[test]
    fn the_gradient_in_q_and_v_propagates_to_the_velocities_too() {
        let item: ItemImpl = parse_quote! {
            impl P {
                fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
                    let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
                    0.5 * self.m * v[0] * v[0] + q[2] * v[1] + self.k / r
                }
            }
        };
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&item)).unwrap();
        let _ = crate::analyse::analyse(&cx, &mut system);
        cx.check().unwrap();
        let out = gradient_qv(&system.lagrangian).unwrap().to_string();
        for write in ["__out [(0)] =", "__out [(1)] =", "__out [(2)] =", "__out_v [(0)] =", "__out_v [(1)] ="] {
            assert!(out.contains(write), "{write}: {out}");
        }
        // `v[2]` is not read: its derivative stays the zero written first.
        assert!(!out.contains("__out_v [(2)]"), "{out}");
        assert!(out.contains("for __x in __out_v . iter_mut ()"), "{out}");
        // The q-only transformation writes no velocity adjoint.
        let q_only = gradient_q(&system.lagrangian).unwrap().to_string();
        assert!(!q_only.contains("__out_v"), "{q_only}");
    }

    #[test]
    fn a_lagrangian_of_velocities_only_has_a_zero_gradient() {
        let out = lagrangian(parse_quote!({ 0.5 * v[0] * v[0] })).unwrap();
        assert!(!out.contains("__out [(0)] +="), "{out}");
        assert!(out.contains("* __x = 0.0f64"), "{out}");
    }

    #[test]
    fn loops_get_a_reverse_loop_and_no_forward_loop_when_only_the_sum_is_returned() {
        let chain: ItemImpl = parse_quote! {
            impl<const N: usize> Chain<N> {
                fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
                    let mut l = 0.0;
                    for i in 0..N {
                        l += 0.5 * v[i] * v[i];
                    }
                    for i in 0..N - 1 {
                        let d = q[i + 1] - q[i];
                        l -= 0.5 * d * d + self.beta / 4.0 * d.powi(4);
                    }
                    l
                }
            }
        };
        let out = gradient(&chain).unwrap();
        // Only the potential's loop, once, in the reverse sweep.
        assert_eq!(out.matches("for ").count(), 2, "{out}"); // zeroing `out` and the reverse loop
        assert!(out.contains("__out [((__l2_0) + (1))] +="), "{out}");
        assert!(out.contains("f64 :: powi"), "{out}");
    }

    #[test]
    fn the_form_at_rest_adds_to_out_and_reassociates_the_sums_only_the_value_reads() {
        let chain: ItemImpl = parse_quote! {
            impl<const N: usize> Chain<N> {
                fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
                    let mut kinetic = 0.0;
                    for i in 0..N {
                        kinetic += 0.5 * v[i] * v[i];
                    }
                    let mut s = 0.0;
                    for i in 0..N {
                        s += q[i] * q[i];
                    }
                    let mut potential = 0.5 * q[0] * q[0];
                    for i in 0..N - 1 {
                        let d = q[i + 1] - q[i];
                        potential -= 0.25 * d.powi(4);
                    }
                    for i in 0..=N - 1 {
                        potential += q[i];
                    }
                    kinetic - potential + s.sqrt()
                }
            }
        };
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&chain)).unwrap();
        let _ = crate::analyse::analyse(&cx, &mut system);
        cx.check().unwrap();
        let out = add_gradient_q_at_rest(&system.lagrangian).unwrap().to_string();
        // At rest: no velocity is read; `d.powi(4)` as products.
        assert!(!out.contains("__v ["), "{out}");
        assert!(out.contains("((__t6 * __t6) * (__t6 * __t6))"), "{out}");
        // Added to, never cleared or assigned.
        assert!(!out.contains("iter_mut"), "{out}");
        assert!(!out.contains("__out [(0)] ="), "{out}");
        // The kinetic sum (`kinetic` is local 0), which no reverse loop
        // reads, in a forward loop of four partial sums.
        for lane in 0..4 {
            assert!(out.contains(&format!("let mut __s0_{lane} : f64 = 0.0f64")), "{lane}: {out}");
        }
        assert!(out.contains("__l0_0 += (__s0_0 + __s0_1) + (__s0_2 + __s0_3)"), "{out}");
        // The quartic sum (`potential`, local 4) in the reverse loop's four
        // partial sums, which the value adds at the end; no forward loop.
        assert!(!out.contains("__s4_"), "{out}");
        for lane in 0..4 {
            assert!(out.contains(&format!("let mut __w0_{lane} : f64 = 0.0f64")), "{lane}: {out}");
            assert!(out.contains(&format!("__w0_{lane} = __w ;")), "{lane}: {out}");
        }
        assert_eq!(out.matches("__w -=").count(), 5, "{out}");
        assert!(out.trim_end().ends_with("__value + ((__w0_0 + __w0_1) + (__w0_2 + __w0_3))"), "{out}");
        // `s` (local 2), which the reverse sweep reads, and the inclusive
        // range in order.
        assert!(!out.contains("__s2_0"), "{out}");
        assert!(out.contains("__l2_0 +="), "{out}");
        assert!(out.contains("..= "), "{out}");
        // The kinetic forward loop and the fused reverse loop: chunks of
        // four, then the rest; `s` forward and reverse, the inclusive range
        // forward and reverse.
        assert_eq!(out.matches("while __base < __end && __end - __base >= 4").count(), 2, "{out}");
        assert_eq!(out.matches("for ").count(), 2 + 2 + 2, "{out}");
        // The value form of the same body clears `out` and sums in order.
        let value = value_gradient_q(&system.lagrangian).unwrap().to_string();
        assert!(value.contains("iter_mut") && !value.contains("__base"), "{value}");
    }

    #[test]
    fn a_sum_read_through_a_local_keeps_its_forward_loop() {
        // `r`'s derivative reads the value of `s` through `let r = s`.
        let out = lagrangian(parse_quote!({
            let mut s = 0.0;
            for i in 0..3 {
                s += q[i] * q[i];
            }
            let r = s;
            r.sqrt()
        }))
        .unwrap();
        assert_eq!(out.matches("for ").count(), 3, "{out}");
        assert!(out.contains("__l0_0 +="), "{out}");
    }

    #[test]
    fn a_sum_the_value_does_not_read_is_not_carried_at_rest() {
        // `unused` enters no term of `L`: its terms, NaN or not, leave the
        // value as it is.
        let chain: ItemImpl = parse_quote! {
            impl<const N: usize> Chain<N> {
                fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
                    let mut unused = 0.0;
                    let mut potential = 0.0;
                    for i in 0..N {
                        unused += q[i].ln();
                        potential += q[i] * q[i];
                    }
                    0.5 * v[0] * v[0] - potential
                }
            }
        };
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&chain)).unwrap();
        let _ = crate::analyse::analyse(&cx, &mut system);
        cx.check().unwrap();
        let out = add_gradient_q_at_rest(&system.lagrangian).unwrap().to_string();
        assert!(!out.contains("__w"), "{out}");
        assert!(out.contains("__s0_0 +="), "{out}");
    }

    #[test]
    fn a_sum_read_nonlinearly_keeps_its_forward_loop() {
        let out = lagrangian(parse_quote!({
            let mut s = 0.0;
            for i in 0..3 {
                s += q[i] * q[i];
            }
            s.sqrt()
        }))
        .unwrap();
        assert_eq!(out.matches("for ").count(), 3, "{out}");
    }

    #[test]
    fn nested_loops_and_loop_locals() {
        let out = lagrangian(parse_quote!({
            let mut e = 0.0;
            for i in 0..3 {
                let x = q[i];
                for j in 0..i {
                    let d = x - q[j];
                    e -= 1.0 / d.abs();
                }
            }
            e
        }))
        .unwrap();
        assert_eq!(out.matches("for ").count(), 3, "{out}");
    }

    #[test]
    fn outside_the_subset_there_is_no_gradient() {
        let refused: [syn::Block; 10] = [
            parse_quote!({ if self.on { q[0] } else { 0.0 } }),
            parse_quote!({
                let mut s = q[0];
                s *= q[1];
                s
            }),
            // A value carried into the next iteration, or out of the loop.
            parse_quote!({
                let mut s = 0.0;
                let mut left = 0.0;
                for i in 0..3 {
                    s += q[i] * left;
                    left = q[i];
                }
                s
            }),
            parse_quote!({
                let mut d = 0.0;
                for i in 0..3 {
                    d = q[i];
                }
                d * d
            }),
            // An accumulator read inside a loop: iterations depend on each other.
            parse_quote!({
                let mut s = 1.0;
                for i in 0..3 {
                    s += s * q[i];
                }
                s
            }),
            // An active exponent.
            parse_quote!({ self.b.powf(q[0]) }),
            // A mutable local inside a loop.
            parse_quote!({
                let mut s = 0.0;
                for i in 0..3 {
                    let mut x = q[i];
                    x += 1.0;
                    s += x;
                }
                s
            }),
            // Active arrays.
            parse_quote!({
                let x = [q[0], q[1]];
                x[0] * x[1]
            }),
            // A block and a `return`.
            parse_quote!({
                {
                    let a = q[0];
                    a * a
                }
            }),
            parse_quote!({
                return q[0];
            }),
        ];
        for body in refused {
            let text = body.to_token_stream().to_string();
            assert_eq!(lagrangian(body), None, "{text}");
        }
    }

    #[test]
    fn scratch_variables_assigned_before_they_are_read_get_one_name_per_assignment() {
        let out = lagrangian(parse_quote!({
            let mut d = q[0];
            let mut e = d * d;
            for i in 0..2 {
                d = q[i + 1] - q[i];
                e += d.powi(4);
            }
            d = q[2];
            e + d * d
        }))
        .unwrap();
        for version in ["let __l0_0 : f64", "let __l0_1 : f64", "let __l0_2 : f64"] {
            assert!(out.contains(version), "{version}: {out}");
        }
        // Nothing reads `e`'s value: no forward loop.
        assert_eq!(out.matches("for ").count(), 2, "{out}");
    }

    #[test]
    fn signum_is_not_differentiated_and_powf_with_a_constant_exponent_is() {
        assert_eq!(lagrangian(parse_quote!({ q[0].signum() * q[1] })), None);
        let out = lagrangian(parse_quote!({ q[0].powf(self.p) + q[1].log(10.0) + q[2].mul_add(t, q[1]) })).unwrap();
        assert!(out.contains("f64 :: powf"), "{out}");
    }

    /// The generic `gradient_qv_scalar` body for a three-coordinate `L`.
    fn generic(body: syn::Block) -> Option<String> {
        let item: ItemImpl = parse_quote! {
            impl P { fn lagrangian(&self, t: f64, q: [f64; 3], v: [f64; 3]) -> f64 #body }
        };
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&item)).unwrap();
        let _ = crate::analyse::analyse(&cx, &mut system);
        cx.check().unwrap();
        gradient_qv_generic(&system.lagrangian).map(|body| body.to_string())
    }

    #[test]
    fn the_value_version_keeps_every_forward_loop_and_returns_l() {
        let chain: ItemImpl = parse_quote! {
            impl<const N: usize> Chain<N> {
                fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
                    let mut l = 0.0;
                    for i in 0..N {
                        l += 0.5 * v[i] * v[i];
                    }
                    for i in 0..N - 1 {
                        let d = q[i + 1] - q[i];
                        l -= 0.5 * d * d + self.beta / 4.0 * d.powi(4);
                    }
                    l + q[0].cos()
                }
            }
        };
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&chain)).unwrap();
        let _ = crate::analyse::analyse(&cx, &mut system);
        cx.check().unwrap();
        let gradient = gradient_qv_generic(&system.lagrangian).unwrap().to_string();
        let out = value_gradient_qv_generic(&system.lagrangian).unwrap().to_string();
        // Zeroing both outputs, the reverse loops over both sums, and here
        // the two forward loops the value reads.
        assert_eq!(out.matches("for ").count(), gradient.matches("for ").count() + 2, "{out}");
        // The value, bound before the reverse sweep, is the body's last
        // expression; the gradient is the same code.
        let bound = out.find("let __value : __D =").expect(&out);
        assert!(bound < out.find("__out [(0)]").unwrap(), "{out}");
        assert!(out.trim_end().ends_with("__value"), "{out}");
        assert!(!gradient.contains("__value"), "{gradient}");
        // A value with a constant term.
        let item: ItemImpl = parse_quote! {
            impl P { fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 { 0.0 * q[0] + self.k } }
        };
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&item)).unwrap();
        let _ = crate::analyse::analyse(&cx, &mut system);
        cx.check().unwrap();
        let out = value_gradient_qv_generic(&system.lagrangian).unwrap().to_string();
        assert!(out.contains("let __value : __D ="), "{out}");
    }

    #[test]
    fn the_generic_gradient_is_printed_over_the_scalar_with_constants_in_f64() {
        let out = generic(parse_quote!({
            let mut l = 0.0;
            l += 2.0 - q[0].cos() + 3.0 * q[1] + self.k / q[2] + q[0].abs() - 0.5 * v[0] * v[0];
            l + t * q[1].sqrt() + q[2].powi(3)
        }))
        .unwrap();
        // Active values are `__D`, no `f64` function is called on them.
        for piece in [
            "let mut __l0_0 : __D = __D :: from ((0.0))",
            ". sin_cos ()",
            ". sqrt ()",
            ". powi (n - 1) * f64 :: from (n)",
            "__D :: from (f64 :: signum (",
            "* __x = __D :: from (0.0f64)",
            // First contributions assign, later ones add; a constant
            // adjoint is an `f64`, made active where it is stored.
            "__out [(1)] = __g",
            "__out [(1)] += __D :: from (__g",
            "__out_v [(0)] = __g",
            "let __g3 : f64 = - 1.0f64",
            "(- __t5_sin) * __g3",
        ] {
            assert!(out.contains(piece), "{piece}: {out}");
        }
        // Only constant adjoints are `f64` (`: f64 = - 1.0f64`, `(3.0)`),
        // never a value computed from `q` or `v`.
        for absent in [": f64 = __t", ": f64 = __q", "f64 :: cos", "f64 :: sin", "f64 :: sqrt", "f64 :: powi"] {
            assert!(!out.contains(absent), "{absent}: {out}");
        }
        // `c - x` keeps its order with `c` made active; `c * x` and `c / x`
        // become `x * c` (exact) and `D::from(c) / x`.
        assert!(out.contains("__D :: from ((2.0)) - __t"), "{out}");
        assert!(out.contains("* (3.0)"), "{out}");
        assert!(out.contains("__D :: from (((self) . k)) / __t"), "{out}");
        // The reverse sweep starts from the seed one, an `f64` constant.
        assert!(out.contains("- 1.0f64"), "{out}");
    }

    #[test]
    fn the_generic_gradient_makes_the_operands_of_atan2_and_mul_add_active() {
        let out = generic(parse_quote!({ self.y.atan2(q[0]) + q[1].mul_add(2.0, t) })).unwrap();
        assert!(out.contains("__D :: from (((self) . y)) . atan2 (__t"), "{out}");
        assert!(out.contains(". mul_add (__D :: from ((2.0)) , __t)"), "{out}");
        // The partial in the constant receiver's operand is active too.
        assert!(out.contains("- __D :: from (((self) . y)) /"), "{out}");
    }

    #[test]
    fn the_generic_and_the_f64_transformations_cover_the_same_bodies() {
        let bodies: [syn::Block; 3] = [
            parse_quote!({ if self.on { q[0] } else { 0.0 } }),
            parse_quote!({ self.b.powf(q[0]) }),
            parse_quote!({ q[0].sin() * v[1] }),
        ];
        for body in bodies {
            let text = body.to_token_stream().to_string();
            assert_eq!(lagrangian(body.clone()).is_some(), generic(body).is_some(), "{text}");
        }
    }

    /// The reverse sweep of `body`: what follows the adjoints' declarations
    /// (or the zeroing of `__out` when there are none).
    fn reverse_of(body: syn::Block) -> String {
        let out = lagrangian(body).unwrap();
        let start = ["let mut __a", "let __g"].iter().filter_map(|s| out.find(s)).min().unwrap();
        out[start..].to_string()
    }

    #[test]
    fn a_power_written_as_a_product_is_one_rule_with_its_constant_formed_once() {
        let reverse = reverse_of(parse_quote!({
            let d = q[1] - q[0];
            0.25 * self.beta * d * d * d * d
        }));
        // One contribution to `d`: `g · (4 · 0.25 · β) · d³`, `d³ = d² · d`,
        // not one per partial product of the chain.
        assert!(reverse.contains("let mut __a0_0 : f64 = __g"), "{reverse}");
        assert!(!reverse.contains("__a0_0 +="), "{reverse}");
        // `g` is the seed, a constant: the chain's constant is formed with
        // it first (and folds), then multiplies `d³`.
        assert!(reverse.contains("= (4f64 * ((0.25) * ((self) . beta)))"), "{reverse}");
        assert!(reverse.contains("= __t0 * __t0 ;"), "{reverse}");
        // No temporary of the forward sweep but `d`'s own is read: no
        // partial product of the chain.
        assert!(!reverse.contains("__t1"), "{reverse}");
    }

    #[test]
    fn repeated_factors_among_others_and_divisions_by_constants_fold() {
        let reverse = reverse_of(parse_quote!({ q[0] * q[1] * q[0] + q[2] * q[2] / self.c }));
        // `x·y·x`: `x` gets `g · 2 · x · y` once, `y` gets `g · x²`.
        assert_eq!(reverse.matches("__out [(0)] =").count(), 1, "{reverse}");
        assert_eq!(reverse.matches("__out [(1)] =").count(), 1, "{reverse}");
        // `z·z / c`: `g · (2 / c) · z`.
        assert_eq!(reverse.matches("__out [(2)] =").count(), 1, "{reverse}");
        assert!(!reverse.contains("+="), "{reverse}");
        assert!(reverse.contains("(2f64 / (((self) . c)))"), "{reverse}");
    }

    #[test]
    fn in_a_loop_every_output_adds_and_the_constant_meets_the_adjoint_first() {
        let reverse = reverse_of(parse_quote!({
            let mut s = 0.0;
            for i in 0..2 {
                let d = q[i + 1] - q[i];
                s += 0.25 * self.beta * d * d * d * d;
            }
            s + q[0] * q[0]
        }));
        // A loop may write any index: nothing is assigned, the zeroing
        // stays, and `g · C` comes first (`g`, the accumulator's adjoint, is
        // the same at every iteration). Here `g` is the seed, a constant:
        // the accumulator's adjoint is not a variable at all, and `g · C`
        // is a constant `f64` (folded at compile time).
        assert!(!reverse.contains("] = __"), "{reverse}");
        assert!(!reverse.contains("__a0_0"), "{reverse}");
        assert!(reverse.contains(": f64 = (4f64 * ((0.25) * ((self) . beta)))"), "{reverse}");
    }

    #[test]
    fn an_adjoint_is_bound_by_its_first_contribution_and_zero_only_before_a_loop_adds_to_it() {
        let reverse = reverse_of(parse_quote!({
            let x = q[0] * q[1];
            let mut s = x.sin();
            for i in 0..3 {
                s += x * q[i];
            }
            s
        }));
        // `s` gets its adjoint from the tail, the seed: a constant, no
        // variable; `x` is added to in the loop, so it exists (as zero)
        // before it.
        assert!(!reverse.contains("__a1_0"), "{reverse}");
        assert!(reverse.contains("let mut __a0_0 : f64 = 0.0f64 ; for"), "{reverse}");
    }

    #[test]
    fn powi_with_a_literal_exponent_is_a_repeated_factor_of_its_chain() {
        let reverse = reverse_of(parse_quote!({ 0.5 * q[0] * q[0] + 0.25 * self.beta * q[0].powi(4) + q[1].powi(3) }));
        // `4 · 0.25 · β` in one constant, `x³` by multiplications; alone,
        // `powi` keeps its own rule.
        assert!(reverse.contains("(4f64 * ((0.25) * ((self) . beta)))"), "{reverse}");
        assert_eq!(reverse.matches("f64 :: powi").count(), 1, "{reverse}");
        assert!(reverse.contains("f64 :: powi (__t"), "{reverse}");
    }

    #[test]
    fn a_constant_over_a_square_root_costs_one_division() {
        let reverse = reverse_of(parse_quote!({ self.mu / (q[0] * q[0] + q[1] * q[1]).sqrt() }));
        assert_eq!(reverse.matches(" / ").count(), 1, "{reverse}");
        assert!(reverse.contains("(- 0.5f64 * ((self) . mu))"), "{reverse}");
        assert!(!reverse.contains("0.5f64 / "), "{reverse}");
    }

    #[test]
    fn two_factor_products_keep_their_own_rule() {
        // `c·x`, `x·y` and `x / c` cost one multiplication or division per
        // operand either way: printed as before.
        let reverse = reverse_of(parse_quote!({ self.c * q[0] + q[1] * q[2] + q[0] / self.c }));
        assert!(!reverse.contains("f64 *"), "{reverse}");
        assert!(reverse.contains("/ ((self) . c)"), "{reverse}");
    }

    #[test]
    fn slices_are_supported_with_the_same_code() {
        let out = gradient(&parse_quote! {
            impl Chain {
                fn dimension(&self) -> usize { self.n }
                fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
                    let mut l = 0.0;
                    for i in 1..q.len() {
                        l += 0.5 * v[i] * v[i] - (q[i] - q[i - 1]).powi(2);
                    }
                    l
                }
            }
        })
        .unwrap();
        assert!(out.contains("(__q . len ())"), "{out}");
    }
}
