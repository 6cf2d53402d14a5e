//! The pipeline: parse → validate → analyse → generate, with a fallback that
//! still emits the user's block (and a stub trait impl) after errors.

use crate::ctxt::Ctxt;
use crate::parse::{Dim, Input};
use crate::{analyse, attr, discontinuity, generate, validate};
use proc_macro2::TokenStream;
use syn::ItemImpl;

/// Expands `#[lagrangian]` with arguments `attr` on `item`.
pub(crate) fn expand(attr: TokenStream, item: ItemImpl) -> TokenStream {
    let cx = Ctxt::new();
    let args = attr::parse(&cx, attr);
    let input = Input::from_syn(&item);
    let mut system = validate::validate(&cx, &input);
    match system.as_ref().map(|system| &system.n) {
        Some(Dim::Fixed(n)) => attr::check(&cx, &args.symmetries, n),
        // `DynLagrangian` has no `SYMMETRIES`.
        Some(Dim::Dynamic) => {
            attr::refuse_symmetries(&cx, &args);
            attr::refuse_parameters(&cx, &args);
        }
        None => {}
    }
    let parametric = match system.as_ref().map(|system| &system.n) {
        Some(Dim::Fixed(n)) => generate::parameters::prepare(&cx, &input, &args).map(|copy| (copy, n.clone())),
        _ => None,
    };
    let analysis = system.as_mut().map(|system| analyse::analyse(&cx, system));
    if let Some(system) = &system {
        discontinuity::check(&cx, &system.lagrangian, args.discontinuous);
    }
    match (cx.check(), system, analysis) {
        (Ok(()), Some(system), Some(analysis)) if analysis.consistent => {
            let mut out = generate::expand(&item, &system, &analysis, &args);
            if let Some((copy, n)) = &parametric {
                out.extend(generate::parameters::items(&item, copy, n));
            }
            out
        }
        // The body mixes types in a way rustc rejects on the user's own
        // method; generated code would only repeat that error.
        (Ok(()), Some(_), _) => generate::fallback(&item, validate::arity(&input).as_ref(), None),
        // Every stage reports what makes it give up, so this is a bug; it
        // must still not end in a stub that only fails at run time.
        (Ok(()), None, _) => {
            let cx = Ctxt::new();
            cx.error_spanned_by(
                &item.self_ty,
                "internal error: `#[lagrangian]` cannot rewrite this block but found nothing to report; \
                 please report this with the block",
            );
            let errors = cx.check().err();
            generate::fallback(&item, validate::arity(&input).as_ref(), errors.as_ref())
        }
        (Err(errors), ..) => generate::fallback(&item, validate::arity(&input).as_ref(), Some(&errors)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use quote::quote;
    use syn::parse_quote;

    #[test]
    fn a_valid_block_expands_to_itself_plus_the_trait_impl() {
        let out = expand(
            TokenStream::new(),
            parse_quote! {
                impl Pendulum {
                    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 { v[0] * v[0] - q[0].cos() }
                }
            },
        )
        .to_string();
        assert!(!out.contains("compile_error"), "{out}");
        assert!(out.contains("impl :: lagrangian :: __private :: Lagrangian < 1 > for Pendulum"), "{out}");
    }

    #[test]
    fn every_error_of_a_block_is_reported_and_a_stub_follows() {
        let out = expand(
            quote!(oops),
            parse_quote! {
                impl P {
                    fn lagrangian(&mut self, q: [f64; 2], v: [f64; 2]) -> f64 {
                        let s = q[2] + v[0].floor();
                        self.m = s;
                        s
                    }
                    fn force(&self, q: [f64; 3], v: [f64; 3]) -> [f64; 3] { [0.0; 3] }
                }
            },
        )
        .to_string();
        let errors = out.matches("compile_error").count();
        // The attribute argument, the receiver, `q[2]`, `floor`, writing to
        // `self`, and `force`'s two lengths and its return type.
        assert_eq!(errors, 8, "{out}");
        assert!(out.contains("impl :: lagrangian :: __private :: Lagrangian < 2 > for P"), "{out}");
        assert!(out.contains("unreachable"), "{out}");
    }

    #[test]
    fn rustc_type_errors_get_a_silent_stub() {
        let out = expand(
            TokenStream::new(),
            parse_quote! {
                impl P { fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 { 2 * q[0] } }
            },
        )
        .to_string();
        assert!(!out.contains("compile_error"), "{out}");
        assert!(out.contains("unreachable"), "{out}");
    }

    #[test]
    fn a_branch_on_q_is_refused_unless_acknowledged() {
        let item: ItemImpl = parse_quote! {
            impl Step {
                fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
                    0.5 * v[0] * v[0] - if q[0] > 0.0 { self.h } else { 0.0 }
                }
            }
        };
        let out = expand(TokenStream::new(), item.clone()).to_string();
        assert_eq!(out.matches("compile_error").count(), 1, "{out}");
        assert!(out.contains("`lagrangian` is discontinuous here"), "{out}");
        assert!(!out.contains("DISCONTINUOUS"), "{out}");

        let out = expand(quote!(discontinuous), item.clone()).to_string();
        assert!(!out.contains("compile_error"), "{out}");
        assert!(out.contains("const DISCONTINUOUS : bool = true ;"), "{out}");

        // With symmetries too, in any order; a smooth body never sets it.
        let out = expand(quote!(symmetry = translation(0), discontinuous), item).to_string();
        assert!(!out.contains("compile_error") && out.contains("const DISCONTINUOUS : bool = true ;"), "{out}");
        let out = expand(
            TokenStream::new(),
            parse_quote! { impl P { fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 { v[0] * q[0] } } },
        )
        .to_string();
        assert!(!out.contains("DISCONTINUOUS"), "{out}");
    }

    #[test]
    fn discontinuous_takes_no_value_and_is_given_once() {
        let item: ItemImpl =
            parse_quote! { impl P { fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 { v[0] * q[0] } } };
        for attr in [quote!(discontinuous = true), quote!(discontinuous(yes)), quote!(discontinuous, discontinuous)] {
            let out = expand(attr.clone(), item.clone()).to_string();
            assert_eq!(out.matches("compile_error").count(), 1, "{attr}: {out}");
        }
    }

    #[test]
    fn slices_expand_to_dyn_lagrangian_and_refuse_what_it_cannot_carry() {
        let item: ItemImpl = parse_quote! {
            impl Chain {
                fn dimension(&self) -> usize { self.n }
                fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 { v[0] * v[0] - q[0].cos() }
            }
        };
        let out = expand(TokenStream::new(), item.clone()).to_string();
        assert!(!out.contains("compile_error"), "{out}");
        assert!(out.contains("impl :: lagrangian :: __private :: DynLagrangian for Chain"), "{out}");

        let out = expand(quote!(discontinuous), item.clone()).to_string();
        assert!(!out.contains("compile_error") && out.contains("const DISCONTINUOUS : bool = true ;"), "{out}");

        // One error per declared symmetry, then a stub.
        let out = expand(quote!(symmetry = translation(0), symmetry = rotation(0, 1)), item).to_string();
        assert_eq!(out.matches("compile_error").count(), 2, "{out}");
        assert!(out.contains("`symmetry` is not supported for run-time-sized systems"), "{out}");
        assert!(out.contains("DynLagrangian for Chain") && out.contains("unreachable"), "{out}");
    }
}
