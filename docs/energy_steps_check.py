#!/usr/bin/env python3
"""Numerical checks of the energy-step formulas in docs/energy-steps.md.

Independent of the Rust code: the discrete Lagrangians are re-implemented
here in mpmath (50 digits) with derivatives of L from sympy, so that the
expansions can be checked far below f64 round-off.

    pip install mpmath sympy
    python3 docs/energy_steps_check.py            # all checks, about a minute
    python3 docs/energy_steps_check.py coeffs     # one section

Notation as in the document: z = (q, p) a node, v its velocity
(p = dL/dv(q, v)), H(z) = E_L(q, v), Ehat_z(h) the discrete energy
-dA/dt_{k+1} of the step of signed size h from z, and
Ehat_z(h) = H(z) + a_m h^m + a_{m+1} h^{m+1} + ...
"""

import sys
from math import factorial

import mpmath as mp
import sympy as sp

mp.mp.dps = 50


# --------------------------------------------------------------------------
# Systems: L(q, v) symbolic, derivatives lambdified to mpmath
# --------------------------------------------------------------------------

class System:
    def __init__(self, name, n, builder):
        self.name, self.n = name, n
        q = sp.symbols(f"q0:{n}")
        v = sp.symbols(f"v0:{n}")
        L = builder(q, v)
        lq = [sp.diff(L, x) for x in q]
        lv = [sp.diff(L, x) for x in v]
        args = list(q) + list(v)
        f = lambda e: sp.lambdify(args, e, "mpmath")
        self._L = f(L)
        self._lq = f(sp.Matrix(lq))
        self._lv = f(sp.Matrix(lv))
        self._lqq = f(sp.Matrix(n, n, lambda i, j: sp.diff(lq[i], q[j])))
        self._lqv = f(sp.Matrix(n, n, lambda i, j: sp.diff(lq[i], v[j])))   # d2L/dq_i dv_j
        self._lvv = f(sp.Matrix(n, n, lambda i, j: sp.diff(lv[i], v[j])))

    def _a(self, q, v):
        return list(q) + list(v)

    def L(self, q, v):
        return self._L(*self._a(q, v))

    def lq(self, q, v):
        return mp.matrix(self._lq(*self._a(q, v)))

    def lv(self, q, v):
        return mp.matrix(self._lv(*self._a(q, v)))

    def lqq(self, q, v):
        return mp.matrix(self._lqq(*self._a(q, v)))

    def lqv(self, q, v):
        return mp.matrix(self._lqv(*self._a(q, v)))

    def lvv(self, q, v):
        return mp.matrix(self._lvv(*self._a(q, v)))

    def energy(self, q, v):
        lv = self.lv(q, v)
        return sum(v[i] * lv[i] for i in range(self.n)) - self.L(q, v)

    def velocity(self, q, p, guess=None):
        """Inverse Legendre transform: v with dL/dv(q, v) = p."""
        v = mp.matrix(guess if guess is not None else p)
        for _ in range(100):
            r = self.lv(q, v) - mp.matrix(p)
            dv = mp.lu_solve(self.lvv(q, v), r)
            v = v - dv
            if mp.norm(dv) < mp.mpf(10) ** (-mp.mp.dps + 5):
                break
        return v

    def accel(self, q, v):
        """a = L_vv^{-1} (L_q - B v), B_ij = d2L/dv_i dq_j (the Euler-Lagrange equation)."""
        B = self.lqv(q, v).T
        return mp.lu_solve(self.lvv(q, v), self.lq(q, v) - B * mp.matrix(v))


def pendulum():
    return System("pendulum (L = v^2/2 + 9.81 cos q)", 1, lambda q, v: v[0] ** 2 / 2 + sp.Rational(981, 100) * sp.cos(q[0]))


def oscillator(w=sp.Integer(2)):
    return System(f"oscillator (omega = {w})", 1, lambda q, v: v[0] ** 2 / 2 - w ** 2 * q[0] ** 2 / 2)


def kepler_polar():
    return System("Kepler, polar (r, phi)", 2, lambda q, v: (v[0] ** 2 + q[0] ** 2 * v[1] ** 2) / 2 + 1 / q[0])


def double_pendulum():
    return System("double pendulum", 2, lambda q, v: v[0] ** 2 + v[1] ** 2 / 2 + v[0] * v[1] * sp.cos(q[0] - q[1])
                  + sp.Rational(1962, 100) * sp.cos(q[0]) + sp.Rational(981, 100) * sp.cos(q[1]))


def odd_lagrangian():
    """Non-separable, L_vv depending on q and v, a gyroscopic q-v term: tests the general formulas."""
    return System("non-separable 2-DOF", 2, lambda q, v: (1 + sp.sin(q[0]) / 3) * v[0] ** 2 / 2 + v[1] ** 2 / 2
                  + v[0] ** 4 / 10 + sp.Rational(3, 10) * (q[0] * v[1] - q[1] * v[0]) + q[0] * q[1] * v[0] * v[1] / 5
                  - (1 - sp.cos(q[0])) - q[1] ** 2 / 2 - q[0] ** 2 * q[1] / 4)


