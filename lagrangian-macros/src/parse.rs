//! Syntactic model of the annotated `impl` block.
//!
//! This stage finds the methods the macro recognises and describes the shape
//! of their signatures. It judges nothing: `validate` does, so that it can
//! report every problem at once with the whole picture in hand.

use proc_macro2::TokenStream;
use quote::{ToTokens, quote};
use std::fmt;
use syn::{Expr, FnArg, Ident, ImplItem, ImplItemFn, ItemImpl, Lit, LitInt, Pat, Receiver, ReturnType, Type};

/// The methods of the block that `#[lagrangian]` gives a meaning to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MethodKind {
    /// `fn lagrangian(&self, [t,] q, v) -> f64`, required.
    Lagrangian,
    /// `fn dissipation(&self, q, v) -> f64`, optional.
    Dissipation,
    /// `fn force(&self, [t,] q, v) -> [f64; N]`, optional.
    Force,
    /// `fn step_density(&self, [t,] q) -> f64`, optional: the monitor
    /// `g(t, q)` of the time-transformed integrators.
    StepDensity,
    /// `fn constraints(&self, [t,] q) -> [f64; M]`, optional: holonomic
    /// constraints `g(t, q) = 0` (see `crate::constraints`).
    Constraints,
}

impl MethodKind {
    /// The recognised method name.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Self::Lagrangian => "lagrangian",
            Self::Dissipation => "dissipation",
            Self::Force => "force",
            Self::StepDensity => "step_density",
            Self::Constraints => "constraints",
        }
    }

    /// The kind of a method called `ident`, if it is one the macro recognises.
    pub(crate) fn from_ident(ident: &Ident) -> Option<Self> {
        [Self::Lagrangian, Self::Dissipation, Self::Force, Self::StepDensity, Self::Constraints]
            .into_iter()
            .find(|kind| ident == kind.name())
    }

    /// Whether the method may take a leading `t: f64`; the trait's
    /// `dissipation` has no time argument.
    pub(crate) fn takes_time(self) -> bool {
        self != Self::Dissipation
    }

    /// Whether the method takes the velocity; a step density and the
    /// constraints are functions of `(t, q)`.
    pub(crate) fn takes_velocity(self) -> bool {
        !matches!(self, Self::StepDensity | Self::Constraints)
    }

    /// Whether the method returns one value per coordinate (`[f64; N]`)
    /// rather than a scalar; the constraints return `[f64; M]`, one value
    /// per constraint.
    pub(crate) fn returns_array(self) -> bool {
        matches!(self, Self::Force | Self::Constraints)
    }
}

/// The annotated block with its recognised methods picked out.
pub(crate) struct Input<'a> {
    /// The block as the user wrote it.
    pub(crate) item: &'a ItemImpl,
    /// `fn lagrangian`, if present.
    pub(crate) lagrangian: Option<Method<'a>>,
    /// `fn dissipation`, if present.
    pub(crate) dissipation: Option<Method<'a>>,
    /// `fn force`, if present.
    pub(crate) force: Option<Method<'a>>,
    /// `fn step_density`, if present.
    pub(crate) step_density: Option<Method<'a>>,
    /// `fn constraints`, if present.
    pub(crate) constraints: Option<Method<'a>>,
    /// `fn dimension`, if present: the size of a run-time-sized system,
    /// whose `lagrangian` takes slices. Not rewritten, so not a
    /// [`MethodKind`]; ignored when the Lagrangian takes arrays.
    pub(crate) dimension: Option<&'a ImplItemFn>,
}

impl<'a> Input<'a> {
    /// Picks the recognised methods out of `item`. When a name appears twice
    /// the first one is kept: rustc reports the duplicate definition itself.
    pub(crate) fn from_syn(item: &'a ItemImpl) -> Self {
        let mut input = Input {
            item,
            lagrangian: None,
            dissipation: None,
            force: None,
            step_density: None,
            constraints: None,
            dimension: None,
        };
        for func in item.items.iter().filter_map(|item| match item {
            ImplItem::Fn(func) => Some(func),
            _ => None,
        }) {
            if func.sig.ident == "dimension" && input.dimension.is_none() {
                input.dimension = Some(func);
            }
            let Some(kind) = MethodKind::from_ident(&func.sig.ident) else {
                continue;
            };
            let slot = match kind {
                MethodKind::Lagrangian => &mut input.lagrangian,
                MethodKind::Dissipation => &mut input.dissipation,
                MethodKind::Force => &mut input.force,
                MethodKind::StepDensity => &mut input.step_density,
                MethodKind::Constraints => &mut input.constraints,
            };
            if slot.is_none() {
                *slot = Some(Method::from_syn(kind, func));
            }
        }
        input
    }
}

