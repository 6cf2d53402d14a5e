//! Discontinuity detection: where the Lagrangian's value can jump as `t`,
//! `q` or `v` move.
//!
//! Variational integrators assume a smooth Lagrangian. A body that reads the
//! real part of a value depending on `t`, `q` or `v` into a discrete one (a
//! comparison, a cast to an integer, `signum`) and lets that discrete value
//! steer the result computes a piecewise function: its derivatives, taken
//! on dual numbers inside each piece, know nothing of the jump, and the
//! discrete energy jumps where the piece changes.
//!
//! Every value gets the set of parameters it depends on, propagated through
//! locals to a fixpoint as in `analyse`. Reported, in `lagrangian` only:
//! - an `if` condition that depends on `t`, `q` or `v`, however it was
//!   computed (`q[0] > 0.0`, a `bool` local holding such a comparison, ...);
//! - a cast to an integer type of a value that depends on them — the only way
//!   to get an integer from them, so loop bounds and indices computed from
//!   `t`, `q` or `v` are reported at this cast;
//! - `signum` of a value that depends on them.
//!
//! A site is reported once: the discrete value it produces counts as
//! independent afterwards, so `if k > 2` after `let k = q[0] as i32;` adds no
//! second error. Kinks (`abs`) are continuous and not reported; neither are
//! `dissipation` and `force`, whose effect is not measured by the energy.

use crate::ctxt::Ctxt;
use crate::ir::{Block, Class, Expr, ExprKind, Function, LocalId, Math, ParamRef, Stmt};
use crate::parse::MethodKind;
use proc_macro2::Span;

/// A set of the parameters `t`, `q`, `v`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Deps(u8);

impl Deps {
    const T: Deps = Deps(1);
    const Q: Deps = Deps(2);
    const V: Deps = Deps(4);

    fn union(self, other: Deps) -> Deps {
        Deps(self.0 | other.0)
    }

    fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// "`q`", "`q` and `v`", "`t`, `q` and `v`".
    fn describe(self) -> String {
        let names: Vec<&str> = [(Deps::T, "`t`"), (Deps::Q, "`q`"), (Deps::V, "`v`")]
            .into_iter()
            .filter(|(d, _)| self.0 & d.0 != 0)
            .map(|(_, name)| name)
            .collect();
        match names.as_slice() {
            [] => String::new(),
            [one] => (*one).to_owned(),
            [init @ .., last] => format!("{} and {last}", init.join(", ")),
        }
    }
}

/// A site: the first and last spans of its expression, what it is, and what
/// it depends on.
type Site = ((Span, Span), SiteKind, Deps);

/// What kind of site makes the body piecewise; it words the error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SiteKind {
    Condition,
    IntegerCast,
    Signum,
}

/// Reports every discontinuity of the `lagrangian` body to `cx`, unless the
/// user acknowledged them with `#[lagrangian(discontinuous)]`. Runs after
/// `analyse`, whose classes tell conditions from type errors.
pub(crate) fn check(cx: &Ctxt, function: &Function, acknowledged: bool) {
    if function.kind != MethodKind::Lagrangian || acknowledged {
        return;
    }
    for (span, kind, deps) in sites(function) {
        // Two tokens with the first and last spans: the error underlines
        // the whole condition or cast (spans cannot be joined on stable).
        let (start, end) = span;
        let tokens = quote::quote_spanned!(start=> start).into_iter().chain(quote::quote_spanned!(end=> end));
        cx.body_error_spanned_by(function.kind, tokens.collect::<proc_macro2::TokenStream>(), message(kind, deps));
    }
}

