//! The constraint items of `Lagrangian<N>` from the user's
//! `fn constraints(&self, [t,] q) -> [f64; M]`: the count `CONSTRAINTS = M`,
//! whether they depend on time, and `constraints`, the body printed generic
//! over the scalar `D` so that the runtime takes the Jacobian `G = ∂g/∂q`
//! from one evaluation on dual numbers seeded on `q`.

use super::{Chunks, Printer, scalar_type};
use crate::ir::{Binder, Function};
use crate::parse::Len;
use proc_macro2::{Ident, Span, TokenStream};
use quote::{ToTokens, quote};

/// The trait items, and the chunks of the body's long chains.
pub(super) fn items(function: &Function, m: &Len, n: &TokenStream) -> (TokenStream, Vec<TokenStream>) {
    let d = scalar_type();
    let binder = |binder: &Binder| match binder {
        Some(ident) => ident.to_token_stream(),
        None => quote!(_),
    };
    let q = binder(&function.q);
    let t = function.time.as_ref().map_or_else(|| quote!(_), binder);
    let autonomous = function.time.is_none();
    let chunks = Chunks::new(function, function.time.as_ref(), None, Some(n));
    let printer =
        Printer { locals: &function.locals, ret: function.return_class(), d: d.clone(), chunks: Some(&chunks) };
    let body = printer.block(&function.body, Some(function.return_class()));
    let self_token = syn::Token![self](function.self_span);
    let q_ref = Ident::new("__lagrangian_q", Span::call_site());
    let out = Ident::new("__lagrangian_g", Span::call_site());
    let value = Ident::new("__lagrangian_value", Span::call_site());
    let m = m.generic_arg();
    let items = quote! {
        const CONSTRAINTS: usize = #m;
        const CONSTRAINTS_AUTONOMOUS: bool = #autonomous;
        #[inline(always)]
        fn constraints<#d: ::lagrangian::__private::Scalar>(&#self_token, #t: #d, #q_ref: &[#d; #n], #out: &mut [#d]) {
            let #q: [#d; #n] = *#q_ref;
            let #value: [#d; #m] = #body;
            // The runtime passes `CONSTRAINTS` slots; zip never panics.
            for (slot, x) in #out.iter_mut().zip(#value) {
                *slot = x;
            }
        }
    };
    (items, chunks.into_items())
}
