#!/usr/bin/env python3
"""Writes tests/verification/gradient_fuzz.rs: random Lagrangians for the
macro's gradient code, checked there against dual numbers.

Each system is a random body of the subset the adjoint stage transforms
(`let` bindings, arithmetic, product chains with repeated factors, divisions
by constants, the float methods, `powi`/`powf`, accumulators in loops over
neighbours), kept finite on the sampled box by construction (square roots,
logarithms and denominators of `1 + x²`-like arguments). The seed is fixed,
so the file is reproducible: `python3 scripts/gradient_fuzz.py > tests/verification/gradient_fuzz.rs && cargo fmt`.
"""
import random
import re

SEED = 20261125
STRAIGHT = 20  # straight-line systems, N = 2 or 3
LOOPED = 8  # systems with loops, const N


class Gen:
    def __init__(self, rng, n, time, locals_, loop_var=None):
        self.rng, self.n, self.time, self.locals, self.loop_var = rng, n, time, locals_, loop_var

    def leaf(self):
        r = self.rng.random()
        if self.loop_var and r < 0.45:
            return self.rng.choice([f"q[{self.loop_var}]", f"q[{self.loop_var} + 1]", f"v[{self.loop_var}]", "d", "d"])
        if self.loop_var and r < 0.6:
            return self.rng.choice(["self.a", "self.b", "0.5", "1.3"])
        if r < 0.55:
            return f"q[{self.rng.randrange(self.n)}]"
        if r < 0.65:
            return f"v[{self.rng.randrange(self.n)}]"
        if r < 0.7 and self.time:
            return "t"
        if r < 0.78:
            return self.rng.choice(["self.a", "self.b"])
        if r < 0.9 and self.locals:
            return self.rng.choice(self.locals)
        return self.rng.choice(["0.5", "1.3", "2.0", "3.0", "0.25", "-0.7"])

    def active(self, depth):
        """An expression that depends on an active value: methods are only
        called on those (`(0.5).sin()` has no type in Rust)."""
        while True:
            x = self.expr(depth)
            if re.search(r"q\[|v\[|\bt\b|\bx\d|\bs\b|\bd\b", x):
                return x

    def expr(self, depth):
        if depth <= 0:
            return self.leaf()
        e = lambda: self.expr(depth - 1)
        a = lambda: self.active(depth - 1)
        k = self.rng.randrange(15)
        if k == 0:
            return f"{e()} + {e()}"
        if k == 1:
            return f"{e()} - ({e()})"
        if k == 2:
            x = self.leaf()
            return f"{x} * {e()} * {x}"  # a repeated factor
        if k == 3:
            return f"({e()}) * ({e()})"
        if k == 4:
            return f"({e()}) / {self.rng.choice(['3.0', 'self.a', '(self.b + 1.0)'])}"
        if k == 5:
            x = e()
            return f"({e()}) / (1.5 + ({x}) * ({x}))"
        if k == 6:
            return f"-({e()})"
        if k == 7:
            return f"({a()}).{self.rng.choice(['sin', 'cos', 'tanh', 'atan'])}()"
        if k == 8:
            return f"(0.3 * ({a()})).tanh().exp()"
        if k == 9:
            x = a()
            return f"(1.0 + ({x}) * ({x})).sqrt()"
        if k == 10:
            return f"(2.0 + ({a()}).sin()).ln()"
        if k == 11:
            return f"(0.5 * ({a()})).tanh().powi({self.rng.choice([2, 3, 4])})"
        if k == 12:
            x = a()
            return f"(1.0 + ({x}) * ({x})).powf({self.rng.choice(['1.5', '0.5', 'self.b'])})"
        if k == 13:
            x = self.leaf()
            return f"{self.rng.choice(['0.25', 'self.a', '2.0'])} * {x} * {x} * {x}"
        return f"({a()}).abs() * {self.leaf()}"


def straight(rng, index):
    n = rng.choice([2, 3])
    time = rng.random() < 0.3
    lines, locals_ = [], []
    for j in range(rng.randrange(0, 3)):
        g = Gen(rng, n, time, list(locals_))
        lines.append(f"let x{j} = {g.expr(2)};")
        locals_.append(f"x{j}")
    g = Gen(rng, n, time, locals_)
    if rng.random() < 0.4:
        # An accumulator outside loops, read by the tail.
        lines.append(f"let mut s = {g.expr(1)};")
        lines.append(f"s += {g.expr(2)};")
        lines.append(f"s -= {g.expr(1)};")
        locals_.append("s")
    kinetic = " + ".join(f"{rng.choice(['0.5', '0.5 * self.a', '0.75'])} * v[{i}] * v[{i}]" for i in range(n))
    used = "".join(f" + 0.1 * {x} * q[{rng.randrange(n)}]" for x in locals_ + (["t"] if time else []))
    tail = f"{kinetic} + v[{rng.randrange(n)}] * ({g.expr(2)}) - ({g.expr(3)}) + {g.expr(2)}{used}"
    args = "t: f64, " if time else ""
    body = "\n        ".join(lines + [tail])
    return (
        f"pub struct Straight{index} {{\n    pub a: f64,\n    pub b: f64,\n}}\n\n"
        f"#[lagrangian]\nimpl Straight{index} {{\n"
        f"    fn lagrangian(&self, {args}q: [f64; {n}], v: [f64; {n}]) -> f64 {{\n        {body}\n    }}\n}}\n",
        f"Straight{index} {{ a: {rng.choice([0.7, 1.2, 1.9])}, b: {rng.choice([0.4, 1.1, 2.3])} }}",
        n,
    )


