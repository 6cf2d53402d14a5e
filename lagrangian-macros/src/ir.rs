//! The checked form of a method body: `validate` builds it, `analyse`
//! annotates it with activity classes and `generate` prints it.
//!
//! It only has room for the constructs the rewrite supports, so once a body
//! has been lowered into it no later stage needs an "unsupported" case. Names
//! are already resolved: a variable is a parameter, a local or a constant.

use crate::parse::{Dim, Len, MethodKind};
use proc_macro2::Span;
use syn::{BinOp, ExprPath, Ident, Item, Lit, Member, RangeLimits, Token, Type, UnOp};

/// A validated impl block: the number of coordinates and the recognised
/// methods, ready for analysis.
pub(crate) struct System {
    /// `N`, from the Lagrangian's `q: [f64; N]`, or [`Dim::Dynamic`] for
    /// `q: &[f64]`.
    pub(crate) n: Dim,
    /// The Lagrangian.
    pub(crate) lagrangian: Function,
    /// The Rayleigh dissipation function, if given.
    pub(crate) dissipation: Option<Function>,
    /// The applied forces, if given.
    pub(crate) force: Option<Function>,
    /// The step density `g(t, q)` of the time-transformed integrators, if given.
    pub(crate) step_density: Option<Function>,
    /// The holonomic constraints `g(t, q)` and their number `M`, if given.
    pub(crate) constraints: Option<(Function, Len)>,
}

impl System {
    /// The methods present, Lagrangian first.
    pub(crate) fn functions_mut(&mut self) -> impl Iterator<Item = &mut Function> {
        std::iter::once(&mut self.lagrangian)
            .chain(self.dissipation.as_mut())
            .chain(self.force.as_mut())
            .chain(self.step_density.as_mut())
            .chain(self.constraints.as_mut().map(|(function, _)| function))
    }
}

/// One recognised method.
pub(crate) struct Function {
    /// Which method.
    pub(crate) kind: MethodKind,
    /// The method name as written, for spans.
    pub(crate) name: Ident,
    /// The span of the user's `self`: the generated method's `self` must come
    /// from the same place (the same macro hygiene) as the `self.field`s of
    /// the body, e.g. when the block is written by a `macro_rules!`.
    pub(crate) self_span: Span,
    /// The time parameter; `None` when the signature has no `t`.
    pub(crate) time: Option<Binder>,
    /// The position parameter.
    pub(crate) q: Binder,
    /// The velocity parameter (`None` also for `step_density`, which has none).
    pub(crate) v: Binder,
    /// The out-parameter of a run-time-sized system's `force`, `f: &mut
    /// [f64]`, which the body writes into instead of returning an array;
    /// `None` for the other methods.
    pub(crate) out: Option<Out>,
    /// The body.
    pub(crate) body: Block,
    /// Every `let` and loop variable of the body, indexed by [`LocalId`].
    pub(crate) locals: Vec<Local>,
}

impl Function {
    /// The class the body's value must be coerced to: the trait returns `D`
    /// or `[D; N]` whatever the body computes, and nothing when it writes
    /// into an out-parameter.
    pub(crate) fn return_class(&self) -> Class {
        match (&self.out, self.kind.returns_array()) {
            (Some(_), _) => Class::Unit,
            (None, true) => Class::ActiveArray,
            (None, false) => Class::Active,
        }
    }
}

/// The out-parameter `f: &mut [f64]` of a run-time-sized system's `force`.
///
/// The body reads and writes it like a `let mut` local array of class
/// [`Class::ActiveArray`], so it is one: the first local of the function,
/// declared before the body's own.
pub(crate) struct Out {
    /// Its name as written.
    pub(crate) name: Binder,
    /// The local standing for it; `None` for `_`, which the body cannot use.
    pub(crate) local: Option<LocalId>,
}

/// A parameter name as written: an identifier, or `None` for `_`.
pub(crate) type Binder = Option<Ident>;

/// Index of a local variable in [`Function::locals`]. Shadowing creates a new
/// local, so one id is one binding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LocalId(pub(crate) usize);

/// A local variable.
pub(crate) struct Local {
    /// Its name at the declaration.
    pub(crate) name: Ident,
    /// The join of the classes of every value assigned to it; set by `analyse`.
    pub(crate) class: Class,
}

/// The three parameters a body can refer to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ParamRef {
    /// `t`.
    Time,
    /// `q`.
    Q,
    /// `v`.
    V,
}