# --------------------------------------------------------------------------
# Discrete Lagrangians: the step polynomial of degree s through control nodes
# tau_m, integrated by a quadrature (c_j, b_j). s = 1 covers midpoint,
# trapezoid, alpha-beta (one point c = beta), Simpson.
# --------------------------------------------------------------------------

def lagrange_tables(tau, c):
    s = len(tau) - 1
    ell = [[None] * (s + 1) for _ in c]
    dell = [[None] * (s + 1) for _ in c]
    for j, cj in enumerate(c):
        for m in range(s + 1):
            num = mp.mpf(1)
            for k in range(s + 1):
                if k != m:
                    num *= (cj - tau[k]) / (tau[m] - tau[k])
            ell[j][m] = num
            d = mp.mpf(0)
            for k in range(s + 1):
                if k == m:
                    continue
                t = 1 / (tau[m] - tau[k])
                for l in range(s + 1):
                    if l != m and l != k:
                        t *= (cj - tau[l]) / (tau[m] - tau[l])
                d += t
            dell[j][m] = d
    return ell, dell


class Method:
    def __init__(self, name, s, c, b, tau=None):
        self.name, self.s = name, s
        self.c = [mp.mpf(x) for x in c]
        self.b = [mp.mpf(x) for x in b]
        self.tau = [mp.mpf(m) / s for m in range(s + 1)] if tau is None else [mp.mpf(x) for x in tau]
        self.ell, self.dell = lagrange_tables(self.tau, self.c)

    def points(self, q0, D, h):
        """Quadrature points W_j = (q_h(c_j), q_h'(c_j)/h) from the increments D_m = Q_m - q0."""
        out = []
        for j in range(len(self.c)):
            q = mp.matrix(q0)
            v = mp.matrix(len(q0), 1)
            for m in range(1, self.s + 1):
                q += self.ell[j][m] * D[m - 1]
                v += self.dell[j][m] * D[m - 1] / h
            out.append((q, v))
        return out

    def step(self, sysm, q0, p0, h, v0=None):
        """Solve p0 + dA/dQ_0 = 0, dA/dQ_m = 0 (0 < m < s) for D_1..D_s; return (q1, p1, Ehat, D)."""
        n, s = sysm.n, self.s
        q0 = mp.matrix(q0)
        if v0 is None:
            v0 = sysm.velocity(q0, p0)
        D = [self.tau[m] * h * v0 for m in range(1, s + 1)]
        for it in range(200):
            W = self.points(q0, D, h)
            grads = [(sysm.lq(*w), sysm.lv(*w)) for w in W]
            hess = [(sysm.lqq(*w), sysm.lqv(*w), sysm.lvv(*w)) for w in W]
            R = mp.matrix(s * n, 1)
            J = mp.matrix(s * n, s * n)
            for row in range(s):          # rows: Q_0 .. Q_{s-1}
                for j in range(len(self.c)):
                    lr, dlr = self.ell[j][row], self.dell[j][row]
                    lq, lv = grads[j]
                    for i in range(n):
                        R[row * n + i] += self.b[j] * (h * lr * lq[i] + dlr * lv[i])
                    Lqq, Lqv, Lvv = hess[j]
                    for col in range(1, s + 1):   # columns: D_1 .. D_s
                        lc, dlc = self.ell[j][col], self.dell[j][col]
                        for i in range(n):
                            for k in range(n):
                                J[row * n + i, (col - 1) * n + k] += self.b[j] * (
                                    h * lr * lc * Lqq[i, k] + lr * dlc * Lqv[i, k]
                                    + dlr * lc * Lqv[k, i] + dlr * dlc * Lvv[i, k] / h)
            for i in range(n):
                R[i] += p0[i]
            dx = mp.lu_solve(J, R)
            for m in range(s):
                for i in range(n):
                    D[m][i] -= dx[m * n + i]
            if mp.norm(dx) <= mp.mpf(10) ** (-mp.mp.dps + 8) * (1 + mp.norm(D[-1])):
                break
        W = self.points(q0, D, h)
        p1 = mp.matrix(n, 1)
        for j in range(len(self.c)):
            lq, lv = sysm.lq(*W[j]), sysm.lv(*W[j])
            for i in range(n):
                p1[i] += self.b[j] * (h * self.ell[j][s] * lq[i] + self.dell[j][s] * lv[i])
        ehat = sum(self.b[j] * sysm.energy(*W[j]) for j in range(len(self.c)))
        return q0 + D[-1], p1, ehat, D

    def action(self, sysm, q0, D, h):
        return h * sum(self.b[j] * sysm.L(*w) for j, w in enumerate(self.points(q0, D, h)))


def gauss_legendre(r):
    x, w = zip(*[(xi, wi) for xi, wi in zip(*gauss_nodes(r))])
    return [(1 + xi) / 2 for xi in x], [wi / 2 for wi in w]


