//! The arguments of the attribute: `#[lagrangian(discontinuous, symmetry =
//! ..., parameters(...), ...)]`.
//!
//! `discontinuous` acknowledges a Lagrangian that jumps where a branch on
//! `t`, `q` or `v` changes (see `discontinuity`): the body is accepted and
//! `Lagrangian::DISCONTINUOUS` is set, so that the runtime records the energy
//! jumps.
//!
//! Each `symmetry = ...` declares a one-parameter group acting on the
//! configuration space (docs/theory.md §7) whose discrete momentum map the runtime
//! can follow: `translation(i)`, `rotation(i, j)` or `generator(f)` with `f`
//! a closure or function `&[f64; N] -> [f64; N]` giving `ξ(q)`. The indices
//! are checked against `N` when `N` is a literal; a declared symmetry is not
//! proven (the runtime's `noether::symmetry_defect` measures it).
//!
//! `parameters(m, l, g)` names `f64` fields of the system whose derivatives
//! the runtime's sensitivities and adjoint carry (`generate::parameters`);
//! `parameters(m, u: [f64; K])` adds an array field, each entry a parameter.
//! The attribute sits on the `impl` block and never sees the struct, so an
//! array parameter states its type, `K` a literal or a constant; rustc
//! checks it against the field. The list must be non-empty and name each
//! field once; a name that no body reads as `self.name` is an error
//! (differentiating with respect to it would give zero, which is more likely
//! a typo than a wish).

use crate::ctxt::Ctxt;
use crate::parse::{Len, is_f64};
use proc_macro2::TokenStream;
use syn::parse::{Parse, ParseStream};
use syn::punctuated::Punctuated;
use syn::{Expr, ExprCall, ExprLit, Ident, Lit, LitInt, Meta, Token, Type};

/// The parsed arguments.
#[derive(Default)]
pub(crate) struct Args {
    /// `discontinuous` was given.
    pub(crate) discontinuous: bool,
    /// The declared symmetries, in order.
    pub(crate) symmetries: Vec<SymmetryDecl>,
    /// The `symmetry` key of every `symmetry = ...`, readable or not: where
    /// a run-time-sized system refuses them.
    pub(crate) symmetry_keys: Vec<syn::Path>,
    /// The entries of `parameters(...)`, in order, and the `parameters` key.
    pub(crate) parameters: Option<(syn::Path, Vec<Parameter>)>,
}

/// One entry of `parameters(...)`: an `f64` field, or an array of them.
pub(crate) struct Parameter {
    /// The field.
    pub(crate) name: Ident,
    /// `K` of `name: [f64; K]`; `None` for a scalar.
    pub(crate) len: Option<Len>,
}

/// An entry as written: `name` or `name: Type`.
struct Entry {
    name: Ident,
    ty: Option<Type>,
}

impl Parse for Entry {
    fn parse(input: ParseStream<'_>) -> syn::Result<Self> {
        let name = input.parse()?;
        let ty = if input.peek(Token![:]) {
            input.parse::<Token![:]>()?;
            Some(input.parse()?)
        } else {
            None
        };
        Ok(Entry { name, ty })
    }
}

/// One declared symmetry.
pub(crate) enum SymmetryDecl {
    /// `translation(i)`.
    Translation(LitInt),
    /// `rotation(i, j)`.
    Rotation(LitInt, LitInt),
    /// `generator(f)`.
    Generator(Box<Expr>),
}

const EXPECTED: &str = "`symmetry = translation(i)`, `symmetry = rotation(i, j)` or `symmetry = generator(|q| ...)`";

/// Every argument the attribute takes.
const ARGUMENTS: &str = "`discontinuous`, `parameters(a, b, ...)`, `symmetry = translation(i)`, \
                         `symmetry = rotation(i, j)` or `symmetry = generator(|q| ...)`";

/// What `parameters` takes.
const PARAMETERS: &str = "`parameters` takes the names of `f64` fields of the system, and of `[f64; K]` fields \
                          with their type, as in `parameters(m, l, u: [f64; K])`";