/// What an expression computes, as far as the rewrite is concerned.
///
/// The order matters: [`Class::join`] takes the larger of two scalar classes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Class {
    /// No value: statements, `return`, loops. Also the bottom of the join, the
    /// class of a local before any assignment has been seen.
    Unit,
    /// A `bool`: comparisons and logic.
    Bool,
    /// An integer: integer literals, loop variables, casts to integer types.
    Int,
    /// A value that cannot depend on `t`, `q` or `v`: float literals, `self`
    /// fields, constants. Kept as plain `f64` in the generated code (cheap).
    /// Its exact type is unknown (`self.n` may be a `usize`).
    Const,
    /// A scalar depending on `t`, `q` or `v`: becomes the scalar type `D`.
    Active,
    /// An array of constants.
    ConstArray,
    /// An array with elements depending on `t`, `q` or `v`: `[D; _]`.
    ActiveArray,
}

impl Class {
    /// Whether values of this class have type `D` (or arrays of it).
    pub(crate) fn is_active(self) -> bool {
        matches!(self, Class::Active | Class::ActiveArray)
    }

    /// Whether this is an array class.
    pub(crate) fn is_array(self) -> bool {
        matches!(self, Class::ConstArray | Class::ActiveArray)
    }

    /// The least class holding values of both: what a variable becomes when
    /// assigned both, or what an `if` is when its branches are. Mixtures that
    /// make no sense (a scalar and an array) do not occur in code rustc
    /// accepts, so any answer will do for them.
    pub(crate) fn join(self, other: Class) -> Class {
        match (self, other) {
            (Class::Active, Class::ConstArray) | (Class::ConstArray, Class::Active) => Class::ActiveArray,
            // An integer variable assigned an opaque constant (`self.n`)
            // stays an integer.
            (Class::Int, Class::Const) | (Class::Const, Class::Int) => Class::Int,
            _ => self.max(other),
        }
    }
}

/// A block `{ stmts }`.
pub(crate) struct Block {
    /// The braces' span.
    pub(crate) span: Span,
    /// Its statements; a final expression without `;` is the block's value.
    pub(crate) stmts: Vec<Stmt>,
}

impl Block {
    /// Calls [`Expr::visit`] on every expression of the block.
    pub(crate) fn visit(&self, f: &mut impl FnMut(&Expr) -> bool) {
        for stmt in &self.stmts {
            match stmt {
                Stmt::Let { inits, .. } => inits.iter().for_each(|init| init.visit(f)),
                Stmt::Expr { expr, .. } => expr.visit(f),
                Stmt::Item(_) => {}
            }
        }
    }

    /// Calls [`Expr::visit_mut`] on every expression of the block.
    pub(crate) fn visit_mut(&mut self, f: &mut impl FnMut(&mut Expr) -> bool) {
        for stmt in &mut self.stmts {
            match stmt {
                Stmt::Let { inits, .. } => inits.iter_mut().for_each(|init| init.visit_mut(f)),
                Stmt::Expr { expr, .. } => expr.visit_mut(f),
                Stmt::Item(_) => {}
            }
        }
    }

    /// The final expression giving the block its value, if any.
    #[cfg(test)]
    pub(crate) fn tail(&self) -> Option<&Expr> {
        match self.stmts.last() {
            Some(Stmt::Expr { expr, semi: false }) => Some(expr),
            _ => None,
        }
    }
}

/// A statement.
pub(crate) enum Stmt {
    /// `let pattern[: ty] = init;`: one binding and one initializer, or a
    /// tuple of bindings destructuring a tuple of as many initializers.
    Let {
        /// The `let` keyword's span.
        span: Span,
        /// The variables declared, one per initializer.
        bindings: Vec<LetBinding>,
        /// Whether the pattern is a tuple: `let (a, b) = (x, y);`.
        tuple: bool,
        /// The type annotation, if any.
        ty: Option<Box<Type>>,
        /// The initializers.
        inits: Vec<Expr>,
    },
    /// An expression, with or without a trailing `;`.
    Expr {
        /// The expression.
        expr: Expr,
        /// Whether a `;` follows.
        semi: bool,
    },
    /// A `const` or `use` item, copied as written.
    Item(Box<Item>),
}

/// One variable of a `let` pattern.
#[derive(Clone, Copy)]
pub(crate) struct LetBinding {
    /// The variable; `None` for `_`.
    pub(crate) local: Option<LocalId>,
    /// Whether it was declared `mut`.
    pub(crate) mutable: bool,
}

/// An expression with its source span and, once analysed, its class.
pub(crate) struct Expr {
    /// What it is.
    pub(crate) kind: ExprKind,
    /// Where the user wrote it; generated code around it reuses this span so
    /// errors point into the user's method.
    pub(crate) span: Span,
    /// Set by `analyse`; [`Class::Unit`] until then.
    pub(crate) class: Class,
}