/// The span of the last token of `expr`, as far as the IR keeps it (a
/// closing parenthesis is not kept: the span ends before it).
fn last_span(expr: &Expr) -> Span {
    match &expr.kind {
        ExprKind::Binary { rhs: last, .. }
        | ExprKind::Unary { expr: last, .. }
        | ExprKind::Paren(last)
        | ExprKind::Assign { value: last, .. } => last_span(last),
        ExprKind::Cast { ty, .. } => {
            quote::ToTokens::to_token_stream(ty).into_iter().last().map_or(expr.span, |token| token.span())
        }
        ExprKind::Index { bracket: last, .. } | ExprKind::MethodCall { paren: last, .. } => *last,
        ExprKind::Local(_, ident) | ExprKind::Param(_, ident) => ident.span(),
        ExprKind::Field { member, .. } => syn::spanned::Spanned::span(member),
        ExprKind::Lit(lit) => lit.span(),
        ExprKind::Path(path) => path.path.segments.last().map_or(expr.span, |segment| segment.ident.span()),
        ExprKind::Block(block) => block.span,
        _ => expr.span,
    }
}

fn message(kind: SiteKind, deps: Deps) -> String {
    let deps = deps.describe();
    let (what, changes) = match kind {
        SiteKind::Condition => (format!("the condition depends on {deps}"), "the branch"),
        SiteKind::IntegerCast => (format!("the cast to an integer type is a step function of {deps}"), "the integer"),
        SiteKind::Signum => (format!("`signum` is a step function of {deps}"), "the sign"),
    };
    format!(
        "`lagrangian` is discontinuous here: {what}; variational integrators assume a smooth Lagrangian \
         (the energy jumps where {changes} changes); write a smooth expression, or acknowledge it with \
         `#[lagrangian(discontinuous)]`"
    )
}

/// The discontinuities of `function`, in source order.
fn sites(function: &Function) -> Vec<Site> {
    let mut locals = vec![Deps::default(); function.locals.len()];
    // Sets only grow, by at most three parameters per local; the bound is a
    // guard, not a limit in practice.
    for _ in 0..=3 * locals.len() {
        let before = locals.clone();
        Walk { locals: &mut locals, sites: None }.block(&function.body);
        if locals == before {
            break;
        }
    }
    let mut sites = Vec::new();
    Walk { locals: &mut locals, sites: Some(&mut sites) }.block(&function.body);
    sites
}

/// One pass: the dependencies of every expression, and, in the final pass,
/// the sites found.
struct Walk<'a> {
    locals: &'a mut [Deps],
    sites: Option<&'a mut Vec<Site>>,
}