/// One recognised method, its signature broken into parts.
pub(crate) struct Method<'a> {
    /// Which method this is.
    pub(crate) kind: MethodKind,
    /// The method as written.
    pub(crate) func: &'a ImplItemFn,
    /// The `self` parameter, if any.
    pub(crate) receiver: Option<&'a Receiver>,
    /// The parameters after the receiver.
    pub(crate) params: Vec<Param<'a>>,
    /// The return type, `None` when the signature has none.
    pub(crate) output: Option<(&'a Type, Shape)>,
}

impl<'a> Method<'a> {
    fn from_syn(kind: MethodKind, func: &'a ImplItemFn) -> Self {
        let params = func
            .sig
            .inputs
            .iter()
            .filter_map(|arg| match arg {
                FnArg::Typed(typed) => Some(Param { pat: &typed.pat, ty: &typed.ty, shape: Shape::of(&typed.ty) }),
                FnArg::Receiver(_) => None,
            })
            .collect();
        let output = match &func.sig.output {
            ReturnType::Type(_, ty) => Some((&**ty, Shape::of(ty))),
            ReturnType::Default => None,
        };
        Method { kind, func, receiver: func.sig.receiver(), params, output }
    }
}

/// A typed parameter.
pub(crate) struct Param<'a> {
    /// The binding pattern, normally a plain name.
    pub(crate) pat: &'a Pat,
    /// The type as written.
    pub(crate) ty: &'a Type,
    /// What the type looks like to the macro.
    pub(crate) shape: Shape,
}

/// The shape of a parameter or return type, as far as the macro cares.
#[derive(Clone, Debug)]
pub(crate) enum Shape {
    /// `f64`.
    F64,
    /// `[E; len]`; `of_f64` tells whether `E` is `f64`. Kept even for other
    /// element types so that the length is known for error recovery.
    Array {
        /// Whether the element type is `f64`.
        of_f64: bool,
        /// The length.
        len: Len,
    },
    /// `&[E]` or `&mut [E]`: a run-time-sized system when `E` is `f64` and
    /// the borrow is shared.
    Slice {
        /// Whether the element type is `f64`.
        of_f64: bool,
        /// Whether the borrow is `&mut`.
        mutable: bool,
    },
    /// Anything else.
    Other,
}

impl Shape {
    /// Classifies a written type.
    pub(crate) fn of(ty: &Type) -> Self {
        match ty {
            Type::Paren(inner) => Self::of(&inner.elem),
            Type::Group(inner) => Self::of(&inner.elem),
            Type::Array(array) => Shape::Array { of_f64: is_f64(&array.elem), len: Len::from_expr(&array.len) },
            Type::Reference(reference) => match strip_groups(&reference.elem) {
                Type::Slice(slice) => {
                    Shape::Slice { of_f64: is_f64(&slice.elem), mutable: reference.mutability.is_some() }
                }
                _ => Shape::Other,
            },
            ty if is_f64(ty) => Shape::F64,
            _ => Shape::Other,
        }
    }
}

/// `ty` without parentheses or invisible groups around it.
fn strip_groups(ty: &Type) -> &Type {
    match ty {
        Type::Paren(inner) => strip_groups(&inner.elem),
        Type::Group(inner) => strip_groups(&inner.elem),
        ty => ty,
    }
}

/// Whether `ty` is written `Vec<...>` (any path ending in `Vec`), for a
/// message that points to the slice form.
pub(crate) fn is_vec(ty: &Type) -> bool {
    match strip_groups(ty) {
        Type::Path(path) => path.qself.is_none() && path.path.segments.last().is_some_and(|seg| seg.ident == "Vec"),
        _ => false,
    }
}

