//! Lowering of a method body into the IR.
//!
//! This is where the supported subset of Rust is defined: every construct
//! either has an IR counterpart or is reported, naming the construct and
//! listing what is supported instead. Names are resolved on the way: a path
//! is a parameter, a local variable or, failing both, a constant.

use super::Signature;
use crate::ctxt::Ctxt;
use crate::ir::{Block, Expr, ExprKind, Function, LetBinding, Local, LocalId, Math, Out, ParamRef, Stmt};
use crate::parse::{Dim, Len, Method, MethodKind, is_f64};
use quote::{ToTokens, quote};
use syn::spanned::Spanned;
use syn::{BinOp, Ident, Item, Lit, Pat, PatIdent, Type, UnOp};

/// What the body may contain, for the messages about what it may not.
const SUPPORTED: &str = "literals, `self` fields, constants, `q[i]` and `v[i]`, \
    `+ - * /`, `%` on integers and constants, comparisons, `&& || !`, `let` and `let mut`, \
    `= += -= *= /= %=` on local variables, \
    `if`/`else`, `for i in a..b`, `return`, arrays `[a, b]` and `[x; n]`, `as` casts \
    and the math methods of `f64`";

/// The supported `f64` methods: name, rewrite rule and number of arguments
/// besides the receiver. These are the ones the dual numbers implement too.
const METHODS: &[(&str, Math, usize)] = &[
    ("sin", Math::Plain, 0),
    ("cos", Math::Plain, 0),
    ("tan", Math::Plain, 0),
    ("asin", Math::Plain, 0),
    ("acos", Math::Plain, 0),
    ("atan", Math::Plain, 0),
    ("atan2", Math::Uniform, 1),
    ("sinh", Math::Plain, 0),
    ("cosh", Math::Plain, 0),
    ("tanh", Math::Plain, 0),
    ("asinh", Math::Plain, 0),
    ("acosh", Math::Plain, 0),
    ("atanh", Math::Plain, 0),
    ("exp", Math::Plain, 0),
    ("exp2", Math::Plain, 0),
    ("exp_m1", Math::Plain, 0),
    ("ln", Math::Plain, 0),
    ("ln_1p", Math::Plain, 0),
    ("log", Math::Log, 1),
    ("log2", Math::Plain, 0),
    ("log10", Math::Plain, 0),
    ("sqrt", Math::Plain, 0),
    ("cbrt", Math::Plain, 0),
    ("powi", Math::Powi, 1),
    ("powf", Math::Powf, 1),
    ("abs", Math::Plain, 0),
    ("signum", Math::Plain, 0),
    ("recip", Math::Plain, 0),
    ("mul_add", Math::Uniform, 2),
];

/// The supported methods as a message fragment: "`sin`, `cos`, ...".
fn method_list() -> String {
    METHODS.iter().map(|(name, ..)| format!("`{name}`")).collect::<Vec<_>>().join(", ")
}

/// The rewrite rule and arity of a supported method.
fn math_method(name: &Ident) -> Option<(Math, usize)> {
    METHODS.iter().find(|(known, ..)| name == known).map(|&(_, math, arity)| (math, arity))
}

/// Lowers the body of `method`, whose signature has been read into
/// `signature`. `None` if any part of the body is unsupported (reported).
pub(super) fn lower(cx: &Ctxt, method: &Method<'_>, signature: &Signature) -> Option<Function> {
    let params = [
        (signature.time.clone().flatten(), ParamRef::Time),
        (signature.q.clone(), ParamRef::Q),
        (signature.v.clone(), ParamRef::V),
    ]
    .into_iter()
    .filter_map(|(ident, param)| Some((ident?, param)))
    .collect();
    let mut lower = Lower {
        cx,
        kind: method.kind,
        n: signature.n.as_ref().and_then(Dim::len).and_then(Len::value),
        params,
        scopes: Vec::new(),
        locals: Vec::new(),
        out: None,
        failed: Vec::new(),
    };
    // The out-parameter is a `let mut` local array of active values
    // declared before the body: the first local, in a scope of its own.
    lower.scopes.push(Vec::new());
    let out = signature.out.as_ref().map(|name| {
        let local = name.as_ref().map(|ident| {
            let local = lower.declare(ident);
            lower.locals[local.0].class = crate::ir::Class::ActiveArray;
            lower.out = Some(local);
            local
        });
        Out { name: name.clone(), local }
    });
    let body = lower.block(&method.func.block);
    lower.scopes.pop();
    let body = body?;
    Some(Function {
        kind: method.kind,
        name: signature.name.clone(),
        self_span: method.receiver.map_or_else(proc_macro2::Span::call_site, |receiver| receiver.self_token.span),
        time: signature.time.clone(),
        q: signature.q.clone(),
        v: signature.v.clone(),
        out,
        body,
        locals: lower.locals,
    })
}