def gauss_nodes(r):
    xs, ws = [], []
    for i in range(1, r + 1):
        x = mp.cos(mp.pi * (i - mp.mpf(1) / 4) / (r + mp.mpf(1) / 2))
        for _ in range(100):
            p0, p1 = mp.mpf(1), x
            for k in range(2, r + 1):
                p0, p1 = p1, ((2 * k - 1) * x * p1 - (k - 1) * p0) / k
            dp = r * (x * p1 - p0) / (x * x - 1) if r > 1 else mp.mpf(1)
            if r == 1:
                p1, dp = x, mp.mpf(1)
            dx = p1 / dp
            x -= dx
            if abs(dx) < mp.mpf(10) ** (-mp.mp.dps + 3):
                break
        xs.append(x)
        ws.append(2 / ((1 - x * x) * dp * dp))
    return xs, ws


MIDPOINT = Method("midpoint", 1, [mp.mpf(1) / 2], [1])
TRAPEZOID = Method("trapezoid", 1, [0, 1], [mp.mpf(1) / 2, mp.mpf(1) / 2])
SIMPSON = Method("linear element, Simpson", 1, [0, mp.mpf(1) / 2, 1], [mp.mpf(1) / 6, mp.mpf(2) / 3, mp.mpf(1) / 6])


def alpha_beta(alpha):
    alpha = mp.mpf(alpha)
    return Method(f"alpha-beta, alpha = {alpha}", 1, [1 - alpha], [1])


def galerkin(s):
    c, b = gauss_legendre(s)
    return Method(f"Galerkin s = {s}, {s} Gauss points", s, c, b)


# --------------------------------------------------------------------------
# The closed forms of the document
# --------------------------------------------------------------------------

def mu2(method):
    return sum(b * c * c for b, c in zip(method.b, method.c))


def a2_formula(sysm, method, q, v):
    """Leading energy coefficient of a symmetric linear element (s = 1):
    a2 = [(1 - 12 kappa) v.L_qq.v - a.L_vv.a] / 8,  kappa = sum b_j c_j^2 - 1/4."""
    kappa = mu2(method) - mp.mpf(1) / 4
    v = mp.matrix(v)
    a = sysm.accel(q, v)
    vqv = (v.T * sysm.lqq(q, v) * v)[0]
    ava = (a.T * sysm.lvv(q, v) * a)[0]
    return ((1 - 12 * kappa) * vqv - ava) / 8


def a1_alpha_beta(sysm, alpha, q, v):
    """Leading energy coefficient of alpha-beta: a1 = (alpha - beta) v.L_q."""
    v = mp.matrix(v)
    return (2 * mp.mpf(alpha) - 1) * (v.T * sysm.lq(q, v))[0]


def flow_derivative(f, sysm, q, v, eps=mp.mpf("1e-12")):
    """d/dt f(q, v) along the exact flow (central difference along (v, a))."""
    q, v = mp.matrix(q), mp.matrix(v)
    a = sysm.accel(q, v)
    return (f(q + eps * v, v + eps * a) - f(q - eps * v, v - eps * a)) / (2 * eps)


def model_threshold(s):
    """x*_s = max over rho > 1 of -(rho^(2s+1) + 1)/(rho^(2s) - 1), and where it is attained."""
    phi = lambda r: -(r ** (2 * s + 1) + 1) / (r ** (2 * s) - 1)
    # phi'(rho) = 0  <=>  rho^(2s+1) - (2s+1) rho - 2s = 0, one root in (1, 3)
    f = lambda r: r ** (2 * s + 1) - (2 * s + 1) * r - 2 * s
    lo, hi = mp.mpf(1), mp.mpf(3)
    for _ in range(200):   # bisection: f(1) < 0 < f(3)
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if f(mid) < 0 else (lo, mid)
    rho = (lo + hi) / 2
    return phi(rho), rho


def model_ratio(x, s=1):
    """The root rho = h/h' of x (rho^(2s) - 1) + rho^(2s+1) + 1 = 0 continuous with rho = 1 at |x| = oo."""
    f = lambda r: x * (r ** (2 * s) - 1) + r ** (2 * s + 1) + 1
    if s == 1:
        disc = (x + 3) * (x - 1)
        if disc < 0:
            return None
        return ((1 - x) + mp.sign(x) * mp.sqrt(disc)) / 2
    return mp.findroot(f, 1 - 1 / x)


# --------------------------------------------------------------------------
# Checks
# --------------------------------------------------------------------------

def coefficients(sysm, method, q, p, hs, m):
    """Even and odd parts of Ehat_z(h) - H(z), divided by h^m and h^(m+1)."""
    v = sysm.velocity(q, p)
    H = sysm.energy(q, v)
    rows = []
    for h in hs:
        ep = method.step(sysm, q, p, h, v)[2]
        em = method.step(sysm, q, p, -h, v)[2]
        rows.append((h, ((ep + em) / 2 - H) / h ** m, ((ep - em) / 2) / h ** (m + 1)))
    return v, H, rows


def richardson(rows, col, k=2):
    """Eliminate the O(h^k) term between the last two rows (h halves)."""
    (h1, *r1), (h2, *r2) = rows[-2], rows[-1]
    f = (h1 / h2) ** k
    return (f * r2[col] - r1[col]) / (f - 1)


