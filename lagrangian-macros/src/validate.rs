//! Validation: checks the signatures of the recognised methods and lowers
//! their bodies into the IR, reporting everything the rewrite cannot handle.
//!
//! Every check reports to the [`Ctxt`] and carries on, so one build shows all
//! the problems of a block. The signatures are checked here; the bodies in
//! [`body`].

mod body;
mod constraints;

use crate::ctxt::Ctxt;
use crate::ir::{Binder, System};
use crate::parse::{Dim, Input, Len, Method, MethodKind, Param, Shape};
use quote::ToTokens;
use syn::{Ident, Pat, PatIdent};

/// Checks `input` and builds the validated model of the block.
///
/// Returns `None` when no model can be built (no `lagrangian`, unknown `N`,
/// a body that could not be lowered). A `Some` may still come with errors in
/// `cx`, e.g. a wrong receiver: whether to generate is the caller's decision,
/// taken on `cx`.
pub(crate) fn validate(cx: &Ctxt, input: &Input<'_>) -> Option<System> {
    let item = input.item;
    if let Some((_, path, _)) = &item.trait_ {
        cx.error_spanned_by(
            path,
            "`#[lagrangian]` goes on an inherent impl block (`impl MySystem { ... }`), not on a trait impl",
        );
    }
    check_cfgs(cx, item);
    let Some(lagrangian) = &input.lagrangian else {
        // Without the Lagrangian there is no `N` to check the other methods
        // against, so this is the only error reported for the block.
        cx.error_spanned_by(
            &item.self_ty,
            "no `lagrangian` method in this impl block: `#[lagrangian]` needs \
             `fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64`",
        );
        return None;
    };

    let signature = check_signature(cx, lagrangian, &item.self_ty, None, false);
    let n = signature.n.clone();
    let dynamic = n.as_ref().is_some_and(Dim::is_dynamic);
    // A body written to return another type (`Ok(x)` for `Result<f64, _>`)
    // is not lowered: its errors would all follow from the signature's.
    let lower = |method: &Method<'_>, signature: &Signature| {
        if signature.returns { body::lower(cx, method, signature) } else { None }
    };
    let lagrangian_fn = lower(lagrangian, &signature);
    let expected = n.as_ref().and_then(Dim::len);
    let optional = |method: &Option<Method<'_>>| {
        method.as_ref().map(|method| {
            if dynamic && method.kind == MethodKind::Force && takes_arrays(method) {
                // The const form beside a slice Lagrangian.
                cx.error_spanned_by(
                    &method.func.sig.ident,
                    format!("`force` of a run-time-sized system takes slices like `lagrangian`: write {DYN_FORCE}"),
                );
                return None;
            }
            if dynamic && !matches!(method.kind, MethodKind::Dissipation | MethodKind::Force) {
                // What `DynLagrangian` does not carry (or the rewrite does
                // not write over slices): refused, not lowered.
                cx.error_spanned_by(&method.func.sig.ident, dynamic_refusal(method.kind));
                return None;
            }
            let signature = check_signature(cx, method, &item.self_ty, expected, dynamic);
            if dynamic && !signature.n.as_ref().is_none_or(Dim::is_dynamic) {
                // Arrays beside a slice Lagrangian.
                cx.error_spanned_by(
                    &method.func.sig.ident,
                    format!(
                        "`{}` of a run-time-sized system takes slices like `lagrangian`: \
                         write `fn {}(&self, q: &[f64], v: &[f64]) -> f64`",
                        method.kind.name(),
                        method.kind.name()
                    ),
                );
                return None;
            }
            lower(method, &signature)
        })
    };
    let dissipation = optional(&input.dissipation);
    let force = optional(&input.force);
    let step_density = optional(&input.step_density);
    let constraints =
        optional(&input.constraints).map(|f| Some((f?, input.constraints.as_ref().and_then(constraints::count)?)));
    if dynamic {
        check_dimension(cx, input.dimension, lagrangian, &item.self_ty);
    }

    Some(System {
        n: n?,
        lagrangian: lagrangian_fn?,
        // Absent is fine; present but not lowered is not.
        dissipation: dissipation.map_or(Some(None), |f| f.map(Some))?,
        force: force.map_or(Some(None), |f| f.map(Some))?,
        step_density: step_density.map_or(Some(None), |f| f.map(Some))?,
        constraints: constraints.map_or(Some(None), |f| f.map(Some))?,
    })
}

/// The force of a run-time-sized system, for messages.
const DYN_FORCE: &str = "`fn force(&self, [t: f64,] q: &[f64], v: &[f64], f: &mut [f64])`";

/// Why `kind` is refused in a run-time-sized system (`q: &[f64]`).
fn dynamic_refusal(kind: MethodKind) -> String {
    let name = kind.name();
    format!(
        "`{name}` is not supported for run-time-sized systems (`q: &[f64]`): \
         `DynLagrangian` has no `{name}`; use `q: [f64; N]`"
    )
}

/// Whether `method` is written in the const form, some parameter an array
/// `[f64; N]`.
fn takes_arrays(method: &Method<'_>) -> bool {
    method.params.iter().any(|param| matches!(param.shape, Shape::Array { .. }))
}