/// Lowering state for one body.
struct Lower<'a> {
    cx: &'a Ctxt,
    kind: MethodKind,
    /// `N` when it is a literal, for bounds checks on `q[i]` and `v[i]`.
    n: Option<usize>,
    /// The named parameters: the outermost scope.
    params: Vec<(Ident, ParamRef)>,
    /// Local variables in scope, innermost scope last.
    scopes: Vec<Vec<(Ident, LocalId)>>,
    /// Every local declared so far.
    locals: Vec<Local>,
    /// The local standing for the out-parameter of a force over slices.
    out: Option<LocalId>,
    /// Locals whose initializer was reported (`let f = |x| ...;`): their
    /// uses are not reported again.
    failed: Vec<LocalId>,
}

/// What a name refers to.
enum Binding {
    Param(ParamRef),
    Local(LocalId),
}

/// `Some` of all the items if every one is `Some`. Callers lower every item
/// before calling this, so that errors in all of them get reported.
fn all<T>(items: Vec<Option<T>>) -> Option<Vec<T>> {
    items.into_iter().collect()
}

impl Lower<'_> {
    /// Reports an error about this body.
    fn error(&self, tokens: impl ToTokens, msg: impl std::fmt::Display) {
        self.cx.body_error_spanned_by(self.kind, tokens, msg);
    }

    /// Reports an unsupported construct. `what` names it, with its verb
    /// ("closures are").
    fn unsupported<T>(&self, tokens: impl ToTokens, what: &str) -> Option<T> {
        self.error(tokens, format!("{what} not supported in `{}`; supported: {SUPPORTED}", self.kind.name()));
        None
    }

    fn resolve(&self, ident: &Ident) -> Option<Binding> {
        let local = self.scopes.iter().rev().flat_map(|scope| scope.iter().rev());
        if let Some((_, id)) = local.into_iter().find(|(name, _)| name == ident) {
            return Some(Binding::Local(*id));
        }
        self.params.iter().find(|(name, _)| name == ident).map(|(_, param)| Binding::Param(*param))
    }

    fn declare(&mut self, ident: &Ident) -> LocalId {
        let id = LocalId(self.locals.len());
        self.locals.push(Local { name: ident.clone(), class: crate::ir::Class::Unit });
        if let Some(scope) = self.scopes.last_mut() {
            scope.push((ident.clone(), id));
        }
        id
    }

    fn block(&mut self, block: &syn::Block) -> Option<Block> {
        self.scopes.push(Vec::new());
        let stmts = block.stmts.iter().map(|stmt| self.stmt(stmt)).collect();
        self.scopes.pop();
        Some(Block { span: block.brace_token.span.join(), stmts: all(stmts)? })
    }

    fn stmt(&mut self, stmt: &syn::Stmt) -> Option<Stmt> {
        match stmt {
            syn::Stmt::Local(local) => self.local(local),
            // Constants and imports (`use std::f64::consts::PI;`) cannot see
            // the locals, so they are copied as they are.
            syn::Stmt::Item(item @ (Item::Const(_) | Item::Use(_))) => Some(Stmt::Item(Box::new(item.clone()))),
            syn::Stmt::Item(item) => self.unsupported(item, "items other than `const` and `use` are"),
            syn::Stmt::Expr(expr, semi) => Some(Stmt::Expr { expr: self.expr(expr)?, semi: semi.is_some() }),
            syn::Stmt::Macro(stmt) => self.macro_call(&stmt.mac),
        }
    }

    fn local(&mut self, local: &syn::Local) -> Option<Stmt> {
        let (pat, ty) = match &local.pat {
            Pat::Type(typed) => (&*typed.pat, Some(typed.ty.clone())),
            pat => (pat, None),
        };
        let init = match &local.init {
            Some(syn::LocalInit { diverge: Some((else_token, _)), .. }) => {
                return self.unsupported(else_token, "`let ... else` is");
            }
            Some(init) => Some(&*init.expr),
            None => {
                self.error(pat, "a `let` without an initial value is not supported: write `let x = ...;`");
                None
            }
        };
        // `let (a, b) = (x, y);` is lowered element by element, the others
        // as one binding and one initializer.
        let (patterns, inits, tuple): (Vec<&Pat>, _, _) = match (pat, init) {
            (Pat::Tuple(pats), Some(syn::Expr::Tuple(exprs))) if pats.elems.len() == exprs.elems.len() => {
                (pats.elems.iter().collect(), exprs.elems.iter().map(|expr| self.expr(expr)).collect(), true)
            }
            // Already reported as a `let` without a value.
            (Pat::Tuple(_), None) => return None,
            (Pat::Tuple(pats), init) => {
                self.error(pats, "tuple patterns are only supported with as many values: `let (a, b) = (x, y);`");
                init.map(|init| self.expr(init));
                return None;
            }
            (pat, init) => (vec![pat], vec![init.and_then(|init| self.expr(init))], false),
        };
        let bindings: Vec<_> = patterns.into_iter().map(|pat| self.binding(pat)).collect();
        // Declared after the initializers, which still see outer variables of
        // the same names (`let x = x + 1.0;`, `let (a, b) = (b, a);`).
        let bindings: Vec<LetBinding> = all(bindings)?
            .into_iter()
            .map(|binding| LetBinding {
                local: binding.map(|(ident, _)| self.declare(ident)),
                mutable: binding.is_some_and(|(_, mutable)| mutable),
            })
            .collect();
        for (binding, init) in bindings.iter().zip(&inits) {
            if let (Some(local), None) = (binding.local, init.as_ref()) {
                self.failed.push(local);
            }
        }
        Some(Stmt::Let { span: local.let_token.span, bindings, tuple, ty, inits: all(inits)? })
    }

    /// The variable bound by one `let` pattern and whether it is `mut`;
    /// `Some(None)` for `_`.
    fn binding<'p>(&self, pat: &'p Pat) -> Option<Option<(&'p Ident, bool)>> {
        match pat {
            Pat::Ident(PatIdent { by_ref: None, subpat: None, ident, mutability, .. }) => {
                Some(Some((ident, mutability.is_some())))
            }
            Pat::Wild(_) => Some(None),
            pat => self.unsupported(pat, "patterns other than names, `_` and tuples of them are"),
        }
    }

    fn macro_call<T>(&self, mac: &syn::Macro) -> Option<T> {
        let path = &mac.path;
        let bang = &mac.bang_token;
        let name = path.segments.iter().map(|segment| segment.ident.to_string()).collect::<Vec<_>>().join("::");
        self.unsupported(quote!(#path #bang), &format!("macros such as `{name}!` are"))
    }

    fn expr(&mut self, expr: &syn::Expr) -> Option<Expr> {
        use syn::Expr as E;
        let kind = match expr {
            E::Lit(lit) => match &lit.lit {
                Lit::Int(_) | Lit::Float(_) | Lit::Bool(_) => ExprKind::Lit(lit.lit.clone()),
                other => return self.unsupported(other, "string, byte and character literals are"),
            },
            E::Path(path) => self.path(path)?,
            E::Field(field) => self.field(field)?,
            E::Index(index) => self.index(index)?,
            E::Unary(unary) => match unary.op {
                UnOp::Neg(_) | UnOp::Not(_) => {
                    ExprKind::Unary { op: unary.op, expr: Box::new(self.expr(&unary.expr)?) }
                }
                op => return self.unsupported(op, "dereferencing (`*`) is"),
            },
            E::Binary(binary) => self.binary(binary)?,
            E::Assign(assign) => {
                let place = self.place(&assign.left);
                let value = self.expr(&assign.right);
                ExprKind::Assign { place: Box::new(place?), op: None, value: Box::new(value?) }
            }
            E::Cast(cast) => self.cast(cast)?,
            E::Paren(paren) => ExprKind::Paren(Box::new(self.expr(&paren.expr)?)),
            // Invisible groups come from `macro_rules!` expansions: transparent.
            E::Group(group) => return self.expr(&group.expr),
            E::Block(block) => match &block.label {
                Some(label) => return self.unsupported(label, "labelled blocks are"),
                None => ExprKind::Block(self.block(&block.block)?),
            },
            E::If(expr_if) => self.if_expr(expr_if)?,
            E::ForLoop(for_loop) => self.for_loop(for_loop)?,
            E::MethodCall(call) => self.method_call(call)?,
            E::Call(call) => self.call(call)?,
            E::Array(array) => {
                let elems = array.elems.iter().map(|elem| self.expr(elem)).collect();
                ExprKind::Array(all(elems)?)
            }
            E::Repeat(repeat) => ExprKind::Repeat { elem: Box::new(self.expr(&repeat.expr)?), len: repeat.len.clone() },
            E::Return(ret) => ExprKind::Return(match &ret.expr {
                Some(value) => Some(Box::new(self.expr(value)?)),
                None => None,
            }),
            E::Break(brk) if brk.label.is_none() && brk.expr.is_none() => ExprKind::Break(brk.break_token),
            E::Break(brk) => return self.unsupported(brk, "`break` with a label or a value is"),
            E::Continue(cont) if cont.label.is_none() => ExprKind::Continue(cont.continue_token),
            E::Continue(cont) => return self.unsupported(cont, "`continue` with a label is"),
            E::Closure(closure) => {
                let (or1, inputs, or2) = (&closure.or1_token, &closure.inputs, &closure.or2_token);
                return self.unsupported(quote!(#or1 #inputs #or2), "closures are");
            }
            E::Macro(mac) => return self.macro_call(&mac.mac),
            E::While(expr) => return self.unsupported(expr.while_token, "`while` loops are"),
            E::Loop(expr) => return self.unsupported(expr.loop_token, "`loop` is"),
            E::Match(expr) => return self.unsupported(expr.match_token, "`match` is"),
            E::Unsafe(expr) => return self.unsupported(expr.unsafe_token, "`unsafe` blocks are"),
            E::Reference(expr) => {
                let (and, mutability) = (&expr.and_token, &expr.mutability);
                return self.unsupported(quote!(#and #mutability), "references (`&`, `&mut`) are");
            }
            E::RawAddr(expr) => return self.unsupported(expr, "raw pointers are"),
            E::Tuple(expr) => return self.unsupported(expr, "tuples are"),
            E::Struct(expr) => return self.unsupported(&expr.path, "struct expressions are"),
            E::Range(expr) => return self.unsupported(expr.limits, "ranges outside `for i in a..b` are"),
            E::Let(expr) => return self.unsupported(expr.let_token, "`let` in conditions (`if let`) is"),
            E::Async(expr) => return self.unsupported(expr.async_token, "`async` blocks are"),
            E::Await(expr) => return self.unsupported(expr.await_token, "`.await` is"),
            E::Try(expr) => return self.unsupported(expr.question_token, "the `?` operator is"),
            E::TryBlock(expr) => return self.unsupported(expr.try_token, "`try` blocks are"),
            E::Const(expr) => return self.unsupported(expr.const_token, "`const` blocks are"),
            E::Yield(expr) => return self.unsupported(expr.yield_token, "`yield` is"),
            other => return self.unsupported(other, "this expression is"),
        };
        Some(Expr::new(kind, expr.span()))
    }

    fn path(&self, path: &syn::ExprPath) -> Option<ExprKind> {
        if let Some(function) = function_value(path) {
            self.error(
                path,
                format!(
                    "the function `{function}` used as a value is not supported in `{}`: the macro \
                     rewrites calls, not function values; call it where it is needed, as in `x.cos()`",
                    self.kind.name()
                ),
            );
            return None;
        }
        let Some(ident) = path.path.get_ident().filter(|_| path.qself.is_none()) else {
            return Some(ExprKind::Path(path.clone()));
        };
        if ident == "self" {
            return Some(ExprKind::SelfValue(syn::Token![self](ident.span())));
        }
        Some(match self.resolve(ident) {
            Some(Binding::Param(param)) => ExprKind::Param(param, ident.clone()),
            Some(Binding::Local(local)) => ExprKind::Local(local, ident.clone()),
            // Not a variable: a constant in scope (`PI`, `G`); rustc resolves it.
            None => ExprKind::Path(path.clone()),
        })
    }

    fn field(&mut self, field: &syn::ExprField) -> Option<ExprKind> {
        if !is_self_rooted(&field.base) {
            self.error(
                field,
                format!(
                    "field access is only supported on `self` (`self.m`, `self.params.k`) in `{}`",
                    self.kind.name()
                ),
            );
            return None;
        }
        Some(ExprKind::Field { base: Box::new(self.expr(&field.base)?), member: field.member.clone() })
    }

    fn index(&mut self, index: &syn::ExprIndex) -> Option<ExprKind> {
        let base = self.expr(&index.expr);
        let position = self.expr(&index.index);
        let (base, position) = (base?, position?);
        if let (ExprKind::Param(ParamRef::Q | ParamRef::V, name), Some(n), Some(i)) =
            (&base.kind, self.n, position.literal_index())
            && i >= n
        {
            self.error(&index.index, format!("index `{i}` is out of bounds for `{name}: [f64; {n}]`"));
            return None;
        }
        Some(ExprKind::Index {
            base: Box::new(base),
            index: Box::new(position),
            bracket: index.bracket_token.span.join(),
        })
    }

    fn binary(&mut self, binary: &syn::ExprBinary) -> Option<ExprKind> {
        use BinOp as B;
        match binary.op {
            B::Add(_)
            | B::Sub(_)
            | B::Mul(_)
            | B::Div(_)
            | B::Rem(_)
            | B::Lt(_)
            | B::Le(_)
            | B::Gt(_)
            | B::Ge(_)
            | B::Eq(_)
            | B::Ne(_)
            | B::And(_)
            | B::Or(_) => {
                let lhs = self.expr(&binary.left);
                let rhs = self.expr(&binary.right);
                Some(ExprKind::Binary { lhs: Box::new(lhs?), op: binary.op, rhs: Box::new(rhs?) })
            }
            B::AddAssign(_) | B::SubAssign(_) | B::MulAssign(_) | B::DivAssign(_) | B::RemAssign(_) => {
                let place = self.place(&binary.left);
                let value = self.expr(&binary.right);
                Some(ExprKind::Assign { place: Box::new(place?), op: Some(binary.op), value: Box::new(value?) })
            }
            op => {
                let what = format!("the operator `{}` is", op.to_token_stream());
                self.unsupported(op, &what)
            }
        }
    }

    /// The left-hand side of an assignment: a local variable or an element of
    /// a local array.
    fn place(&mut self, place: &syn::Expr) -> Option<Expr> {
        let name = self.kind.name();
        if is_self_rooted(place) {
            self.error(
                place,
                format!(
                    "writing to `self` is not allowed: `{name}` only reads the system; \
                     assign to a `let mut` local variable instead"
                ),
            );
            return None;
        }
        let variable = match place {
            syn::Expr::Index(index) => &*index.expr,
            place => place,
        };
        let ident = match variable {
            syn::Expr::Path(path) if path.qself.is_none() => path.path.get_ident(),
            _ => None,
        };
        match ident.and_then(|ident| Some((ident, self.resolve(ident)?))) {
            Some((_, Binding::Local(_))) => self.expr(place),
            Some((ident, Binding::Param(_))) => {
                self.error(
                    place,
                    format!(
                        "cannot assign to the parameter `{ident}`: copy it into a \
                         `let mut` local variable first"
                    ),
                );
                None
            }
            None => {
                self.error(
                    place,
                    format!("only local variables and elements of local arrays can be assigned in `{name}`"),
                );
                None
            }
        }
    }

    fn cast(&mut self, cast: &syn::ExprCast) -> Option<ExprKind> {
        let supported = is_f64(&cast.ty) || is_integer(&cast.ty);
        if !supported {
            self.error(
                &cast.ty,
                format!("only casts to `f64` or to an integer type are supported in `{}`", self.kind.name()),
            );
        }
        let expr = self.expr(&cast.expr)?;
        supported.then(|| ExprKind::Cast { expr: Box::new(expr), ty: cast.ty.clone() })
    }

    fn if_expr(&mut self, expr_if: &syn::ExprIf) -> Option<ExprKind> {
        let cond = self.expr(&expr_if.cond);
        let then_branch = self.block(&expr_if.then_branch);
        let else_branch = expr_if.else_branch.as_ref().map(|(_, else_branch)| self.expr(else_branch));
        Some(ExprKind::If {
            cond: Box::new(cond?),
            then_branch: then_branch?,
            else_branch: match else_branch {
                Some(else_branch) => Some(Box::new(else_branch?)),
                None => None,
            },
        })
    }

    fn for_loop(&mut self, for_loop: &syn::ExprForLoop) -> Option<ExprKind> {
        if let Some(label) = &for_loop.label {
            return self.unsupported(label, "loop labels are");
        }
        let range = match &*for_loop.expr {
            syn::Expr::Range(range) => {
                range.start.as_ref().zip(range.end.as_ref()).map(|bounds| (bounds, range.limits))
            }
            _ => None,
        };
        let Some(((start, end), limits)) = range else {
            self.error(
                &for_loop.expr,
                "only `for i in a..b` and `for i in a..=b` loops over integer ranges are supported",
            );
            return None;
        };
        let start = self.expr(start);
        let end = self.expr(end);
        let var = match &*for_loop.pat {
            Pat::Ident(PatIdent { by_ref: None, subpat: None, mutability: None, ident, .. }) => Some(Some(ident)),
            Pat::Wild(_) => Some(None),
            pat => self.unsupported(pat, "loop patterns other than a plain name or `_` are"),
        };
        self.scopes.push(Vec::new());
        let var = var.map(|var| var.map(|ident| (self.declare(ident), ident.clone())));
        let body = self.block(&for_loop.body);
        self.scopes.pop();
        Some(ExprKind::For { var: var?, start: Box::new(start?), limits, end: Box::new(end?), body: body? })
    }

    fn method_call(&mut self, call: &syn::ExprMethodCall) -> Option<ExprKind> {
        let name = self.kind.name();
        let method = &call.method;
        if is_self(&call.receiver) {
            self.error(
                method,
                format!("calls to methods of `self` are not supported: inline `{method}` into `{name}`"),
            );
            return None;
        }
        let receiver = self.expr(&call.receiver);
        let args = all(call.args.iter().map(|arg| self.expr(arg)).collect());
        // `q.len()`, `v.len()`: the bound of a loop over a run-time-sized
        // chain (and valid on arrays too), also through a local (`let x =
        // q;`, a local array) or of an array field (`self.u.len()`, which
        // a parameter array turns into a local).
        let is_len = method == "len"
            && call.args.is_empty()
            && match &receiver {
                Some(Expr { kind: ExprKind::Param(ParamRef::Q | ParamRef::V, _) | ExprKind::Local(..), .. }) => true,
                Some(Expr { kind: ExprKind::Field { base, .. }, .. }) => matches!(base.kind, ExprKind::SelfValue(_)),
                _ => false,
            };
        let math = match &receiver {
            _ if is_len => Some(Math::Len),
            Some(Expr { kind: ExprKind::Local(local, out), .. }) if Some(*local) == self.out => {
                self.error(
                    method,
                    format!(
                        "the method `{method}` is not supported on `{out}` in `{name}`: \
                         write its entries (`{out}[i] = ...`, `{out}[i] += ...`) or take its length (`{out}.len()`)"
                    ),
                );
                None
            }
            Some(Expr { kind: ExprKind::Param(ParamRef::Q | ParamRef::V, param), .. }) => {
                self.error(
                    method,
                    format!(
                        "the method `{method}` is not supported on `{param}` in `{name}`: \
                         index it (`{param}[i]`) or take its length (`{param}.len()`)"
                    ),
                );
                None
            }
            _ => self.math(method, call.args.len()),
        };
        if let Some(turbofish) = &call.turbofish {
            return self.unsupported(turbofish, "type arguments on methods are");
        }
        Some(ExprKind::MethodCall {
            receiver: Box::new(receiver?),
            method: method.clone(),
            math: math?,
            args: args?,
            path: None,
            paren: call.paren_token.span.join(),
        })
    }

    /// The rewrite rule of a method called with `args` arguments besides the
    /// receiver; reports unsupported methods and wrong argument counts.
    fn math(&self, method: &Ident, args: usize) -> Option<Math> {
        let Some((math, arity)) = math_method(method) else {
            self.error(
                method,
                format!(
                    "the method `{method}` is not supported in `{}`; supported methods: {}",
                    self.kind.name(),
                    method_list()
                ),
            );
            return None;
        };
        if args != arity {
            self.error(
                method,
                format!("`{method}` takes {arity} argument{} besides its receiver", if arity == 1 { "" } else { "s" }),
            );
            return None;
        }
        Some(math)
    }

    fn call(&mut self, call: &syn::ExprCall) -> Option<ExprKind> {
        let name = self.kind.name();
        let args: Vec<_> = call.args.iter().map(|arg| self.expr(arg)).collect();
        let path = match &*call.func {
            syn::Expr::Path(path) if path.qself.is_none() => Some(path),
            _ => None,
        };
        let segments: Vec<&Ident> =
            path.iter().flat_map(|path| path.path.segments.iter().map(|segment| &segment.ident)).collect();
        match segments.as_slice() {
            // A local holding a function value (`let c = f64::cos;`, or one
            // chosen by an `if`): the rewrite cannot see which function it
            // holds, so it cannot make it generic over the dual numbers.
            // Its initializer was reported already.
            [local] if matches!(self.resolve(local), Some(Binding::Local(id)) if self.failed.contains(&id)) => None,
            [local] if matches!(self.resolve(local), Some(Binding::Local(_)) | Some(Binding::Param(_))) => {
                self.error(
                    &call.func,
                    format!(
                        "calling the variable `{local}` is not supported in `{name}`: the macro cannot \
                         rewrite a function held in a variable; call the math method itself, \
                         as in `x.cos()` or `f64::cos(x)`"
                    ),
                );
                None
            }
            // `f64::sqrt(x)`: a method in path form.
            [ty, method] if *ty == "f64" => {
                // The receiver is the first argument; none at all is reported as a
                // wrong count (`usize::MAX` matches no arity).
                let math = self.math(method, args.len().checked_sub(1).unwrap_or(usize::MAX));
                let mut args = all(args)?.into_iter();
                let receiver = args.next()?;
                Some(ExprKind::MethodCall {
                    receiver: Box::new(receiver),
                    method: (*method).clone(),
                    math: math?,
                    args: args.collect(),
                    path: path.cloned(),
                    paren: call.paren_token.span.join(),
                })
            }
            [this, method] if *this == "Self" => {
                self.error(
                    &call.func,
                    format!("calls to methods of `Self` are not supported: inline `{method}` into `{name}`"),
                );
                None
            }
            _ => {
                self.error(
                    &call.func,
                    format!(
                        "calls to functions are not supported in `{name}`: inline `{}` \
                         or use the supported methods of `f64`: {}",
                        call.func.to_token_stream().to_string().replace(' ', ""),
                        method_list()
                    ),
                );
                None
            }
        }
    }
}

/// The name of an `f64` function written as a value, `f64::cos` or
/// `std::f64::cos`: a path through `f64` ending in a lower-case name (the
/// associated constants, `f64::EPSILON`, and `std::f64::consts::PI` are upper
/// case).
fn function_value(path: &syn::ExprPath) -> Option<String> {
    let segments: Vec<&Ident> = path.path.segments.iter().map(|segment| &segment.ident).collect();
    let [.., ty, last] = segments.as_slice() else { return None };
    let lower = last.to_string().chars().next().is_some_and(char::is_lowercase);
    (path.qself.is_none() && *ty == "f64" && lower).then(|| format!("f64::{last}"))
}

/// `self`, possibly parenthesized.
fn is_self(expr: &syn::Expr) -> bool {
    match expr {
        syn::Expr::Path(path) => path.qself.is_none() && path.path.is_ident("self"),
        syn::Expr::Paren(paren) => is_self(&paren.expr),
        syn::Expr::Group(group) => is_self(&group.expr),
        _ => false,
    }
}

/// `self` or a place inside it: `self.m`, `self.k[0]`, `*self`.
fn is_self_rooted(expr: &syn::Expr) -> bool {
    match expr {
        syn::Expr::Field(field) => is_self_rooted(&field.base),
        syn::Expr::Index(index) => is_self_rooted(&index.expr),
        syn::Expr::Unary(syn::ExprUnary { op: UnOp::Deref(_), expr, .. }) => is_self_rooted(expr),
        expr => is_self(expr),
    }
}

/// Whether `ty` is a primitive integer type.
fn is_integer(ty: &Type) -> bool {
    const INTEGERS: &[&str] = &["i8", "i16", "i32", "i64", "i128", "isize", "u8", "u16", "u32", "u64", "u128", "usize"];
    match ty {
        Type::Path(path) if path.qself.is_none() => {
            path.path.get_ident().is_some_and(|ident| INTEGERS.iter().any(|int| ident == int))
        }
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse::Input;
    use syn::{ItemImpl, parse_quote};

    /// The errors reported for a Lagrangian with `body` and `N = 2`.
    fn errors(body: syn::Block) -> Vec<String> {
        let item: ItemImpl = parse_quote! {
            impl P { fn lagrangian(&self, t: f64, q: [f64; 2], v: [f64; 2]) -> f64 #body }
        };
        let cx = Ctxt::new();
        let _ = super::super::validate(&cx, &Input::from_syn(&item));
        cx.check().err().map_or_else(Vec::new, |errors| errors.messages())
    }

    fn starts(errors: &[String]) -> Vec<&str> {
        errors.iter().map(|e| e.split([';', ':']).next().unwrap_or("")).collect()
    }

    #[test]
    fn the_supported_subset_lowers_cleanly() {
        let body = parse_quote!({
            use std::f64::consts::PI;
            const K: f64 = 2.0;
            let mut acc = 0.0;
            for i in 0..2 {
                acc += self.k[i] * q[i].powi(2);
                if i == 1 {
                    break;
                } else {
                    continue;
                }
            }
            let x: f64 = if q[0] > 0.0 && !(v[1] < 0.0) { q[0].sin() } else { -q[1] };
            let f = [x, 1.0];
            let mut g = [0.0; 2];
            g[1] = f64::atan2(q[0], v[0]) + (i as f64) + 1.0f64.mul_add(x, K);
            return acc / (2.0 - x) + f[0] * g[1] + PI * t.powf(1.5).log(2.0);
        });
        assert_eq!(errors(body), Vec::<String>::new());
    }

    #[test]
    fn reports_every_unsupported_construct() {
        let body = parse_quote!({
            let f = |x: f64| x * 2.0;
            println!("{}", q[0]);
            let y = helper(q[0]) + self.helper(v[0]) + q[0].floor();
            while true {}
            match 1 {
                _ => {}
            }
            let r = &q;
            self.m = q[1];
            q[0] = 1.0;
            let [a, b] = [1.0, 2.0];
            let pair = (1.0, 2.0);
            0.0
        });
        assert_eq!(
            starts(&errors(body)),
            [
                "closures are not supported in `lagrangian`",
                "macros such as `println!` are not supported in `lagrangian`",
                "calls to functions are not supported in `lagrangian`",
                "calls to methods of `self` are not supported",
                "the method `floor` is not supported in `lagrangian`",
                "`while` loops are not supported in `lagrangian`",
                "`match` is not supported in `lagrangian`",
                "references (`&`, `&mut`) are not supported in `lagrangian`",
                "writing to `self` is not allowed",
                "cannot assign to the parameter `q`",
                "patterns other than names, `_` and tuples of them are not supported in `lagrangian`",
                "tuples are not supported in `lagrangian`",
            ]
        );
    }

    #[test]
    fn calls_of_variables_and_function_values_are_reported_once() {
        let body = parse_quote!({
            let c = f64::cos;
            let g = G;
            let h = |x: f64| x;
            c(q[0]) + g(q[1]) + h(v[0]) + q(1)
        });
        assert_eq!(
            starts(&errors(body)),
            [
                "the function `f64", // `::cos` (`starts` cuts at the first `:`)
                "closures are not supported in `lagrangian`",
                // `c` and `h` were reported at their `let`; `g` holds an
                // opaque constant that could be a function.
                "calling the variable `g` is not supported in `lagrangian`",
                "calling the variable `q` is not supported in `lagrangian`",
            ]
        );
    }

    #[test]
    fn reports_literal_indices_out_of_bounds() {
        let errors = errors(parse_quote!({ q[1] + v[2] + q[7] }));
        assert_eq!(
            errors,
            ["index `2` is out of bounds for `v: [f64; 2]`", "index `7` is out of bounds for `q: [f64; 2]`",]
        );
    }

    #[test]
    fn resolves_names_with_shadowing() {
        let item: ItemImpl = parse_quote! {
            impl P {
                fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
                    let x = v[0];
                    let x = x * G;
                    { let q = x; q }
                }
            }
        };
        let cx = Ctxt::new();
        let system = super::super::validate(&cx, &Input::from_syn(&item)).unwrap();
        cx.check().unwrap();
        let f = &system.lagrangian;
        assert_eq!(f.locals.len(), 3);
        let Stmt::Let { inits, .. } = &f.body.stmts[1] else { panic!("expected a let") };
        let ExprKind::Binary { lhs, rhs, .. } = &inits[0].kind else { panic!("expected x * G") };
        assert!(matches!(lhs.kind, ExprKind::Local(LocalId(0), _)));
        assert!(matches!(rhs.kind, ExprKind::Path(_)));
        let Some(Expr { kind: ExprKind::Block(inner), .. }) = f.body.tail() else { panic!("expected a block") };
        assert!(matches!(inner.tail().map(|e| &e.kind), Some(ExprKind::Local(LocalId(2), _))));
    }
}
