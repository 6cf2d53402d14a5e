//! `Parametric<N, P>` from `#[lagrangian(parameters(m, l, u: [f64; K]))]`:
//! the bodies of `lagrangian`, `dissipation` and `force` once more, with
//! every `self.m` read from a parameter vector `theta` of the scalar type
//! `D`, so that the runtime can seed dual numbers on the parameters.
//!
//! `theta` is the concatenation of the parameters in the order of the list,
//! an array field contributing its `K` entries, so `P` is the sum of the
//! lengths. The copy is a second lowering of the user's methods (`validate`
//! again) in which each `self.<parameter>` becomes a local of class `Active`
//! (an array: `ActiveArray`) bound at the top of the generated method to
//! `theta[j]` (to `theta[j..j + K]`); `analyse` then classifies the copy as
//! it would a body reading `t`, and the printer prints it with the same
//! rules, so `self.u[i]` and `let u = self.u;` read `theta`'s entries.
//! Whether a parameter field has the declared type is left to rustc:
//! `parameters()` and `with_parameters` read and write the fields at the
//! names' spans, so a field of another type is a type error there.

use super::{Printer, cfgs, scalar_type};
use crate::attr::{Args, Parameter};
use crate::ctxt::Ctxt;
use crate::ir::{Binder, Block, Class, Expr, ExprKind, Function, Local, LocalId, Math};
use crate::parse::{Input, Len};
use proc_macro2::{Ident, Literal, Span, TokenStream, TokenTree};
use quote::{ToTokens, format_ident, quote, quote_spanned};
use syn::{ItemImpl, Member};

/// The rewritten methods and the parameters.
pub(crate) struct Copy {
    parameters: Vec<(Ident, Option<Len>)>,
    functions: Vec<Function>,
}

/// Lowers the methods once more with the parameters active; reports a name
/// no body reads, a scalar parameter a body indexes, a parameter used where
/// the rewrite needs a constant, and an array length from the impl's
/// generics.
pub(crate) fn prepare(cx: &Ctxt, input: &Input<'_>, args: &Args) -> Option<Copy> {
    let (_, parameters) = args.parameters.as_ref()?;
    if !lengths_are_constants(cx, input.item, parameters) {
        return None;
    }
    let names: Vec<Ident> = parameters.iter().map(|parameter| parameter.name.clone()).collect();
    let classes: Vec<Class> = parameters
        .iter()
        .map(|parameter| if parameter.len.is_some() { Class::ActiveArray } else { Class::Active })
        .collect();
    // The errors of the methods themselves were reported by the first lowering.
    let system = crate::validate::validate(&Ctxt::new(), input)?;
    let mut used = vec![false; names.len()];
    let mut indexed = vec![false; names.len()];
    let mut functions: Vec<Function> =
        std::iter::once(system.lagrangian).chain(system.dissipation).chain(system.force).collect();
    for function in &mut functions {
        let ids: Vec<(LocalId, Ident)> = names
            .iter()
            .zip(&classes)
            .map(|(name, &class)| {
                let id = LocalId(function.locals.len());
                let ident = local_name(name);
                function.locals.push(Local { name: ident.clone(), class });
                (id, ident)
            })
            .collect();
        substitute(&mut function.body, &names, &ids, &mut used, &mut indexed);
    }
    for (name, used) in names.iter().zip(&used) {
        if !used {
            cx.error_spanned_by(
                name,
                format!("parameter `{name}` is not read as `self.{name}` in `lagrangian`, `force` or `dissipation`"),
            );
        }
    }
    let mut scalar_arrays = false;
    for (parameter, indexed) in parameters.iter().zip(&indexed) {
        if *indexed && parameter.len.is_none() {
            let name = &parameter.name;
            cx.error_spanned_by(
                name,
                format!(
                    "parameter `{name}` is indexed as an array: declare an array parameter with its type, \
                     `{name}: [f64; K]`"
                ),
            );
            scalar_arrays = true;
        }
    }
    if scalar_arrays {
        return None;
    }
    let mut consistent = true;
    for function in &mut functions {
        consistent &= crate::analyse::classify(&Ctxt::new(), function);
    }
    if !consistent {
        for name in &names {
            cx.error_spanned_by(
                name,
                format!(
                    "parameter `{name}` cannot be differentiated: a body uses `self.{name}` where a constant is \
                     needed (an integer, an index, a length)"
                ),
            );
        }
        return None;
    }
    let parameters = parameters.iter().map(|Parameter { name, len }| (name.clone(), len.clone())).collect();
    Some(Copy { parameters, functions })
}

