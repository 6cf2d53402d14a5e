#!/usr/bin/env python3
"""Writes tests/verification/gradient_fuzz.rs: random Lagrangians for the
macro's gradient code, checked there against dual numbers; with the argument
`structure`, tests/systems/structure_fuzz.rs: random Lagrangians whose
proven structure (separability, coupling pattern, autonomy, cyclic
coordinates) is checked against derivatives at random points.

Each system is a random body of the subset the adjoint stage transforms
(`let` bindings, arithmetic, product chains with repeated factors, divisions
by constants, the float methods, `powi`/`powf`, accumulators in loops over
neighbours), kept finite on the sampled box by construction (square roots,
logarithms and denominators of `1 + x²`-like arguments). The seed is fixed,
so the file is reproducible: `python3 scripts/gradient_fuzz.py > tests/verification/gradient_fuzz.rs && cargo fmt`.
"""
import random
import re
import sys

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


def smooth(rng, x):
    """A smooth function of the active expression `x`, growing at most
    quadratically (as a potential it keeps short runs bounded)."""
    return rng.choice([
        f"({x}).sin()",
        f"({x}).cos()",
        f"(1.0 + ({x}) * ({x})).sqrt()",
        f"0.5 * ({x}) * ({x})",
        f"(0.5 * ({x})).tanh()",
        f"(0.5 * ({x})).tanh().powi(3)",
    ])


def structure_system(rng, index):
    """A random body built from terms whose coupling is chosen: potential
    terms in one or two coordinates at a random distance, kinetic terms
    `v_i v_j` with a constant, position- or time-dependent coefficient,
    terms linear in `v`, loops over neighbours at distance 1 or 2."""
    n = rng.choice([4, 5, 6])
    terms, uses_t = [], False
    for _ in range(rng.randrange(2, 5)):
        i = rng.randrange(n)
        j = min(n - 1, i + rng.choice([0, 1, 1, 2, 3]))
        k = rng.random()
        if k < 0.35:
            terms.append(f"- self.a * {smooth(rng, f'q[{j}] - q[{i}]' if i != j else f'q[{i}]')}")
        elif k < 0.5:
            terms.append(f"- self.b * (q[{i}] * q[{j}] * {smooth(rng, f'q[{i}]')}).tanh()")
        elif k < 0.6:
            uses_t = True
            terms.append(f"- (self.b * t).cos() * {smooth(rng, f'q[{j}]')}")
        elif k < 0.75:
            coefficient = rng.choice(["self.a", f"(1.5 + ({smooth(rng, f'q[{rng.randrange(n)}]')}))", "0.3"])
            terms.append(f"+ 0.5 * {coefficient} * v[{i}] * v[{j}]")
        elif k < 0.82:
            uses_t = uses_t or rng.random() < 0.5
            factor = "(1.0 + 0.1 * (t).sin())" if uses_t else f"q[{j}]"
            terms.append(f"+ 0.2 * {factor} * v[{i}] * v[{i}]")
        elif k < 0.9:
            terms.append(f"+ self.b * v[{i}] * {smooth(rng, f'q[{j}]')}")
        else:
            terms.append(f"+ 0.1 * v[{i}] * v[{j}] * v[{i}] * v[{j}]")
    loops = []
    if rng.random() < 0.6:
        step = rng.choice([1, 1, 2])
        d = f"q[i + {step}] - q[i]"
        kinetic = rng.choice(["", f"\n            kinetic += 0.1 * v[i] * v[i + {step}];"])
        loops.append(
            f"for i in 0..N - {step} {{\n            let d = {d};\n"
            f"            potential += self.a * {smooth(rng, 'd')};{kinetic}\n        }}"
        )
    body = [
        "let mut kinetic = 0.0;",
        "for i in 0..N {",
        "    kinetic += 0.5 * v[i] * v[i];",
        "}",
        "let mut potential = 0.0;",
    ] + loops + [f"kinetic - potential {' '.join(terms)}"]
    args = "t: f64, " if uses_t else ""
    code = (
        f"pub struct Random{index}<const N: usize> {{\n    pub a: f64,\n    pub b: f64,\n}}\n\n"
        f"#[lagrangian]\nimpl<const N: usize> Random{index}<N> {{\n"
        f"    fn lagrangian(&self, {args}q: [f64; N], v: [f64; N]) -> f64 {{\n        "
        + "\n        ".join(body)
        + "\n    }\n}\n"
    )
    value = f"Random{index}::<{n}> {{ a: {rng.choice([0.7, 1.2])}, b: {rng.choice([0.4, 1.1])} }}"
    return code, value


