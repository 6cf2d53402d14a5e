//! The `#[lagrangian]` attribute macro.
use proc_macro::TokenStream;

/// Placeholder until the macro pipeline lands.
#[proc_macro_attribute]
pub fn lagrangian(_attr: TokenStream, item: TokenStream) -> TokenStream {
    item
}
