//! Code generation: the user's block, then the `Lagrangian` trait impl whose
//! methods are the analysed bodies printed generic over the scalar type `D`.
//!
//! Printing follows the classes: constant subexpressions come out as the user
//! wrote them, in `f64`, and only active ones are touched. The rewrites are
//! those needed because `D` implements `D op f64` but not `f64 op D`, and
//! compares and converts only through its real part.

use crate::analyse::{Analysis, Band, Cyclic, Separability, Structure};
use crate::attr::{Args, SymmetryDecl};
use crate::ctxt::{Errors, Site};
use crate::ir::{Binder, Block, Class, Expr, ExprKind, Function, LetBinding, Local, Math, ParamRef, Stmt, System};
use crate::parse::{Dim, Len, MethodKind};
use proc_macro2::{Delimiter, Group, Ident, Span, TokenStream};
use quote::{ToTokens, quote, quote_spanned};
use std::cell::RefCell;
use syn::{BinOp, ImplItem, ItemImpl, Token, Type};

mod constraints;
pub(crate) mod parameters;

/// The user's block followed by the trait impl: `Lagrangian<N>` for a
/// system of arrays, `DynLagrangian` for one of slices.
pub(crate) fn expand(item: &ItemImpl, system: &System, analysis: &Analysis, args: &Args) -> TokenStream {
    let Dim::Fixed(len) = &system.n else {
        return expand_dynamic(item, system, analysis, args);
    };
    let user_impl = user_impl(item, None);
    let cfgs = cfgs(item);
    let (impl_generics, _, where_clause) = item.generics.split_for_impl();
    let self_ty = &item.self_ty;
    let n = len.generic_arg();
    let autonomous = system.lagrangian.time.is_none();
    let cyclic = cyclic(len, &analysis.cyclic);
    let has_dissipation = system.dissipation.is_some().then(|| quote! { const HAS_DISSIPATION: bool = true; });
    let has_force = system.force.is_some().then(|| quote! { const HAS_FORCE: bool = true; });
    let symmetries = declared_symmetries(&n, &args.symmetries);
    let structure = structure(&n, &analysis.structure);
    // Turns on the runtime's record of energy jumps.
    let discontinuous = args.discontinuous.then(|| quote! { const DISCONTINUOUS: bool = true; });
    let mut chunks = Vec::new();
    let methods: Vec<_> = std::iter::once(&system.lagrangian)
        .chain(&system.dissipation)
        .chain(&system.force)
        .map(|function| {
            let (method, method_chunks) = method(function, Some(&n));
            chunks.extend(method_chunks);
            method
        })
        .collect();
    let gradient = crate::adjoint::method(&system.lagrangian, Some(&n));
    let constraints = system.constraints.as_ref().map(|(function, m)| {
        let (items, constraint_chunks) = constraints::items(function, m, &n);
        chunks.extend(constraint_chunks);
        items
    });
    let step_density = system.step_density.as_ref().map(|function| {
        let (density, density_chunks) = density_method(function, &n);
        chunks.extend(density_chunks);
        let time_dependent = function.time.is_some();
        quote! {
            #cfgs
            #[allow(warnings, clippy::all, clippy::pedantic, clippy::nursery, clippy::restriction)]
            impl #impl_generics ::lagrangian::__private::StepDensity<#n> for #self_ty #where_clause {
                const TIME_DEPENDENT: bool = #time_dependent;
                #density
            }
        }
    });
    let chunk_impl = chunk_impl(item, chunks);
    quote! {
        #user_impl

        // The bodies are the user's code, already linted as the `f64` methods
        // above: a lint here would repeat one of those, or be about the
        // rewrite rather than anything the user can change.
        #cfgs
        #[allow(warnings, clippy::all, clippy::pedantic, clippy::nursery, clippy::restriction)]
        impl #impl_generics ::lagrangian::__private::Lagrangian<#n> for #self_ty #where_clause {
            const AUTONOMOUS: bool = #autonomous;
            const CYCLIC: [bool; #n] = #cyclic;
            #has_dissipation
            #has_force
            #discontinuous
            #symmetries
            #structure
            #(#methods)*
            #gradient
            #constraints
        }

        #step_density
        #chunk_impl
    }
}

/// The user's block followed by `DynLagrangian`: the run-time-sized form,
/// whose `lagrangian` (and `dissipation`, `force`) take slices. `validate`
/// refused what `DynLagrangian` does not carry (symmetries, step
/// densities, constraints), so only the Lagrangian, the dissipation
/// function, the force and the structure constants are printed; `dimension`
/// calls the user's method.
fn expand_dynamic(item: &ItemImpl, system: &System, analysis: &Analysis, args: &Args) -> TokenStream {
    let user_impl = user_impl(item, None);
    let cfgs = cfgs(item);
    let (impl_generics, _, where_clause) = item.generics.split_for_impl();
    let self_ty = &item.self_ty;
    let autonomous = system.lagrangian.time.is_none();
    // A bandwidth bounds `|i − j|` whatever the dimension: `banded` with the
    // largest `n` keeps it (0 → `Diagonal`), and the runtime normalises it
    // against the real `n` (a band as wide as the system is general).
    let structure = structure(&quote!(::core::primitive::usize::MAX), &analysis.structure);
    let (separability, coupling) = (&structure.separability, &structure.coupling);
    let discontinuous = args.discontinuous.then(|| quote! { const DISCONTINUOUS: bool = true; });
    let (lagrangian, mut chunks) = method(&system.lagrangian, None);
    // The Rayleigh function and the applied force over slices, and the
    // pattern of the Jacobian of their sum.
    let dissipation = system.dissipation.as_ref().map(|function| {
        let (dissipation, dissipation_chunks) = method(function, None);
        chunks.extend(dissipation_chunks);
        quote! {
            const HAS_DISSIPATION: bool = true;
            #dissipation
        }
    });
    let force = system.force.as_ref().map(|function| {
        let (force, force_chunks) = method(function, None);
        chunks.extend(force_chunks);
        quote! {
            const HAS_FORCE: bool = true;
            #force
        }
    });
    let force_coupling = (system.dissipation.is_some() || system.force.is_some()).then_some(&structure.force_coupling);
    let chunk_impl = chunk_impl(item, chunks);
    let gradient = crate::adjoint::method(&system.lagrangian, None);
    quote! {
        #user_impl

        // As for `Lagrangian<N>`: the bodies were linted as the user's methods.
        #cfgs
        #[allow(warnings, clippy::all, clippy::pedantic, clippy::nursery, clippy::restriction)]
        impl #impl_generics ::lagrangian::__private::DynLagrangian for #self_ty #where_clause {
            const AUTONOMOUS: bool = #autonomous;
            #discontinuous
            #separability
            #coupling
            #[inline(always)]
            fn dimension(&self) -> ::core::primitive::usize {
                // The inherent method, which path resolution prefers to the
                // trait's.
                Self::dimension(self)
            }
            #lagrangian
            #gradient
            #force_coupling
            #dissipation
            #force
        }

        #chunk_impl
    }
}

/// What is emitted when the block cannot be rewritten: the errors, the
/// user's block unchanged, and, when `N` is known, a trait impl with the
/// right `N` and a body that is never run, so that code using the type as a
/// `Lagrangian` does not add "trait not implemented" errors to the real ones.
/// `errors` is `None` when rustc reports the problem itself.
pub(crate) fn fallback(item: &ItemImpl, n: Option<&Dim>, errors: Option<&Errors>) -> TokenStream {
    let block_errors = errors.map(|errors| errors.at(Site::Block));
    let user_impl = user_impl(item, errors);
    let stub = n.map(|n| {
        let (impl_generics, _, where_clause) = item.generics.split_for_impl();
        let self_ty = &item.self_ty;
        let d = scalar_type();
        let cfgs = cfgs(item);
        let Dim::Fixed(n) = n else {
            return quote! {
                #cfgs
                impl #impl_generics ::lagrangian::__private::DynLagrangian for #self_ty #where_clause {
                    const AUTONOMOUS: bool = true;
                    fn dimension(&self) -> ::core::primitive::usize {
                        ::core::unreachable!("`#[lagrangian]` generated no implementation: its impl block does not compile")
                    }
                    fn lagrangian<#d: ::lagrangian::__private::Scalar>(&self, _: #d, _: &[#d], _: &[#d]) -> #d {
                        ::core::unreachable!("`#[lagrangian]` generated no implementation: its impl block does not compile")
                    }
                }
            };
        };
        let n = n.generic_arg();
        // A block with `fn step_density` is used as a monitor too.
        let has_density = item.items.iter().any(|i| matches!(i, ImplItem::Fn(f) if f.sig.ident == "step_density"));
        let density_stub = has_density.then(|| {
            quote! {
                #cfgs
                impl #impl_generics ::lagrangian::__private::StepDensity<#n> for #self_ty #where_clause {
                    fn density<S, #d>(&self, _: &S, _: #d, _: &[#d; #n]) -> #d
                    where
                        S: ::lagrangian::__private::Lagrangian<#n> + ?::core::marker::Sized,
                        #d: ::lagrangian::__private::Scalar,
                    {
                        ::core::unreachable!("`#[lagrangian]` generated no implementation: its impl block does not compile")
                    }
                }
            }
        });
        quote! {
            #cfgs
            impl #impl_generics ::lagrangian::__private::Lagrangian<#n> for #self_ty #where_clause {
                const AUTONOMOUS: bool = true;
                const CYCLIC: [bool; #n] = [false; #n];
                fn lagrangian<#d: ::lagrangian::__private::Scalar>(
                    &self, _: #d, _: [#d; #n], _: [#d; #n]
                ) -> #d {
                    ::core::unreachable!("`#[lagrangian]` generated no implementation: its impl block does not compile")
                }
            }
            #density_stub
        }
    });
    quote!(#block_errors #user_impl #stub)
}