def fmt(x, d=6):
    return mp.nstr(x, d)


def check_symmetry():
    print("\n== E_k = Ehat_{z_k}(-h_{k-1}): the energy of the step behind a node is the discrete energy of a")
    print("   backward step from it (self-adjoint A), so the energy equation is Ehat_z(h) = Ehat_z(-h') ==")
    sysm = pendulum()
    for method in (MIDPOINT, TRAPEZOID, galerkin(2)):
        q0, p0, hp = mp.matrix([1]), mp.matrix([mp.mpf("0.3")]), mp.mpf("0.07")
        q1, p1, e_behind, _ = method.step(sysm, q0, p0, hp)
        back = method.step(sysm, q1, p1, -hp)
        print(f"  {method.name:32s} |E_k - Ehat(-h')| = {fmt(abs(back[2] - e_behind), 3)}, "
              f"|q_(k-1) - q(-h')| = {fmt(mp.norm(back[0] - q0), 3)}")
    a = alpha_beta("0.3")
    adj = alpha_beta("0.7")
    q1, p1, e_behind, _ = a.step(sysm, q0, p0, hp)
    print(f"  {a.name:32s} |E_k - Ehat^adj(-h')| = {fmt(abs(adj.step(sysm, q1, p1, -hp)[2] - e_behind), 3)} "
          f"(adjoint: alpha -> 1 - alpha), |E_k - Ehat(-h')| = {fmt(abs(a.step(sysm, q1, p1, -hp)[2] - e_behind), 3)}")
    # Ehat = sum b_j E_L(W_j) is -dA/dh at fixed q0, q1 (envelope over interior nodes): check by differencing A.
    g = galerkin(2)
    q1, p1, ehat, D = g.step(sysm, q0, p0, hp)
    eps = mp.mpf("1e-15")

    def reduced_action(h):
        # interior node re-solved at fixed q0, q1: dA/dQ_1 = 0
        Dm = [x.copy() for x in D]
        for _ in range(50):
            f = lambda y: g.action(sysm, q0, [mp.matrix([y]), Dm[1]], h)
            y = Dm[0][0]
            d1 = mp.diff(f, y)
            d2 = mp.diff(f, y, 2)
            Dm[0][0] = y - d1 / d2
            if abs(d1 / d2) < mp.mpf(10) ** -45:
                break
        return g.action(sysm, q0, Dm, h)
    dadh = (reduced_action(hp + eps) - reduced_action(hp - eps)) / (2 * eps)
    print(f"  Galerkin s = 2: Ehat = sum b_j E_L(W_j) = {fmt(ehat, 20)}, -dA/dh (differenced) = {fmt(-dadh, 20)}")


def check_linear_elements():
    print("\n== s = 1, symmetric rules: a1 = 0 and a2 = [(1 - 12 kappa) v.L_qq.v - a.L_vv.a]/8, a3 = (da2/dt)/3 ==")
    print("   columns: h, (even part)/h^2 vs a2 (relative error), (odd part)/h^3 vs a3 = (da2/dt)/3 (relative error)")
    hs = [mp.mpf(2) ** -k for k in range(4, 9)]
    cases = [
        (pendulum(), [mp.mpf("0.8")], [mp.mpf("1.1")]),
        (oscillator(), [mp.mpf("0.6")], [mp.mpf("-0.9")]),
        (kepler_polar(), [mp.mpf("0.35"), mp.mpf("0.4")], [mp.mpf("0.13"), mp.mpf("0.6")]),
        (double_pendulum(), [mp.mpf("0.9"), mp.mpf("-0.4")], [mp.mpf("0.5"), mp.mpf("0.8")]),
        (odd_lagrangian(), [mp.mpf("0.5"), mp.mpf("-0.3")], [mp.mpf("0.7"), mp.mpf("0.2")]),
    ]
    worst = 0
    for sysm, q, p in cases:
        for method in (MIDPOINT, TRAPEZOID, SIMPSON):
            v = sysm.velocity(mp.matrix(q), mp.matrix(p))
            a2 = a2_formula(sysm, method, mp.matrix(q), v)
            a3 = flow_derivative(lambda qq, vv: a2_formula(sysm, method, qq, vv), sysm, q, v) / 3
            _, _, rows = coefficients(sysm, method, mp.matrix(q), mp.matrix(p), hs, 2)
            print(f"  {sysm.name} / {method.name}: a2 = {fmt(a2)}, a3 = {fmt(a3)}")
            for h, ev, od in rows:
                e2 = abs(ev / a2 - 1)
                e3 = abs(od / a3 - 1) if abs(a3) > 1e-30 * abs(a2) else abs(od)
                print(f"    h = {fmt(h, 4):8s} {fmt(ev, 10):>16s} ({fmt(e2, 2)})   {fmt(od, 10):>16s} ({fmt(e3, 2)})")
            r2 = abs(richardson(rows, 0) / a2 - 1)
            # a3 = 0 (the oscillator under the midpoint rule): the absolute odd part is reported
            r3 = abs(richardson(rows, 1) / a3 - 1) if abs(a3) > 1e-30 * abs(a2) else abs(richardson(rows, 1))
            worst = max(worst, r2, r3)
            print(f"    Richardson (h^2 term removed): a2 rel. error {fmt(r2, 2)}, a3 rel. error {fmt(r3, 2)}")
    print(f"  worst relative error after Richardson: {fmt(worst, 2)}")