/// Whether every array length is a constant outside the impl: `P`, their
/// sum, is a const argument of `Parametric<N, P>`, and stable Rust takes no
/// arithmetic on the impl's generic parameters there (nor `Self`).
fn lengths_are_constants(cx: &Ctxt, item: &ItemImpl, parameters: &[Parameter]) -> bool {
    let generics: Vec<Ident> = item
        .generics
        .params
        .iter()
        .map(|param| match param {
            syn::GenericParam::Type(param) => param.ident.clone(),
            syn::GenericParam::Const(param) => param.ident.clone(),
            syn::GenericParam::Lifetime(param) => param.lifetime.ident.clone(),
        })
        .collect();
    let mut ok = true;
    for Parameter { name, len } in parameters {
        let Some(Len::Const(expr)) = len else { continue };
        if let Some(ident) = idents(expr.to_token_stream()).find(|ident| ident == "Self" || generics.contains(ident)) {
            cx.error_spanned_by(
                expr,
                format!(
                    "the length of parameter `{name}` is not known to the macro: `{ident}` belongs to the impl, and \
                     the number of parameters must be a constant; write a literal or a `const` item"
                ),
            );
            ok = false;
        }
    }
    ok
}

/// Every identifier in `tokens`, inside groups too.
fn idents(tokens: TokenStream) -> impl Iterator<Item = Ident> {
    fn walk(tokens: TokenStream, out: &mut Vec<Ident>) {
        for tree in tokens {
            match tree {
                TokenTree::Ident(ident) => out.push(ident),
                TokenTree::Group(group) => walk(group.stream(), out),
                TokenTree::Punct(_) | TokenTree::Literal(_) => {}
            }
        }
    }
    let mut out = Vec::new();
    walk(tokens, &mut out);
    out.into_iter()
}

/// The local a parameter is read from in the generated methods.
fn local_name(name: &Ident) -> Ident {
    format_ident!("__lagrangian_theta_{}", name, span = Span::call_site())
}

/// Replaces every `self.<parameter>` in `block` by the parameter's local,
/// marking the parameters it met in `used` and those it met indexed or
/// measured (`self.u[i]`, `self.u.len()`) in `indexed`.
fn substitute(block: &mut Block, names: &[Ident], ids: &[(LocalId, Ident)], used: &mut [bool], indexed: &mut [bool]) {
    let parameter = |e: &Expr| match &e.kind {
        ExprKind::Field { base, member: Member::Named(member) } if matches!(base.kind, ExprKind::SelfValue(_)) => {
            names.iter().position(|name| name == member)
        }
        _ => None,
    };
    block.visit_mut(&mut |e: &mut Expr| {
        if let ExprKind::Index { base: array, .. } | ExprKind::MethodCall { receiver: array, math: Math::Len, .. } =
            &e.kind
            && let Some(j) = parameter(array)
        {
            indexed[j] = true;
        }
        if let Some(j) = parameter(e) {
            used[j] = true;
            e.kind = ExprKind::Local(ids[j].0, ids[j].1.clone());
            return false;
        }
        true
    });
}