/// The `#[cfg(...)]` attributes of the block, for the trait impl: with
/// `#[lagrangian] #[cfg(feature = "x")] impl S { ... }` the macro runs before
/// the `cfg` is evaluated, and the trait impl must exist exactly when the
/// block does.
fn cfgs(item: &ItemImpl) -> TokenStream {
    item.attrs.iter().filter(|attr| attr.path().is_ident("cfg")).map(ToTokens::to_token_stream).collect()
}

/// The user's block as written, with `#[allow(dead_code)]` on the recognised
/// methods (they are usually only called through the trait) and the errors
/// found in their bodies, if any, at the start of each body (see [`Site`]).
fn user_impl(item: &ItemImpl, errors: Option<&Errors>) -> TokenStream {
    let mut item = item.clone();
    for impl_item in &mut item.items {
        let ImplItem::Fn(func) = impl_item else { continue };
        let Some(kind) = MethodKind::from_ident(&func.sig.ident) else { continue };
        func.attrs.push(syn::parse_quote!(#[allow(dead_code)]));
        let body_errors = errors.map(|errors| errors.at(Site::Body(kind))).unwrap_or_default();
        if !body_errors.is_empty() {
            func.block.stmts.insert(0, syn::Stmt::Item(syn::Item::Verbatim(body_errors)));
        }
    }
    item.into_token_stream()
}

/// The generic parameter of the generated methods.
fn scalar_type() -> Ident {
    Ident::new("__D", Span::call_site())
}

/// `const SYMMETRIES` for the declared symmetries, or nothing. The checked
/// constructors run in the constant, so an index the macro could not check
/// (a symbolic `N`) fails at compile time, at the index.
fn declared_symmetries(n: &TokenStream, symmetries: &[SymmetryDecl]) -> Option<TokenStream> {
    if symmetries.is_empty() {
        return None;
    }
    let symmetry = quote!(::lagrangian::__private::Symmetry::<#n>);
    let checked = |call: TokenStream, span: Span| {
        quote_spanned! {span=>
            match #call {
                ::core::option::Option::Some(symmetry) => symmetry,
                ::core::option::Option::None => ::core::panic!("symmetry index out of range"),
            }
        }
    };
    let items = symmetries.iter().map(|decl| match decl {
        SymmetryDecl::Translation(i) => checked(quote!(#symmetry::translation(#i)), i.span()),
        SymmetryDecl::Rotation(i, j) => checked(quote!(#symmetry::rotation(#i, #j)), j.span()),
        SymmetryDecl::Generator(f) => quote!(#symmetry::generator(#f)),
    });
    Some(quote! {
        const SYMMETRIES: &'static [::lagrangian::__private::Symmetry<#n>] = &[#(#items),*];
    })
}

/// The value of `CYCLIC`.
fn cyclic(n: &Len, cyclic: &Cyclic) -> TokenStream {
    match n.value() {
        Some(n) => {
            let flags = (0..n).map(|i| cyclic.is_cyclic(i));
            quote!([#(#flags),*])
        }
        None if cyclic.any => quote!([false; #n]),
        // `N` is a constant the macro cannot evaluate: let the compiler.
        None => {
            let read = &cyclic.read;
            quote!({
                let mut cyclic = [true; #n];
                #(cyclic[#read] = false;)*
                cyclic
            })
        }
    }
}

/// `SEPARABILITY`, `COUPLING` and `FORCE_COUPLING`. Bandwidths go through
/// the runtime's `Pattern::banded`, which normalises them against `N` (a
/// symbolic `N` is only known to the compiler).
fn structure(n: &TokenStream, structure: &Structure) -> StructureItems {
    let private = quote!(::lagrangian::__private);
    let separability = match structure.separability {
        Separability::NotProven => quote!(NotProven),
        Separability::QuadraticKinetic => quote!(QuadraticKinetic),
        Separability::ConstantMass => quote!(ConstantMass),
    };
    let pattern = |band: Band| match band {
        Band::Width(width) => {
            // A width beyond `usize` covers any `N`.
            let width = usize::try_from(width).unwrap_or(usize::MAX);
            quote!(#private::Pattern::banded(#n, #width))
        }
        Band::General => quote!(#private::Pattern::General),
    };
    let (q_q, q_v, v_v) =
        (pattern(structure.coupling.q_q), pattern(structure.coupling.q_v), pattern(structure.coupling.v_v));
    let (force_q, force_v) = (pattern(structure.force.q), pattern(structure.force.v));
    StructureItems {
        separability: quote! {
            const SEPARABILITY: #private::Separability = #private::Separability::#separability;
        },
        coupling: quote! {
            const COUPLING: #private::Coupling = #private::Coupling { q_q: #q_q, q_v: #q_v, v_v: #v_v };
        },
        force_coupling: quote! {
            const FORCE_COUPLING: #private::ForceCoupling = #private::ForceCoupling { q: #force_q, v: #force_v };
        },
    }
}

/// The structure constants, one item each (`DynLagrangian` prints
/// `FORCE_COUPLING` only with a dissipation function or a force).
struct StructureItems {
    separability: TokenStream,
    coupling: TokenStream,
    force_coupling: TokenStream,
}

impl ToTokens for StructureItems {
    fn to_tokens(&self, tokens: &mut TokenStream) {
        tokens.extend([self.separability.clone(), self.coupling.clone(), self.force_coupling.clone()]);
    }
}

/// One trait method, and the chunks of its long chains (see [`Chunks`]);
/// `n` is `None` for a run-time-sized system, whose `q` and `v` are slices.
fn method(function: &Function, n: Option<&TokenStream>) -> (TokenStream, Vec<TokenStream>) {
    let d = scalar_type();
    let name = &function.name;
    let binder = |binder: &Binder| match binder {
        Some(ident) => ident.to_token_stream(),
        None => quote!(_),
    };
    let (q, v) = (binder(&function.q), binder(&function.v));
    let state = match n {
        Some(n) => quote!([#d; #n]),
        None => quote!(&[#d]),
    };
    let mut params = if function.kind.takes_time() {
        let t = function.time.as_ref().map_or_else(|| quote!(_), binder);
        quote!(#t: #d, #q: #state, #v: #state)
    } else {
        quote!(#q: #state, #v: #state)
    };
    // A force over slices writes into its out-parameter and returns nothing.
    let ret = match &function.out {
        Some(out) => {
            let f = binder(&out.name);
            params.extend(quote!(, #f: &mut [#d]));
            quote!(())
        }
        None if function.kind.returns_array() => quote!([#d; #n]),
        None => quote!(#d),
    };
    let time = function.time.as_ref().filter(|_| function.kind.takes_time());
    let chunks = Chunks::new(function, time, Some(&function.v), n);
    let printer =
        Printer { locals: &function.locals, ret: function.return_class(), d: d.clone(), chunks: Some(&chunks) };
    let body = printer.block(&function.body, function.out.is_none().then(|| function.return_class()));
    let self_token = syn::Token![self](function.self_span);
    // `inline(always)`: evaluated on the runtime's array hyper-duals, the body
    // is large enough that LLVM keeps it out of line and passes every dual
    // argument through memory (measured 10% of a double-pendulum step). A
    // long body is a list of calls to its chunks by then, which LLVM is left
    // to inline or not: copied into every caller, the calls of an 11-link
    // pendulum's 135 chunks made up 15 copies of the list.
    let chunks = chunks.into_items();
    let inline = if chunks.is_empty() { quote!(#[inline(always)]) } else { quote!(#[inline]) };
    let method = quote! {
        #inline
        fn #name<#d: ::lagrangian::__private::Scalar>(&#self_token, #params) -> #ret #body
    };
    (method, chunks)
}

/// `StepDensity::density` from the user's `fn step_density(&self, [t,] q)`:
/// the body printed generic over `D`, with `q` taken from the reference the
/// trait passes. `self` is the monitor, which is the system itself
/// (`TimeTransformed::with_own_density` shares one value for both roles).
fn density_method(function: &Function, n: &TokenStream) -> (TokenStream, Vec<TokenStream>) {
    let d = scalar_type();
    let binder = |binder: &Binder| match binder {
        Some(ident) => ident.to_token_stream(),
        None => quote!(_),
    };
    let q = binder(&function.q);
    let t = function.time.as_ref().map_or_else(|| quote!(_), binder);
    let chunks = Chunks::new(function, function.time.as_ref(), None, Some(n));
    let printer =
        Printer { locals: &function.locals, ret: function.return_class(), d: d.clone(), chunks: Some(&chunks) };
    let body = printer.block(&function.body, Some(function.return_class()));
    let self_token = syn::Token![self](function.self_span);
    let system = Ident::new("__LagrangianSystem", Span::call_site());
    let q_ref = Ident::new("__lagrangian_q", Span::call_site());
    let density = quote! {
        #[inline(always)]
        fn density<#system, #d>(&#self_token, _: &#system, #t: #d, #q_ref: &[#d; #n]) -> #d
        where
            #system: ::lagrangian::__private::Lagrangian<#n> + ?::core::marker::Sized,
            #d: ::lagrangian::__private::Scalar,
        {
            let #q: [#d; #n] = *#q_ref;
            #body
        }
    };
    (density, chunks.into_items())
}

/// The chunks of one method's long chains, printed as methods of their own.
///
/// `chains` splits a chain of more than [`CHUNK`](crate::chains::CHUNK)
/// operands into a block of partial results. Printed inline, the generated
/// method would still be as long as the chain, and the runtime instantiates
/// it for every scalar type it evaluates `L` on (`f64`, dual and hyper-dual
/// numbers of several widths, its tape variables: about ten) and inlines it
/// into its callers; LLVM's optimisation of one function costs more than
/// linear time in its length, and its function specialisation recurses
/// along the chain of partial results deep enough to overflow rustc's
/// stack. So each partial result whose operands read only `t`, `q`, `v`,
/// `self`, constants and partial results becomes an `#[inline(never)]`
/// method of a hidden inherent impl, which takes the previous partial
/// result as an argument: the same operations in the same order (the same
/// bits), and no function longer than one chunk. A chunk that reads `t`,
/// `q` and `v` only at literal indices is moreover lowered to `f64` (see
/// [`Chunks::lowered`]), so that its body is compiled for two small
/// types (`f64`, `HyperDual64`) instead of about ten, some of them `N²`
/// wide.
struct Chunks {
    /// The names of the chunk methods, before their index.
    prefix: String,
    /// The user's `self`, for the hygiene of `self.field` in the operands.
    self_token: Token![self],
    /// The scalar type parameter.
    d: Ident,
    /// The parameters after the partial result: name, type and argument.
    params: Vec<(Ident, TokenStream, TokenStream)>,
    /// Whether the body declares items (`const`, `use`), which a chunk
    /// printed elsewhere could not see: then nothing is outlined.
    has_items: bool,
    /// The chunk methods printed so far.
    items: RefCell<Vec<TokenStream>>,
    /// The binders of `t`, `q` and `v` where the chunks receive them.
    binders: [Option<Ident>; 3],
    /// The length of `q` and `v`; `None` for slices, whose chunks stay
    /// generic (no [`Leaf`] can be proven in range).
    n: Option<TokenStream>,
}

/// A variable a chunk reads, seeded when its derivatives are taken in
/// `f64` (see `lagrangian_runtime::chunk`).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Leaf {
    /// `t`.
    Time,
    /// `q[i]` (0) or `v[i]` (1), at a literal index.
    State(usize, usize),
}

/// The leaves of a chunk lowered to `f64`, and the pairs of them (by
/// position) whose Hessian entry its jet evaluates.
type JetLeaves = (Vec<Leaf>, Vec<(usize, usize)>);

/// The most leaves a chunk lowered to `f64` may read: its jet evaluates
/// its body once per pair of them, and `chunk::lift` keeps their gradient
/// and Hessian on the stack (`chunk::MAX_LEAVES`, the same bound). A chunk
/// reading more stays generic.
const MAX_LEAVES: usize = 16;

impl Chunks {
    /// The chunks of `function`, whose generated method receives `t` (when
    /// `time` is given), `q` and `v` (when given) of length `n`, or slices
    /// when `n` is `None`.
    fn new(function: &Function, time: Option<&Binder>, v: Option<&Binder>, n: Option<&TokenStream>) -> Self {
        let d = scalar_type();
        let state = match n {
            Some(n) => quote!(&[#d; #n]),
            None => quote!(&[#d]),
        };
        let mut params = Vec::new();
        if let Some(Some(t)) = time {
            params.push((t.clone(), d.to_token_stream(), t.to_token_stream()));
        }
        // `&q`: the method holds an array or a slice, a chunk a reference
        // to one; the argument coerces from either.
        for x in [Some(&function.q), v].into_iter().flatten().flatten() {
            params.push((x.clone(), state.clone(), quote!(&#x)));
        }
        let binders = [time.cloned().flatten(), function.q.clone(), v.cloned().flatten()];
        Chunks {
            prefix: format!("__lagrangian_{}_chunk", function.name),
            self_token: Token![self](function.self_span),
            d,
            params,
            has_items: has_items(&function.body),
            items: RefCell::new(Vec::new()),
            binders,
            n: n.cloned(),
        }
    }

    /// The leaves `expr` reads, in order of first reading; `None` when it
    /// indexes `q` or `v` other than by an integer literal, or reads more
    /// than [`MAX_LEAVES`].
    fn leaves(expr: &Expr) -> Option<Vec<Leaf>> {
        let mut leaves = Vec::new();
        let mut ok = true;
        expr.visit(&mut |expr| {
            let leaf = match &expr.kind {
                ExprKind::Index { base, index, .. } => match (&base.kind, index.literal_index()) {
                    (ExprKind::Param(ParamRef::Q, _), Some(i)) => Leaf::State(0, i),
                    (ExprKind::Param(ParamRef::V, _), Some(i)) => Leaf::State(1, i),
                    (ExprKind::Param(..), None) => {
                        ok = false;
                        return false;
                    }
                    _ => return ok,
                },
                ExprKind::Param(ParamRef::Time, _) => Leaf::Time,
                _ => return ok,
            };
            if !leaves.contains(&leaf) {
                leaves.push(leaf);
            }
            false
        });
        (ok && !leaves.is_empty() && leaves.len() <= MAX_LEAVES).then_some(leaves)
    }

    /// The leaves `expr` reads (see [`Chunks::leaves`]) and the pairs of
    /// them, by position `(a, b)` with `a ≤ b`, whose entry of the Hessian
    /// of `expr` may be nonzero: for a sum or difference, the pairs some
    /// operand reads together (each leaf with itself included); for
    /// anything else, every pair.
    fn jet_leaves(expr: &Expr) -> Option<JetLeaves> {
        let leaves = Self::leaves(expr)?;
        let mut operands = Vec::new();
        let mut node = expr;
        while let ExprKind::Binary { lhs, op: BinOp::Add(_) | BinOp::Sub(_), rhs } = &node.kind {
            operands.push(&**rhs);
            node = lhs;
        }
        operands.push(node);
        let mut together = vec![false; leaves.len() * leaves.len()];
        for operand in operands.into_iter().rev() {
            let read: Vec<usize> = Self::leaves(operand)
                .unwrap_or_default()
                .iter()
                .filter_map(|leaf| leaves.iter().position(|l| l == leaf))
                .collect();
            for &a in &read {
                for &b in &read {
                    together[a.min(b) * leaves.len() + a.max(b)] = true;
                }
            }
        }
        let k = leaves.len();
        let pairs = (0..k).flat_map(|a| (a..k).map(move |b| (a, b))).filter(|&(a, b)| together[a * k + b]).collect();
        Some((leaves, pairs))
    }

    /// Prints `body` as the next chunk method and returns the statement
    /// `let partial = self.chunk(previous, t, &q, &v);` that calls it.
    /// With `leaves`, the chunk is lowered to `f64` as well (see
    /// [`Chunks::lowered`]).
    fn call(
        &self,
        span: Span,
        partial: &Ident,
        previous: Option<&Ident>,
        body: TokenStream,
        leaves: Option<JetLeaves>,
    ) -> TokenStream {
        let mut items = self.items.borrow_mut();
        let name = Ident::new(&format!("{}_{}", self.prefix, items.len()), Span::call_site());
        let (d, self_token) = (&self.d, &self.self_token);
        let names = self.params.iter().map(|(name, ..)| name);
        let types = self.params.iter().map(|(_, ty, _)| ty);
        let args = self.params.iter().map(|(.., arg)| arg);
        let (previous_param, previous_arg) = match previous {
            Some(previous) => (quote!(#previous: #d,), quote!(#previous,)),
            None => (TokenStream::new(), TokenStream::new()),
        };
        match (leaves, &self.n) {
            (Some((leaves, pairs)), Some(n)) => {
                items.push(self.lowered(&name, previous, body, &leaves, &pairs, n));
            }
            _ => items.push(quote! {
                #[inline(never)]
                fn #name<#d: ::lagrangian::__private::Scalar>(&#self_token, #previous_param #(#names: #types),*) -> #d {
                    #body
                }
            }),
        }
        quote_spanned!(span=> let #partial = #self_token.#name(#previous_arg #(#args),*);)
    }

    /// A chunk reading `leaves` (of a system of `n` coordinates), as three
    /// methods: its body generic over the scalar; its jet in `f64`
    /// (`lagrangian_runtime::chunk::Jet`: value, gradient and Hessian at
    /// the real parts of its inputs, from the body on `HyperDual64`, one
    /// leaf or one pair of leaves at a time); and the
    /// method the chunk's caller calls, which hands the jet to
    /// `chunk::lift` for dual numbers over `f64` and evaluates the body for
    /// any other scalar. The body is then compiled for `f64`,
    /// `HyperDual64` and whatever extended-precision numbers are used,
    /// whatever the number of leaves, and every other scalar type adds a
    /// call, not a copy of the body.
    fn lowered(
        &self,
        name: &Ident,
        previous: Option<&Ident>,
        body: TokenStream,
        leaves: &[Leaf],
        pairs: &[(usize, usize)],
        n: &TokenStream,
    ) -> TokenStream {
        let (d, self_token) = (&self.d, &self.self_token);
        let chunk = quote!(::lagrangian::__private::chunk);
        let scalar = quote!(::lagrangian::__private::Scalar);
        let k = leaves.len();
        let suffixed = |suffix: &str| Ident::new(&format!("{name}_{suffix}"), Span::call_site());
        let (body_name, jet_name) = (suffixed("body"), suffixed("jet"));
        let names: Vec<_> = self.params.iter().map(|(name, ..)| name).collect();
        let types: Vec<_> = self.params.iter().map(|(_, ty, _)| ty).collect();
        let (previous_param, previous_arg) = match previous {
            Some(previous) => (quote!(#previous: #d,), quote!(#previous,)),
            None => (TokenStream::new(), TokenStream::new()),
        };
        // Leaf numbers as `chunk::lift` reads them: `q[i]` is `i`, `v[i]`
        // is `N + i`, `t` is `2N`.
        let numbers: Vec<_> = leaves
            .iter()
            .map(|leaf| match leaf {
                Leaf::Time => quote!(2 * (#n)),
                Leaf::State(0, i) => quote!(#i),
                Leaf::State(_, i) => quote!((#n) + #i),
            })
            .collect();
        let which = |name: &Ident| {
            if self.binders[0].as_ref() == Some(name) {
                0
            } else if self.binders[1].as_ref() == Some(name) {
                1
            } else {
                2
            }
        };
        // The jet: the body on `HyperDual64` (gradient, Hessian entries),
        // every input a constant but the seeded leaves, through a closure
        // with the signature `chunk::HyperBody` whatever inputs the body
        // takes.
        let x = Ident::new("__lagrangian_inputs", Span::mixed_site());
        let (s, p, t, q, v) = (
            Ident::new("__lagrangian_system", Span::mixed_site()),
            Ident::new("__lagrangian_p", Span::mixed_site()),
            Ident::new("__lagrangian_t", Span::mixed_site()),
            Ident::new("__lagrangian_q", Span::mixed_site()),
            Ident::new("__lagrangian_v", Span::mixed_site()),
        );
        let closure_args = self.params.iter().map(|(name, ..)| match which(name) {
            0 => quote!(#t),
            1 => quote!(#q),
            _ => quote!(#v),
        });
        let closure_args: Vec<_> = closure_args.collect();
        let closure_previous = previous.map(|_| quote!(#p,));
        let closure = |ty: TokenStream| {
            quote! {
                |#s: &Self, #p: #ty, #t: #ty, #q: &[#ty; #n], #v: &[#ty; #n]| -> #ty {
                    #s.#body_name(#closure_previous #(#closure_args),*)
                }
            }
        };
        let hyper = closure(quote!(::lagrangian::num_dual::HyperDual64));
        let real_args = self.params.iter().map(|(name, ..)| match which(name) {
            0 => quote!(#x.t),
            1 => quote!(&#x.q),
            _ => quote!(&#x.v),
        });
        let previous_real = previous.map(|_| quote!(#x.previous,));
        let (second, gradient, hessian) = (
            Ident::new("__lagrangian_second", Span::mixed_site()),
            Ident::new("__lagrangian_gradient", Span::mixed_site()),
            Ident::new("__lagrangian_hessian", Span::mixed_site()),
        );
        let leaf_numbers = Ident::new("__lagrangian_leaves", Span::mixed_site());
        let body_fn = Ident::new("__lagrangian_body", Span::mixed_site());
        let (pairs_a, pairs_b): (Vec<_>, Vec<_>) = pairs.iter().copied().unzip();
        let pair_count = pairs.len();
        let jet = quote! {
            #[inline(never)]
            fn #jet_name(
                &#self_token,
                #x: &#chunk::Reals<#n>,
                #second: bool,
                #gradient: &mut [f64],
                #hessian: &mut [f64]
            ) -> f64 {
                let #leaf_numbers: [usize; #k] = [#(#numbers),*];
                let #body_fn: #chunk::HyperBody<Self, #n> = #hyper;
                if #second {
                    // Only pairs of leaves that one operand reads together:
                    // the other entries of the Hessian of a sum are zero.
                    const PAIRS: [(usize, usize); #pair_count] = [#((#pairs_a, #pairs_b)),*];
                    #chunk::second_order(#self_token, #x, &#leaf_numbers, &PAIRS, #body_fn, #gradient, #hessian);
                } else {
                    #chunk::first_order(#self_token, #x, &#leaf_numbers, #body_fn, #gradient);
                }
                #self_token.#body_name(#previous_real #(#real_args),*)
            }
        };
        // The dispatch on the scalar: `if` on a constant, so each type
        // compiles one branch.
        let input =
            |i: usize| self.params.iter().find(|(name, ..)| which(name) == i).map(|(name, ..)| name.to_token_stream());
        let zero = quote!(<#d as ::core::convert::From<f64>>::from(0.0));
        let previous_value = previous.map_or_else(|| zero.clone(), |previous| quote!(#previous));
        let time_value = input(0).unwrap_or_else(|| zero.clone());
        let q_value = input(1).unwrap_or_else(|| quote!(&[#zero; #n]));
        let v_value = input(2).unwrap_or_else(|| q_value.clone());
        let body_args = self.params.iter().map(|(name, ..)| name);
        quote! {
            #[inline(never)]
            fn #body_name<#d: #scalar>(&#self_token, #previous_param #(#names: #types),*) -> #d {
                #body
            }
            #jet
            // Inlined: per scalar type, a call to `lift` or to the body,
            // not one more function for LLVM to compile.
            #[inline(always)]
            fn #name<#d: #scalar>(&#self_token, #previous_param #(#names: #types),*) -> #d {
                if <#d as #scalar>::SECOND_ORDER || <#d as #scalar>::FIRST_ORDER {
                    #chunk::lift(#self_token, #previous_value, #time_value, #q_value, #v_value, &[#(#numbers),*], Self::#jet_name)
                } else {
                    #self_token.#body_name(#previous_arg #(#body_args),*)
                }
            }
        }
    }

    /// The chunk methods, for the hidden inherent impl.
    fn into_items(self) -> Vec<TokenStream> {
        self.items.into_inner()
    }
}

/// Whether `block` or a block inside it declares an item.
fn has_items(block: &Block) -> bool {
    let mut found = block.stmts.iter().any(|stmt| matches!(stmt, Stmt::Item(_)));
    block.visit(&mut |expr| {
        let inner = |block: &Block| block.stmts.iter().any(|stmt| matches!(stmt, Stmt::Item(_)));
        match &expr.kind {
            ExprKind::Block(block) | ExprKind::For { body: block, .. } => found |= inner(block),
            ExprKind::If { then_branch, .. } => found |= inner(then_branch),
            _ => {}
        }
        !found
    });
    found
}

/// The hidden inherent impl holding the chunk methods of long chains, or
/// nothing when no chain was long.
fn chunk_impl(item: &ItemImpl, chunks: Vec<TokenStream>) -> Option<TokenStream> {
    if chunks.is_empty() {
        return None;
    }
    let cfgs = cfgs(item);
    let (impl_generics, _, where_clause) = item.generics.split_for_impl();
    let self_ty = &item.self_ty;
    Some(quote! {
        // Pieces of the user's bodies, linted as the user's methods.
        #cfgs
        #[allow(warnings, clippy::all, clippy::pedantic, clippy::nursery, clippy::restriction)]
        #[doc(hidden)]
        impl #impl_generics #self_ty #where_clause {
            #(#chunks)*
        }
    })
}

/// Prints the IR of one function as code generic over `D`.
struct Printer<'a> {
    locals: &'a [Local],
    /// The class of the function's value: `return`s are coerced to it.
    ret: Class,
    /// The scalar type parameter.
    d: Ident,
    /// Where the chunks of long chains go; `None` prints them inline.
    chunks: Option<&'a Chunks>,
}

impl Printer<'_> {
    /// A block; `to` is the class its final expression must be coerced to.
    fn block(&self, block: &Block, to: Option<Class>) -> TokenStream {
        let span = block.span;
        let last = block.stmts.len().saturating_sub(1);
        let stmts = block.stmts.iter().enumerate().map(|(i, stmt)| match (stmt, to) {
            (Stmt::Expr { expr, semi: false }, Some(to)) if i == last => self.coerce(expr, to),
            _ => self.outlined(stmt).unwrap_or_else(|| self.stmt(stmt)),
        });
        quote_spanned!(span=> { #(#stmts)* })
    }

    /// A partial result of a long chain as a call to a chunk method (see
    /// [`Chunks`]), or `None` when `stmt` is not one or cannot be outlined.
    fn outlined(&self, stmt: &Stmt) -> Option<TokenStream> {
        let chunks = self.chunks.filter(|chunks| !chunks.has_items)?;
        let Stmt::Let { span, bindings, tuple: false, ty: None, inits } = stmt else { return None };
        let ([LetBinding { local: Some(local), mutable: false }], [init]) = (bindings.as_slice(), inits.as_slice())
        else {
            return None;
        };
        let partial = &self.locals[local.0];
        if !crate::chains::is_partial(&partial.name) || partial.class != Class::Active {
            return None;
        }
        // The previous partial result opens the chain, and is passed in
        // as a `D`.
        let mut first = init;
        while let ExprKind::Binary { lhs, .. } = &first.kind {
            first = lhs;
        }
        let previous = match &first.kind {
            ExprKind::Local(id, _) if crate::chains::is_partial(&self.locals[id.0].name) => {
                let previous = &self.locals[id.0];
                if previous.class != Class::Active {
                    return None;
                }
                Some(&previous.name)
            }
            _ => None,
        };
        if !self.outlinable(init) {
            return None;
        }
        let body = self.coerce(init, Class::Active);
        Some(chunks.call(*span, &partial.name, previous, body, Chunks::jet_leaves(init)))
    }

    /// Whether `expr` reads nothing a chunk method does not receive: `q`
    /// and `v` only indexed or measured, no local but partial results, no
    /// control flow leaving it, no assignment.
    fn outlinable(&self, expr: &Expr) -> bool {
        let mut ok = true;
        expr.visit(&mut |expr| {
            match &expr.kind {
                ExprKind::Index { base, index, .. } if matches!(base.kind, ExprKind::Param(..)) => {
                    ok &= self.outlinable(index);
                    return false;
                }
                ExprKind::MethodCall { receiver, math: Math::Len, .. }
                    if matches!(receiver.kind, ExprKind::Param(..)) =>
                {
                    return false;
                }
                ExprKind::Param(ParamRef::Time, _) => {}
                ExprKind::Local(id, _) => ok &= crate::chains::is_partial(&self.locals[id.0].name),
                ExprKind::Param(..)
                | ExprKind::Assign { .. }
                | ExprKind::Return(_)
                | ExprKind::Break(_)
                | ExprKind::Continue(_)
                | ExprKind::For { .. } => ok = false,
                _ => {}
            }
            ok
        });
        ok
    }

    fn stmt(&self, stmt: &Stmt) -> TokenStream {
        match stmt {
            Stmt::Let { span, bindings, tuple, ty, inits } => {
                let span = *span;
                let classes: Vec<Class> = bindings
                    .iter()
                    .map(|binding| binding.local.map_or(Class::Unit, |local| self.locals[local.0].class))
                    .collect();
                let patterns = bindings.iter().map(|binding| match binding.local {
                    Some(local) => {
                        let name = &self.locals[local.0].name;
                        let mutability = binding.mutable.then(|| quote_spanned!(span=> mut));
                        quote_spanned!(span=> #mutability #name)
                    }
                    None => quote_spanned!(span=> _),
                });
                let inits = inits.iter().zip(&classes).map(|(init, class)| self.coerce(init, *class));
                let ty = ty.as_ref().map(|ty| {
                    let ty = self.binding_type(ty, &classes);
                    quote_spanned!(span=> : #ty)
                });
                if *tuple {
                    quote_spanned!(span=> let (#(#patterns),*) #ty = (#(#inits),*);)
                } else {
                    quote_spanned!(span=> let #(#patterns)* #ty = #(#inits)*;)
                }
            }
            Stmt::Expr { expr, semi } => {
                let span = expr.span;
                let expr = self.expr(expr);
                let semi = semi.then(|| quote_spanned!(span=> ;));
                quote_spanned!(span=> #expr #semi)
            }
            Stmt::Item(item) => item.to_token_stream(),
        }
    }

    /// The annotation `ty` of variables of the given classes: `f64` becomes
    /// `D` for active ones, element by element in a tuple type.
    fn binding_type(&self, ty: &Type, classes: &[Class]) -> Type {
        match (ty, classes) {
            (ty, [class]) if class.is_active() => self.active_type(ty),
            (Type::Tuple(tuple), classes) if tuple.elems.len() == classes.len() => {
                let mut tuple = tuple.clone();
                for (elem, class) in tuple.elems.iter_mut().zip(classes) {
                    *elem = self.binding_type(elem, &[*class]);
                }
                Type::Tuple(tuple)
            }
            (ty, _) => ty.clone(),
        }
    }

    /// `ty` with `f64` replaced by `D`, for annotations of active variables.
    fn active_type(&self, ty: &Type) -> Type {
        let mut ty = ty.clone();
        match &mut ty {
            ty if crate::parse::is_f64(ty) => {
                let d = &self.d;
                return syn::parse_quote!(#d);
            }
            Type::Array(array) => *array.elem = self.active_type(&array.elem),
            // `let x: &[f64] = q;` in a run-time-sized system.
            Type::Slice(slice) => *slice.elem = self.active_type(&slice.elem),
            Type::Reference(reference) => *reference.elem = self.active_type(&reference.elem),
            Type::Paren(paren) => *paren.elem = self.active_type(&paren.elem),
            _ => {}
        }
        ty
    }

    /// An expression at its own class.
    fn expr(&self, expr: &Expr) -> TokenStream {
        // Tokens the printer adds take the span of the user's expression, so
        // that rustc's diagnostics about generated code coincide with (and
        // are deduplicated against) those about the user's method.
        let span = expr.span;
        match &expr.kind {
            ExprKind::Lit(lit) => lit.to_token_stream(),
            ExprKind::Path(path) => path.to_token_stream(),
            ExprKind::SelfValue(token) => token.to_token_stream(),
            ExprKind::Param(_, ident) | ExprKind::Local(_, ident) => ident.to_token_stream(),
            ExprKind::Field { base, member } => {
                let base = self.expr(base);
                quote_spanned!(span=> #base.#member)
            }
            ExprKind::Index { base, index, bracket } => {
                let (base, index) = (self.expr(base), delimited(Delimiter::Bracket, *bracket, self.expr(index)));
                quote_spanned!(span=> #base #index)
            }
            ExprKind::Unary { op, expr } => {
                let expr = self.expr(expr);
                quote_spanned!(span=> #op #expr)
            }
            ExprKind::Binary { lhs, op, rhs } => self.binary(span, lhs, op, rhs),
            // `f64 as f64` on an active value: the value is already `D`.
            ExprKind::Cast { expr: inner, .. } if expr.class.is_active() => self.expr(inner),
            // An active value to an integer: through its real part, like a
            // comparison; an integer has no derivative to lose.
            ExprKind::Cast { expr: inner, ty } if inner.class.is_active() => {
                let inner = self.real(inner);
                quote_spanned!(span=> #inner as #ty)
            }
            ExprKind::Cast { expr: inner, ty } => {
                let inner = self.expr(inner);
                quote_spanned!(span=> #inner as #ty)
            }
            ExprKind::Paren(inner) => {
                let inner = self.expr(inner);
                quote_spanned!(span=> (#inner))
            }
            ExprKind::Block(block) => self.block(block, None),
            ExprKind::If { .. } => self.if_expr(expr, expr.class),
            ExprKind::For { var, start, limits, end, body } => {
                let var = match var {
                    Some((_, ident)) => ident.to_token_stream(),
                    None => quote_spanned!(span=> _),
                };
                let (start, end) = (self.expr(start), self.expr(end));
                let body = self.block(body, None);
                quote_spanned!(span=> for #var in #start #limits #end #body)
            }
            ExprKind::MethodCall { .. } => self.method_call(expr),
            ExprKind::Array(elems) => {
                let elems = elems.iter().map(|elem| match expr.class {
                    Class::ActiveArray => self.coerce(elem, Class::Active),
                    _ => self.expr(elem),
                });
                quote_spanned!(span=> [#(#elems),*])
            }
            ExprKind::Repeat { elem, len } => {
                let elem = match expr.class {
                    Class::ActiveArray => self.coerce(elem, Class::Active),
                    _ => self.expr(elem),
                };
                quote_spanned!(span=> [#elem; #len])
            }
            ExprKind::Assign { place, op, value } => {
                let target = self.expr(place);
                match op {
                    // `D op= f64` exists: a constant needs no conversion.
                    Some(op) => {
                        let value = self.expr(value);
                        quote_spanned!(span=> #target #op #value)
                    }
                    None => {
                        let value = self.coerce(value, place.class);
                        quote_spanned!(span=> #target = #value)
                    }
                }
            }
            ExprKind::Return(value) => {
                let value = value.as_ref().map(|value| self.coerce(value, self.ret));
                quote_spanned!(span=> return #value)
            }
            ExprKind::Break(token) => token.to_token_stream(),
            ExprKind::Continue(token) => token.to_token_stream(),
        }
    }

    /// `expr` converted to class `to`: constants become `D` (or arrays of
    /// `D`). The conversion is pushed into blocks, `if` branches and array
    /// literals, so it lands on the constant parts only.
    fn coerce(&self, expr: &Expr, to: Class) -> TokenStream {
        let span = expr.span;
        if !to.is_active() || expr.class.is_active() || expr.class == Class::Unit {
            return self.expr(expr);
        }
        match (&expr.kind, to) {
            (ExprKind::Paren(inner), _) => {
                let inner = self.coerce(inner, to);
                quote_spanned!(span=> (#inner))
            }
            (ExprKind::Block(block), _) => self.block(block, Some(to)),
            (ExprKind::If { .. }, _) => self.if_expr(expr, to),
            (ExprKind::Array(elems), Class::ActiveArray) => {
                let elems = elems.iter().map(|elem| self.coerce(elem, Class::Active));
                quote_spanned!(span=> [#(#elems),*])
            }
            (ExprKind::Repeat { elem, len }, Class::ActiveArray) => {
                let elem = self.coerce(elem, Class::Active);
                quote_spanned!(span=> [#elem; #len])
            }
            (_, Class::ActiveArray) => {
                let (d, array) = (&self.d, self.receiver(expr));
                quote_spanned!(expr.span=> #array.map(#d::from))
            }
            _ => self.to_active(expr),
        }
    }

    /// A constant scalar as `D`.
    fn to_active(&self, expr: &Expr) -> TokenStream {
        let (d, value) = (&self.d, self.expr(expr));
        quote_spanned!(expr.span=> #d::from(#value))
    }

    /// `expr` as an active receiver: converted if constant.
    fn active_receiver(&self, expr: &Expr) -> TokenStream {
        if expr.class.is_active() { self.receiver(expr) } else { self.to_active(expr) }
    }

    /// The `f64` real part of an active scalar (the scalar itself if
    /// constant), for comparisons and integer casts.
    fn real(&self, expr: &Expr) -> TokenStream {
        if expr.class.is_active() {
            let receiver = self.receiver(expr);
            quote_spanned!(expr.span=> #receiver.re())
        } else {
            self.expr(expr)
        }
    }

    /// `expr` where a method call may follow it: parenthesized unless it binds
    /// at least as tightly as a method call.
    fn receiver(&self, expr: &Expr) -> TokenStream {
        let span = expr.span;
        if binds_like_postfix(expr) {
            self.expr(expr)
        } else {
            let expr = self.expr(expr);
            quote_spanned!(span=> (#expr))
        }
    }

    /// `expr` as an operand moved to the other side of a binary operator:
    /// parenthesized unless it is postfix, unary or a cast, which bind more
    /// tightly than any binary operator whichever side they are on.
    fn moved_operand(&self, expr: &Expr) -> TokenStream {
        match expr.kind {
            ExprKind::Unary { .. } | ExprKind::Cast { .. } => self.expr(expr),
            _ => self.receiver(expr),
        }
    }

    fn binary(&self, span: Span, lhs: &Expr, op: &BinOp, rhs: &Expr) -> TokenStream {
        let constant_then_active = !lhs.class.is_active() && rhs.class.is_active();
        match op {
            // `c + x` → `x + c`: `D` has `D op f64` but not `f64 op D`, and
            // IEEE addition and multiplication commute exactly.
            BinOp::Add(_) | BinOp::Mul(_) if constant_then_active => {
                let (lhs, rhs) = (self.moved_operand(rhs), self.moved_operand(lhs));
                quote_spanned!(span=> #lhs #op #rhs)
            }
            // `c - x` → `D::from(c) - x`: subtraction and division do not
            // commute.
            BinOp::Sub(_) | BinOp::Div(_) if constant_then_active => {
                let (lhs, rhs) = (self.to_active(lhs), self.expr(rhs));
                quote_spanned!(span=> #lhs #op #rhs)
            }
            BinOp::Lt(_) | BinOp::Le(_) | BinOp::Gt(_) | BinOp::Ge(_) | BinOp::Eq(_) | BinOp::Ne(_) => {
                let (lhs, rhs) = (self.real(lhs), self.real(rhs));
                quote_spanned!(span=> #lhs #op #rhs)
            }
            _ => {
                let (lhs, rhs) = (self.expr(lhs), self.expr(rhs));
                quote_spanned!(span=> #lhs #op #rhs)
            }
        }
    }

    /// An `if` whose branches are coerced to `to`.
    fn if_expr(&self, expr: &Expr, to: Class) -> TokenStream {
        let span = expr.span;
        let ExprKind::If { cond, then_branch, else_branch } = &expr.kind else {
            return self.expr(expr);
        };
        let to = to.is_active().then_some(to);
        let cond = self.expr(cond);
        let then_branch = self.block(then_branch, to);
        let else_branch = else_branch.as_ref().map(|else_branch| {
            let else_branch = match to {
                Some(to) => self.coerce(else_branch, to),
                None => self.expr(else_branch),
            };
            quote_spanned!(span=> else #else_branch)
        });
        quote_spanned!(span=> if #cond #then_branch #else_branch)
    }

    fn method_call(&self, expr: &Expr) -> TokenStream {
        let span = expr.span;
        let ExprKind::MethodCall { receiver, method, math, args, path, paren } = &expr.kind else {
            return self.expr(expr);
        };
        let arguments = |args: Vec<TokenStream>| delimited(Delimiter::Parenthesis, *paren, quote!(#(#args),*));
        if !expr.class.is_active() {
            // Plain `f64` (or integer) arithmetic: as written.
            return match path {
                Some(path) => {
                    let operands = arguments(std::iter::once(&**receiver).chain(args).map(|x| self.expr(x)).collect());
                    quote_spanned!(span=> #path #operands)
                }
                None => {
                    let receiver = self.expr(receiver);
                    let args = arguments(args.iter().map(|arg| self.expr(arg)).collect());
                    quote_spanned!(span=> #receiver.#method #args)
                }
            };
        }
        match (math, args.as_slice()) {
            // An active exponent needs the dual-exponent power.
            (Math::Powf, [exponent]) if exponent.class.is_active() => {
                let (receiver, exponent) = (self.active_receiver(receiver), self.expr(exponent));
                quote_spanned!(method.span()=> #receiver.powd(#exponent))
            }
            // `log` takes an `f64` base; `f64::log` is `ln() / base.ln()`.
            (Math::Log, [base]) if base.class.is_active() => {
                let (receiver, base) = (self.active_receiver(receiver), self.receiver(base));
                quote_spanned!(method.span()=> (#receiver.ln() / #base.ln()))
            }
            (Math::Uniform, _) => {
                let receiver = self.active_receiver(receiver);
                let args = arguments(args.iter().map(|arg| self.coerce(arg, Class::Active)).collect());
                quote_spanned!(span=> #receiver.#method #args)
            }
            // The receiver is active and the arguments are `f64` or `i32`.
            _ => {
                let receiver = self.receiver(receiver);
                let args = arguments(args.iter().map(|arg| self.expr(arg)).collect());
                quote_spanned!(span=> #receiver.#method #args)
            }
        }
    }
}

/// `tokens` between delimiters carrying the span of the user's own, so that
/// the generated expression spans exactly what the user wrote.
fn delimited(delimiter: Delimiter, span: Span, tokens: TokenStream) -> Group {
    let mut group = Group::new(delimiter, tokens);
    group.set_span(span);
    group
}

/// Whether `expr` prints as something a method call can follow without
/// parentheses.
fn binds_like_postfix(expr: &Expr) -> bool {
    match &expr.kind {
        ExprKind::Lit(_)
        | ExprKind::Path(_)
        | ExprKind::SelfValue(_)
        | ExprKind::Param(..)
        | ExprKind::Local(..)
        | ExprKind::Field { .. }
        | ExprKind::Index { .. }
        | ExprKind::MethodCall { .. }
        | ExprKind::Paren(_)
        | ExprKind::Array(_)
        | ExprKind::Repeat { .. } => true,
        // Printed as its operand when active.
        ExprKind::Cast { expr: inner, .. } if expr.class.is_active() => binds_like_postfix(inner),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ctxt::Ctxt;
    use crate::parse::Input;
    use syn::parse_quote;

    /// The trait impl generated for `item`, as a string.
    fn generated(item: &ItemImpl) -> String {
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(item)).unwrap();
        let analysis = crate::analyse::analyse(&cx, &mut system);
        cx.check().unwrap();
        let out = expand(item, &system, &analysis, &Args::default()).to_string();
        // The generated gradient, the impl's last item, has its own tests
        // (`adjoint.rs`); the expectations here end with `lagrangian`.
        match out.find("const HAS_GRADIENT") {
            Some(i) => format!("{}}}", &out[..i]),
            None => out,
        }
    }

    /// The generated `lagrangian` body for a one-coordinate Lagrangian.
    fn body(body: syn::Block) -> String {
        let out = generated(&parse_quote! {
            impl P { fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 #body }
        });
        let start = out.find("-> __D").map_or(0, |i| i + "-> __D".len());
        let body = out[start..].trim();
        // Drop the brace closing the impl.
        body.strip_suffix('}').unwrap_or(body).trim().to_owned()
    }

    #[test]
    fn pendulum() {
        let item: ItemImpl = parse_quote! {
            impl Pendulum {
                fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
                    0.5 * self.m * self.l * self.l * v[0] * v[0] + self.m * self.g * self.l * q[0].cos()
                }
            }
        };
        let expected = quote! {
            impl ::lagrangian::__private::Lagrangian<1> for Pendulum {
                const AUTONOMOUS: bool = true;
                const CYCLIC: [bool; 1] = [false];
                const SEPARABILITY: ::lagrangian::__private::Separability =
                    ::lagrangian::__private::Separability::ConstantMass;
                const COUPLING: ::lagrangian::__private::Coupling = ::lagrangian::__private::Coupling {
                    q_q: ::lagrangian::__private::Pattern::banded(1, 0usize),
                    q_v: ::lagrangian::__private::Pattern::banded(1, 0usize),
                    v_v: ::lagrangian::__private::Pattern::banded(1, 0usize)
                };
                const FORCE_COUPLING: ::lagrangian::__private::ForceCoupling = ::lagrangian::__private::ForceCoupling {
                    q: ::lagrangian::__private::Pattern::banded(1, 0usize),
                    v: ::lagrangian::__private::Pattern::banded(1, 0usize)
                };
                #[inline(always)]
                fn lagrangian<__D: ::lagrangian::__private::Scalar>(&self, _: __D, q: [__D; 1], v: [__D; 1]) -> __D {
                    v[0] * (0.5 * self.m * self.l * self.l) * v[0]
                        + q[0].cos() * (self.m * self.g * self.l)
                }
            }
        };
        let out = generated(&item);
        assert!(out.starts_with("impl Pendulum"), "{out}");
        assert!(out.contains("# [allow (dead_code)] fn lagrangian"), "{out}");
        assert!(out.ends_with(&expected.to_string()), "{out}");
    }

    /// The whole expansion of `item`, chains split as the macro splits them.
    fn expanded(mut item: ItemImpl) -> String {
        crate::chains::split(&mut item);
        generated(&item)
    }

    #[test]
    fn long_chains_become_chunk_methods_in_order() {
        let chain = (1..crate::chains::LONG).map(|k| format!(" + {k}.0 * (q[0] * self.c).sin()")).collect::<String>();
        let source = format!(
            "impl P {{ fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {{ 0.5 * v[0] * v[0]{chain} }} }}"
        );
        let out = expanded(syn::parse_str(&source).unwrap());
        let partial = "__lagrangian_partial";
        // The first chunk starts the chain, the others continue it; `t` is
        // passed although unread (the chunk cannot know), `q` and `v` by
        // reference.
        let calls = [
            format!("let {partial} = self . __lagrangian_lagrangian_chunk_0 (t , & q , & v) ;"),
            format!("let {partial} = self . __lagrangian_lagrangian_chunk_1 ({partial} , t , & q , & v) ;"),
            format!("let {partial} = self . __lagrangian_lagrangian_chunk_2 ({partial} , t , & q , & v) ;"),
        ];
        for call in &calls {
            assert!(out.contains(call.as_str()), "{call}\n{out}");
        }
        let last = (crate::chains::LONG - 1) / crate::chains::CHUNK;
        assert!(out.contains(&format!("__lagrangian_lagrangian_chunk_{last} (")), "{out}");
        assert!(!out.contains(&format!("__lagrangian_lagrangian_chunk_{} (", last + 1)), "{out}");
        // Its body, generic over the scalar.
        let second = format!(
            "# [inline (never)] fn __lagrangian_lagrangian_chunk_1_body < __D : :: lagrangian :: __private :: Scalar > \
             (& self , __lagrangian_partial : __D , t : __D , q : & [__D ; 1] , v : & [__D ; 1]) -> __D \
             {{ __lagrangian_partial + (q [0] * self . c) . sin () * {}.0",
            crate::chains::CHUNK
        );
        assert!(out.contains(&second), "{out}");
        // Its jet in `f64`, which every dual number over `f64` reaches
        // through `chunk::lift`, with its one leaf `q[0]`.
        let jet = "fn __lagrangian_lagrangian_chunk_1_jet (& self , __lagrangian_inputs : & :: lagrangian :: \
                   __private :: chunk :: Reals < 1 > , __lagrangian_second : bool , __lagrangian_gradient : \
                   & mut [f64] , __lagrangian_hessian : & mut [f64]) -> f64 { \
                   let __lagrangian_leaves : [usize ; 1usize] = [0usize] ;";
        assert!(out.contains(jet), "{jet}\n{out}");
        let lift = "if < __D as :: lagrangian :: __private :: Scalar > :: SECOND_ORDER || \
                    < __D as :: lagrangian :: __private :: Scalar > :: FIRST_ORDER { \
                    :: lagrangian :: __private :: chunk :: lift (self , __lagrangian_partial , t , q , v , \
                    & [0usize] , Self :: __lagrangian_lagrangian_chunk_1_jet) }";
        assert!(out.contains(lift), "{lift}\n{out}");
        assert!(out.contains("# [doc (hidden)] impl P {"), "{out}");
    }

    #[test]
    fn chunks_seed_the_leaves_they_read_and_index_nothing_else() {
        let chain =
            (1..crate::chains::LONG).map(|k| format!(" + {k}.0 * (q[{}] * v[1] + t)", k % 2)).collect::<String>();
        let source = format!(
            "impl P {{ fn lagrangian(&self, t: f64, q: [f64; 2], v: [f64; 2]) -> f64 {{ 0.5 * v[0] * v[0]{chain} }} }}"
        );
        let out = expanded(syn::parse_str(&source).unwrap());
        // The second chunk reads `q[0]`, `v[1]`, `t`, `q[1]`, in that order.
        let chunk = out.split("fn __lagrangian_lagrangian_chunk_1_jet").nth(1).expect("a lowered chunk");
        let chunk = &chunk[..chunk.find("fn ").unwrap()];
        let leaves = "let __lagrangian_leaves : [usize ; 4usize] = [0usize , (2) + 1usize , 2 * (2) , 1usize] ;";
        assert!(chunk.contains(leaves), "{leaves}\n{chunk}");
        // Every operand reads `q[0]` or `q[1]` with `v[1]` and `t`: no
        // operand reads both coordinates, so that pair's Hessian entry is
        // not evaluated.
        let pairs = "const PAIRS : [(usize , usize) ; 9usize] = [(0usize , 0usize) , (0usize , 1usize) , \
                     (0usize , 2usize) , (1usize , 1usize) , (1usize , 2usize) , (1usize , 3usize) , \
                     (2usize , 2usize) , (2usize , 3usize) , (3usize , 3usize)] ;";
        assert!(chunk.contains(pairs), "{pairs}\n{chunk}");

        // An index the macro cannot read keeps the chunk generic only.
        let chain = (1..crate::chains::LONG).map(|k| format!(" + {k}.0 * q[self.i]")).collect::<String>();
        let source = format!(
            "impl P {{ fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {{ 0.5 * v[0] * v[0]{chain} }} }}"
        );
        let out = expanded(syn::parse_str(&source).unwrap());
        assert!(out.contains("fn __lagrangian_lagrangian_chunk_1 <"), "{out}");
        assert!(!out.contains("_jet") && !out.contains("SECOND_ORDER"), "{out}");
    }

    #[test]
    fn chains_reading_locals_or_items_stay_inline() {
        for prelude in ["let x = q[0] * 2.0;", "const K: f64 = 2.0; let y = 1.0;"] {
            let read = if prelude.starts_with("let") { "x" } else { "K * q[0]" };
            let chain = (0..crate::chains::LONG).map(|k| format!(" + {k}.0 * {read}")).collect::<String>();
            let source = format!(
                "impl P {{ fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {{ {prelude} v[0] * v[0]{chain} }} }}"
            );
            let out = expanded(syn::parse_str(&source).unwrap());
            assert!(!out.contains("chunk"), "{out}");
        }
    }

    #[test]
    fn structure_constants_are_normalised_against_a_symbolic_n() {
        let out = generated(&parse_quote! {
            impl<const N: usize> Chain<N> {
                fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
                    let mut l = 0.0;
                    for i in 1..N {
                        l += 0.5 * v[i] * v[i] - (q[i] - q[i - 1]).powi(2);
                    }
                    l
                }
            }
        });
        let private = ":: lagrangian :: __private ::";
        assert!(
            out.contains(&format!(
                "const SEPARABILITY : {private} Separability = {private} Separability :: ConstantMass ;"
            )),
            "{out}"
        );
        assert!(
            out.contains(&format!(
                "q_q : {private} Pattern :: banded (N , 1usize) , q_v : {private} Pattern :: banded (N , 0usize)"
            )),
            "{out}"
        );
    }

    #[test]
    fn constant_on_the_left() {
        assert_eq!(
            body(parse_quote!({ 1.0 - q[0] + 2.0 / v[0] + 3.0 * t })),
            quote!({ __D::from(1.0) - q[0] + __D::from(2.0) / v[0] + t * 3.0 }).to_string()
        );
        // The moved operand keeps its grouping: `c + (a + b)` is not `c + a + b`.
        assert_eq!(body(parse_quote!({ self.a + self.b + t })), quote!({ t + (self.a + self.b) }).to_string());
    }

    #[test]
    fn comparisons_use_the_real_part() {
        assert_eq!(
            body(parse_quote!({ if 0.0 < q[0] && q[0] * 2.0 <= self.x { q[0] } else { 1.0 } })),
            quote!({ if 0.0 < q[0].re() && (q[0] * 2.0).re() <= self.x { q[0] } else { __D::from(1.0) } }).to_string()
        );
    }

    #[test]
    fn methods_follow_their_operands() {
        assert_eq!(
            body(parse_quote!({ q[0].powf(self.p) + self.b.powf(v[0]) + self.c.sqrt() })),
            quote!({ q[0].powf(self.p) + __D::from(self.b).powd(v[0]) + self.c.sqrt() }).to_string()
        );
        assert_eq!(
            body(parse_quote!({ self.y.atan2(q[0]) + f64::mul_add(q[0], 2.0, t) + 2.0f64.log(v[0]) })),
            quote!({
                __D::from(self.y).atan2(q[0]) + q[0].mul_add(__D::from(2.0), t) + (__D::from(2.0f64).ln() / v[0].ln())
            })
            .to_string()
        );
    }

    #[test]
    fn mutable_locals_and_loops() {
        assert_eq!(
            body(parse_quote!({
                let mut s: f64 = 0.0;
                let k = 2.0;
                for i in 0..3 {
                    s += (i as f64) * k * v[0];
                }
                s
            })),
            quote!({
                let mut s: __D = __D::from(0.0);
                let k = 2.0;
                for i in 0..3 {
                    s += v[0] * ((i as f64) * k);
                }
                s
            })
            .to_string()
        );
    }

    #[test]
    fn tuple_lets_are_coerced_element_by_element() {
        assert_eq!(
            body(parse_quote!({
                let (x, mut y, _): (f64, f64, f64) = (q[0], 1.0, self.z);
                y += x;
                y
            })),
            quote!({
                let (x, mut y, _): (__D, __D, f64) = (q[0], __D::from(1.0), self.z);
                y += x;
                y
            })
            .to_string()
        );
    }

    #[test]
    fn force_arrays_are_coerced_element_by_element() {
        let out = generated(&parse_quote! {
            impl P {
                fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 { v[0] * v[1] }
                fn force(&self, q: [f64; 2], v: [f64; 2]) -> [f64; 2] {
                    if self.on { [-self.c * v[0], 0.0] } else { self.f0 }
                }
            }
        });
        assert!(out.contains("const AUTONOMOUS : bool = true ;"), "{out}");
        assert!(out.contains("const CYCLIC : [bool ; 2] = [true , true] ;"), "{out}");
        assert!(out.contains("const HAS_FORCE : bool = true ;"), "{out}");
        let expected = quote!({ if self.on { [v[0] * -self.c, __D::from(0.0)] } else { self.f0.map(__D::from) } });
        assert!(out.contains(&expected.to_string()), "{out}");
    }

    #[test]
    fn constant_length_and_generics_carry_over() {
        let out = generated(&parse_quote! {
            impl<const N: usize> Chain<N> where [f64; N]: Copy {
                fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 { q[0] * v[1] }
            }
        });
        let expected = quote! {
            impl<const N: usize> ::lagrangian::__private::Lagrangian<N> for Chain<N> where [f64; N]: Copy {
                const AUTONOMOUS: bool = true;
                const CYCLIC: [bool; N] = {
                    let mut cyclic = [true; N];
                    cyclic[0usize] = false;
                    cyclic
                };
            }
        };
        let expected = expected.to_string();
        let prefix = &expected[..expected.len() - 1];
        assert!(out.contains(prefix), "{out}");
    }

    #[test]
    fn fallback_emits_a_stub_after_errors() {
        let item: ItemImpl = parse_quote!(impl P { fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 { q[0] } });
        let cx = Ctxt::new();
        cx.error_at(Span::call_site(), "boom");
        cx.body_error_at(MethodKind::Lagrangian, Span::call_site(), "bang");
        let errors = cx.check().unwrap_err();
        let n = crate::validate::arity(&Input::from_syn(&item));
        let out = fallback(&item, n.as_ref(), Some(&errors)).to_string();
        assert!(out.starts_with(":: core :: compile_error ! { \"boom\" }"), "{out}");
        // The body's error opens the body, which keeps rustc from checking it.
        assert!(out.contains("-> f64 { :: core :: compile_error ! { \"bang\" } q [0] }"), "{out}");
        assert!(out.contains("Lagrangian < 3 > for P"), "{out}");
        assert!(out.contains("unreachable !"), "{out}");
        assert!(!fallback(&item, None, None).to_string().contains("Lagrangian"));
        assert!(!out.contains("StepDensity"), "{out}");
    }

    #[test]
    fn fallback_of_a_block_with_a_monitor_stubs_the_monitor_too() {
        let item: ItemImpl = parse_quote!(impl P {
            fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 { q[0] }
            fn step_density(&self, q: [f64; 2], v: [f64; 2]) -> f64 { 1.0 }
        });
        let n = crate::validate::arity(&Input::from_syn(&item));
        let out = fallback(&item, n.as_ref(), None).to_string();
        assert!(out.contains("Lagrangian < 2 > for P"), "{out}");
        assert!(out.contains("StepDensity < 2 > for P"), "{out}");
    }

    #[test]
    fn slices_implement_dyn_lagrangian() {
        let item: ItemImpl = parse_quote! {
            impl Chain {
                fn dimension(&self) -> usize { self.n }
                fn lagrangian(&self, t: f64, q: &[f64], v: &[f64]) -> f64 {
                    let mut l = 0.0;
                    for i in 1..q.len() {
                        l += 0.5 * v[i] * v[i] - (q[i] - q[i - 1]).powi(2);
                    }
                    l * t
                }
            }
        };
        let private = quote!(::lagrangian::__private);
        let max = quote!(::core::primitive::usize::MAX);
        let expected = quote! {
            impl #private::DynLagrangian for Chain {
                const AUTONOMOUS: bool = false;
                const SEPARABILITY: #private::Separability = #private::Separability::NotProven;
                const COUPLING: #private::Coupling = #private::Coupling {
                    q_q: #private::Pattern::banded(#max, 1usize),
                    q_v: #private::Pattern::banded(#max, 0usize),
                    v_v: #private::Pattern::banded(#max, 0usize)
                };
                #[inline(always)]
                fn dimension(&self) -> ::core::primitive::usize {
                    Self::dimension(self)
                }
                #[inline(always)]
                fn lagrangian<__D: #private::Scalar>(&self, t: __D, q: &[__D], v: &[__D]) -> __D {
                    let mut l = __D::from(0.0);
                    for i in 1..q.len() {
                        l += v[i] * 0.5 * v[i] - (q[i] - q[i - 1]).powi(2);
                    }
                    l * t
                }
            }
        };
        let out = generated(&item);
        assert!(out.starts_with("impl Chain"), "{out}");
        assert!(out.ends_with(&expected.to_string()), "{out}");
        assert!(!out.contains("CYCLIC") && !out.contains("FORCE_COUPLING") && !out.contains("Lagrangian <"), "{out}");
    }

    #[test]
    fn a_force_over_slices_writes_into_a_slice_of_duals() {
        let item: ItemImpl = parse_quote! {
            impl Chain {
                fn dimension(&self) -> usize { self.n }
                fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 { v[0] * v[0] - q[0] * q[0] }
                fn force(&self, t: f64, q: &[f64], _: &[f64], f: &mut [f64]) {
                    for i in 0..q.len() - 1 {
                        f[i] = 1.0;
                        f[i + 1] -= self.k * (q[i + 1] - q[i]) * t;
                    }
                }
            }
        };
        let private = quote!(::lagrangian::__private);
        let max = quote!(::core::primitive::usize::MAX);
        let expected = quote! {
            const FORCE_COUPLING: #private::ForceCoupling = #private::ForceCoupling {
                q: #private::Pattern::banded(#max, 1usize),
                v: #private::Pattern::banded(#max, 0usize)
            };
            const HAS_FORCE: bool = true;
            #[inline(always)]
            fn force<__D: #private::Scalar>(&self, t: __D, q: &[__D], _: &[__D], f: &mut [__D]) -> () {
                for i in 0..q.len() - 1 {
                    f[i] = __D::from(1.0);
                    f[i + 1] -= (q[i + 1] - q[i]) * self.k * t;
                }
            }
        };
        // After the gradient, which `generated` cuts off.
        let cx = Ctxt::new();
        let mut system = crate::validate::validate(&cx, &Input::from_syn(&item)).unwrap();
        let analysis = crate::analyse::analyse(&cx, &mut system);
        cx.check().unwrap();
        let out = expand(&item, &system, &analysis, &Args::default()).to_string();
        assert!(out.contains(&expected.to_string()), "{out}");
        assert!(!out.contains("HAS_DISSIPATION"), "{out}");
    }

    #[test]
    fn slice_annotations_become_slices_of_duals() {
        let out = generated(&parse_quote! {
            impl Chain {
                fn dimension(&self) -> usize { 3 }
                fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
                    let x: &[f64] = q;
                    x[0] * v[0]
                }
            }
        });
        assert!(out.contains(&quote!(let x: &[__D] = q;).to_string()), "{out}");
    }

    #[test]
    fn fallback_for_slices_is_a_dyn_stub() {
        let item: ItemImpl = parse_quote!(impl P { fn lagrangian(&self, q: &mut [f64], v: &[f64]) -> f64 { q[0] } });
        let n = crate::validate::arity(&Input::from_syn(&item));
        let out = fallback(&item, n.as_ref(), None).to_string();
        assert!(out.contains("DynLagrangian for P"), "{out}");
        assert!(out.contains("fn dimension (& self) -> :: core :: primitive :: usize"), "{out}");
        assert!(out.contains("unreachable !"), "{out}");
    }
}