/// Parses the attribute's arguments, reporting what it cannot read.
pub(crate) fn parse(cx: &Ctxt, attr: TokenStream) -> Args {
    let mut out = Args::default();
    if attr.is_empty() {
        return out;
    }
    let metas = match syn::parse::Parser::parse2(Punctuated::<Meta, Token![,]>::parse_terminated, attr) {
        Ok(metas) => metas,
        Err(error) => {
            cx.error_at(error.span(), format!("`#[lagrangian]` takes {ARGUMENTS}"));
            return out;
        }
    };
    for meta in metas {
        if let Meta::Path(path) = &meta
            && path.is_ident("discontinuous")
        {
            if out.discontinuous {
                cx.error_spanned_by(path, "`discontinuous` is given twice");
            }
            out.discontinuous = true;
            continue;
        }
        if meta.path().is_ident("parameters") {
            parameters(cx, &meta, &mut out);
            continue;
        }
        let Meta::NameValue(pair) = &meta else {
            cx.error_spanned_by(&meta, format!("unknown argument: `#[lagrangian]` takes {ARGUMENTS}"));
            continue;
        };
        if !pair.path.is_ident("symmetry") {
            cx.error_spanned_by(&pair.path, format!("unknown argument: `#[lagrangian]` takes {ARGUMENTS}"));
            continue;
        }
        out.symmetry_keys.push(pair.path.clone());
        if let Some(decl) = symmetry(cx, &pair.value) {
            out.symmetries.push(decl);
        }
    }
    out
}

/// `parameters(a, b: [f64; K], ...)`: field names, at least one, each once,
/// an array with its type.
fn parameters(cx: &Ctxt, meta: &Meta, out: &mut Args) {
    let Meta::List(list) = meta else {
        cx.error_spanned_by(meta, PARAMETERS);
        return;
    };
    if out.parameters.is_some() {
        cx.error_spanned_by(&list.path, "`parameters` is given twice: name every parameter in one list");
        return;
    }
    let entries = match list.parse_args_with(Punctuated::<Entry, Token![,]>::parse_terminated) {
        Ok(entries) => entries,
        Err(error) => {
            cx.error_at(error.span(), PARAMETERS);
            return;
        }
    };
    if entries.is_empty() {
        cx.error_at(list.delimiter.span().join(), format!("`parameters()` names no parameter: {PARAMETERS}"));
        return;
    }
    let mut seen: Vec<Parameter> = Vec::new();
    // After a wrong entry the list is dropped: the bodies would only repeat
    // the error, reading a field of another shape than the list says.
    let mut wrong = false;
    for Entry { name, ty } in entries {
        if seen.iter().any(|parameter| parameter.name == name) {
            cx.error_spanned_by(&name, format!("parameter `{name}` is named twice"));
            wrong = true;
            continue;
        }
        let len = match &ty {
            None => None,
            Some(ty) => match parameter_type(cx, &name, ty) {
                Some(len) => len,
                None => {
                    wrong = true;
                    continue;
                }
            },
        };
        seen.push(Parameter { name, len });
    }
    if !wrong {
        out.parameters = Some((list.path.clone(), seen));
    }
}

/// The length of a parameter of type `ty`: `Some(None)` for `f64`,
/// `Some(Some(K))` for `[f64; K]`; `None` after reporting any other type.
fn parameter_type(cx: &Ctxt, name: &Ident, ty: &Type) -> Option<Option<Len>> {
    if is_f64(ty) {
        return Some(None);
    }
    let Type::Array(array) = ungroup(ty) else {
        cx.error_spanned_by(ty, format!("parameter `{name}` must be `f64` or an array `[f64; K]`"));
        return None;
    };
    if let Type::Array(_) = ungroup(&array.elem) {
        cx.error_spanned_by(
            &array.elem,
            format!(
                "parameter `{name}` is a nested array: a parameter array is flat, `[f64; K]`; \
                 store the entries in one array and index it"
            ),
        );
        return None;
    }
    if !is_f64(&array.elem) {
        cx.error_spanned_by(
            &array.elem,
            format!("parameter `{name}` must hold `f64`: the sensitivities are carried by `f64` entries, `[f64; K]`"),
        );
        return None;
    }
    if let Expr::Infer(_) = array.len {
        cx.error_spanned_by(
            &array.len,
            format!("parameter `{name}` needs its length: write `[f64; K]` with `K` a literal or a `const` item"),
        );
        return None;
    }
    Some(Some(Len::from_expr(&array.len)))
}

/// `ty` without invisible groups and parentheses.
fn ungroup(ty: &Type) -> &Type {
    match ty {
        Type::Group(inner) => ungroup(&inner.elem),
        Type::Paren(inner) => ungroup(&inner.elem),
        _ => ty,
    }
}

