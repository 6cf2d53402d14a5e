//! Long operator chains, split into partial results before anything else
//! runs.
//!
//! `a + b + c + ...` parses into a tree as deep as the chain is long, and
//! every recursive walk over it (syn's own `Clone` and `ToTokens`, the
//! stages of this macro, and rustc's front end on the output) needs stack in
//! proportion. Measured with rustc 1.95 and its default 8 MiB stack: rustc
//! alone overflows on a plain `f64` function summing about 6000 terms, and
//! `syn::Item::clone` on about 5000. So the first thing the macro does, in
//! one pass that walks chains with a loop, is to rewrite every chain of at
//! least [`LONG`] operands (of one precedence level: `+ -`, `* / %`, `&&`,
//! `||`, ...) into a block of partial results of [`CHUNK`] operands each,
//!
//! ```text
//! { let __lagrangian_partial = t0 + ... + t7;
//!   let __lagrangian_partial = __lagrangian_partial + t8 + ... + t15;
//!   ...
//!   __lagrangian_partial }
//! ```
//!
//! in the user's method and hence in the generated one. These are the same
//! operations on the same operands in the same (left-to-right) order, so the
//! result is bit for bit the same, and `&&`/`||` keep their short-circuits.
//! Shorter chains, i.e. all ordinary code, are left as written (the
//! gradient code of `adjoint` covers them, not blocks). `generate` prints
//! each partial result of the generic method as a function of its own,
//! whose optimisation costs LLVM time growing faster than its length: hence
//! chunks shorter than the threshold. After the pass no tree is deeper than the user's nesting of
//! parentheses, blocks, calls and `else if`s, which no stage flattens: those
//! stay limited by syn's recursive parser (see the crate docs).

use proc_macro2::Span;
use syn::visit_mut::{self, VisitMut};
use syn::{BinOp, Expr, ExprBinary, Ident};

/// The fewest operands of a chain that is split.
pub(crate) const LONG: usize = 65;

/// The operands of each partial result of a split chain. Measured on a
/// generated crate summing 300 sines (`scripts/compile_time.py`): chunks
/// of 64 took 25 s of CPU, 16 took 15 s, 8 took 12 s and 4 took 13 s.
pub(crate) const CHUNK: usize = 8;

/// The local variable holding the partial results; hygienic
/// (`Span::mixed_site`), so it cannot capture or shadow a user's variable.
const PARTIAL: &str = "__lagrangian_partial";

/// Whether `ident` names a partial result of a split chain. The name is
/// hygienic, so a user's variable cannot carry it into the generated code.
pub(crate) fn is_partial(ident: &Ident) -> bool {
    ident == PARTIAL
}

/// Splits every chain of at least [`LONG`] operands in `item`.
pub(crate) fn split(item: &mut syn::ItemImpl) {
    Splitter.visit_item_impl_mut(item);
}

/// The precedence level of a chainable left-associative operator: operators
/// of one level chain with each other (`a + b - c`).
fn level(op: &BinOp) -> Option<u8> {
    use BinOp as B;
    Some(match op {
        B::Mul(_) | B::Div(_) | B::Rem(_) => 0,
        B::Add(_) | B::Sub(_) => 1,
        B::Shl(_) | B::Shr(_) => 2,
        B::BitAnd(_) => 3,
        B::BitXor(_) => 4,
        B::BitOr(_) => 5,
        B::And(_) => 6,
        B::Or(_) => 7,
        // Comparisons do not chain; assignments are right-associative.
        _ => return None,
    })
}

struct Splitter;

impl VisitMut for Splitter {
    fn visit_expr_mut(&mut self, expr: &mut Expr) {
        let chain_level = match expr {
            Expr::Binary(binary) if binary.attrs.is_empty() => level(&binary.op),
            _ => None,
        };
        let Some(chain_level) = chain_level else {
            return visit_mut::visit_expr_mut(self, expr);
        };
        // Down the left spine with a loop, taking the tree apart as it goes,
        // so that neither this walk nor the drop of the old tree recurses.
        let mut rest = Vec::new();
        let mut node = std::mem::replace(expr, Expr::Verbatim(proc_macro2::TokenStream::new()));
        let mut first = loop {
            match node {
                Expr::Binary(binary) if binary.attrs.is_empty() && level(&binary.op) == Some(chain_level) => {
                    rest.push((binary.op, *binary.right));
                    node = *binary.left;
                }
                other => break other,
            }
        };
        rest.reverse();
        // Operands recurse only as deep as the user nested them.
        self.visit_expr_mut(&mut first);
        for (_, operand) in &mut rest {
            self.visit_expr_mut(operand);
        }
        *expr = if rest.len() + 1 < LONG { fold(first, rest) } else { partials(first, rest) };
    }
}