impl Expr {
    /// An expression not yet analysed.
    pub(crate) fn new(kind: ExprKind, span: Span) -> Self {
        Expr { kind, span, class: Class::Unit }
    }

    /// The value of an integer literal, as in the index of `q[2]`.
    pub(crate) fn literal_index(&self) -> Option<usize> {
        match &self.kind {
            ExprKind::Lit(Lit::Int(lit)) => lit.base10_parse().ok(),
            _ => None,
        }
    }

    /// Calls `f` on this expression and, where it returns `true`, on its
    /// subexpressions, in source order.
    pub(crate) fn visit(&self, f: &mut impl FnMut(&Expr) -> bool) {
        if !f(self) {
            return;
        }
        match &self.kind {
            ExprKind::Lit(_)
            | ExprKind::Path(_)
            | ExprKind::SelfValue(_)
            | ExprKind::Param(..)
            | ExprKind::Local(..)
            | ExprKind::Break(_)
            | ExprKind::Continue(_) => {}
            ExprKind::Field { base: expr, .. }
            | ExprKind::Unary { expr, .. }
            | ExprKind::Cast { expr, .. }
            | ExprKind::Paren(expr)
            | ExprKind::Repeat { elem: expr, .. } => expr.visit(f),
            ExprKind::Return(expr) => {
                if let Some(expr) = expr {
                    expr.visit(f);
                }
            }
            ExprKind::Index { base: a, index: b, .. }
            | ExprKind::Binary { lhs: a, rhs: b, .. }
            | ExprKind::Assign { place: a, value: b, .. } => {
                a.visit(f);
                b.visit(f);
            }
            ExprKind::Block(block) => block.visit(f),
            ExprKind::If { cond, then_branch, else_branch } => {
                cond.visit(f);
                then_branch.visit(f);
                if let Some(else_branch) = else_branch {
                    else_branch.visit(f);
                }
            }
            ExprKind::For { start, end, body, .. } => {
                start.visit(f);
                end.visit(f);
                body.visit(f);
            }
            ExprKind::MethodCall { receiver, args, .. } => {
                receiver.visit(f);
                args.iter().for_each(|arg| arg.visit(f));
            }
            ExprKind::Array(elems) => elems.iter().for_each(|elem| elem.visit(f)),
        }
    }

    /// [`visit`](Self::visit) with mutable access: `f` may rewrite an
    /// expression, and returns whether to descend into what it left.
    pub(crate) fn visit_mut(&mut self, f: &mut impl FnMut(&mut Expr) -> bool) {
        if !f(self) {
            return;
        }
        match &mut self.kind {
            ExprKind::Lit(_)
            | ExprKind::Path(_)
            | ExprKind::SelfValue(_)
            | ExprKind::Param(..)
            | ExprKind::Local(..)
            | ExprKind::Break(_)
            | ExprKind::Continue(_) => {}
            ExprKind::Field { base: expr, .. }
            | ExprKind::Unary { expr, .. }
            | ExprKind::Cast { expr, .. }
            | ExprKind::Paren(expr)
            | ExprKind::Repeat { elem: expr, .. } => expr.visit_mut(f),
            ExprKind::Return(expr) => {
                if let Some(expr) = expr {
                    expr.visit_mut(f);
                }
            }
            ExprKind::Index { base: a, index: b, .. }
            | ExprKind::Binary { lhs: a, rhs: b, .. }
            | ExprKind::Assign { place: a, value: b, .. } => {
                a.visit_mut(f);
                b.visit_mut(f);
            }
            ExprKind::Block(block) => block.visit_mut(f),
            ExprKind::If { cond, then_branch, else_branch } => {
                cond.visit_mut(f);
                then_branch.visit_mut(f);
                if let Some(else_branch) = else_branch {
                    else_branch.visit_mut(f);
                }
            }
            ExprKind::For { start, end, body, .. } => {
                start.visit_mut(f);
                end.visit_mut(f);
                body.visit_mut(f);
            }
            ExprKind::MethodCall { receiver, args, .. } => {
                receiver.visit_mut(f);
                args.iter_mut().for_each(|arg| arg.visit_mut(f));
            }
            ExprKind::Array(elems) => elems.iter_mut().for_each(|elem| elem.visit_mut(f)),
        }
    }
}