/// Whether `ty` is written `usize`.
pub(crate) fn is_usize(ty: &Type) -> bool {
    matches!(strip_groups(ty), Type::Path(path) if path.qself.is_none() && path.path.is_ident("usize"))
}

/// Whether `ty` is written `f64`.
pub(crate) fn is_f64(ty: &Type) -> bool {
    match ty {
        Type::Path(path) => path.qself.is_none() && path.path.is_ident("f64"),
        Type::Paren(inner) => is_f64(&inner.elem),
        Type::Group(inner) => is_f64(&inner.elem),
        _ => false,
    }
}

/// The number of coordinates of a system: fixed by its type (`[f64; N]`,
/// the trait `Lagrangian<N>`) or known only at run time (`&[f64]`, the trait
/// `DynLagrangian`).
#[derive(Clone, Debug)]
pub(crate) enum Dim {
    /// `q: [f64; N]`.
    Fixed(Len),
    /// `q: &[f64]`.
    Dynamic,
}

impl Dim {
    /// `N`, for a fixed-size system.
    pub(crate) fn len(&self) -> Option<&Len> {
        match self {
            Dim::Fixed(len) => Some(len),
            Dim::Dynamic => None,
        }
    }

    /// Whether the size is known only at run time.
    pub(crate) fn is_dynamic(&self) -> bool {
        matches!(self, Dim::Dynamic)
    }
}

/// The number of coordinates `N`, as written in `[f64; N]`.
#[derive(Clone, Debug)]
pub(crate) enum Len {
    /// An integer literal; its value allows bounds checks on `q[i]`.
    Lit {
        /// The value.
        value: usize,
        /// The literal, for spans.
        lit: LitInt,
    },
    /// A constant expression (`N`, `Self::DIM`): not evaluated, compared by
    /// its tokens, and no bounds checks.
    Const(Box<Expr>),
}

impl Len {
    /// The length written as `expr`.
    pub(crate) fn from_expr(expr: &Expr) -> Self {
        match expr {
            Expr::Lit(syn::ExprLit { lit: Lit::Int(lit), .. }) => match lit.base10_parse() {
                Ok(value) => Len::Lit { value, lit: lit.clone() },
                // Too large for usize: rustc rejects the type itself.
                Err(_) => Len::Const(Box::new(expr.clone())),
            },
            _ => Len::Const(Box::new(expr.clone())),
        }
    }

    /// The value, when written as a literal.
    pub(crate) fn value(&self) -> Option<usize> {
        match self {
            Len::Lit { value, .. } => Some(*value),
            Len::Const(_) => None,
        }
    }

    /// Whether two lengths are the same: equal values for literals, equal
    /// tokens for constants. A literal and a constant never match, since the
    /// macro cannot evaluate the constant.
    pub(crate) fn same_as(&self, other: &Len) -> bool {
        match (self, other) {
            (Len::Lit { value: a, .. }, Len::Lit { value: b, .. }) => a == b,
            (Len::Const(a), Len::Const(b)) => a.to_token_stream().to_string() == b.to_token_stream().to_string(),
            _ => false,
        }
    }