/// `first op1 o1 op2 o2 ...`, left-associated as parsed.
fn fold(first: Expr, rest: impl IntoIterator<Item = (BinOp, Expr)>) -> Expr {
    rest.into_iter().fold(first, |left, (op, right)| {
        Expr::Binary(ExprBinary { attrs: Vec::new(), left: Box::new(left), op, right: Box::new(right) })
    })
}

/// The chain as a block of partial results of [`CHUNK`] operands each.
fn partials(first: Expr, rest: Vec<(BinOp, Expr)>) -> Expr {
    let partial = Ident::new(PARTIAL, Span::mixed_site());
    let mut rest = rest.into_iter();
    let read = || -> Expr { syn::parse_quote!(#partial) };
    // Built as syn values, not through `parse_quote!`, which would print and
    // re-parse every operand.
    let define = |value: Expr| {
        syn::Stmt::Local(syn::Local {
            attrs: Vec::new(),
            let_token: Default::default(),
            pat: syn::Pat::Ident(syn::PatIdent {
                attrs: Vec::new(),
                by_ref: None,
                mutability: None,
                ident: partial.clone(),
                subpat: None,
            }),
            init: Some(syn::LocalInit { eq_token: Default::default(), expr: Box::new(value), diverge: None }),
            semi_token: Default::default(),
        })
    };
    let head: Vec<_> = rest.by_ref().take(CHUNK - 1).collect();
    let mut stmts = vec![define(fold(first, head))];
    loop {
        let chunk: Vec<_> = rest.by_ref().take(CHUNK).collect();
        if chunk.is_empty() {
            break;
        }
        stmts.push(define(fold(read(), chunk)));
    }
    stmts.push(syn::Stmt::Expr(read(), None));
    Expr::Block(syn::ExprBlock {
        attrs: Vec::new(),
        label: None,
        block: syn::Block { brace_token: Default::default(), stmts },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use quote::{ToTokens, quote};
    use syn::parse_quote;

    fn split_body(body: syn::Block) -> String {
        let mut item: syn::ItemImpl = parse_quote!(impl P { fn f(&self, x: f64) -> f64 #body });
        split(&mut item);
        let syn::ImplItem::Fn(f) = &item.items[0] else { unreachable!() };
        f.block.to_token_stream().to_string()
    }

    #[test]
    fn short_chains_are_left_as_written() {
        let body: syn::Block = parse_quote!({ a * b - c / d + (e + f) % g && h || i });
        assert_eq!(split_body(body.clone()), body.to_token_stream().to_string());
    }

    #[test]
    fn long_chains_become_partial_results_in_order() {
        let terms: Vec<syn::Expr> = (0..LONG).map(|i| parse_quote!(x * #i)).collect();
        let chain = quote!(#(#terms)-*);
        let out = split_body(parse_quote!({ #chain }));
        let partial = Ident::new(PARTIAL, Span::call_site());
        let (head, rest) = terms.split_at(CHUNK);
        let stmts = rest.chunks(CHUNK).map(|chunk| quote!(let #partial = #partial #(- #chunk)*;));
        let expected = quote!({
            {
                let #partial = #(#head)-*;
                #(#stmts)*
                #partial
            }
        });
        assert_eq!(out, expected.to_string());
        // One operand fewer is left as written.
        let short = &terms[..LONG - 1];
        let chain = quote!(#(#short)-*);
        assert_eq!(split_body(parse_quote!({ #chain })), quote!({ #chain }).to_string());
    }

    #[test]
    fn chains_inside_operands_are_split_too() {
        let product = vec!["y"; LONG].join(" * ");
        let product: syn::Expr = syn::parse_str(&product).unwrap();
        let out = split_body(parse_quote!({ 1.0 + (#product).sqrt() }));
        let chunk = ["y"; CHUNK].join(" * ");
        let rest = (CHUNK..LONG)
            .collect::<Vec<_>>()
            .chunks(CHUNK)
            .map(|c| format!("let {PARTIAL} = {PARTIAL} * {} ; ", vec!["y"; c.len()].join(" * ")))
            .collect::<String>();
        let expected = format!("{{ 1.0 + ({{ let {PARTIAL} = {chunk} ; {rest}{PARTIAL} }}) . sqrt () }}");
        assert_eq!(out, expected);
    }

    #[test]
    fn a_very_long_chain_does_not_recurse() {
        // Far past what a recursive walk survives in a test thread's 2 MiB.
        let source = format!("{{ {} }}", vec!["x"; 50_000].join(" + "));
        let mut item: syn::ItemImpl = syn::parse_str(&format!("impl P {{ fn f(&self, x: f64) -> f64 {source} }}"))
            .expect("syn parses a flat chain without recursing");
        split(&mut item);
        let syn::ImplItem::Fn(f) = &item.items[0] else { unreachable!() };
        let syn::Stmt::Expr(syn::Expr::Block(block), None) = &f.block.stmts[0] else { panic!("expected a block") };
        assert_eq!(block.block.stmts.len(), 50_000usize.div_ceil(CHUNK) + 1);
    }
}
