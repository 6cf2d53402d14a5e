//! Activity analysis: which values depend on `t`, `q` or `v`.
//!
//! Every expression gets a [`Class`]. Only `Active` values become the dual
//! scalar type `D`; constants stay `f64`, which keeps the generated code as
//! cheap as the user's. A `let mut` variable is active if any value assigned
//! to it is, so classes are propagated to a fixpoint before generation.
//!
//! The analysis also proves which coordinates are cyclic (`CYCLIC`), and
//! the `structure` module what the bodies prove about the Hessian of `L`
//! and the Jacobian of the forces.

mod structure;

pub(crate) use structure::{Band, Separability, Structure};

use crate::ctxt::Ctxt;
use crate::ir::{Block, Class, Expr, ExprKind, Function, Local, LocalId, Math, ParamRef, Stmt, System};
use crate::parse::MethodKind;
use std::collections::BTreeSet;
use syn::BinOp;

/// The dual numbers implement `%` by panicking.
const NO_REMAINDER: &str = "the remainder `%` of values that depend on `t`, `q` or `v` is not supported: \
    it has no derivative in the dual numbers; use `%` on integers and constants only";

/// What the analysis found, besides the classes written into the IR.
pub(crate) struct Analysis {
    /// How the Lagrangian reads `q`.
    pub(crate) cyclic: Cyclic,
    /// `false` when a body mixes types in a way rustc rejects (an integer
    /// times an active value, arithmetic on whole arrays, ...). rustc reports
    /// that on the user's own `f64` method, so generation is skipped instead of
    /// repeating the error in generated code.
    pub(crate) consistent: bool,
    /// What the bodies prove about the Hessian of `L` and the Jacobian of
    /// the forces.
    pub(crate) structure: Structure,
}

/// How the Lagrangian reads `q`, from which `CYCLIC` follows.
#[derive(Debug, Default, PartialEq, Eq)]
pub(crate) struct Cyclic {
    /// Coordinates read as `q[i]` with a literal `i`.
    pub(crate) read: BTreeSet<usize>,
    /// Whether `q` is also used some other way (`q[i]` with a variable `i`,
    /// `q` as a whole), which could read any coordinate.
    pub(crate) any: bool,
}

impl Cyclic {
    /// Whether coordinate `i` is proven absent from the Lagrangian.
    pub(crate) fn is_cyclic(&self, i: usize) -> bool {
        !self.any && !self.read.contains(&i)
    }
}

/// Classifies every expression of every method of `system` and computes
/// `CYCLIC`. Errors (values the rewrite cannot differentiate through) go to
/// `cx`.
pub(crate) fn analyse(cx: &Ctxt, system: &mut System) -> Analysis {
    let mut consistent = true;
    for function in system.functions_mut() {
        consistent &= classify(cx, function);
    }
    Analysis { cyclic: cyclic(&system.lagrangian.body), consistent, structure: structure::structure(system) }
}

/// Classifies `function`; `false` if it is inconsistent (see [`Analysis`]).
pub(crate) fn classify(cx: &Ctxt, function: &mut Function) -> bool {
    let ret = function.return_class();
    let Function { kind, body, locals, .. } = function;
    let kind = *kind;
    // A loop can assign an active value to a variable read earlier in its
    // body, so passes repeat until no local changes class. Classes only grow,
    // each at most a few steps; the bound is a guard, not a limit in practice.
    for _ in 0..=4 * locals.len() {
        let before: Vec<Class> = locals.iter().map(|local| local.class).collect();
        Infer::new(kind, locals, ret, None).body(body);
        if locals.iter().map(|local| local.class).eq(before) {
            break;
        }
    }
    // One more pass, reporting, now that every class is final.
    let mut infer = Infer::new(kind, locals, ret, Some(cx));
    infer.body(body);
    infer.consistent
}