/// The number of entries of each parameter: `1` for a scalar, `K` for an
/// array, as constant expressions.
fn lengths(copy: &Copy) -> Vec<TokenStream> {
    copy.parameters
        .iter()
        .map(|(_, len)| match len {
            None => quote!(1usize),
            Some(Len::Lit { value, .. }) => Literal::usize_suffixed(*value).to_token_stream(),
            Some(len @ Len::Const(_)) => quote!((#len)),
        })
        .collect()
}

/// `P` and the offset of each parameter in `theta`: literals when every
/// length is one, sums of the lengths otherwise.
fn layout(copy: &Copy) -> (TokenStream, Vec<TokenStream>) {
    let literal: Option<Vec<usize>> = copy
        .parameters
        .iter()
        .map(|(_, len)| match len {
            None => Some(1),
            Some(len) => len.value(),
        })
        .collect();
    if let Some(lens) = literal {
        let offsets = lens
            .iter()
            .scan(0, |at, len| {
                let offset = *at;
                *at += len;
                Some(Literal::usize_unsuffixed(offset).to_token_stream())
            })
            .collect();
        return (Literal::usize_unsuffixed(lens.iter().sum()).to_token_stream(), offsets);
    }
    let lens = lengths(copy);
    let offsets = (0..lens.len()).map(|j| {
        let before = &lens[..j];
        quote!((0usize #(+ #before)*))
    });
    (quote!({ 0usize #(+ #lens)* }), offsets.collect())
}

/// The `Parametric<N, P>` impl.
pub(crate) fn items(item: &ItemImpl, copy: &Copy, n: &Len) -> TokenStream {
    let cfgs = cfgs(item);
    let (impl_generics, _, where_clause) = item.generics.split_for_impl();
    let self_ty = &item.self_ty;
    let n = n.generic_arg();
    let (p, offsets) = layout(copy);
    let lens = lengths(copy);
    let names = names(copy, &p);
    let reads = copy.parameters.iter().zip(&offsets).zip(&lens).map(|(((name, len), at), k)| match len {
        None => quote_spanned!(name.span()=> theta[#at] = self.#name;),
        Some(_) => quote_spanned!(name.span()=> theta[#at..#at + #k].copy_from_slice(&self.#name);),
    });
    let writes = copy.parameters.iter().zip(&offsets).zip(&lens).map(|(((name, len), at), k)| match len {
        None => quote_spanned!(name.span()=> copy.#name = theta[#at];),
        Some(_) => quote_spanned!(name.span()=> copy.#name.copy_from_slice(&theta[#at..#at + #k]);),
    });
    let methods = copy.functions.iter().map(|function| method(function, copy, &n, &p, &offsets, &lens));
    quote! {
        #cfgs
        #[allow(warnings, clippy::all, clippy::pedantic, clippy::nursery, clippy::restriction)]
        impl #impl_generics ::lagrangian::__private::Parametric<#n, #p> for #self_ty #where_clause {
            const NAMES: [&'static str; #p] = #names;
            fn parameters(&self) -> [f64; #p] {
                let mut theta = [0.0f64; #p];
                #(#reads)*
                theta
            }
            fn with_parameters(&self, theta: [f64; #p]) -> Self {
                let mut copy = ::core::clone::Clone::clone(self);
                #(#writes)*
                copy
            }
            #(#methods)*
        }
    }
}

/// `NAMES`: the field names of scalars, `u[0]`, `u[1]`, … for the entries
/// of an array, spelt at compile time by the runtime's `const fn`s since
/// an array's length may be a constant the macro cannot evaluate.
fn names(copy: &Copy, p: &TokenStream) -> TokenStream {
    if copy.parameters.iter().all(|(_, len)| len.is_none()) {
        let strings = copy.parameters.iter().map(|(name, _)| name.to_string());
        return quote!([#(#strings),*]);
    }
    let names = quote!(::lagrangian::__private::parameter_names);
    let fields = copy.parameters.iter().map(|(name, len)| {
        let name = name.to_string();
        match len {
            None => quote!((#name, ::core::option::Option::None)),
            Some(len) => quote!((#name, ::core::option::Option::Some(#len))),
        }
    });
    quote!({
        const FIELDS: &[#names::Field<'static>] = &[#(#fields),*];
        const BYTES: [u8; #names::len(FIELDS)] = #names::bytes(FIELDS);
        const NAMES: [&str; #p] = #names::split(&BYTES, FIELDS);
        NAMES
    })
}

/// One `*_with` method: the body printed generic over `D` after the
/// parameters' locals.
fn method(
    function: &Function,
    copy: &Copy,
    n: &TokenStream,
    p: &TokenStream,
    offsets: &[TokenStream],
    lens: &[TokenStream],
) -> TokenStream {
    let d = scalar_type();
    let name = format_ident!("{}_with", function.name);
    let binder = |binder: &Binder| match binder {
        Some(ident) => ident.to_token_stream(),
        None => quote!(_),
    };
    let (q, v) = (binder(&function.q), binder(&function.v));
    let theta = Ident::new("__lagrangian_theta", Span::call_site());
    let params = if function.kind.takes_time() {
        let t = function.time.as_ref().map_or_else(|| quote!(_), binder);
        quote!(#theta: &[#d; #p], #t: #d, #q: [#d; #n], #v: [#d; #n])
    } else {
        quote!(#theta: &[#d; #p], #q: [#d; #n], #v: [#d; #n])
    };
    let ret = if function.kind.returns_array() { quote!([#d; #n]) } else { quote!(#d) };
    let locals = copy.parameters.iter().zip(offsets).zip(lens).map(|(((name, len), at), k)| {
        let local = local_name(name);
        match len {
            None => quote!(let #local: #d = #theta[#at];),
            Some(_) => quote!(let #local: [#d; #k] = ::core::array::from_fn(|i| #theta[#at + i]);),
        }
    });
    let printer = Printer { locals: &function.locals, ret: function.return_class(), d: d.clone(), chunks: None };
    let body = printer.block(&function.body, Some(function.return_class()));
    let self_token = syn::Token![self](function.self_span);
    quote! {
        #[inline(always)]
        fn #name<#d: ::lagrangian::__private::Scalar>(&#self_token, #params) -> #ret {
            #(#locals)*
            #body
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::expand::expand;
    use proc_macro2::TokenStream;
    use quote::quote;
    use syn::{ItemImpl, parse_quote};

    /// A system reading a scalar, an array (by entry, as a whole and in a
    /// loop) and another scalar.
    fn controlled() -> ItemImpl {
        parse_quote! {
            impl Cart {
                fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 { 0.5 * self.m * v[0] * v[0] - self.g * q[0] }
                fn force(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> [f64; 1] {
                    let u = self.u;
                    let mut sum = 0.0;
                    for i in 0..self.u.len() {
                        sum += self.u[i] * t;
                    }
                    [sum + u[2]]
                }
            }
        }
    }

    fn expanded(attr: TokenStream, item: ItemImpl) -> String {
        expand(attr, item).to_string()
    }

    #[test]
    fn an_array_parameter_contributes_its_entries_in_declaration_order() {
        let out = expanded(quote!(parameters(m, u: [f64; 3], g)), controlled());
        assert!(!out.contains("compile_error"), "{out}");
        // θ = (m, u[0], u[1], u[2], g).
        assert!(out.contains("Parametric < 1 , 5 > for Cart"), "{out}");
        assert!(out.contains("theta [0] = self . m ;"), "{out}");
        assert!(out.contains("theta [1 .. 1 + 3usize] . copy_from_slice (& self . u) ;"), "{out}");
        assert!(out.contains("theta [4] = self . g ;"), "{out}");
        assert!(out.contains("copy . u . copy_from_slice (& theta [1 .. 1 + 3usize]) ;"), "{out}");
        assert!(out.contains("copy . g = theta [4] ;"), "{out}");
        // The bodies read the entries from `theta`, whole or indexed.
        assert!(
            out.contains(
                "let __lagrangian_theta_u : [__D ; 3usize] = :: core :: array :: from_fn (| i | __lagrangian_theta [1 + i]) ;"
            ),
            "{out}"
        );
        assert!(out.contains("let u = __lagrangian_theta_u ;"), "{out}");
        assert!(out.contains("__lagrangian_theta_u [i]"), "{out}");
        assert!(out.contains("0 .. __lagrangian_theta_u . len ()"), "{out}");
        assert!(out.contains(":: lagrangian :: __private :: parameter_names :: split (& BYTES , FIELDS)"), "{out}");
        assert!(out.contains("(\"u\" , :: core :: option :: Option :: Some (3))"), "{out}");
    }

    #[test]
    fn a_constant_length_is_summed_as_an_expression() {
        let out = expanded(quote!(parameters(u: [f64; CONTROLS], m, g)), controlled());
        assert!(!out.contains("compile_error"), "{out}");
        assert!(out.contains("Parametric < 1 , { 0usize + (CONTROLS) + 1usize + 1usize } > for Cart"), "{out}");
        assert!(out.contains("theta [(0usize + (CONTROLS))] = self . m ;"), "{out}");
        assert!(out.contains("theta [(0usize + (CONTROLS) + 1usize)] = self . g ;"), "{out}");
        assert!(
            out.contains("[__D ; (CONTROLS)] = :: core :: array :: from_fn (| i | __lagrangian_theta [(0usize) + i])"),
            "{out}"
        );
    }

    #[test]
    fn scalars_alone_keep_literal_names() {
        let out = expanded(quote!(parameters(m, g: f64)), controlled().clone());
        // `u` is not a parameter here: it stays a field read.
        assert!(out.contains("const NAMES : [& 'static str ; 2] = [\"m\" , \"g\"] ;"), "{out}");
        assert!(out.contains("let u = self . u ;"), "{out}");
    }

    /// The one error `attr` gets on [`controlled`], which must contain `message`.
    fn refused(attr: TokenStream, item: ItemImpl, message: &str) {
        let out = expanded(attr.clone(), item);
        assert_eq!(out.matches("compile_error").count(), 1, "{attr}: {out}");
        assert!(out.contains(message), "{attr}: {out}");
        assert!(!out.contains("Parametric <"), "{attr}: {out}");
    }

    #[test]
    fn wrong_array_parameters_are_refused_at_their_type() {
        refused(quote!(parameters(m, u: [f32; 3], g)), controlled(), "parameter `u` must hold `f64`");
        refused(quote!(parameters(m, u: [[f64; 3]; 1], g)), controlled(), "parameter `u` is a nested array");
        refused(quote!(parameters(m, u: [f64; _], g)), controlled(), "parameter `u` needs its length");
        refused(quote!(parameters(m, u: Vec<f64>, g)), controlled(), "parameter `u` must be `f64` or an array");
        refused(quote!(parameters(m, u, u: [f64; 3], g)), controlled(), "parameter `u` is named twice");
    }

    #[test]
    fn the_length_of_a_field_is_a_constant_of_the_rewrite() {
        let out = expanded(
            TokenStream::new(),
            parse_quote! {
                impl W {
                    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
                        0.5 * v[0] * v[0] - self.w[self.w.len() - 1] * q[0]
                    }
                }
            },
        );
        assert!(!out.contains("compile_error") && !out.contains("unreachable"), "{out}");
        assert!(out.contains("const HAS_GRADIENT : bool = true"), "{out}");
        assert!(out.contains("self) . w) . len ()"), "{out}");
    }

    #[test]
    fn an_array_named_without_its_type_is_refused_where_it_is_indexed() {
        refused(quote!(parameters(m, u, g)), controlled(), "parameter `u` is indexed as an array: declare");
    }

    #[test]
    fn a_length_from_the_impl_is_refused() {
        let mut item = controlled();
        item.generics = parse_quote!(<const K: usize>);
        refused(quote!(parameters(m, u: [f64; K], g)), item.clone(), "the length of parameter `u` is not known");
        refused(quote!(parameters(m, u: [f64; Self::K], g)), item.clone(), "`Self` belongs to the impl");
        // A constant outside the impl is fine in a generic impl.
        let out = expanded(quote!(parameters(m, u: [f64; CONTROLS], g)), item);
        assert!(!out.contains("compile_error"), "{out}");
    }
}