def check_alpha_beta():
    print("\n== alpha-beta: Ehat_z(h) - H(z) = a1 h + O(h^2), a1 = (alpha - beta) v.L_q;")
    print("   the adjoint (alpha <-> beta) has -a1, so the energy equation's leading term is a1 (h - h') ==")
    hs = [mp.mpf(2) ** -k for k in range(6, 11)]
    for sysm, q, p in ((pendulum(), [mp.mpf("0.8")], [mp.mpf("1.1")]),
                       (double_pendulum(), [mp.mpf("0.9"), mp.mpf("-0.4")], [mp.mpf("0.5"), mp.mpf("0.8")])):
        for alpha in ("0.3", "1", "0"):
            m = alpha_beta(alpha)
            q_, p_ = mp.matrix(q), mp.matrix(p)
            v = sysm.velocity(q_, p_)
            H = sysm.energy(q_, v)
            a1 = a1_alpha_beta(sysm, alpha, q_, v)
            errs = []
            for h in hs:
                e = m.step(sysm, q_, p_, h, v)[2]
                errs.append(abs((e - H) / h / a1 - 1))
            print(f"  {sysm.name} / {m.name}: a1 = {fmt(a1)}; |((Ehat - H)/h)/a1 - 1| for h = 2^-6..2^-10: "
                  + ", ".join(fmt(x, 2) for x in errs))
            if alpha == "0.3":
                adj = alpha_beta("0.7")
                da1 = flow_derivative(lambda qq, vv: a1_alpha_beta(sysm, alpha, qq, vv), sysm, q_, v)
                rows = []
                for h in hs[:4]:
                    e_a = m.step(sysm, q_, p_, h, v)
                    e_adj = adj.step(sysm, q_, p_, h, v)[2]
                    diff = ((e_a[2] - H - a1 * h) - (e_adj - H + a1 * h)) / h ** 2
                    v1 = sysm.velocity(e_a[0], e_a[1])
                    e2 = (sysm.energy(e_a[0], v1) - H) / h ** 2
                    rows.append((h, diff, e2))
                print(f"    a2^alpha - a2^adj against (da1/dt)/2 = {fmt(da1 / 2)}: "
                      + ", ".join(fmt(r[1], 6) for r in rows) + f" (h = 2^-6..2^-9)")
                print(f"    (H(z1) - H(z))/h^2 against -(da1/dt)/2 = {fmt(-da1 / 2)}: "
                      + ", ".join(fmt(r[2], 6) for r in rows))


def check_galerkin():
    print("\n== Galerkin, s Gauss points (order 2s): Ehat_z(h) - H(z) = a_2s h^2s + a_(2s+1) h^(2s+1) + ...,")
    print("   a_(2s+1) = s/(2s+1) da_2s/dt; oscillator: a_2s = -(s!)^2/((2s)!)^2 omega^2s H ==")
    old = mp.mp.dps
    mp.mp.dps = 60
    for s in (1, 2, 3):
        g = galerkin(s)
        m = 2 * s
        # the oscillator: closed form
        osc = oscillator()
        q, p = mp.matrix([mp.mpf("0.6")]), mp.matrix([mp.mpf("-0.9")])
        hs = [mp.mpf(2) ** -k for k in range(3, 7)]
        v, H, rows = coefficients(osc, g, q, p, hs, m)
        exact = -(mp.mpf(factorial(s)) ** 2 / mp.mpf(factorial(2 * s)) ** 2) * 2 ** m * H
        est = richardson(rows, 0)
        print(f"  s = {s}, oscillator (omega = 2): a_{m} Richardson {fmt(est, 12)}, closed form {fmt(exact, 12)}, "
              f"rel. error {fmt(abs(est / exact - 1), 2)}; odd part/h^{m + 1} at h = 2^-6: {fmt(rows[-1][2], 3)}")
        # the pendulum: lower coefficients vanish, and the odd/even identity
        pend = pendulum()
        hs = [mp.mpf(2) ** -k for k in range(4, 8)]

        def a_even(qq, vv):
            pp = pend.lv(qq, vv)
            return richardson(coefficients(pend, g, qq, pp, hs, m)[2], 0)
        q = mp.matrix([mp.mpf("0.8")])
        p = mp.matrix([mp.mpf("1.1")])
        v, H, rows = coefficients(pend, g, q, p, hs, m)
        lower = [((g.step(pend, q, p, h, v)[2] + g.step(pend, q, p, -h, v)[2]) / 2 - H) / h ** 2 for h in hs[-2:]]
        a_m = richardson(rows, 0)
        a_m1 = richardson(rows, 1)
        da = flow_derivative(a_even, pend, q, v, eps=mp.mpf("1e-6"))
        print(f"  s = {s}, pendulum: (even part)/h^{m} for h = 2^-4..2^-7: " + ", ".join(fmt(r[1], 8) for r in rows)
              + f"; a_{m} = {fmt(a_m, 8)}")
        print(f"           a_{m + 1} = {fmt(a_m1, 8)}, s/(2s+1) da_{m}/dt = {fmt(s * da / (2 * s + 1), 8)}, "
              f"rel. difference {fmt(abs(a_m1 / (s * da / (2 * s + 1)) - 1), 2)}")
        if s > 1:
            print(f"           (even part)/h^2 at h = 2^-6, 2^-7: {fmt(lower[0], 3)}, {fmt(lower[1], 3)} (-> 0: no h^2 term)")
    mp.mp.dps = old
    print("  root-existence thresholds of the local model x (rho^2s - 1) + rho^(2s+1) + 1 = 0:")
    for s in range(1, 9):
        xs, rho = model_threshold(s)
        print(f"    s = {s}: no root for x in ({fmt(xs, 6)}, 1); at x = x*_s the root is rho = {fmt(rho, 6)}")