/// One classification pass over a body.
struct Infer<'a> {
    kind: MethodKind,
    locals: &'a mut [Local],
    /// The class the body's value and `return`s are coerced to.
    ret: Class,
    /// Where to report errors; `None` in the passes before the fixpoint,
    /// whose classes are provisional.
    cx: Option<&'a Ctxt>,
    consistent: bool,
}

impl<'a> Infer<'a> {
    fn new(kind: MethodKind, locals: &'a mut [Local], ret: Class, cx: Option<&'a Ctxt>) -> Self {
        Infer { kind, locals, ret, cx, consistent: true }
    }

    fn mismatch(&mut self) {
        self.consistent = false;
    }

    fn body(&mut self, body: &mut Block) {
        let class = self.block(body);
        self.returns(class);
    }

    /// Checks a value returned from the function.
    fn returns(&mut self, class: Class) {
        let fits = match self.ret {
            // A force written into its out-parameter returns nothing.
            Class::Unit => class == Class::Unit,
            Class::ActiveArray => matches!(class, Class::Unit | Class::Const | Class::ConstArray | Class::ActiveArray),
            _ => matches!(class, Class::Unit | Class::Const | Class::Active),
        };
        if !fits {
            self.mismatch();
        }
    }

    fn block(&mut self, block: &mut Block) -> Class {
        let mut class = Class::Unit;
        for stmt in &mut block.stmts {
            class = self.stmt(stmt);
        }
        // Only a final expression without `;` gives the block a value.
        match block.stmts.last() {
            Some(Stmt::Expr { semi: false, .. }) => class,
            _ => Class::Unit,
        }
    }

    fn stmt(&mut self, stmt: &mut Stmt) -> Class {
        match stmt {
            Stmt::Let { bindings, inits, .. } => {
                for (binding, init) in bindings.iter().zip(inits) {
                    let class = self.expr(init);
                    if let Some(local) = binding.local {
                        self.assign(local, class);
                    }
                }
                Class::Unit
            }
            Stmt::Expr { expr, .. } => self.expr(expr),
            Stmt::Item(_) => Class::Unit,
        }
    }

    /// Records that a value of `class` is stored in `local`.
    fn assign(&mut self, local: LocalId, class: Class) {
        let old = self.locals[local.0].class;
        let integer = |c: Class| matches!(c, Class::Int | Class::Bool);
        if (integer(old) && class.is_active()) || (old.is_active() && integer(class)) {
            self.mismatch();
        }
        self.locals[local.0].class = old.join(class);
    }

    fn expr(&mut self, expr: &mut Expr) -> Class {
        let class = self.kind(expr);
        expr.class = class;
        class
    }