/// One `symmetry = <value>`.
fn symmetry(cx: &Ctxt, value: &Expr) -> Option<SymmetryDecl> {
    let Expr::Call(ExprCall { func, args, paren_token, .. }) = value else {
        cx.error_spanned_by(value, format!("expected {EXPECTED}"));
        return None;
    };
    let kind = match &**func {
        Expr::Path(path) if path.qself.is_none() => path.path.get_ident().map(ToString::to_string),
        _ => None,
    };
    let args: Vec<&Expr> = args.iter().collect();
    let arity = |expected: usize, what: &str| {
        if args.len() == expected {
            true
        } else {
            cx.error_at(paren_token.span.join(), format!("`{}` takes {what}", kind.as_deref().unwrap_or_default()));
            false
        }
    };
    match kind.as_deref() {
        Some("translation") => {
            arity(1, "one coordinate index, as in `translation(0)`").then_some(())?;
            Some(SymmetryDecl::Translation(index(cx, args[0])?))
        }
        Some("rotation") => {
            arity(2, "two coordinate indices, as in `rotation(0, 1)`").then_some(())?;
            let (i, j) = (index(cx, args[0]), index(cx, args[1]));
            Some(SymmetryDecl::Rotation(i?, j?))
        }
        Some("generator") => {
            arity(1, "one closure or function `|q: &[f64; N]| -> [f64; N]` giving ξ(q)").then_some(())?;
            Some(SymmetryDecl::Generator(Box::new(args[0].clone())))
        }
        _ => {
            cx.error_spanned_by(func, format!("unknown symmetry: expected {EXPECTED}"));
            None
        }
    }
}

/// A coordinate index: an integer literal.
fn index(cx: &Ctxt, expr: &Expr) -> Option<LitInt> {
    match expr {
        Expr::Lit(ExprLit { lit: Lit::Int(lit), .. }) if lit.base10_parse::<usize>().is_ok() => Some(lit.clone()),
        _ => {
            cx.error_spanned_by(expr, "a coordinate index must be an integer literal such as `0`");
            None
        }
    }
}

/// Checks the indices against `N` (when it is a literal) and that a
/// rotation turns two different coordinates.
pub(crate) fn check(cx: &Ctxt, decls: &[SymmetryDecl], n: &Len) {
    let in_range = |lit: &LitInt| {
        let (Some(n), Ok(i)) = (n.value(), lit.base10_parse::<usize>()) else { return };
        if i >= n {
            let valid = match n {
                0 => "no coordinates".to_owned(),
                1 => "1 coordinate, `q[0]`".to_owned(),
                n => format!("{n} coordinates, `q[0]` to `q[{}]`", n - 1),
            };
            cx.error_spanned_by(lit, format!("coordinate index {i} is out of range: the system has {valid}"));
        }
    };
    for decl in decls {
        match decl {
            SymmetryDecl::Translation(i) => in_range(i),
            SymmetryDecl::Rotation(i, j) => {
                in_range(i);
                in_range(j);
                if i.base10_parse::<usize>().ok() == j.base10_parse::<usize>().ok() {
                    cx.error_spanned_by(j, "a rotation turns the plane of two different coordinates");
                }
            }
            SymmetryDecl::Generator(_) => {}
        }
    }
}

/// Refuses parameters on a run-time-sized system: the runtime's
/// sensitivities are written for compile-time-sized states.
pub(crate) fn refuse_parameters(cx: &Ctxt, args: &Args) {
    if let Some((key, _)) = &args.parameters {
        cx.error_spanned_by(
            key,
            "`parameters` is not supported for run-time-sized systems (`q: &[f64]`): \
             the sensitivities are written for `q: [f64; N]`",
        );
    }
}

/// Refuses declared symmetries on a run-time-sized system: `DynLagrangian`
/// has no `SYMMETRIES` (a symmetry of a chain of unknown length would be a
/// run-time object).
pub(crate) fn refuse_symmetries(cx: &Ctxt, args: &Args) {
    for key in &args.symmetry_keys {
        cx.error_spanned_by(
            key,
            "`symmetry` is not supported for run-time-sized systems (`q: &[f64]`): \
             `DynLagrangian` has no declared symmetries; use `q: [f64; N]`",
        );
    }
}
