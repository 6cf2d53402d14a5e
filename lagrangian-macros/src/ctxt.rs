//! Error accumulation, after serde_derive's `internals/ctxt.rs`.
//!
//! Every stage reports problems here instead of returning at the first one, so
//! a user with three mistakes in a method sees all three in one build.

use crate::parse::MethodKind;
use proc_macro2::{Span, TokenStream};
use quote::ToTokens;
use std::cell::RefCell;
use std::fmt::Display;

/// Where an error is emitted in the expansion.
///
/// An error about a method body goes inside that body: rustc then skips its
/// own later checks of the body, which would otherwise repeat some of the
/// mistakes (borrowck's "cannot assign to `self.x`" after ours).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Site {
    /// Beside the block: signatures, missing methods, arguments.
    Block,
    /// Inside the body of the given method.
    Body(MethodKind),
}

/// Collects the errors of one `#[lagrangian]` expansion.
///
/// The stages share it by `&` reference (hence the `RefCell`), which keeps
/// their signatures free of `&mut` plumbing.
#[derive(Default)]
pub(crate) struct Ctxt {
    errors: RefCell<Vec<(Site, syn::Error)>>,
}

impl Ctxt {
    /// An empty context.
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// Records an error spanning the tokens of `obj`, emitted beside the block.
    pub(crate) fn error_spanned_by<A: ToTokens, T: Display>(&self, obj: A, msg: T) {
        self.push(Site::Block, spanned(obj.into_token_stream(), msg.to_string()));
    }

    /// Records an error at `span`, emitted beside the block.
    pub(crate) fn error_at<T: Display>(&self, span: Span, msg: T) {
        self.push(Site::Block, syn::Error::new(span, msg));
    }

    /// Records an error spanning the tokens of `obj`, found in the body of
    /// `method`.
    pub(crate) fn body_error_spanned_by<A: ToTokens, T: Display>(&self, method: MethodKind, obj: A, msg: T) {
        self.push(Site::Body(method), spanned(obj.into_token_stream(), msg.to_string()));
    }

    /// Records an error at `span`, found in the body of `method`.
    pub(crate) fn body_error_at<T: Display>(&self, method: MethodKind, span: Span, msg: T) {
        self.push(Site::Body(method), syn::Error::new(span, msg));
    }

    /// Consumes the context: `Ok` if nothing was reported.
    pub(crate) fn check(self) -> Result<(), Errors> {
        let errors = self.errors.into_inner();
        if errors.is_empty() { Ok(()) } else { Err(Errors(errors)) }
    }

    fn push(&self, site: Site, error: syn::Error) {
        self.errors.borrow_mut().push((site, error));
    }
}

/// Non-generic, so that it is compiled once rather than once per caller's
/// argument types.
fn spanned(tokens: TokenStream, msg: String) -> syn::Error {
    syn::Error::new_spanned(tokens, msg)
}

/// The errors of a failed expansion, in the order they were found.
#[derive(Debug)]
pub(crate) struct Errors(Vec<(Site, syn::Error)>);

impl Errors {
    /// `compile_error!` invocations for the errors to emit at `site`, one
    /// per error, each at its own span.
    pub(crate) fn at(&self, site: Site) -> TokenStream {
        self.0.iter().filter(|(at, _)| *at == site).map(|(_, error)| error.to_compile_error()).collect()
    }

    /// The messages, for tests.
    #[cfg(test)]
    pub(crate) fn messages(&self) -> Vec<String> {
        self.0.iter().map(|(_, error)| error.to_string()).collect()
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
    fn errors_keep_their_order_and_site() {
        let cx = Ctxt::new();
        cx.error_at(Span::call_site(), "first");
        cx.body_error_spanned_by(MethodKind::Force, quote::quote!(a + b), "second");
        cx.error_spanned_by(quote::quote!(c), "third");
        let errors = cx.check().unwrap_err();
        assert_eq!(errors.messages(), ["first", "second", "third"]);
        let block = errors.at(Site::Block).to_string();
        assert!(block.contains("\"first\"") && block.contains("\"third\"") && !block.contains("second"));
        assert!(errors.at(Site::Body(MethodKind::Force)).to_string().contains("\"second\""));
        assert!(errors.at(Site::Body(MethodKind::Lagrangian)).is_empty());
    }
}