    fn kind(&mut self, expr: &mut Expr) -> Class {
        match &mut expr.kind {
            ExprKind::Lit(syn::Lit::Int(lit)) if !matches!(lit.suffix(), "f32" | "f64") => Class::Int,
            ExprKind::Lit(syn::Lit::Bool(_)) => Class::Bool,
            ExprKind::Lit(_) | ExprKind::Path(_) | ExprKind::SelfValue(_) => Class::Const,
            ExprKind::Param(ParamRef::Time, _) => Class::Active,
            ExprKind::Param(ParamRef::Q | ParamRef::V, _) => Class::ActiveArray,
            ExprKind::Local(local, _) => self.locals[local.0].class,
            ExprKind::Field { base, .. } => {
                self.expr(base);
                Class::Const
            }
            ExprKind::Index { base, index, .. } => {
                let base = self.expr(base);
                let index_class = self.expr(index);
                if index_class.is_active() && !base.is_array() {
                    // `self.table[q[0]]`: valid for a user type indexed by
                    // `f64`, but the rewrite cannot see through it.
                    self.report(index.span, "indexing with a value that depends on `t`, `q` or `v` is not supported");
                } else if index_class.is_active() || matches!(index_class, Class::Bool) {
                    self.mismatch();
                }
                match base {
                    Class::ActiveArray => Class::Active,
                    Class::ConstArray | Class::Const | Class::Unit => Class::Const,
                    _ => {
                        self.mismatch();
                        Class::Const
                    }
                }
            }
            ExprKind::Unary { expr, .. } => {
                let class = self.expr(expr);
                if class.is_array() {
                    self.mismatch();
                }
                class
            }
            ExprKind::Binary { lhs, op, rhs } => {
                let (lhs, rhs) = (self.expr(lhs), self.expr(rhs));
                self.binary(*op, lhs, rhs, expr.span)
            }
            ExprKind::Cast { expr: inner, ty } => {
                let class = self.expr(inner);
                if class.is_array() {
                    self.mismatch();
                }
                match (crate::parse::is_f64(ty), class) {
                    (true, Class::Active) => Class::Active,
                    (true, _) => Class::Const,
                    // Integers are piecewise constant, so reading the real
                    // part (as comparisons do) loses no derivative.
                    (false, _) => Class::Int,
                }
            }
            ExprKind::Paren(inner) => self.expr(inner),
            ExprKind::Block(block) => self.block(block),
            ExprKind::If { cond, then_branch, else_branch } => {
                let cond = self.expr(cond);
                if !matches!(cond, Class::Bool | Class::Const) {
                    self.mismatch();
                }
                let then_class = self.block(then_branch);
                let else_class = else_branch.as_mut().map_or(Class::Unit, |e| self.expr(e));
                self.branches(then_class, else_class)
            }
            ExprKind::For { var, start, end, body, .. } => {
                let (start, end) = (self.expr(start), self.expr(end));
                if start.is_active() || end.is_active() {
                    self.mismatch();
                }
                if let Some((local, _)) = var {
                    self.locals[local.0].class = Class::Int;
                }
                self.block(body);
                Class::Unit
            }
            ExprKind::MethodCall { receiver, method, math, args, .. } => {
                let receiver = self.expr(receiver);
                let args: Vec<Class> = args.iter_mut().map(|arg| self.expr(arg)).collect();
                self.method(method.span(), *math, receiver, &args)
            }
            ExprKind::Array(elems) => {
                let classes: Vec<Class> = elems.iter_mut().map(|elem| self.expr(elem)).collect();
                self.array(expr.span, &classes)
            }
            ExprKind::Repeat { elem, .. } => {
                let class = self.expr(elem);
                self.array(expr.span, &[class])
            }
            ExprKind::Assign { place, op, value } => {
                let value = self.expr(value);
                let target = self.expr(place);
                if matches!(op, Some(BinOp::RemAssign(_))) && (target.is_active() || value.is_active()) {
                    self.report(expr.span, NO_REMAINDER);
                }
                match &place.kind {
                    ExprKind::Local(local, _) => self.assign(*local, value),
                    ExprKind::Index { base, .. } => {
                        if let ExprKind::Local(local, _) = base.kind {
                            let element = match value {
                                class if class.is_array() => {
                                    self.mismatch();
                                    class
                                }
                                Class::Active => Class::ActiveArray,
                                _ => Class::ConstArray,
                            };
                            self.assign(local, element);
                        }
                    }
                    _ => {}
                }
                Class::Unit
            }
            ExprKind::Return(value) => {
                let class = value.as_mut().map_or(Class::Unit, |value| self.expr(value));
                self.returns(class);
                Class::Unit
            }
            ExprKind::Break(_) | ExprKind::Continue(_) => Class::Unit,
        }
    }

