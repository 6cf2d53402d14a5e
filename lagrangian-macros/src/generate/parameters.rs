//! `Parametric<N, P>` from `#[lagrangian(parameters(m, l, g))]`: the
//! bodies of `lagrangian`, `dissipation` and `force` once more, with every
//! `self.m` read from a parameter vector `theta` of the scalar type `D`, so
//! that the runtime can seed dual numbers on the parameters.
//!
//! The copy is a second lowering of the user's methods (`validate` again)
//! in which each `self.<parameter>` becomes a local of class `Active` bound
//! at the top of the generated method to `theta[j]`; `analyse` then
//! classifies the copy as it would a body reading `t`, and the printer
//! prints it with the same rules. Whether a parameter field is `f64` is
//! left to rustc: `parameters()` reads the fields at the names' spans, so
//! a field of another type is a type error there.

use super::{Printer, cfgs, scalar_type};
use crate::attr::Args;
use crate::ctxt::Ctxt;
use crate::ir::{Binder, Block, Expr, ExprKind, Function, Local, LocalId};
use crate::parse::{Input, Len};
use proc_macro2::{Ident, Span, TokenStream};
use quote::{ToTokens, format_ident, quote, quote_spanned};
use syn::{ItemImpl, Member};

/// The rewritten methods and the parameter names.
pub(crate) struct Copy {
    names: Vec<Ident>,
    functions: Vec<Function>,
}

/// Lowers the methods once more with the parameters active; reports a name
/// no body reads and a parameter used where the rewrite needs a constant.
pub(crate) fn prepare(cx: &Ctxt, input: &Input<'_>, args: &Args) -> Option<Copy> {
    let (_, names) = args.parameters.as_ref()?;
    // The errors of the methods themselves were reported by the first lowering.
    let system = crate::validate::validate(&Ctxt::new(), input)?;
    let mut used = vec![false; names.len()];
    let mut functions: Vec<Function> =
        std::iter::once(system.lagrangian).chain(system.dissipation).chain(system.force).collect();
    for function in &mut functions {
        let ids: Vec<(LocalId, Ident)> = names
            .iter()
            .map(|name| {
                let id = LocalId(function.locals.len());
                let ident = local_name(name);
                function.locals.push(Local { name: ident.clone(), class: crate::ir::Class::Active });
                (id, ident)
            })
            .collect();
        substitute(&mut function.body, names, &ids, &mut used);
    }
    for (name, used) in names.iter().zip(&used) {
        if !used {
            cx.error_spanned_by(
                name,
                format!("parameter `{name}` is not read as `self.{name}` in `lagrangian`, `force` or `dissipation`"),
            );
        }
    }
    let mut consistent = true;
    for function in &mut functions {
        consistent &= crate::analyse::classify(&Ctxt::new(), function);
    }
    if !consistent {
        for name in names {
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
    Some(Copy { names: names.clone(), functions })
}

/// The local a parameter is read from in the generated methods.
fn local_name(name: &Ident) -> Ident {
    format_ident!("__lagrangian_theta_{}", name, span = Span::call_site())
}

/// Replaces every `self.<parameter>` in `block` by the parameter's local,
/// marking the parameters it met in `used`.
fn substitute(block: &mut Block, names: &[Ident], ids: &[(LocalId, Ident)], used: &mut [bool]) {
    block.visit_mut(&mut |e: &mut Expr| {
        if let ExprKind::Field { base, member: Member::Named(member) } = &e.kind
            && matches!(base.kind, ExprKind::SelfValue(_))
            && let Some(j) = names.iter().position(|name| name == member)
        {
            used[j] = true;
            e.kind = ExprKind::Local(ids[j].0, ids[j].1.clone());
            return false;
        }
        true
    });
}

/// The `Parametric<N, P>` impl.
pub(crate) fn items(item: &ItemImpl, copy: &Copy, n: &Len) -> TokenStream {
    let cfgs = cfgs(item);
    let (impl_generics, _, where_clause) = item.generics.split_for_impl();
    let self_ty = &item.self_ty;
    let n = n.generic_arg();
    let p = copy.names.len();
    let names = &copy.names;
    let strings: Vec<String> = names.iter().map(ToString::to_string).collect();
    let reads = names.iter().map(|name| quote_spanned!(name.span()=> self.#name));
    let writes = names.iter().enumerate().map(|(j, name)| quote_spanned!(name.span()=> copy.#name = theta[#j];));
    let methods = copy.functions.iter().map(|function| method(function, copy, &n));
    quote! {
        #cfgs
        #[allow(warnings, clippy::all, clippy::pedantic, clippy::nursery, clippy::restriction)]
        impl #impl_generics ::lagrangian::__private::Parametric<#n, #p> for #self_ty #where_clause {
            const NAMES: [&'static str; #p] = [#(#strings),*];
            fn parameters(&self) -> [f64; #p] {
                [#(#reads),*]
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

/// One `*_with` method: the body printed generic over `D` after the
/// parameters' locals.
fn method(function: &Function, copy: &Copy, n: &TokenStream) -> TokenStream {
    let d = scalar_type();
    let name = format_ident!("{}_with", function.name);
    let binder = |binder: &Binder| match binder {
        Some(ident) => ident.to_token_stream(),
        None => quote!(_),
    };
    let (q, v) = (binder(&function.q), binder(&function.v));
    let theta = Ident::new("__lagrangian_theta", Span::call_site());
    let p = copy.names.len();
    let params = if function.kind.takes_time() {
        let t = function.time.as_ref().map_or_else(|| quote!(_), binder);
        quote!(#theta: &[#d; #p], #t: #d, #q: [#d; #n], #v: [#d; #n])
    } else {
        quote!(#theta: &[#d; #p], #q: [#d; #n], #v: [#d; #n])
    };
    let ret = if function.kind.returns_array() { quote!([#d; #n]) } else { quote!(#d) };
    let locals = copy.names.iter().enumerate().map(|(j, name)| {
        let local = local_name(name);
        quote!(let #local: #d = #theta[#j];)
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