def check_model():
    print("\n== the local model near a zero of a2 (midpoint/trapezoid): the exact nontrivial root of")
    print("   Ehat_z(h) = Ehat_z(-h') against rho(x) = [(1 - x) + sign(x) sqrt((x + 3)(x - 1))]/2, x = a2/(a3 h') ==")
    sysm = oscillator(sp.Integer(1))
    method = TRAPEZOID
    # trapezoid on the oscillator: a2 = (2 v^2 - q^2)/8 vanishes where |q| = sqrt(2)|v|
    E = mp.mpf(1) / 2
    for hp in (mp.mpf("0.02"), mp.mpf("0.005")):
        print(f"  trapezoid, oscillator omega = 1, H = 1/2, h' = {hp}:")
        for theta0 in (-4, -3.2, -3.05, -2.5, -1, 0.5, 1, 1.3, 3, 10):
            # the state a known x-distance from the zero of a2 along the exact orbit
            phase_zero = mp.atan(1 / mp.sqrt(2))     # q = cos(th), v = -sin(th): a2 = 0 at tan th = 1/sqrt 2
            th = phase_zero + theta0 * hp / 3         # x ~ 3 (t - t0)/h'
            q, v = mp.matrix([mp.sqrt(2 * E) * mp.cos(th)]), mp.matrix([-mp.sqrt(2 * E) * mp.sin(th)])
            p = sysm.lv(q, v)
            a2 = a2_formula(sysm, method, q, v)
            a3 = flow_derivative(lambda qq, vv: a2_formula(sysm, method, qq, vv), sysm, q, v) / 3
            x = a2 / (a3 * hp)
            target = method.step(sysm, q, p, -hp, v)[2]
            g = lambda h: method.step(sysm, q, p, h, v)[2] - target
            # scan (0, 3h'] for sign changes of g, excluding tiny h
            grid = [hp * (mp.mpf(k) / 200) for k in range(2, 601)]
            vals = [g(h) for h in grid]
            roots = []
            for (h1, g1), (h2, g2) in zip(zip(grid, vals), zip(grid[1:], vals[1:])):
                if g1 == 0 or g1 * g2 < 0:
                    roots.append(mp.findroot(g, (h1, h2), solver="anderson") / hp)
            rho = model_ratio(x)
            if rho is None:
                rho_s = "none"
            elif x < -3:  # both roots positive: rho and 1 - x - rho
                rho_s = f"{fmt(rho, 5)}, {fmt(1 - x - rho, 5)}"
            else:
                rho_s = fmt(rho, 5)
            print(f"    x = {fmt(x, 4):>8s}: model roots rho = {rho_s:>16s}; exact roots in (0, 3h']: "
                  + (", ".join(fmt(r, 5) for r in roots) if roots else "none"))


def variable_steps(sysm, method, q0, v0, h0, t_end, ratio=2, max_steps=100000, report=None):
    """A plain energy-preserving integrator (first step fixed, then Ehat_z(h) = E_k on [h'/r, r h'],
    sampled for a sign change as the runtime does). Returns the nodes and, if it stops, the node it stops at."""
    q, v = mp.matrix(q0), mp.matrix(v0)
    p = sysm.lv(q, v)
    q, p, E, _ = method.step(sysm, q, p, h0, v)
    t, hp = h0, h0
    nodes = [(t, q, p, hp)]
    for _ in range(max_steps):
        if t >= t_end:
            return nodes, None
        v = sysm.velocity(q, p)
        g = lambda h: method.step(sysm, q, p, h, v)[2] - E
        lo, hi = hp / ratio, hp * ratio
        prev = hp
        gp = g(prev)
        found = None
        for k in range(1, 9):
            for h in (hp - k / mp.mpf(8) * (hp - lo), hp + k / mp.mpf(8) * (hi - hp)):
                gh = g(h)
                if gh * gp <= 0:
                    found = (min(h, prev), max(h, prev))
                    break
            if found:
                break
            # compare with the nearest sample on each side
            prev, gp = hp, g(hp)
        if found is None:
            # check both sides properly: any sign change on a fine grid?
            grid = [lo + (hi - lo) * k / 64 for k in range(65)]
            vals = [g(h) for h in grid]
            for (h1, g1), (h2, g2) in zip(zip(grid, vals), zip(grid[1:], vals[1:])):
                if g1 * g2 <= 0:
                    found = (h1, h2)
                    break
        if found is None:
            return nodes, (t, q, p, hp)
        h = mp.findroot(g, found, solver="anderson")
        q, p, E2, _ = method.step(sysm, q, p, h, v)
        t += h
        hp = h
        nodes.append((t, q, p, hp))
    return nodes, None