    fn binary(&mut self, op: BinOp, lhs: Class, rhs: Class, span: proc_macro2::Span) -> Class {
        use Class as C;
        // A diverging operand (`x + return y`) takes the other's type.
        let (lhs, rhs) = match (lhs, rhs) {
            (C::Unit, other) | (other, C::Unit) => (other, other),
            pair => pair,
        };
        let int_with_active = matches!((lhs, rhs), (C::Int, C::Active) | (C::Active, C::Int));
        match op {
            BinOp::Add(_) | BinOp::Sub(_) | BinOp::Mul(_) | BinOp::Div(_) | BinOp::Rem(_) => {
                if matches!(op, BinOp::Rem(_)) && (lhs.is_active() || rhs.is_active()) {
                    self.report(span, NO_REMAINDER);
                }
                if int_with_active || lhs.is_array() || rhs.is_array() || lhs == C::Bool || rhs == C::Bool {
                    self.mismatch();
                }
                match (lhs, rhs) {
                    (C::Int, C::Int) => C::Int,
                    (C::Active, _) | (_, C::Active) => C::Active,
                    _ => C::Const,
                }
            }
            BinOp::And(_) | BinOp::Or(_) => {
                if lhs.is_active() || rhs.is_active() {
                    self.mismatch();
                }
                C::Bool
            }
            // Comparisons.
            _ => {
                if int_with_active {
                    self.mismatch();
                }
                if lhs == C::ActiveArray || rhs == C::ActiveArray {
                    self.report(
                        span,
                        "comparing whole arrays that depend on `q` or `v` is not supported; compare elements",
                    );
                }
                C::Bool
            }
        }
    }

    fn method(&mut self, span: proc_macro2::Span, math: Math, receiver: Class, args: &[Class]) -> Class {
        // `q.len()`: a number of coordinates, not a function of them.
        if math == Math::Len {
            // On a scalar local, rustc reports it on the user's method. A
            // constant may be an array (`self.u`, a local holding it).
            if !receiver.is_array() && receiver != Class::Const {
                self.mismatch();
            }
            return Class::Int;
        }
        let operands = std::iter::once(receiver).chain(args.iter().copied());
        // Not left to rustc: an extension trait could give arrays a `sin`.
        if operands.clone().any(|class| class.is_array() || class == Class::Bool) {
            self.report(span, "math methods apply to numbers, not to arrays or `bool`s");
        }
        let active = match math {
            // The exponent of `powi` is an `i32`.
            Math::Powi => {
                if args.iter().any(|class| class.is_active()) {
                    self.mismatch();
                }
                receiver.is_active()
            }
            _ => operands.clone().any(Class::is_active),
        };
        if active && operands.clone().any(|class| class == Class::Int) && math != Math::Powi {
            self.mismatch();
        }
        match (active, receiver) {
            (true, _) => Class::Active,
            // `abs` and `signum` exist on integers too.
            (false, Class::Int) => Class::Int,
            (false, _) => Class::Const,
        }
    }

    fn array(&mut self, span: proc_macro2::Span, elems: &[Class]) -> Class {
        if elems.iter().any(|class| class.is_array()) {
            self.report(span, "nested arrays are not supported");
        }
        if elems.iter().any(|class| class.is_active()) {
            if elems.iter().any(|class| matches!(class, Class::Int | Class::Bool)) {
                self.mismatch();
            }
            Class::ActiveArray
        } else {
            Class::ConstArray
        }
    }

    /// The class of an `if`: the join of its branches. A branch without a
    /// value (`{ return x; }`) must diverge in code rustc accepts, so it
    /// takes the other branch's class.
    fn branches(&mut self, then_class: Class, else_class: Class) -> Class {
        let integer = |c: Class| matches!(c, Class::Int | Class::Bool);
        if (integer(then_class) && else_class.is_active()) || (then_class.is_active() && integer(else_class)) {
            self.mismatch();
        }
        then_class.join(else_class)
    }

    /// Reports an error, in the final pass only.
    fn report(&mut self, span: proc_macro2::Span, message: &str) {
        if let Some(cx) = self.cx {
            cx.body_error_at(self.kind, span, message);
        }
    }
}