PATHS = """
/// The same system with its structure hidden: the general Newton path.
struct Hidden<S>(S);

impl<S: Lagrangian<N>, const N: usize> Lagrangian<N> for Hidden<S> {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const CYCLIC: [bool; N] = S::CYCLIC;
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> D {
        self.0.lagrangian(t, q, v)
    }
}

/// The largest difference in `q` and `p` between two integrators over `n` steps.
fn difference<A: Lagrangian<N>, B: Lagrangian<N>, M: Method<f64>, const N: usize>(
    mut a: Integrator<A, M, N>,
    mut b: Integrator<B, M, N>,
    n: usize,
) -> f64 {
    let mut worst = 0.0f64;
    for _ in 0..n {
        a.step().unwrap();
        b.step().unwrap();
        for i in 0..N {
            worst = worst.max((a.state().q[i] - b.state().q[i]).abs());
            worst = worst.max((a.state().p[i] - b.state().p[i]).abs());
        }
    }
    worst
}

/// Every path a random system can take gives the same steps, to round-off
/// amplified over the run: trapezoid steps (explicit Störmer–Verlet where
/// the mass matrix is proven constant) against Newton on the hidden system;
/// Yoshida 4 likewise (fused explicit sub-steps); midpoint steps in forward
/// mode (hyper-duals, dense solves) against reverse mode (the gradient code
/// on lane duals, banded solves of the proven band).
fn paths_agree<S: Lagrangian<N>, const N: usize>(name: &str, system: impl Fn() -> S) -> [f64; 3] {
    let q0: [f64; N] = core::array::from_fn(|i| 0.3 + 0.2 * (i as f64).sin());
    let v0: [f64; N] = core::array::from_fn(|i| 0.1 * (1.7 * i as f64).cos());
    let h = 0.01;
    let start = |m| (Integrator::new(system(), m, h).start(0.0, q0, v0).unwrap());
    let trapezoid = difference(
        Integrator::new(system(), Trapezoid, h).start(0.0, q0, v0).unwrap(),
        Integrator::new(Hidden(system()), Trapezoid, h).start(0.0, q0, v0).unwrap(),
        300,
    );
    let yoshida = difference(
        Integrator::new(system(), Composition::YOSHIDA4, h).start(0.0, q0, v0).unwrap(),
        Integrator::new(Hidden(system()), Composition::YOSHIDA4, h).start(0.0, q0, v0).unwrap(),
        100,
    );
    let modes = difference(
        start(Midpoint),
        Integrator::new(system(), Midpoint, h).derivatives(Derivatives::Reverse).start(0.0, q0, v0).unwrap(),
        300,
    );
    println!("{name}: trapezoid {trapezoid:.1e}, Yoshida 4 {yoshida:.1e}, forward/reverse midpoint {modes:.1e}");
    for (what, found) in [("trapezoid", trapezoid), ("Yoshida 4", yoshida), ("forward/reverse midpoint", modes)] {
        assert!(found <= TOLERANCE, "{name}: {what} paths differ by {found:e}");
    }
    [trapezoid, yoshida, modes]
}

/// Round-off, amplified over at most three time units of smooth motion
/// (measured: at most 1.8e-15); a wrong step (a wrong mass matrix, a wrong
/// gradient, a wrong band) shows at `O(h²)`.
const TOLERANCE: f64 = 1e-13;
"""


def structure_main():
    rng = random.Random(SEED + 1)
    systems = [structure_system(rng, i) for i in range(16)]
    print("//! Random Lagrangians for the structure analysis, written by")
    print("//! `scripts/gradient_fuzz.py structure` (fixed seed; regenerate with")
    print("//! `python3 scripts/gradient_fuzz.py structure > tests/systems/structure_fuzz.rs && cargo fmt`):")
    print("//! bodies made of terms with chosen couplings (potentials in one or two")
    print("//! coordinates at distances 0 to 3, kinetic terms with constant, position-")
    print("//! or time-dependent coefficients, terms linear or quartic in `v`, loops")
    print("//! over neighbours at distance 1 or 2). What the macro claims for each")
    print("//! (`SEPARABILITY`, `COUPLING`, `AUTONOMOUS`, `CYCLIC`) is checked against")
    print("//! derivatives at random points (`structure_analysis::check`), never")
    print("//! compared with an expected answer: an overstated claim fails.")
    print("#![allow(clippy::all, dead_code, unused_mut, unused_parens, unused_variables)]")
    print("use super::structure_analysis::{check, check_autonomy_and_cyclic};")
    print("use lagrangian::prelude::*;")
    print("use lagrangian::{Composition, Derivatives, Method};")
    print()
    for code, _ in systems:
        print(code)
    print("#[test]")
    print("fn random_bodies_claim_no_more_structure_than_they_have() {")
    for i, (_, value) in enumerate(systems):
        print(f"    check(\"random {i}\", &{value}, {100 + i});")
        print(f"    check_autonomy_and_cyclic(\"random {i}\", &{value}, {200 + i});")
    print("}")
    print(PATHS)
    print("#[test]")
    print("fn random_bodies_step_the_same_on_every_path() {")
    print("    let mut worst = [0.0f64; 3];")
    for i, (_, value) in enumerate(systems):
        print(f"    let found = paths_agree(\"random {i}\", || {value});")
        print("    for k in 0..3 {")
        print("        worst[k] = worst[k].max(found[k]);")
        print("    }")
    print('    println!("largest differences: trapezoid {:.1e}, Yoshida 4 {:.1e}, forward/reverse midpoint {:.1e}", worst[0], worst[1], worst[2]);')
    print("}")


def main():
    if sys.argv[1:] == ["structure"]:
        return structure_main()
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