/// Checks `fn dimension(&self) -> usize`, which a run-time-sized system
/// needs: the runtime allocates its state from it. Its body is not
/// rewritten (it computes an integer from the system, never from `q`), so
/// the trait implementation calls the method as written.
fn check_dimension(cx: &Ctxt, dimension: Option<&syn::ImplItemFn>, lagrangian: &Method<'_>, self_ty: &syn::Type) {
    const EXPECTED: &str = "`fn dimension(&self) -> usize`";
    let Some(func) = dimension else {
        // At the slice type that makes the system run-time-sized.
        let at = lagrangian
            .params
            .iter()
            .rev()
            .nth(1)
            .map_or_else(|| lagrangian.func.sig.ident.to_token_stream(), |q| q.ty.to_token_stream());
        cx.error_spanned_by(
            at,
            format!(
                "a `lagrangian` taking slices (`q: &[f64]`) needs {EXPECTED} in the same impl block: \
                 the number of coordinates is known only at run time"
            ),
        );
        return;
    };
    let sig = &func.sig;
    for attr in func.attrs.iter().filter(|attr| attr.path().is_ident("cfg")) {
        cx.error_spanned_by(
            attr,
            "`#[cfg]` on `dimension` is not supported: the generated trait implementation \
             cannot follow it; put each configuration in its own impl block",
        );
    }
    if sig.generics.lt_token.is_some() || sig.generics.where_clause.is_some() {
        cx.error_spanned_by(&sig.generics, format!("`dimension` cannot have generic parameters: write {EXPECTED}"));
    }
    if let Some(token) = &sig.asyncness {
        cx.error_spanned_by(token, "`dimension` cannot be `async`");
    }
    if let Some(token) = &sig.unsafety {
        cx.error_spanned_by(token, "`dimension` cannot be `unsafe`");
    }
    match sig.receiver() {
        None => cx.error_at(sig.paren_token.span.join(), format!("`dimension` must take `&self`: write {EXPECTED}")),
        Some(receiver) if !is_shared_self(receiver, self_ty) => {
            cx.error_spanned_by(receiver, format!("`dimension` must take `&self`: write {EXPECTED}"));
        }
        Some(_) => {}
    }
    for arg in sig.inputs.iter().filter(|arg| matches!(arg, syn::FnArg::Typed(_))) {
        cx.error_spanned_by(arg, format!("`dimension` takes no parameters besides `&self`: write {EXPECTED}"));
    }
    match &sig.output {
        syn::ReturnType::Type(_, ty) if crate::parse::is_usize(ty) => {}
        syn::ReturnType::Type(_, ty) => cx.error_spanned_by(ty, "`dimension` must return `usize`"),
        syn::ReturnType::Default => {
            cx.error_at(sig.paren_token.span.close(), "`dimension` must return `usize`: add `-> usize`");
        }
    }
}

/// Refuses `#[cfg]` on the recognised methods.
///
/// The macro sees every method before configuration, so under `#[cfg(a)] fn
/// lagrangian` and `#[cfg(not(a))] fn lagrangian` it would have to emit one
/// trait implementation per combination of the predicates of every cfg'd
/// method, each under `#[cfg(all(...))]`, and check and rewrite every
/// variant. A `#[cfg]` on the whole impl block says the same with one
/// expansion per block, and the macro carries that `#[cfg]` over to the trait
/// implementation (see `generate::cfgs`), so that is what the error asks for.
/// `#[cfg_attr(pred, cfg(...))]` is a `#[cfg]` too; a `#[cfg_attr]` carrying
/// other attributes (`inline`) is harmless and passes.
fn check_cfgs(cx: &Ctxt, item: &syn::ItemImpl) {
    for attr in item.attrs.iter().filter(|attr| attr.path().is_ident("cfg_attr") && carries_cfg(attr)) {
        cx.error_spanned_by(
            attr,
            "`#[cfg_attr(..., cfg(...))]` on a `#[lagrangian]` block is not supported: \
             write the `#[cfg(...)]` itself",
        );
    }
    for func in item.items.iter().filter_map(|item| match item {
        syn::ImplItem::Fn(func) => Some(func),
        _ => None,
    }) {
        let Some(kind) = MethodKind::from_ident(&func.sig.ident) else { continue };
        let name = kind.name();
        for attr in &func.attrs {
            let cfg = attr.path().is_ident("cfg") || (attr.path().is_ident("cfg_attr") && carries_cfg(attr));
            if cfg {
                cx.error_spanned_by(
                    attr,
                    format!(
                        "`#[cfg]` on `{name}` is not supported: the generated trait implementation \
                         cannot follow it; put each configuration in its own impl block, \
                         `#[lagrangian] #[cfg(...)] impl ... {{ fn {name}(...) }}`"
                    ),
                );
            }
        }
    }
}

