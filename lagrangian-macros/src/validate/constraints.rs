//! The signature rules of `fn constraints(&self, [t: f64,] q: [f64; N]) -> [f64; M]`,
//! the holonomic constraints `g(t, q) = 0`: what differs from the other
//! optional methods is the return type, whose length `M` is the number of
//! constraints and must lie in `1..N`.

use crate::ctxt::Ctxt;
use crate::parse::{Len, Method, Shape};

/// The signature the messages ask for.
pub(super) const EXPECTED: &str = "`fn constraints(&self, [t: f64,] q: [f64; N]) -> [f64; M]`";

/// The message for a velocity parameter: constraints are holonomic.
pub(super) fn velocity_message() -> String {
    format!(
        "`constraints` takes no velocity: holonomic constraints are `g(t, q) = 0`, \
         write {EXPECTED}"
    )
}

/// `M`, the length of the return type `[f64; M]`, when it is one.
pub(super) fn count(method: &Method<'_>) -> Option<Len> {
    match &method.output {
        Some((_, Shape::Array { of_f64: true, len })) => Some(len.clone()),
        _ => None,
    }
}

/// Checks the return type `[f64; M]` with `0 < M < N` where both are
/// literals (symbolic lengths are checked by the runtime when an integrator
/// starts). `n` is the Lagrangian's `N`, when known. `false` if reported.
pub(super) fn check_return(cx: &Ctxt, method: &Method<'_>, n: Option<&Len>) -> bool {
    let Some(len) = count(method) else {
        let message = "`constraints` must return `[f64; M]`, one value per constraint";
        match &method.output {
            Some((ty, _)) => cx.error_spanned_by(ty, message),
            None => cx.error_at(method.func.sig.paren_token.span.close(), format!("{message}: add `-> [f64; M]`")),
        }
        return false;
    };
    match (len.value(), n.and_then(Len::value)) {
        (Some(0), _) => {
            cx.error_spanned_by(&len, "`constraints` must return at least one constraint: `[f64; 0]` declares none");
            false
        }
        (Some(m), Some(n)) if m >= n => {
            cx.error_spanned_by(
                &len,
                format!(
                    "`constraints` must return fewer values than there are coordinates: \
                     {m} constraints on {n} coordinates leave no motion (`M < N` is required)"
                ),
            );
            false
        }
        _ => true,
    }
}