/// The supported expressions.
pub(crate) enum ExprKind {
    /// A numeric or boolean literal.
    Lit(Lit),
    /// A path naming a constant: `PI`, `std::f64::consts::PI`, `Self::G`.
    Path(ExprPath),
    /// `self`, only ever the base of a field access.
    SelfValue(Token![self]),
    /// `t`, `q` or `v`, with the identifier as written at this use.
    Param(ParamRef, Ident),
    /// A local variable, with the identifier as written at this use.
    Local(LocalId, Ident),
    /// `base.member`, where `base` is `self` or another field of it.
    Field {
        /// The value accessed.
        base: Box<Expr>,
        /// The field.
        member: Member,
    },
    /// `base[index]`.
    Index {
        /// The array.
        base: Box<Expr>,
        /// The index.
        index: Box<Expr>,
        /// The brackets' span.
        bracket: Span,
    },
    /// `-expr` or `!expr`.
    Unary {
        /// The operator.
        op: UnOp,
        /// The operand.
        expr: Box<Expr>,
    },
    /// Arithmetic, comparison or logic: `+ - * / % < <= > >= == != && ||`.
    Binary {
        /// Left operand.
        lhs: Box<Expr>,
        /// The operator.
        op: BinOp,
        /// Right operand.
        rhs: Box<Expr>,
    },
    /// `expr as ty`, to `f64` or an integer type.
    Cast {
        /// The value converted.
        expr: Box<Expr>,
        /// The target type.
        ty: Box<Type>,
    },
    /// `(expr)`.
    Paren(Box<Expr>),
    /// `{ ... }`.
    Block(Block),
    /// `if cond { ... } [else ...]`; the else branch is a block or an `if`.
    If {
        /// The condition.
        cond: Box<Expr>,
        /// The `then` block.
        then_branch: Block,
        /// The `else` branch.
        else_branch: Option<Box<Expr>>,
    },
    /// `for var in start..end { body }` (or `..=`).
    For {
        /// The loop variable, `None` for `_`.
        var: Option<(LocalId, Ident)>,
        /// Lower bound.
        start: Box<Expr>,
        /// `..` or `..=`.
        limits: RangeLimits,
        /// Upper bound.
        end: Box<Expr>,
        /// The loop body.
        body: Block,
    },
    /// A supported `f64` method, written `receiver.method(args)` or, when
    /// `path` is set, `f64::method(receiver, args)`.
    MethodCall {
        /// The value the method is called on.
        receiver: Box<Expr>,
        /// The method name as written.
        method: Ident,
        /// How the method treats its arguments.
        math: Math,
        /// The remaining arguments.
        args: Vec<Expr>,
        /// The function path of the `f64::method(x, ...)` form.
        path: Option<ExprPath>,
        /// The span of the parentheses around the arguments.
        paren: Span,
    },
    /// `[a, b, ...]`.
    Array(Vec<Expr>),
    /// `[elem; len]`.
    Repeat {
        /// The repeated element.
        elem: Box<Expr>,
        /// The length, copied as written.
        len: Box<syn::Expr>,
    },
    /// `place = value` or `place op= value`, `place` a local or an element
    /// of a local array.
    Assign {
        /// The variable or element written.
        place: Box<Expr>,
        /// The arithmetic operator of a compound assignment (`+=` ...).
        op: Option<BinOp>,
        /// The value.
        value: Box<Expr>,
    },
    /// `return [expr]`.
    Return(Option<Box<Expr>>),
    /// `break` (unlabelled, no value).
    Break(Token![break]),
    /// `continue` (unlabelled).
    Continue(Token![continue]),
}

/// How a supported method treats its receiver and arguments; each needs its
/// own rewrite when some of them depend on `t`, `q` or `v`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Math {
    /// No arguments: `sin`, `sqrt`, `abs`, ...
    Plain,
    /// `powi(n)`: the exponent is an integer and never active.
    Powi,
    /// `powf(x)`: becomes `powd` when `x` is active.
    Powf,
    /// `log(base)`: becomes `ln() / base.ln()` when `base` is active.
    Log,
    /// `atan2(x)`, `mul_add(a, b)`: all operands must have the same type.
    Uniform,
    /// `q.len()` or `v.len()`: the number of coordinates, an integer that
    /// depends on nothing (the dimension is fixed during a call).
    Len,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn join_is_the_larger_class_with_array_and_integer_exceptions() {
        assert_eq!(Class::Unit.join(Class::Const), Class::Const);
        assert_eq!(Class::Const.join(Class::Active), Class::Active);
        assert_eq!(Class::Active.join(Class::Const), Class::Active);
        assert_eq!(Class::ConstArray.join(Class::ActiveArray), Class::ActiveArray);
        assert_eq!(Class::Const.join(Class::ConstArray), Class::ConstArray);
        assert_eq!(Class::Active.join(Class::ConstArray), Class::ActiveArray);
        assert_eq!(Class::Int.join(Class::Const), Class::Int);
        assert!(Class::ActiveArray.is_active() && Class::ActiveArray.is_array());
        assert!(!Class::Const.is_active());
    }
}