def node_test(sysm, method, nodes, ratio=2):
    """The test of the document at every node after the second: x_k = a2(z_k)/(a3 h'), a3 from the
    finite difference of a2 over the step behind (what an integrator can evaluate), and whether the
    local model has a root in [h'/r, r h'] (x >= (r^2 - r + 1)/(r (r - 1)) or x <= -X_r)."""
    lo_ok = (ratio ** 2 - ratio + 1) / (ratio * (ratio - 1))
    hi_bad = 3 if ratio >= 2 else (ratio ** 2 - ratio + 1) / (ratio - 1)
    out = []
    prev = None
    for t, q, p, hp in nodes:
        a2 = a2_formula(sysm, method, q, sysm.velocity(q, p))
        if prev is not None:
            a3 = (a2 - prev) / (3 * hp)
            x = a2 / (a3 * hp) if a3 != 0 else mp.inf * mp.sign(a2)
            # the same with a3 = (da2/dt)/3 along the exact flow at the node (needs third derivatives of L)
            a3f = flow_derivative(lambda qq, vv: a2_formula(sysm, method, qq, vv), sysm, q, sysm.velocity(q, p),
                                  eps=mp.mpf("1e-8")) / 3
            xf = a2 / (a3f * hp) if a3f != 0 else mp.inf * mp.sign(a2)
            out.append((t, x, x >= lo_ok or x <= -hi_bad, xf))
        prev = a2
    return out


def describe_run(sysm, method, nodes, stop):
    tests = node_test(sysm, method, nodes)
    earlier = tests[:-1] if stop else tests
    wrong = [f"x = {fmt(x, 3)} (t = {fmt(t, 4)})" for t, x, ok, _ in earlier if not ok]
    text = f"{len(nodes)} nodes"
    if stop:
        t, x, ok, xf = tests[-1]
        text += (f", stops at t = {fmt(stop[0], 5)} (h' = {fmt(stop[3], 4)}); test at that node: x = {fmt(x, 3)}, "
                 f"{'root predicted (miss)' if ok else 'no root predicted (hit)'}; with a3 = (da2/dt)/3: x = {fmt(xf, 3)}")
    else:
        text += ", no stop"
    return text + "; earlier nodes where the test predicts no root: " + (", ".join(wrong) if wrong else "none")