impl Walk<'_> {
    /// Records a site spanning `expr`.
    fn site(&mut self, expr: &Expr, kind: SiteKind, deps: Deps) {
        self.site_between(expr.span, last_span(expr), kind, deps);
    }

    fn site_between(&mut self, start: Span, end: Span, kind: SiteKind, deps: Deps) {
        if let Some(sites) = &mut self.sites {
            sites.push(((start, end), kind, deps));
        }
    }

    fn assign(&mut self, local: LocalId, deps: Deps) {
        self.locals[local.0] = self.locals[local.0].union(deps);
    }

    /// The dependencies of the block's value (of every statement: a block
    /// without a tail has no value, and a union over-approximates nothing
    /// that matters since only values reach a site).
    fn block(&mut self, block: &Block) -> Deps {
        let mut deps = Deps::default();
        for stmt in &block.stmts {
            deps = match stmt {
                Stmt::Let { bindings, inits, .. } => {
                    for (binding, init) in bindings.iter().zip(inits) {
                        let deps = self.expr(init);
                        if let Some(local) = binding.local {
                            self.assign(local, deps);
                        }
                    }
                    Deps::default()
                }
                Stmt::Expr { expr, .. } => self.expr(expr),
                Stmt::Item(_) => Deps::default(),
            };
        }
        deps
    }

    fn expr(&mut self, expr: &Expr) -> Deps {
        match &expr.kind {
            ExprKind::Lit(_) | ExprKind::Path(_) | ExprKind::SelfValue(_) => Deps::default(),
            ExprKind::Break(_) | ExprKind::Continue(_) => Deps::default(),
            ExprKind::Param(ParamRef::Time, _) => Deps::T,
            ExprKind::Param(ParamRef::Q, _) => Deps::Q,
            ExprKind::Param(ParamRef::V, _) => Deps::V,
            ExprKind::Local(local, _) => self.locals[local.0],
            ExprKind::Field { base, .. } => self.expr(base),
            ExprKind::Unary { expr, .. } | ExprKind::Paren(expr) | ExprKind::Repeat { elem: expr, .. } => {
                self.expr(expr)
            }
            ExprKind::Index { base, index, .. } => {
                let base = self.expr(base);
                base.union(self.expr(index))
            }
            ExprKind::Binary { lhs, rhs, .. } => {
                let lhs = self.expr(lhs);
                lhs.union(self.expr(rhs))
            }
            ExprKind::Cast { expr: inner, ty } => {
                let deps = self.expr(inner);
                if crate::parse::is_f64(ty) || deps.is_empty() {
                    deps
                } else {
                    self.site(expr, SiteKind::IntegerCast, deps);
                    Deps::default()
                }
            }
            ExprKind::Block(block) => self.block(block),
            ExprKind::If { cond, then_branch, else_branch } => {
                let cond_deps = self.expr(cond);
                // A condition that is not a `bool` (`if v[0]`) is rustc's
                // error to report, not a discontinuity.
                if !cond_deps.is_empty() && cond.class == Class::Bool {
                    self.site(cond, SiteKind::Condition, cond_deps);
                }
                let then_deps = self.block(then_branch);
                let else_deps = else_branch.as_ref().map_or(Deps::default(), |e| self.expr(e));
                then_deps.union(else_deps)
            }
            ExprKind::For { var, start, end, body, .. } => {
                let start = self.expr(start);
                let bounds = start.union(self.expr(end));
                if let Some((local, _)) = var {
                    self.assign(*local, bounds);
                }
                self.block(body);
                Deps::default()
            }
            // The number of coordinates depends on none of their values.
            ExprKind::MethodCall { math: Math::Len, .. } => Deps::default(),
            ExprKind::MethodCall { receiver, method, args, .. } => {
                let mut deps = self.expr(receiver);
                for arg in args {
                    deps = deps.union(self.expr(arg));
                }
                if method == "signum" && !deps.is_empty() {
                    self.site_between(method.span(), method.span(), SiteKind::Signum, deps);
                    return Deps::default();
                }
                deps
            }
            ExprKind::Array(elems) => elems.iter().fold(Deps::default(), |deps, elem| deps.union(self.expr(elem))),
            ExprKind::Assign { place, value, .. } => {
                let value = self.expr(value);
                self.expr(place);
                let target = match &place.kind {
                    ExprKind::Local(local, _) => Some(*local),
                    ExprKind::Index { base, .. } => match base.kind {
                        ExprKind::Local(local, _) => Some(local),
                        _ => None,
                    },
                    _ => None,
                };
                if let Some(local) = target {
                    self.assign(local, value);
                }
                Deps::default()
            }
            ExprKind::Return(value) => {
                value.as_ref().map(|value| self.expr(value));
                Deps::default()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse::Input;
    use syn::{ItemImpl, parse_quote};

    /// The sites of a Lagrangian `fn lagrangian(&self, t, q: [f64; 2], v)`
    /// with `body`, as (kind, "deps") pairs.
    fn found(body: syn::Block) -> Vec<(SiteKind, String)> {
        let item: ItemImpl = parse_quote! {
            impl P { fn lagrangian(&self, t: f64, q: [f64; 2], v: [f64; 2]) -> f64 #body }
        };
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&item)).unwrap();
        crate::analyse::analyse(&cx, &mut system);
        cx.check().unwrap();
        sites(&system.lagrangian).into_iter().map(|(_, kind, deps)| (kind, deps.describe())).collect()
    }

    fn condition(deps: &str) -> (SiteKind, String) {
        (SiteKind::Condition, deps.to_owned())
    }

    #[test]
    fn smooth_bodies_have_no_sites() {
        assert_eq!(
            found(parse_quote!({
                let mut s = 0.0;
                for i in 0..2 {
                    if i > 0 && self.on {
                        s += v[i] * v[i];
                    }
                }
                let k = self.n as usize;
                s - q[k].cos() * (1.0 - q[0]).abs() + t
            })),
            []
        );
    }

    #[test]
    fn conditions_on_q_v_t_are_reported_with_what_they_depend_on() {
        assert_eq!(found(parse_quote!({ if q[0] > 0.0 { v[0] } else { 0.0 } })), [condition("`q`")]);
        assert_eq!(
            found(parse_quote!({
                let fast = v[1] * v[1] > 1.0;
                let late = t > 2.0;
                let either = fast || !late;
                if either { q[0] } else { 1.0 }
            })),
            [condition("`t` and `v`")]
        );
        // An `else if` is a second condition.
        assert_eq!(
            found(parse_quote!({
                if q[0] > 0.0 {
                    1.0
                } else if self.a < q[1] + v[0] * t {
                    2.0
                } else {
                    3.0
                }
            })),
            [condition("`q`"), condition("`t`, `q` and `v`")]
        );
        // Not a `bool`: rustc's type error, not ours.
        assert_eq!(found(parse_quote!({ if v[0] { 1.0 } else { 0.0 } })), []);
    }

    #[test]
    fn dependence_reaches_a_local_through_a_later_assignment_in_a_loop() {
        // `flag` is read before the assignment that makes it depend on `q`.
        assert_eq!(
            found(parse_quote!({
                let mut flag = false;
                let mut s = 0.0;
                for _ in 0..3 {
                    if flag {
                        s += 1.0;
                    }
                    flag = s > q[0];
                }
                s
            })),
            [condition("`q`")]
        );
    }

    #[test]
    fn integer_casts_and_signum_are_reported_once_where_they_happen() {
        assert_eq!(
            found(parse_quote!({
                let k = (q[0] * 3.0) as usize;
                let mut s = 0.0;
                for i in 0..k {
                    s += self.w[k] * (i as f64);
                }
                if k > 2 { s } else { v[0] * q[1].signum() }
            })),
            [(SiteKind::IntegerCast, "`q`".to_owned()), (SiteKind::Signum, "`q`".to_owned())]
        );
        // `as f64` is smooth; a `bool` cast to an integer is a step.
        assert_eq!(
            found(parse_quote!({ (q[0] as f64) + ((v[0] > 0.0) as i32 as f64) })),
            [(SiteKind::IntegerCast, "`v`".to_owned())]
        );
    }

    #[test]
    fn reported_with_the_advice_unless_acknowledged() {
        let item: ItemImpl = parse_quote! {
            impl P { fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 { if q[0] < 1.0 { v[0] } else { q[0] } } }
        };
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&item)).unwrap();
        crate::analyse::analyse(&cx, &mut system);
        check(&cx, &system.lagrangian, true);
        assert!(cx.check().is_ok());
        let cx = Ctxt::new();
        check(&cx, &system.lagrangian, false);
        let messages = cx.check().unwrap_err().messages();
        assert_eq!(messages.len(), 1);
        assert!(messages[0].starts_with("`lagrangian` is discontinuous here: the condition depends on `q`;"));
        assert!(messages[0].ends_with("acknowledge it with `#[lagrangian(discontinuous)]`"));
    }

    #[test]
    fn the_length_of_q_is_not_a_value_of_q() {
        // A branch on `q.len()` (a loop bound) is not a branch on `q`.
        assert_eq!(
            found(parse_quote!({
                let mut s = 0.0;
                for i in 0..q.len() {
                    if i + 1 < v.len() {
                        s += q[i] * q[i + 1];
                    }
                }
                s
            })),
            []
        );
    }
}