    /// The length as a const generic argument (`Lagrangian<#arg>`): complex
    /// expressions need braces there.
    pub(crate) fn generic_arg(&self) -> TokenStream {
        match self {
            Len::Const(expr) if !matches!(**expr, Expr::Path(_) | Expr::Block(_)) => quote!({ #expr }),
            _ => self.to_token_stream(),
        }
    }
}

impl ToTokens for Len {
    fn to_tokens(&self, tokens: &mut TokenStream) {
        match self {
            Len::Lit { value, lit } => {
                // Unsuffixed, so that it fits both `[T; #len]` and
                // `Lagrangian<#len>` whatever suffix the user wrote.
                LitInt::new(&value.to_string(), lit.span()).to_tokens(tokens);
            }
            Len::Const(expr) => expr.to_tokens(tokens),
        }
    }
}

impl fmt::Display for Len {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Len::Lit { value, .. } => write!(f, "{value}"),
            Len::Const(expr) => write!(f, "{}", expr.to_token_stream()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use syn::parse_quote;

    #[test]
    fn finds_the_recognised_methods_and_ignores_others() {
        let item: ItemImpl = parse_quote! {
            impl P {
                fn helper(&self) -> f64 { 1.0 }
                fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 { 0.0 }
                fn force(&self, t: f64, q: [f64; 2], v: [f64; 2]) -> [f64; 2] { [0.0, 0.0] }
                const K: f64 = 1.0;
            }
        };
        let input = Input::from_syn(&item);
        let lagrangian = input.lagrangian.unwrap();
        assert!(lagrangian.receiver.is_some());
        assert_eq!(lagrangian.params.len(), 2);
        assert!(matches!(lagrangian.output, Some((_, Shape::F64))));
        assert!(input.dissipation.is_none());
        assert_eq!(input.force.unwrap().params.len(), 3);
    }

    #[test]
    fn shapes_and_lengths() {
        let shape = |ty: Type| Shape::of(&ty);
        assert!(matches!(shape(parse_quote!(f64)), Shape::F64));
        assert!(matches!(shape(parse_quote!(f32)), Shape::Other));
        assert!(matches!(shape(parse_quote!([f64; 3])), Shape::Array { of_f64: true, len: Len::Lit { value: 3, .. } }));
        assert!(matches!(
            shape(parse_quote!([f32; 3usize])),
            Shape::Array { of_f64: false, len: Len::Lit { value: 3, .. } }
        ));
        let Shape::Array { len, .. } = shape(parse_quote!([f64; DIM])) else {
            panic!("expected an array");
        };
        assert_eq!(len.value(), None);
        assert_eq!(len.to_string(), "DIM");
        assert_eq!(len.generic_arg().to_string(), "DIM");
    }

    #[test]
    fn lengths_compare_by_value_or_by_tokens() {
        let len = |ty: Type| match Shape::of(&ty) {
            Shape::Array { len, .. } => len,
            _ => unreachable!(),
        };
        assert!(len(parse_quote!([f64; 2])).same_as(&len(parse_quote!([f64; 2usize]))));
        assert!(!len(parse_quote!([f64; 2])).same_as(&len(parse_quote!([f64; 3]))));
        assert!(len(parse_quote!([f64; N])).same_as(&len(parse_quote!([f64; N]))));
        assert!(!len(parse_quote!([f64; N])).same_as(&len(parse_quote!([f64; 2]))));
        assert_eq!(len(parse_quote!([f64; 2usize])).to_token_stream().to_string(), "2");
        assert_eq!(len(parse_quote!([f64; 2 * K])).generic_arg().to_string(), "{ 2 * K }");
    }

    #[test]
    fn slice_shapes_and_the_dimension_method() {
        let shape = |ty: Type| Shape::of(&ty);
        assert!(matches!(shape(parse_quote!(&[f64])), Shape::Slice { of_f64: true, mutable: false }));
        assert!(matches!(shape(parse_quote!(&'a [f64])), Shape::Slice { of_f64: true, mutable: false }));
        assert!(matches!(shape(parse_quote!(&mut [f64])), Shape::Slice { of_f64: true, mutable: true }));
        assert!(matches!(shape(parse_quote!(&[f32])), Shape::Slice { of_f64: false, mutable: false }));
        assert!(matches!(shape(parse_quote!(&[f64; 3])), Shape::Other));
        assert!(matches!(shape(parse_quote!(Vec<f64>)), Shape::Other));
        assert!(is_vec(&parse_quote!(std::vec::Vec<f64>)) && !is_vec(&parse_quote!(&[f64])));
        assert!(is_usize(&parse_quote!(usize)) && !is_usize(&parse_quote!(u32)));

        let item: ItemImpl = parse_quote! {
            impl C {
                fn dimension(&self) -> usize { self.n }
                fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 { q[0] * v[0] }
            }
        };
        let input = Input::from_syn(&item);
        assert_eq!(input.dimension.map(|f| f.sig.ident.to_string()).as_deref(), Some("dimension"));
        let params = &input.lagrangian.unwrap().params;
        assert!(params.iter().all(|p| matches!(p.shape, Shape::Slice { of_f64: true, mutable: false })));
    }
}