def looped(rng, index):
    time = rng.random() < 0.3
    g = Gen(rng, 2, time, [], loop_var="i")
    read_after = rng.random() < 0.4
    bond = g.expr(2)
    lines = [
        "let mut kinetic = 0.0;",
        "let mut potential = 0.0;",
        "for i in 0..N - 1 {",
        "    let d = q[i + 1] - q[i];",
        f"    potential += 0.5 * d * d + {bond};",
        f"    kinetic += 0.5 * v[i] * v[i] + 0.25 * v[i] * v[i + 1] * ({Gen(rng, 2, time, ['d'], loop_var='i').expr(1)});",
        "}",
        "kinetic += 0.5 * v[N - 1] * v[N - 1];",
    ]
    if rng.random() < 0.5:
        lines += [
            "for i in 0..N {",
            f"    potential -= {Gen(rng, 2, time, [], loop_var=None).expr(1).replace('q[0]', 'q[i]').replace('q[1]', 'q[i]').replace('v[0]', 'v[i]').replace('v[1]', 'v[i]')};",
            "}",
        ]
    end = Gen(rng, 2, time, [])
    tail = f"kinetic - potential + {end.expr(2)}" + (" + 0.1 * t * q[0]" if time else "")
    if read_after:
        tail += " - 0.1 * potential * potential"
    args = "t: f64, " if time else ""
    body = "\n        ".join(lines + [tail])
    return (
        f"pub struct Looped{index}<const N: usize> {{\n    pub a: f64,\n    pub b: f64,\n}}\n\n"
        f"#[lagrangian]\nimpl<const N: usize> Looped{index}<N> {{\n"
        f"    fn lagrangian(&self, {args}q: [f64; N], v: [f64; N]) -> f64 {{\n        {body}\n    }}\n}}\n",
        f"Looped{index}::<5> {{ a: {rng.choice([0.7, 1.2, 1.9])}, b: {rng.choice([0.4, 1.1, 2.3])} }}",
        5,
    )


def main():
    rng = random.Random(SEED)
    systems = [straight(rng, i) for i in range(STRAIGHT)] + [looped(rng, i) for i in range(LOOPED)]
    print("//! Random Lagrangians for the macro's gradient code, written by")
    print("//! `scripts/gradient_fuzz.py` (fixed seed; regenerate with")
    print("//! `python3 scripts/gradient_fuzz.py > tests/verification/gradient_fuzz.rs && cargo fmt`):")
    print("//! bodies of the subset the adjoint stage transforms, nobody's hand-picked")
    print("//! case. Each one's `gradient_q`, `gradient_qv` and generic gradient are")
    print("//! checked against dual numbers at random states (`gradient_code.rs`).")
    print("#![allow(clippy::all, dead_code, unused_parens)]")
    print("use super::gradient_code::{scalar_difference, worst_difference};")
    print("use lagrangian::prelude::*;")
    print()
    for code, _, _ in systems:
        print(code)
    print("/// Reordered sums and folded products round differently from the dual")
    print("/// path: a few ulps, relative to the largest component of the gradient")
    print("/// (and of the Hessian-vector product), with room for the cancellation")
    print("/// a random expression can have (the worst seen: 1.1e-14).")
    print("const TOLERANCE: f64 = 1e-13;")
    print()
    print("#[test]")
    print("fn random_bodies_have_gradient_code_that_agrees_with_dual_numbers() {")
    print("    let cases: Vec<(&str, f64, f64)> = vec![")
    for i, (_, value, _) in enumerate(systems):
        name = value.split(" ")[0].split("::")[0]
        print(f"        (\"{name}\", worst_difference(&{value}, -1.5, 1.5, 60), scalar_difference(&{value}, -1.5, 1.5, 30)),")
    print("    ];")
    print("    for (name, gradient, products) in &cases {")
    print('        println!("{name}: gradient {gradient:.1e}, Hessian-vector products {products:.1e}");')
    print("    }")
    print("    for (name, gradient, products) in cases {")
    print('        assert!(gradient <= TOLERANCE && products <= TOLERANCE, "{name}: {gradient:e}, {products:e}");')
    print("    }")
    print("}")


main()