def check_runs():
    print("\n== where energy steps stop: sign changes of a2 along the orbit, the node test, actual runs ==")
    print("   (runs: first step fixed, then Ehat_z(h) = E_k on [h'/2, 2h'] as in the runtime; test: x = a2/(a3 h'),")
    print("    a3 = (a2(z_k) - a2(z_(k-1)))/(3h'), no root in the bracket predicted for -3 < x < 3/2)")
    mp.mp.dps = 20
    # 1. trapezoid on the oscillator: a2 = (2 v^2 - omega^2 q^2) omega^2/8 changes sign 4 times a period
    sysm = oscillator(sp.Integer(1))
    t0 = mp.atan(1 / mp.sqrt(2))  # from q = cos t: 2 sin^2 t = cos^2 t
    print(f"  oscillator (omega = 1) from (1, 0): trapezoid a2 = (2 v^2 - q^2)/8 first vanishes at t = atan(1/sqrt 2) "
          f"= {fmt(t0, 5)} (quarter period {fmt(mp.pi / 2, 5)})")
    for h0 in (mp.mpf("0.05"), mp.mpf("0.01")):
        nodes, stop = variable_steps(sysm, TRAPEZOID, [1], [0], h0, 7)
        print(f"    trapezoid, h0 = {h0}: " + describe_run(sysm, TRAPEZOID, nodes, stop))
    nodes, stop = variable_steps(sysm, MIDPOINT, [1], [0], mp.mpf("0.05"), 7)
    hs = [n[3] for n in nodes]
    print(f"    midpoint, h0 = 0.05 (a2 = -H/4 < 0 everywhere): " + describe_run(sysm, MIDPOINT, nodes, stop)
          + f"; steps in [{fmt(min(hs), 5)}, {fmt(max(hs), 5)}] up to t = {fmt(nodes[-1][0], 3)}")
    # 2. midpoint on the pendulum: the density law h^3 |a2| = const
    sysm = pendulum()
    nodes, stop = variable_steps(sysm, MIDPOINT, [1], [0], mp.mpf("0.02"), 2.1)
    vals, a2s = [], []
    for t, q, p, hp in nodes[1:]:
        a2 = a2_formula(sysm, MIDPOINT, q, sysm.velocity(q, p))
        a2s.append(abs(a2))
        vals.append(hp ** 3 * abs(a2))
    print(f"  pendulum from 1 rad, midpoint, h0 = 0.02, one period: " + describe_run(sysm, MIDPOINT, nodes, stop))
    print(f"    steps in [{fmt(min(n[3] for n in nodes), 5)}, {fmt(max(n[3] for n in nodes), 5)}], |a2| in "
          f"[{fmt(min(a2s), 4)}, {fmt(max(a2s), 4)}], h_(k-1)^3 |a2(z_k)| in [{fmt(min(vals), 5)}, {fmt(max(vals), 5)}]")
    quarter = mp.ellipk(mp.sin(mp.mpf(1) / 2) ** 2) / mp.sqrt(mp.mpf("9.81"))
    for method, label in ((TRAPEZOID, "trapezoid, a2 = (2 g cos q v^2 - g^2 sin^2 q)/8"),
                          (SIMPSON, "linear element with Simpson, a2 = -g^2 sin^2 q/8 (double zero at q = 0)"),
                          (alpha_beta("0.3"), "alpha = 0.3, a1 = -0.4 v.L_q (zero at turning points and at q = 0)")):
        nodes, stop = variable_steps(sysm, method, [1], [0], mp.mpf("0.02"), 2.1)
        hs = [n[3] for n in nodes]
        print(f"    {label}: " + (f"stops at t = {fmt(stop[0], 4)}, q = {fmt(stop[1][0], 3)}" if stop else
                                  f"no stop up to t = {fmt(nodes[-1][0], 4)}, steps in [{fmt(min(hs), 4)}, {fmt(max(hs), 4)}]")
              + f" (quarter period {fmt(quarter, 4)})")
    # 3. Kepler e = 0.9 (polar), from perihelion
    sysm = kepler_polar()
    e = mp.mpf("0.9")
    r0 = 1 - e
    q0, v0 = [r0, 0], [0, mp.sqrt(1 - e * e) / r0 ** 2]
    for method in (MIDPOINT, TRAPEZOID):
        first = first_sign_change(sysm, method, q0, v0, 2 * mp.pi)
        print(f"  Kepler e = 0.9 (polar) from perihelion, {method.name}: a2 along the exact orbit first changes sign "
              + (f"at t = {fmt(first[0], 4)} (r = {fmt(first[1], 4)})" if first else "nowhere on the orbit"))
    for h0 in (mp.mpf("0.01"), mp.mpf("0.001")):
        nodes, stop = variable_steps(sysm, MIDPOINT, q0, v0, h0, 1)
        print(f"    midpoint, h0 = {h0}: " + describe_run(sysm, MIDPOINT, nodes, stop))
    # 4. double pendulum from (1, -0.5), v0 = (0, 0.5), midpoint
    sysm = double_pendulum()
    first = first_sign_change(sysm, MIDPOINT, [1, mp.mpf("-0.5")], [0, mp.mpf("0.5")], 1)
    print(f"  double pendulum from (1, -0.5), v0 = (0, 0.5), midpoint: a2 first changes sign at t = {fmt(first[0], 4)}")
    nodes, stop = variable_steps(sysm, MIDPOINT, [1, mp.mpf("-0.5")], [0, mp.mpf("0.5")], mp.mpf("0.01"), 1)
    print(f"    h0 = 0.01: " + describe_run(sysm, MIDPOINT, nodes, stop))
    mp.mp.dps = 50


def first_sign_change(sysm, method, q0, v0, t_end, dt=mp.mpf("0.0005")):
    """Integrate the exact flow (RK4, small dt) and return the first (t, r) where a2 changes sign."""
    q, v = mp.matrix(q0), mp.matrix(v0)
    t = mp.mpf(0)
    prev = a2_formula(sysm, method, q, v)
    f = lambda q, v: (v, sysm.accel(q, v))
    while t < t_end:
        k1 = f(q, v)
        k2 = f(q + dt / 2 * k1[0], v + dt / 2 * k1[1])
        k3 = f(q + dt / 2 * k2[0], v + dt / 2 * k2[1])
        k4 = f(q + dt * k3[0], v + dt * k3[1])
        q = q + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        v = v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        t += dt
        cur = a2_formula(sysm, method, q, v)
        if cur * prev < 0:
            return t, q[0]
        prev = cur
    return None


SECTIONS = {
    "symmetry": check_symmetry,
    "coeffs": check_linear_elements,
    "alphabeta": check_alpha_beta,
    "galerkin": check_galerkin,
    "model": check_model,
    "runs": check_runs,
}

if __name__ == "__main__":
    for name in sys.argv[1:] or SECTIONS:
        SECTIONS[name]()