/// Whether a `#[cfg_attr(pred, attrs...)]` expands to a `#[cfg]`, directly or
/// through a nested `cfg_attr`.
fn carries_cfg(attr: &syn::Attribute) -> bool {
    use syn::punctuated::Punctuated;
    let Ok(metas) = attr.parse_args_with(Punctuated::<syn::Meta, syn::Token![,]>::parse_terminated) else {
        // Malformed: rustc reports it.
        return false;
    };
    metas.iter().skip(1).any(|meta| {
        meta.path().is_ident("cfg")
            || (meta.path().is_ident("cfg_attr")
                && matches!(meta, syn::Meta::List(list) if {
                    let nested: syn::Attribute = syn::parse_quote!(#[#list]);
                    carries_cfg(&nested)
                }))
    })
}

/// A best guess at `N` (or at a run-time size) from the Lagrangian's
/// signature, however broken, so that the fallback can still emit a stub
/// trait impl after errors and spare the user follow-on "trait not
/// implemented" errors.
pub(crate) fn arity(input: &Input<'_>) -> Option<Dim> {
    let params = &input.lagrangian.as_ref()?.params;
    // `q` is second to last and `v` last whether or not `t` is there.
    // `q` decides, as in `check_signature`.
    params.iter().rev().take(2).rev().find_map(|param| match &param.shape {
        Shape::Array { len, .. } => Some(Dim::Fixed(len.clone())),
        Shape::Slice { .. } => Some(Dim::Dynamic),
        _ => None,
    })
}

/// What a method's signature says, as far as it could be read.
pub(crate) struct Signature {
    /// The method name as written.
    pub(crate) name: Ident,
    /// The time parameter, `None` when there is none.
    pub(crate) time: Option<Binder>,
    /// The position parameter (`None` also when unreadable).
    pub(crate) q: Binder,
    /// The velocity parameter.
    pub(crate) v: Binder,
    /// This method's `N` (or a run-time size), from `q` (or `v` if `q` is
    /// unreadable).
    pub(crate) n: Option<Dim>,
    /// Whether the return type is the right one.
    pub(crate) returns: bool,
    /// The out-parameter `f: &mut [f64]` of a run-time-sized system's
    /// `force`; `None` for the other methods.
    pub(crate) out: Option<Binder>,
}

/// Checks the signature of `method`. `expected` is the Lagrangian's `N`, which
/// the optional methods must share; `None` when checking the Lagrangian.
/// `dynamic` tells that the Lagrangian takes slices.
fn check_signature(
    cx: &Ctxt,
    method: &Method<'_>,
    self_ty: &syn::Type,
    expected: Option<&Len>,
    dynamic: bool,
) -> Signature {
    let name = method.kind.name();
    let sig = &method.func.sig;
    let mut signature =
        Signature { name: sig.ident.clone(), time: None, q: None, v: None, n: None, returns: false, out: None };
    // A run-time-sized system's force writes into a last parameter
    // `f: &mut [f64]` instead of returning an array of unknown size.
    let dynamic_force = method.kind == MethodKind::Force && dynamic;

    if sig.generics.lt_token.is_some() || sig.generics.where_clause.is_some() {
        cx.error_spanned_by(
            &sig.generics,
            format!(
                "`{name}` cannot have generic parameters: write it for `f64`, \
                 the macro makes it generic over dual numbers"
            ),
        );
    }
    if let Some(token) = &sig.asyncness {
        cx.error_spanned_by(token, format!("`{name}` cannot be `async`"));
    }
    if let Some(token) = &sig.unsafety {
        cx.error_spanned_by(token, format!("`{name}` cannot be `unsafe`"));
    }

    match method.receiver {
        None => cx.error_at(sig.paren_token.span.join(), format!("`{name}` must take `&self` as its first parameter")),
        Some(receiver) if !is_shared_self(receiver, self_ty) => {
            cx.error_spanned_by(
                receiver,
                format!("`{name}` must take `&self`: the system is only read, never modified"),
            );
        }
        Some(_) => {}
    }

    let params = match method.params.as_slice() {
        // `(t, q, v, f)`, or `(q, v, f)` unless it reads as `(t, q, v)`.
        [params @ .., out]
            if dynamic_force
                && (params.len() == 3
                    || (params.len() == 2
                        && (matches!(out.shape, Shape::Slice { mutable: true, .. })
                            || !matches!(params[0].shape, Shape::F64)))) =>
        {
            signature.out = Some(check_out(cx, out));
            params
        }
        params if dynamic_force => {
            let found = params.len();
            cx.error_at(
                sig.paren_token.span.join(),
                format!(
                    "`force` of a run-time-sized system takes {DYN_FORCE}, found {found} parameter{} \
                     besides `&self`",
                    if found == 1 { "" } else { "s" }
                ),
            );
            signature.returns = check_no_return(cx, method, None);
            return signature;
        }
        params => params,
    };
    let (time, q, v) = if method.kind.takes_velocity() {
        match (params, method.kind.takes_time()) {
            ([q, v], _) => (None, q, Some(v)),
            ([t, q, v], true) => (Some(t), q, Some(v)),
            // A time argument where none is taken: say so at that argument.
            ([t, q, v], false) if matches!(t.shape, Shape::F64) => {
                let (pat, ty) = (t.pat, t.ty);
                cx.error_spanned_by(
                    quote::quote!(#pat #ty),
                    format!(
                        "`{name}` takes no time argument: a rayleigh function is `R(q, v)`; \
                         put time-dependent forces in `fn force(&self, t: f64, q, v) -> [f64; N]`"
                    ),
                );
                (None, q, Some(v))
            }
            (params, _) => return wrong_arity(cx, method, params.len(), signature),
        }
    } else {
        // `g(t, q)`: two parameters are `(t, q)` unless the first is an
        // array (then they are `(q, v)`, and `v` is the mistake).
        let velocity = |v: &Param<'_>| {
            let (pat, ty) = (v.pat, v.ty);
            let message = if method.kind == MethodKind::Constraints {
                constraints::velocity_message()
            } else {
                format!(
                    "`{name}` takes no velocity: a step density is `g(t, q)`, \
                     write `fn {name}(&self, [t: f64,] q: [f64; N]) -> f64`"
                )
            };
            cx.error_spanned_by(quote::quote!(#pat: #ty), message);
        };
        match params {
            [q] => (None, q, None),
            [t, q] if !matches!(t.shape, Shape::Array { .. }) => (Some(t), q, None),
            [q, v] => {
                velocity(v);
                (None, q, None)
            }
            [t, q, v] => {
                velocity(v);
                (Some(t), q, None)
            }
            params => return wrong_arity(cx, method, params.len(), signature),
        }
    };

    if let Some(t) = time {
        signature.time = Some(binder(cx, t));
        if !matches!(t.shape, Shape::F64) {
            cx.error_spanned_by(t.ty, format!("the time parameter of `{name}` must be `f64`"));
        }
    }
    signature.q = binder(cx, q);
    signature.v = v.and_then(|v| binder(cx, v));

    let q_name = display(&signature.q, "q");
    let v_name = display(&signature.v, "v");
    // The Lagrangian chooses between arrays and slices; the dissipation
    // function of a Lagrangian without a compile-time `N` may take slices
    // too (the caller checks it takes them), the force of a Lagrangian
    // over slices takes them, the other optional methods take arrays only.
    let slices = method.kind == MethodKind::Lagrangian
        || (method.kind == MethodKind::Dissipation && expected.is_none())
        || dynamic_force;
    let q_form = form(q, slices);
    // Without a velocity, `q` alone decides.
    let v_form = v.map_or(q_form, |v| form(v, slices));
    report_form(cx, q, &q_name, name, q_form, v_form, slices);
    if let Some(v) = v {
        report_form(cx, v, &v_name, name, v_form, q_form, slices);
    }
    signature.n = match (q_form, v_form) {
        (Form::Array(len), _) | (Form::Bad, Form::Array(len)) => Some(Dim::Fixed(len.clone())),
        (Form::Slice, _) | (Form::Bad, Form::Slice) => Some(Dim::Dynamic),
        (Form::Bad, Form::Bad) => None,
    };
    let (q_len, v_len) = (q_form.len(), v_form.len());
    match expected {
        // The Lagrangian: `v` must match `q`.
        None => match (q_form, v_form) {
            (Form::Array(q_len), Form::Array(v_len)) if !v_len.same_as(q_len) => {
                cx.error_spanned_by(
                    v_len,
                    format!(
                        "`{q_name}` and `{v_name}` must have the same length: \
                         `{q_name}` is `[f64; {q_len}]` but `{v_name}` is `[f64; {v_len}]`"
                    ),
                );
            }
            (Form::Array(len), Form::Slice) | (Form::Slice, Form::Array(len)) => {
                let (q_ty, v_ty) = match q_form {
                    Form::Array(_) => (format!("[f64; {len}]"), "&[f64]".to_owned()),
                    _ => ("&[f64]".to_owned(), format!("[f64; {len}]")),
                };
                cx.error_spanned_by(
                    v.map_or(q.ty, |v| v.ty),
                    format!(
                        "`{q_name}` and `{v_name}` must both be arrays `[f64; N]` or both slices `&[f64]`: \
                         `{q_name}` is `{q_ty}` but `{v_name}` is `{v_ty}`"
                    ),
                );
            }
            _ => {}
        },
        // The optional methods: both must match the Lagrangian.
        Some(expected) => {
            for len in [q_len, v.and(v_len)].into_iter().flatten() {
                if !len.same_as(expected) {
                    cx.error_spanned_by(
                        len,
                        format!(
                            "`{name}` must have as many coordinates as `lagrangian`: \
                             expected `[f64; {expected}]`, found `[f64; {len}]`"
                        ),
                    );
                }
            }
        }
    }
    signature.returns = if dynamic_force {
        check_no_return(cx, method, signature.out.as_ref())
    } else {
        check_return(cx, method, expected.or(signature.n.as_ref().and_then(Dim::len)))
    };
    signature
}

/// Checks the out-parameter of a run-time-sized system's force, which must
/// be `&mut [f64]`, and reads its name.
fn check_out(cx: &Ctxt, out: &Param<'_>) -> Binder {
    let binder = binder(cx, out);
    let role = display(&binder, "f");
    match out.shape {
        Shape::Slice { of_f64: true, mutable: true } => {}
        Shape::Slice { of_f64: true, mutable: false } => cx.error_spanned_by(
            out.ty,
            format!("`{role}` in `force` must be `&mut [f64]`: the force is written into it"),
        ),
        _ => cx.error_spanned_by(
            out.ty,
            format!(
                "`{role}` in `force` must be `&mut [f64]`: a run-time-sized system's force is written \
                 into its last parameter, {DYN_FORCE}"
            ),
        ),
    }
    binder
}

/// Checks that a run-time-sized system's force returns nothing: it writes
/// into its out-parameter. `false` if it was reported.
fn check_no_return(cx: &Ctxt, method: &Method<'_>, out: Option<&Binder>) -> bool {
    let Some((ty, _)) = &method.output else { return true };
    if matches!(ty, syn::Type::Tuple(unit) if unit.elems.is_empty()) {
        return true;
    }
    let role = out.map_or_else(|| "f".to_owned(), |out| display(out, "f"));
    cx.error_spanned_by(
        ty,
        format!(
            "`force` of a run-time-sized system returns nothing: it writes the force into \
             `{role}: &mut [f64]`, which arrives filled with zeros; remove the return type"
        ),
    );
    false
}

/// What a `q` or `v` parameter declares, as far as it is usable.
#[derive(Clone, Copy)]
enum Form<'p> {
    /// `[f64; N]`.
    Array(&'p Len),
    /// `&[f64]`, where slices are accepted.
    Slice,
    /// Anything else (reported by [`report_form`]).
    Bad,
}

impl<'p> Form<'p> {
    fn len(self) -> Option<&'p Len> {
        match self {
            Form::Array(len) => Some(len),
            _ => None,
        }
    }
}

/// The form of `param`; slices count only where `slices` allows them.
fn form<'p>(param: &'p Param<'_>, slices: bool) -> Form<'p> {
    match &param.shape {
        Shape::Array { of_f64: true, len } => Form::Array(len),
        Shape::Slice { of_f64: true, mutable: false } if slices => Form::Slice,
        _ => Form::Bad,
    }
}

/// Reports a `q` or `v` parameter of the wrong type, saying what is allowed:
/// the form of the other parameter if it is usable, both forms otherwise.
fn report_form(cx: &Ctxt, param: &Param<'_>, role: &str, name: &str, this: Form<'_>, other: Form<'_>, slices: bool) {
    if !matches!(this, Form::Bad) {
        return;
    }
    let message = match (&param.shape, other) {
        // Beside an array, or where slices are not accepted: an array.
        (_, Form::Array(_)) | (Shape::Array { .. }, _) => format!("`{role}` in `{name}` must be `[f64; N]`"),
        (_, _) if !slices => format!("`{role}` in `{name}` must be `[f64; N]`"),
        (Shape::Slice { mutable: true, .. }, _) => {
            format!("`{role}` in `{name}` must be `&[f64]`, not `&mut`: `{name}` only reads the state")
        }
        (Shape::Slice { .. }, _) => {
            format!("`{role}` in `{name}` must be `&[f64]` or `[f64; N]`: the body is rewritten from `f64` only")
        }
        (_, _) if crate::parse::is_vec(param.ty) => format!(
            "`{role}` in `{name}` must be `&[f64]` (size known at run time) or `[f64; N]`: \
             take a `Vec<f64>` as a slice, `{role}: &[f64]`"
        ),
        (_, Form::Slice) => format!("`{role}` in `{name}` must be `&[f64]`"),
        (_, Form::Bad) => format!("`{role}` in `{name}` must be `[f64; N]` or `&[f64]`"),
    };
    cx.error_spanned_by(param.ty, message);
}

/// The accepted parameter lists, for messages.
/// Reports a parameter list of the wrong length; the signature stays unread.
fn wrong_arity(cx: &Ctxt, method: &Method<'_>, found: usize, mut signature: Signature) -> Signature {
    cx.error_at(
        method.func.sig.paren_token.span.join(),
        format!(
            "`{}` takes {}, found {found} parameter{} besides `&self`",
            method.kind.name(),
            expected_params(method.kind),
            if found == 1 { "" } else { "s" },
        ),
    );
    signature.returns = check_return(cx, method, None);
    signature
}

fn expected_params(kind: MethodKind) -> &'static str {
    if !kind.takes_velocity() {
        "`(&self, q: [f64; N])` or `(&self, t: f64, q: [f64; N])`"
    } else if kind == MethodKind::Lagrangian {
        "`(&self, q: [f64; N], v: [f64; N])` or `(&self, t: f64, q: [f64; N], v: [f64; N])`, \
         or the same with slices `q: &[f64], v: &[f64]`"
    } else if kind.takes_time() {
        "`(&self, q: [f64; N], v: [f64; N])` or `(&self, t: f64, q: [f64; N], v: [f64; N])`"
    } else {
        "`(&self, q: [f64; N], v: [f64; N])`"
    }
}

/// How to call a parameter in messages: its name, or its role for `_`.
fn display(binder: &Binder, role: &str) -> String {
    binder.as_ref().map_or_else(|| role.to_owned(), Ident::to_string)
}

/// Checks the return type: `f64`, or `[f64; N]` for `force`. `n` is the `N`
/// to expect, when known. `false` if it was reported.
fn check_return(cx: &Ctxt, method: &Method<'_>, n: Option<&Len>) -> bool {
    if method.kind == MethodKind::Constraints {
        return constraints::check_return(cx, method, n);
    }
    let name = method.kind.name();
    let expected = match (method.kind.returns_array(), n) {
        (false, _) => "f64".to_owned(),
        (true, Some(n)) => format!("[f64; {n}]"),
        (true, None) => "[f64; N]".to_owned(),
    };
    let ok = match (&method.output, method.kind.returns_array()) {
        (Some((_, Shape::F64)), false) => true,
        (Some((_, Shape::Array { of_f64: true, len })), true) => n.is_none_or(|n| len.same_as(n)),
        _ => false,
    };
    if ok {
        return true;
    }
    let message = format!("`{name}` must return `{expected}`");
    match &method.output {
        Some((ty, _)) => cx.error_spanned_by(ty, message),
        None => cx.error_at(method.func.sig.paren_token.span.close(), format!("{message}: add `-> {expected}`")),
    }
    false
}

/// Whether the receiver is a shared borrow of the system: `&self`, or
/// `self: &Self` / `self: &MySystem` written out.
fn is_shared_self(receiver: &syn::Receiver, self_ty: &syn::Type) -> bool {
    if receiver.mutability.is_some() {
        return false;
    }
    if receiver.colon_token.is_none() {
        return receiver.reference.is_some();
    }
    let syn::Type::Reference(reference) = strip_parens(&receiver.ty) else { return false };
    let elem = strip_parens(&reference.elem);
    let is_self = matches!(elem, syn::Type::Path(path) if path.qself.is_none() && path.path.is_ident("Self"));
    let same = || {
        use quote::ToTokens;
        elem.to_token_stream().to_string() == strip_parens(self_ty).to_token_stream().to_string()
    };
    reference.mutability.is_none() && (is_self || same())
}

/// `ty` without parentheses or invisible groups around it.
fn strip_parens(ty: &syn::Type) -> &syn::Type {
    match ty {
        syn::Type::Paren(inner) => strip_parens(&inner.elem),
        syn::Type::Group(inner) => strip_parens(&inner.elem),
        ty => ty,
    }
}

/// The name a parameter binds: an identifier, or `None` for `_`. Reports any
/// other pattern.
fn binder(cx: &Ctxt, param: &Param<'_>) -> Binder {
    match param.pat {
        Pat::Ident(PatIdent { by_ref: None, subpat: None, ident, .. }) => Some(ident.clone()),
        Pat::Wild(_) => None,
        pat => {
            cx.error_spanned_by(pat, "parameters must be plain names such as `q` or `_`");
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use syn::{ItemImpl, parse_quote};

    fn errors(item: &ItemImpl) -> Vec<String> {
        let cx = Ctxt::new();
        let _ = validate(&cx, &Input::from_syn(item));
        cx.check().err().map_or_else(Vec::new, |errors| errors.messages())
    }

    #[test]
    fn accepts_the_documented_forms() {
        let item: ItemImpl = parse_quote! {
            impl<T: Copy> P<T> {
                fn lagrangian(&self, _t: f64, q: [f64; 2], v: [f64; 2]) -> f64 { q[0] * v[1] }
                fn dissipation(&self, _: [f64; 2], v: [f64; 2]) -> f64 { v[0] }
                fn force(&self, q: [f64; 2], v: [f64; 2]) -> [f64; 2] { [q[1], v[0]] }
                fn other(&self) {}
            }
        };
        assert_eq!(errors(&item), Vec::<String>::new());
        let cx = Ctxt::new();
        let system = validate(&cx, &Input::from_syn(&item)).unwrap();
        cx.check().unwrap();
        assert_eq!(system.n.len().and_then(Len::value), Some(2));
        assert!(system.lagrangian.time.is_some());
        assert!(system.force.unwrap().time.is_none());
        assert!(system.dissipation.unwrap().q.is_none());
    }

    #[test]
    fn extracts_a_constant_length() {
        let item: ItemImpl = parse_quote! {
            impl<const N: usize> Chain<N> {
                fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 { q[0] }
            }
        };
        let cx = Ctxt::new();
        let system = validate(&cx, &Input::from_syn(&item)).unwrap();
        cx.check().unwrap();
        let n = system.n.len().unwrap();
        assert_eq!(n.value(), None);
        assert_eq!(n.to_string(), "N");
    }

    #[test]
    fn reports_a_missing_lagrangian() {
        let item: ItemImpl = parse_quote!(impl P { fn other(&self) {} });
        let errors = errors(&item);
        assert_eq!(errors.len(), 1);
        assert!(errors[0].starts_with("no `lagrangian` method"));
    }

    #[test]
    fn reports_every_signature_error_at_once() {
        let item: ItemImpl = parse_quote! {
            impl P {
                // `q` is unusable, so `N = 3` comes from `v`.
                fn lagrangian(self, t: f32, q: [f32; 2], v: [f64; 3]) -> f32 { 0.0 }
                fn force(&self, q: [f64; 3], v: [f64; 2]) -> [f64; 2] { [0.0; 2] }
            }
        };
        let errors = errors(&item);
        assert_eq!(
            errors,
            [
                "`lagrangian` must take `&self`: the system is only read, never modified",
                "the time parameter of `lagrangian` must be `f64`",
                "`q` in `lagrangian` must be `[f64; N]`",
                "`lagrangian` must return `f64`",
                "`force` must have as many coordinates as `lagrangian`: expected `[f64; 3]`, found `[f64; 2]`",
                "`force` must return `[f64; 3]`",
            ]
        );
    }

    #[test]
    fn reports_mismatched_lengths_and_parameter_counts() {
        let item: ItemImpl = parse_quote! {
            impl P {
                fn lagrangian(&self, q: [f64; 2], v: [f64; 3]) -> f64 { 0.0 }
                fn dissipation(&self, t: f64, q: [f64; 2], v: [f64; 2]) -> f64 { 0.0 }
                fn force(&self, t: f64, s: f64, q: [f64; 2], v: [f64; 2]) -> [f64; 2] { [0.0; 2] }
            }
        };
        assert_eq!(
            errors(&item),
            [
                "`q` and `v` must have the same length: `q` is `[f64; 2]` but `v` is `[f64; 3]`",
                "`dissipation` takes no time argument: a rayleigh function is `R(q, v)`; \
                 put time-dependent forces in `fn force(&self, t: f64, q, v) -> [f64; N]`",
                "`force` takes `(&self, q: [f64; N], v: [f64; N])` or `(&self, t: f64, q: [f64; N], v: [f64; N])`, \
                 found 4 parameters besides `&self`",
            ]
        );
    }

    #[test]
    fn arity_survives_broken_signatures() {
        let item: ItemImpl = parse_quote! {
            impl P { fn lagrangian(self, q: [f32; 4], v: f64) {} }
        };
        let input = Input::from_syn(&item);
        assert_eq!(arity(&input).as_ref().and_then(Dim::len).and_then(Len::value), Some(4));
    }

    #[test]
    fn slices_make_a_run_time_sized_system() {
        let item: ItemImpl = parse_quote! {
            impl C {
                fn dimension(&self) -> usize { self.n }
                fn lagrangian(&self, t: f64, q: &[f64], v: &[f64]) -> f64 { q[q.len() - 1] * v[0] + t }
            }
        };
        let cx = Ctxt::new();
        let system = validate(&cx, &Input::from_syn(&item)).unwrap();
        cx.check().unwrap();
        assert!(system.n.is_dynamic() && system.n.len().is_none());
        assert!(system.lagrangian.time.is_some());
        assert!(matches!(arity(&Input::from_syn(&item)), Some(Dim::Dynamic)));
    }

    #[test]
    fn reports_what_a_run_time_sized_system_cannot_have() {
        let item: ItemImpl = parse_quote! {
            impl C {
                fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 { q[0] * v[0] }
                fn dissipation(&self, q: [f64; 2], v: [f64; 2]) -> f64 { v[0] }
                fn force(&self, q: &[f64], v: &[f64]) -> Vec<f64> { vec![] }
                fn step_density(&self, q: &[f64]) -> f64 { 1.0 }
            }
        };
        assert_eq!(
            errors(&item),
            [
                "`dissipation` of a run-time-sized system takes slices like `lagrangian`: \
                 write `fn dissipation(&self, q: &[f64], v: &[f64]) -> f64`",
                "`force` of a run-time-sized system takes \
                 `fn force(&self, [t: f64,] q: &[f64], v: &[f64], f: &mut [f64])`, found 2 parameters besides `&self`",
                "`force` of a run-time-sized system returns nothing: it writes the force into `f: &mut [f64]`, \
                 which arrives filled with zeros; remove the return type",
                "`step_density` is not supported for run-time-sized systems (`q: &[f64]`): \
                 `DynLagrangian` has no `step_density`; use `q: [f64; N]`",
                "a `lagrangian` taking slices (`q: &[f64]`) needs `fn dimension(&self) -> usize` in the same \
                 impl block: the number of coordinates is known only at run time",
            ]
        );
    }

    #[test]
    fn a_run_time_sized_system_takes_a_dissipation_function_over_slices() {
        let item: ItemImpl = parse_quote! {
            impl C {
                fn dimension(&self) -> usize { self.n }
                fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 { q[0] * v[0] }
                fn dissipation(&self, q: &[f64], v: &[f64]) -> f64 { 0.5 * v[0] * v[0] * q[q.len() - 1] }
            }
        };
        let cx = Ctxt::new();
        let system = validate(&cx, &Input::from_syn(&item)).unwrap();
        cx.check().unwrap();
        assert!(system.n.is_dynamic() && system.dissipation.is_some());
        // Slices beside an array Lagrangian are refused as before.
        let item: ItemImpl = parse_quote! {
            impl C {
                fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 { q[0] * v[0] }
                fn dissipation(&self, q: &[f64], v: &[f64]) -> f64 { v[0] }
            }
        };
        assert_eq!(
            errors(&item),
            ["`q` in `dissipation` must be `[f64; N]`", "`v` in `dissipation` must be `[f64; N]`"]
        );
    }

    #[test]
    fn a_run_time_sized_system_takes_a_force_written_into_a_slice() {
        for force in [
            quote::quote!(
                fn force(&self, t: f64, q: &[f64], v: &[f64], f: &mut [f64]) {
                    f[0] = q[0] * v[0] + t;
                }
            ),
            quote::quote!(
                fn force(&self, q: &[f64], _: &[f64], out: &mut [f64]) -> () {
                    out[0] -= q[0];
                }
            ),
            quote::quote!(
                fn force(&self, _: f64, _: &[f64], _: &[f64], _: &mut [f64]) {}
            ),
        ] {
            let item: ItemImpl = parse_quote! {
                impl C {
                    fn dimension(&self) -> usize { self.n }
                    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 { q[0] * v[0] }
                    #force
                }
            };
            let cx = Ctxt::new();
            let system = validate(&cx, &Input::from_syn(&item)).unwrap();
            cx.check().unwrap();
            let force = system.force.unwrap();
            assert!(force.out.is_some() && force.return_class() == crate::ir::Class::Unit);
        }
    }

    #[test]
    fn reports_wrong_forces_over_slices_saying_what_is_expected() {
        let force = |force: proc_macro2::TokenStream| -> Vec<String> {
            let item: ItemImpl = parse_quote! {
                impl C {
                    fn dimension(&self) -> usize { 2 }
                    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 { 0.0 }
                    #force
                }
            };
            errors(&item)
        };
        let expected = "`fn force(&self, [t: f64,] q: &[f64], v: &[f64], f: &mut [f64])`";
        assert_eq!(
            force(quote::quote!(
                fn force(&self, q: [f64; N], v: [f64; N]) -> [f64; N] {
                    q
                }
            )),
            [format!("`force` of a run-time-sized system takes slices like `lagrangian`: write {expected}")]
        );
        assert_eq!(
            force(quote::quote!(
                fn force(&self, q: &[f64], v: &[f64], f: &mut [f64]) -> Vec<f64> {
                    vec![]
                }
            )),
            ["`force` of a run-time-sized system returns nothing: it writes the force into `f: &mut [f64]`, \
              which arrives filled with zeros; remove the return type"]
        );
        assert_eq!(
            force(quote::quote!(
                fn force(&self, q: &[f64], v: &[f64], f: &[f64]) {}
            )),
            ["`f` in `force` must be `&mut [f64]`: the force is written into it"]
        );
        assert_eq!(
            force(quote::quote!(
                fn force(&self, t: f64, q: &[f64], v: &[f64], f: Vec<f64>) {}
            )),
            [format!(
                "`f` in `force` must be `&mut [f64]`: a run-time-sized system's force is written into its \
                 last parameter, {expected}"
            )]
        );
        assert_eq!(
            force(quote::quote!(
                fn force(&self, t: f64, q: &[f64], v: &[f64]) {}
            )),
            [format!("`force` of a run-time-sized system takes {expected}, found 3 parameters besides `&self`")]
        );
        assert_eq!(
            force(quote::quote!(
                fn force(&self, t: f32, q: &mut [f64], v: &[f64], f: &mut [f64]) {}
            )),
            [
                "the time parameter of `force` must be `f64`",
                "`q` in `force` must be `&[f64]`, not `&mut`: `force` only reads the state",
            ]
        );
    }

    #[test]
    fn reports_wrong_slice_parameters_saying_what_is_allowed() {
        let lagrangian = |params: proc_macro2::TokenStream| -> Vec<String> {
            let item: ItemImpl = parse_quote! {
                impl C {
                    fn dimension(&self) -> usize { 2 }
                    fn lagrangian(&self, #params) -> f64 { 0.0 }
                }
            };
            errors(&item)
        };
        assert_eq!(
            lagrangian(quote::quote!(q: &[f64], v: [f64; 2])),
            [
                "`q` and `v` must both be arrays `[f64; N]` or both slices `&[f64]`: `q` is `&[f64]` but `v` is `[f64; 2]`"
            ]
        );
        assert_eq!(
            lagrangian(quote::quote!(q: [f64; N], v: &[f64])),
            [
                "`q` and `v` must both be arrays `[f64; N]` or both slices `&[f64]`: `q` is `[f64; N]` but `v` is `&[f64]`"
            ]
        );
        assert_eq!(
            lagrangian(quote::quote!(q: &mut [f64], v: &[f64])),
            ["`q` in `lagrangian` must be `&[f64]`, not `&mut`: `lagrangian` only reads the state"]
        );
        assert_eq!(
            lagrangian(quote::quote!(q: &[f64], v: &[f32])),
            ["`v` in `lagrangian` must be `&[f64]` or `[f64; N]`: the body is rewritten from `f64` only"]
        );
        assert_eq!(
            lagrangian(quote::quote!(q: Vec<f64>, v: &[f64])),
            ["`q` in `lagrangian` must be `&[f64]` (size known at run time) or `[f64; N]`: \
              take a `Vec<f64>` as a slice, `q: &[f64]`"]
        );
        assert_eq!(lagrangian(quote::quote!(q: &[f64], v: f64)), ["`v` in `lagrangian` must be `&[f64]`"]);
        assert_eq!(lagrangian(quote::quote!(q: f64, v: f64)).len(), 2);
        // Beside an array, an array is asked for.
        assert_eq!(lagrangian(quote::quote!(q: Vec<f64>, v: [f64; 2])), ["`q` in `lagrangian` must be `[f64; N]`"]);
        assert_eq!(lagrangian(quote::quote!(q: [f64; 2], v: &mut [f64])), ["`v` in `lagrangian` must be `[f64; N]`"]);
        assert_eq!(
            lagrangian(quote::quote!(q: &[f64])),
            ["`lagrangian` takes `(&self, q: [f64; N], v: [f64; N])` or `(&self, t: f64, q: [f64; N], v: [f64; N])`, \
              or the same with slices `q: &[f64], v: &[f64]`, found 1 parameter besides `&self`"]
        );
    }

    #[test]
    fn checks_the_dimension_signature() {
        let item: ItemImpl = parse_quote! {
            impl C {
                fn dimension<T>(self, k: T) {}
                fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 { 0.0 }
            }
        };
        assert_eq!(
            errors(&item),
            [
                "`dimension` cannot have generic parameters: write `fn dimension(&self) -> usize`",
                "`dimension` must take `&self`: write `fn dimension(&self) -> usize`",
                "`dimension` takes no parameters besides `&self`: write `fn dimension(&self) -> usize`",
                "`dimension` must return `usize`: add `-> usize`",
            ]
        );
        // A `dimension` beside an array Lagrangian is the user's own method.
        let item: ItemImpl = parse_quote! {
            impl C {
                fn dimension(&self) -> u8 { 2 }
                fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 { 0.0 }
            }
        };
        assert_eq!(errors(&item), Vec::<String>::new());
    }
}
