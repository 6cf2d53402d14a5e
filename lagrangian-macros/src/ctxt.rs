//! Error accumulation, after serde_derive's `internals/ctxt.rs`.
//!
//! Every stage reports problems here instead of returning at the first one, so
//! a user with three mistakes in a method sees all three in one build.

use proc_macro2::Span;
use quote::ToTokens;
use std::cell::RefCell;
use std::fmt::Display;

/// Collects the errors of one `#[lagrangian]` expansion.
///
/// The stages share it by `&` reference (hence the `RefCell`), which keeps
/// their signatures free of `&mut` plumbing.
#[derive(Default)]
pub(crate) struct Ctxt {
    errors: RefCell<Vec<syn::Error>>,
}

impl Ctxt {
    /// An empty context.
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// Records an error spanning the tokens of `obj`.
    pub(crate) fn error_spanned_by<A: ToTokens, T: Display>(&self, obj: A, msg: T) {
        // `into_token_stream` first: one non-generic `new_spanned` call per
        // message type instead of one per (tokens, message) pair.
        self.push(syn::Error::new_spanned(obj.into_token_stream(), msg));
    }

    /// Records an error at `span`.
    pub(crate) fn error_at<T: Display>(&self, span: Span, msg: T) {
        self.push(syn::Error::new(span, msg));
    }

    /// Consumes the context: `Ok` if nothing was reported, otherwise every
    /// error combined into one, which renders as one diagnostic per error.
    pub(crate) fn check(self) -> syn::Result<()> {
        let mut errors = self.errors.into_inner().into_iter();
        let Some(mut combined) = errors.next() else {
            return Ok(());
        };
        for rest in errors {
            combined.combine(rest);
        }
        Err(combined)
    }

    fn push(&self, error: syn::Error) {
        self.errors.borrow_mut().push(error);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_context_checks_ok() {
        assert!(Ctxt::new().check().is_ok());
    }

    #[test]
    fn errors_are_combined_in_order() {
        let cx = Ctxt::new();
        cx.error_at(Span::call_site(), "first");
        cx.error_spanned_by(quote::quote!(a + b), "second");
        let messages: Vec<String> = cx.check().unwrap_err().into_iter().map(|e| e.to_string()).collect();
        assert_eq!(messages, ["first", "second"]);
    }
}
