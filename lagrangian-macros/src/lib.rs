//! The `#[lagrangian]` attribute of the `lagrangian` crate.
//!
//! It turns a Lagrangian written as plain `f64` Rust into an implementation
//! of `lagrangian::Lagrangian`, generic over dual numbers so that the runtime
//! can differentiate it. Use it through the `lagrangian` crate, which
//! re-exports it; the generated code names `::lagrangian::__private` only.
//!
//! The expansion is a small compiler, one private module per stage, read top
//! to bottom: `parse` picks the recognised methods out of the block,
//! `validate` checks their signatures and lowers their bodies into the `ir`,
//! `analyse` finds which values depend on `t`, `q` and `v` and what
//! structure the bodies prove, `discontinuity` where the Lagrangian jumps
//! with them, and `generate` prints the trait impl. `expand` runs them in
//! turn; errors accumulate in a `ctxt::Ctxt` so that all of them are
//! reported at once.

mod adjoint;
mod analyse;
mod attr;
mod chains;
mod ctxt;
mod discontinuity;
mod expand;
mod generate;
mod ir;
mod parse;
mod validate;

use proc_macro::TokenStream;

/// Implements `lagrangian::Lagrangian` for the type of an `impl` block.
///
/// ```ignore
/// use lagrangian::prelude::*;
///
/// pub struct Pendulum { pub m: f64, pub l: f64, pub g: f64 }
///
/// #[lagrangian]
/// impl Pendulum {
///     fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
///         0.5 * self.m * self.l * self.l * v[0] * v[0] + self.m * self.g * self.l * q[0].cos()
///     }
/// }
/// ```
///
/// The block must define `fn lagrangian(&self, [t: f64,] q: [f64; N], v:
/// [f64; N]) -> f64` (a `t` parameter makes the system non-autonomous) and
/// may define `fn dissipation(&self, q, v) -> f64` and `fn force(&self, [t,]
/// q, v) -> [f64; N]`. The methods stay in the block as written; the trait
/// impl evaluates the same bodies on dual numbers.
///
/// Run-time-sized systems (a chain built from data, too large for arrays on
/// the stack) take slices instead: `fn lagrangian(&self, [t: f64,] q:
/// &[f64], v: &[f64]) -> f64`, with `fn dimension(&self) -> usize` in the
/// same block. The macro then implements `lagrangian::DynLagrangian`, with
/// the same checks of the body. `fn dissipation(&self, q: &[f64], v:
/// &[f64]) -> f64` takes slices too, and the force is written into a last
/// parameter, `fn force(&self, [t: f64,] q: &[f64], v: &[f64], f: &mut
/// [f64])`: `f` arrives filled with zeros, the body sets or adds to `f[i]`
/// and returns nothing. Step densities, constraints and declared
/// symmetries, which that trait does not carry, are refused
/// (docs/structure.md, "Run-time-sized systems").
///
/// The bodies may use: literals, `self` fields, constants, `q[i]` and `v[i]`,
/// `q.len()` and `v.len()`, `+ - * /`, `%` on integers and constants, comparisons (on the real part of
/// dual numbers), `&& || !`, `let` and `let mut` (also `let (a, b) = (x,
/// y);`), `= += -= *= /= %=` on local variables and elements of local
/// arrays, `if`/`else`, `for i in a..b`, `break`, `continue`, `return`,
/// arrays `[a, b]` and `[x; n]`, `as` casts to `f64` and integer types, and
/// the `f64` methods `sin cos tan asin acos atan atan2 sinh cosh tanh asinh
/// acosh atanh exp exp2 exp_m1 ln ln_1p log log2 log10 sqrt cbrt powi powf
/// abs signum recip mul_add` (also written `f64::sin(x)`). Anything else is
/// a compile error naming the construct.
///
/// Symmetries (docs/theory.md §7) can be declared in the attribute, for the
/// runtime's `noether` module to follow their momentum maps:
/// `#[lagrangian(symmetry = translation(i), symmetry = rotation(i, j),
/// symmetry = generator(|q: &[f64; N]| [...]))]`. They become
/// `Lagrangian::SYMMETRIES`; indices are checked against `N`.
///
/// A Lagrangian that jumps is refused unless acknowledged: an `if` whose
/// condition depends on `t`, `q` or `v`, a cast of such a value to an
/// integer type, or `signum` of one, in `lagrangian`, is an error (variational
/// integrators assume a smooth `L`; the discrete energy jumps where the
/// branch changes). `#[lagrangian(discontinuous)]` accepts the body and sets
/// `Lagrangian::DISCONTINUOUS`, for the runtime to record the energy jumps.
/// Kinks (`abs`) are not reported, nor are `force` and `dissipation`.
///
/// The receiver may be written `&self` or `self: &Self`. `#[cfg]` on the
/// recognised methods is refused (the trait implementation could not follow
/// it); put the `#[cfg]` on the block instead, one block per configuration,
/// and the macro carries it over to the trait implementation.
///
/// Long expressions: a chain of one precedence level (`a + b - c + ...`,
/// `a * b * ...`, `&&`, `||`) of more than 64 operands is split, in the
/// method as written and in the generated one, into a block of partial
/// results of 8 operands each: the same operations in the same order, so
/// the same result bit for bit. In the generated methods each partial
/// result is a separate `#[inline(never)]` function, so that the compile
/// time grows linearly with the length of the chain (`docs/compile-time.md`
/// has the constant). A chunk that reads `t`, `q` and `v` at literal
/// indices only (at most 16 of them) is compiled for `f64` and
/// `HyperDual64` alone, and dual numbers take its value, gradient and
/// Hessian from there by the chain rule (`lagrangian_runtime::chunk`);
/// any other chunk is compiled once per scalar type the runtime evaluates
/// `L` on. rustc itself overflows its default stack on a
/// flat sum of about 6000 terms; split, 10 240-term sums and 16 384-factor
/// products compile, at opt-level 3 too
/// (`release-tests/long_expressions.rs`). Nesting — parentheses,
/// blocks, `else if` — is not flattened: syn's parser and every later stage
/// recurse on it. syn's parser alone overflows rustc's default stack between
/// 500 and 1000 nested parentheses (measured with rustc 1.95), so expressions
/// must stay within a few hundred levels of nesting.
///
/// Values that do not depend on `t`, `q` or `v` stay `f64` in the generated
/// code; only the others become dual numbers. `CYCLIC[i]` is `true` when the
/// Lagrangian provably ignores `q[i]`: `q` is only indexed by integer
/// literals and never by `i`.
///
/// The macro also proves structure for the runtime to exploit
/// (docs/structure.md): `SEPARABILITY` (whether `L = ½ vᵀM(q)v − V(t, q)`,
/// and whether `M` is constant), `COUPLING` (diagonal, banded or general
/// blocks of the Hessian of `L` in `(q, v)`, including bands from `for`
/// loops over neighbours, `q[i + 1] - q[i]`) and `FORCE_COUPLING` (the same
/// for the Jacobian of the forces). What the syntax does not prove is
/// reported as not proven or general, never as a smaller pattern.
#[proc_macro_attribute]
pub fn lagrangian(attr: TokenStream, item: TokenStream) -> TokenStream {
    match syn::parse::<syn::Item>(item) {
        Ok(syn::Item::Impl(mut item)) => {
            // First, so that no later walk recurses along a long chain.
            chains::split(&mut item);
            expand::expand(attr.into(), item).into()
        }
        // Anything else is kept, so that the rest of the crate still sees it.
        Ok(other) => {
            let error = syn::Error::new_spanned(
                &other,
                "`#[lagrangian]` goes on an `impl` block defining \
                 `fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64`",
            );
            let mut out = error.into_compile_error();
            quote::ToTokens::to_tokens(&other, &mut out);
            out.into()
        }
        Err(error) => error.into_compile_error().into(),
    }
}