/// How the Lagrangian reads `q`: coordinates read as `q[literal]`, and
/// whether `q` appears any other way.
fn cyclic(body: &Block) -> Cyclic {
    let mut cyclic = Cyclic::default();
    // Every occurrence of `q` is counted; those that are the base of a
    // literal index are counted again as literal reads. Any difference means
    // some use is not a literal read.
    let (mut uses, mut literal_reads) = (0_usize, 0_usize);
    body.visit(&mut |expr| {
        match &expr.kind {
            ExprKind::Param(ParamRef::Q, _) => uses += 1,
            // `q.len()` reads no coordinate.
            ExprKind::MethodCall { receiver, math: Math::Len, .. }
                if matches!(receiver.kind, ExprKind::Param(ParamRef::Q, _)) =>
            {
                literal_reads += 1;
            }
            ExprKind::Index { base, index, .. } if matches!(base.kind, ExprKind::Param(ParamRef::Q, _)) => {
                if let Some(i) = index.literal_index() {
                    literal_reads += 1;
                    cyclic.read.insert(i);
                }
            }
            _ => {}
        }
        true
    });
    cyclic.any = uses != literal_reads;
    cyclic
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse::Input;
    use syn::{ItemImpl, parse_quote};

    fn analysed(item: &ItemImpl) -> (System, Analysis) {
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(item)).unwrap();
        let analysis = analyse(&cx, &mut system);
        cx.check().unwrap();
        (system, analysis)
    }

    fn lagrangian(body: syn::Block) -> (System, Analysis) {
        analysed(&parse_quote! {
            impl P { fn lagrangian(&self, t: f64, q: [f64; 3], v: [f64; 3]) -> f64 #body }
        })
    }

    fn local_classes(system: &System) -> Vec<(String, Class)> {
        system.lagrangian.locals.iter().map(|local| (local.name.to_string(), local.class)).collect()
    }

    #[test]
    fn classifies_expressions() {
        let (system, analysis) = lagrangian(parse_quote!({
            let c = 0.5 * self.m * PI;
            let k = 3;
            let x = c * v[0];
            let r = (k as f64) + t;
            let b = q[1] > 0.0;
            x + r
        }));
        assert!(analysis.consistent);
        assert_eq!(
            local_classes(&system),
            [
                ("c".to_owned(), Class::Const),
                ("k".to_owned(), Class::Int),
                ("x".to_owned(), Class::Active),
                ("r".to_owned(), Class::Active),
                ("b".to_owned(), Class::Bool),
            ]
        );
        // `0.5 * self.m` inside `c` stays a constant.
        let Stmt::Let { inits, .. } = &system.lagrangian.body.stmts[0] else { panic!() };
        assert_eq!(inits[0].class, Class::Const);
        assert_eq!(system.lagrangian.body.tail().unwrap().class, Class::Active);
    }

    #[test]
    fn let_mut_becomes_active_through_a_later_assignment() {
        let (system, analysis) = lagrangian(parse_quote!({
            let mut acc = 0.0;
            let mut prev = 1.0;
            let mut f = [0.0; 3];
            for i in 0..3 {
                // Reads `acc` before the assignment that makes it active.
                prev = acc * 2.0;
                acc += v[i] * v[i];
                f[i] = 1.0;
            }
            acc + prev + f[0]
        }));
        assert!(analysis.consistent);
        assert_eq!(
            local_classes(&system),
            [
                ("acc".to_owned(), Class::Active),
                ("prev".to_owned(), Class::Active),
                ("f".to_owned(), Class::ConstArray),
                ("i".to_owned(), Class::Int),
            ]
        );
    }

    #[test]
    fn element_assignment_makes_an_array_active() {
        let (system, _) = analysed(&parse_quote! {
            impl P {
                fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 { 0.0 }
                fn force(&self, q: [f64; 2], v: [f64; 2]) -> [f64; 2] {
                    let mut f = [0.0; 2];
                    f[1] = -q[1];
                    f
                }
            }
        });
        assert_eq!(system.force.unwrap().locals[0].class, Class::ActiveArray);
    }

    #[test]
    fn a_force_over_slices_writes_active_entries_and_returns_nothing() {
        let force = |body: syn::Block| {
            analysed(&parse_quote! {
                impl P {
                    fn dimension(&self) -> usize { 2 }
                    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 { 0.0 }
                    fn force(&self, q: &[f64], v: &[f64], f: &mut [f64]) #body
                }
            })
        };
        let (system, analysis) = force(parse_quote!({
            f[0] = 1.0;
        }));
        assert!(analysis.consistent);
        assert_eq!(system.force.unwrap().locals[0].class, Class::ActiveArray);
        // A value where none is returned: rustc reports it on the user's
        // method, so nothing is generated.
        assert!(
            !force(parse_quote!({
                f[0] = 1.0;
                0.0
            }))
            .1
            .consistent
        );
        assert!(
            !force(parse_quote!({
                return q[0];
            }))
            .1
            .consistent
        );
        assert!(
            force(parse_quote!({
                if q[0] > 0.0 {
                    return;
                }
                f[1] = v[0];
            }))
            .1
            .consistent
        );
    }

    #[test]
    fn cyclic_coordinates_are_those_never_read() {
        let (_, analysis) = lagrangian(parse_quote!({ q[0].cos() + v[1] * v[2] }));
        assert_eq!(analysis.cyclic.read, BTreeSet::from([0]));
        assert!(!analysis.cyclic.any);
        assert_eq!((0..3).map(|i| analysis.cyclic.is_cyclic(i)).collect::<Vec<_>>(), [false, true, true]);

        let (_, analysis) = lagrangian(parse_quote!({
            let mut s = 0.0;
            for i in 0..3 {
                s += q[i];
            }
            s
        }));
        assert!(analysis.cyclic.any);
        assert!(!analysis.cyclic.is_cyclic(2));
    }

    #[test]
    fn integer_times_active_is_left_to_rustc() {
        let (_, analysis) = lagrangian(parse_quote!({ 2 * q[0] }));
        assert!(!analysis.consistent);
        let (_, analysis) = lagrangian(parse_quote!({ q[0].powi(v[0]) }));
        assert!(!analysis.consistent);
        let (_, analysis) = lagrangian(parse_quote!({ q[0].powi(2) * (2 as f64) }));
        assert!(analysis.consistent);
    }

    #[test]
    fn remainder_is_for_integers_and_constants() {
        let (system, analysis) = lagrangian(parse_quote!({
            let mut k = 7;
            k %= 3;
            let c = self.a % 2.0;
            q[k % 2] * c
        }));
        assert!(analysis.consistent);
        assert_eq!(local_classes(&system)[..2], [("k".to_owned(), Class::Int), ("c".to_owned(), Class::Const)]);

        let item: ItemImpl = parse_quote! {
            impl P { fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 { let mut x = q[0] % 1.0; x %= v[0]; x } }
        };
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&item)).unwrap();
        analyse(&cx, &mut system);
        assert_eq!(cx.check().unwrap_err().messages().len(), 2);
    }

    #[test]
    fn reports_indexing_opaque_data_with_an_active_value() {
        let item: ItemImpl = parse_quote! {
            impl P { fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 { self.table[q[0]] } }
        };
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&item)).unwrap();
        analyse(&cx, &mut system);
        assert_eq!(
            cx.check().unwrap_err().messages(),
            ["indexing with a value that depends on `t`, `q` or `v` is not supported"]
        );
    }

    #[test]
    fn lengths_are_integers_and_read_no_coordinate() {
        let (system, analysis) = lagrangian(parse_quote!({
            let n = q.len();
            let m = v.len() - 1;
            q[0] * v[m] + (n as f64)
        }));
        assert!(analysis.consistent);
        assert_eq!(local_classes(&system), [("n".to_owned(), Class::Int), ("m".to_owned(), Class::Int)]);
        // `q[0]` is read, `q.len()` reads nothing.
        assert_eq!(analysis.cyclic.read, BTreeSet::from([0]));
        assert!(!analysis.cyclic.any);
        // `len` of a scalar is rustc's error.
        let (_, analysis) = lagrangian(parse_quote!({
            let x = q[0];
            (x.len() as f64) * x
        }));
        assert!(!analysis.consistent);
    }
}
