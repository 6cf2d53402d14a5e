#!/usr/bin/env python3
"""Compile cost of `#[lagrangian]` against the length of the Lagrangian.

Generates one-file user crates (a path dependency on this workspace's facade
crate `lagrangian`, a `main` that integrates the system with the midpoint
rule as the README's first example does), builds each with `cargo build --release`, and
reports the CPU time (user + system of cargo and every rustc it runs, from
GNU time) and the peak resident memory of the build. CPU time, not wall
time: the machine is usually shared, and CPU seconds do not depend on the
load as much as wall seconds do. The dependencies are built once, by a
warm-up crate, into a target directory the generated crates share, so each
measurement is the user crate alone.

Shapes (terms are the operands of the Lagrangian's top-level sum):

  sines     one coordinate, `½v² − Σ_k c_k sin(k·1e-4·q)`
  products  six coordinates, `Σ_i ½v_i² − ½q_i²` plus terms `c_k q_i q_j v_l`
  pendulum  an n-link planar pendulum, the Cartesian kinetic energy expanded
            into `m l_a l_b v_a v_b (cos q_a cos q_b + sin q_a sin q_b)`
            terms per bob and pair of links, uncollected, as a computer
            algebra system emits it, plus the bobs' potential energy; n is
            the smallest with at least the requested number of terms.

  scripts/compile_time.py                      # every shape and size, rewrites docs/compile-time.md
  scripts/compile_time.py --print              # the table only
  scripts/compile_time.py --sizes 100,300 --shapes sines --timeout 900
  scripts/compile_time.py --workspace /tmp/old # measure another checkout
  scripts/compile_time.py --reuse              # keep the builds an earlier run finished or stopped
  scripts/compile_time.py --reuse-only         # the page from earlier runs alone

A build that exceeds `--timeout` wall seconds is stopped and reported as
such; larger sizes of that shape are skipped. The fitted exponent is the
least-squares slope of log(CPU s) against log(terms) over the sizes that
finished.
"""

import argparse
import datetime
import math
import os
import re
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SIZES = [100, 300, 1000, 3000, 10000]
SHAPES = ["sines", "products", "pendulum"]


def coefficient(k):
    """A deterministic coefficient per term, printed exactly as a literal."""
    return "%.6f" % (0.5 + ((k * 7919) % 1000) / 1000.0)


def sines(terms):
    body = ["0.5 * v[0] * v[0]"]
    for k in range(1, terms):
        body.append("- %s * (%de-4 * q[0]).sin()" % (coefficient(k), k))
    return 1, "\n            ".join(body), "[0.1]", "[0.0]"


def products(terms):
    n = 6
    body = []
    for i in range(n):
        body.append("+ 0.5 * v[%d] * v[%d]" % (i, i))
        body.append("- 0.5 * q[%d] * q[%d]" % (i, i))
    for k in range(terms - 2 * n):
        i, j, l = k % n, (k // n) % n, (k // (n * n) + k) % n
        body.append("+ 1e-3 * %s * q[%d] * q[%d] * v[%d]" % (coefficient(k), i, j, l))
    body[0] = body[0][2:]
    return n, "\n            ".join(body), "[0.1; %d]" % n, "[0.0; %d]" % n


def pendulum_terms(n):
    return n * (n + 1) * (2 * n + 1) // 3 + n * (n + 1) // 2


def pendulum(terms):
    n = 1
    while pendulum_terms(n) < terms:
        n += 1
    body = []
    mass = lambda i: "%.3f" % (1.0 + 0.1 * i)
    length = lambda a: "%.3f" % (1.0 - 0.01 * a)
    # Bob i sits at x_i = Σ_{a ≤ i} l_a sin q_a, y_i = −Σ_{a ≤ i} l_a cos q_a.
    for i in range(n):
        for a in range(i + 1):
            for b in range(i + 1):
                c = "0.5 * %s * %s * %s" % (mass(i), length(a), length(b))
                body.append("+ %s * v[%d] * v[%d] * q[%d].cos() * q[%d].cos()" % (c, a, b, a, b))
                body.append("+ %s * v[%d] * v[%d] * q[%d].sin() * q[%d].sin()" % (c, a, b, a, b))
    for i in range(n):
        # V = Σ_i m_i g y_i, with y_i expanded.
        for a in range(i + 1):
            body.append("+ %s * 9.81 * %s * q[%d].cos()" % (mass(i), length(a), a))
    body[0] = body[0][2:]
    return n, "\n            ".join(body), "[0.1; %d]" % n, "[0.0; %d]" % n


def generate(directory, name, shape, terms, workspace):
    n, body, q0, v0 = {"sines": sines, "products": products, "pendulum": pendulum}[shape](terms)
    actual = body.count("\n") + 1
    os.makedirs(os.path.join(directory, "src"), exist_ok=True)
    with open(os.path.join(directory, "Cargo.toml"), "w") as f:
        f.write(
            '[package]\nname = "%s"\nversion = "0.0.0"\nedition = "2024"\npublish = false\n\n'
            '[dependencies]\nlagrangian = { path = "%s" }\n\n[workspace]\n' % (name, workspace)
        )
    # The workspace's own versions of the dependencies, not the newest ones.
    lock = os.path.join(workspace, "Cargo.lock")
    if os.path.exists(lock):
        shutil.copy(lock, os.path.join(directory, "Cargo.lock"))
    with open(os.path.join(directory, "src", "main.rs"), "w") as f:
        f.write(
            """use lagrangian::prelude::*;

pub struct System;

#[lagrangian]
impl System {
    fn lagrangian(&self, q: [f64; %d], v: [f64; %d]) -> f64 {
        %s
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut sim = Integrator::new(System, Midpoint, 0.01).start(0.0, %s, %s)?;
    let e0 = sim.energy()?;
    sim.run(100, |_| {})?;
    println!("{} {:?}", sim.energy()? - e0, sim.state().q);
    Ok(())
}
"""
            % (n, n, body, q0, v0)
        )
    return actual, n


def measured(log):
    """CPU seconds, peak RSS (MB) and wall seconds from a GNU time log."""
    text = open(log).read()
    field = lambda key: float(re.search(re.escape(key) + r":\s*([\d.:]+)", text).group(1))
    cpu = field("User time (seconds)") + field("System time (seconds)")
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", text).group(1)
    seconds = sum(float(x) * 60**i for i, x in enumerate(reversed(wall.split(":"))))
    return cpu, field("Maximum resident set size (kbytes)") / 1024.0, seconds


def load_of(directory):
    """The 1-minute load average when the build in `directory` ended, if recorded."""
    path = os.path.join(directory, "load")
    return float(open(path).read()) if os.path.exists(path) else None


def build(directory, target, timeout, reuse=False):
    """CPU seconds, peak RSS (MB), wall seconds and load of `cargo build --release`; the wall
    seconds after which it was stopped; or, with `reuse == "only"` and no earlier build, a note."""
    log = os.path.join(directory, "time.log")
    # A finished build of the same source, from an earlier run in this directory.
    stopped = os.path.join(directory, "stopped")
    if reuse and os.path.exists(log) and "Exit status: 0" in open(log).read():
        return measured(log) + (load_of(directory),)
    # Or one an earlier run stopped at the same timeout or a longer one.
    if reuse and os.path.exists(stopped) and float(open(stopped).read()) >= timeout:
        return float(open(stopped).read())
    if reuse == "only":
        return "not measured"
    if os.path.exists(stopped):
        os.remove(stopped)
    env = dict(os.environ, CARGO_TARGET_DIR=target)
    cmd = ["/usr/bin/time", "-v", "-o", log, "cargo", "build", "--release", "--quiet"]
    start = time.time()
    # A session of its own, so that a timeout stops cargo and its rustc by
    # their process group and nothing else.
    proc = subprocess.Popen(cmd, cwd=directory, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        _, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 9)
        proc.communicate()
        with open(stopped, "w") as f:
            f.write(repr(timeout))
        return timeout
    if proc.returncode != 0:
        sys.stderr.write(stderr[-4000:])
        raise SystemExit("build failed in %s" % directory)
    # What the machine's other work did to the wall time.
    with open(os.path.join(directory, "load"), "w") as f:
        f.write(open("/proc/loadavg").read().split()[0])
    return measured(log) + (load_of(directory),)


def fit(points):
    """Least-squares slope of log(cpu) against log(terms)."""
    if len(points) < 2:
        return None
    xs = [math.log(t) for t, _ in points]
    ys = [math.log(c) for _, c in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default=",".join(map(str, SIZES)))
    ap.add_argument("--shapes", default=",".join(SHAPES))
    ap.add_argument("--timeout", type=float, default=1800, help="wall seconds per build")
    ap.add_argument("--workspace", default=ROOT, help="checkout whose `lagrangian` the crates depend on")
    ap.add_argument("--dir", default="/tmp/lagrangian-compile-time", help="scratch directory")
    ap.add_argument("--reuse", action="store_true",
                    help="take the measurement of a crate an earlier run in --dir built (same source), "
                    "or stopped at --timeout or later")
    ap.add_argument("--reuse-only", action="store_true",
                    help="as --reuse, and build nothing: sizes no earlier run finished or stopped are not measured")
    ap.add_argument("--print", action="store_true", help="print the page instead of writing docs/compile-time.md")
    args = ap.parse_args()
    workspace = os.path.abspath(args.workspace)
    sizes = [int(s) for s in args.sizes.split(",")]
    shapes = args.shapes.split(",")
    scratch = os.path.abspath(args.dir)
    target = os.path.join(scratch, "target")
    os.makedirs(scratch, exist_ok=True)

    # Dependencies first, with a one-term crate, so that no measurement includes them.
    if not args.reuse_only:
        warm = os.path.join(scratch, "warmup")
        generate(warm, "warmup", "sines", 2, workspace)
        build(warm, target, None)

    rows, fits = [], []
    for shape in shapes:
        points, stopped = [], False
        for size in sizes:
            name = "ct_%s_%d" % (shape, size)
            directory = os.path.join(scratch, name)
            main_rs = os.path.join(directory, "src", "main.rs")
            before = open(main_rs).read() if os.path.exists(main_rs) else None
            terms, n = generate(directory, name, shape, size, workspace)
            if open(main_rs).read() != before:
                for old in ("time.log", "load", "stopped"):
                    if os.path.exists(os.path.join(directory, old)):
                        os.remove(os.path.join(directory, old))
            if stopped:
                rows.append((shape, terms, n, None, None, None, None, "skipped"))
                continue
            result = build(directory, target, args.timeout, "only" if args.reuse_only else args.reuse)
            if isinstance(result, str):
                rows.append((shape, terms, n, None, None, None, None, result))
            elif isinstance(result, float):
                stopped = True
                rows.append((shape, terms, n, None, None, None, None, "stopped after %.0f s wall" % result))
            else:
                cpu, rss, wall, load = result
                points.append((terms, cpu))
                rows.append((shape, terms, n, cpu, rss, wall, load, ""))
            sys.stderr.write("%s %d terms (N = %d): %s\n" % (shape, terms, n, rows[-1][3:]))
        fits.append((shape, fit(points), len(points)))

    rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=workspace, capture_output=True, text=True).stdout.strip()
    cpu_model = next(
        (l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), "unknown"
    )
    rustc = subprocess.run(["rustc", "--version"], capture_output=True, text=True).stdout.strip()
    load = open("/proc/loadavg").read().split()[:3]
    command = "scripts/compile_time.py " + " ".join(
        a for a in sys.argv[1:] if a not in ("--print", "--reuse", "--reuse-only")
    )
    lines = [
        "# Compile time against the length of the Lagrangian",
        "",
        "Generated by `scripts/compile_time.py`; do not edit by hand (rerun it).",
        "",
        "- date: %s" % datetime.datetime.now().strftime("%Y-%m-%d %H:%M"),
        "- commit: `%s`" % (rev or "unknown"),
        "- machine: %d cores (`nproc`), %s; load average %s when the page was written"
        % (os.cpu_count(), cpu_model, " ".join(load)),
        "- compiler: %s" % rustc,
        "- command: `%s`" % command.strip(),
        "",
        "Each row is `cargo build --release` of a generated one-file crate (its",
        "dependencies already built): CPU seconds are user + system of cargo and",
        "the compiler (GNU time), which a shared machine affects far less than",
        "wall seconds (also shown, with the 1-minute load average when the build",
        "ended); peak RSS is the largest process's. Terms are the operands of the",
        "Lagrangian's top-level sum; N the coordinates.",
        "",
        "| shape | terms | N | CPU s | peak RSS MB | wall s | load | |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for shape, terms, n, cpu, rss, wall, load, note in rows:
        fmt = lambda x, f: f % x if x is not None else "–"
        lines.append(
            "| %s | %d | %d | %s | %s | %s | %s | %s |"
            % (shape, terms, n, fmt(cpu, "%.1f"), fmt(rss, "%.0f"), fmt(wall, "%.0f"), fmt(load, "%.1f"), note)
        )
    lines += ["", "Fitted exponent (least squares of log CPU s against log terms):", ""]
    lines += ["| shape | exponent | sizes fitted |", "| --- | ---: | ---: |"]
    for shape, slope, count in fits:
        lines.append("| %s | %s | %d |" % (shape, "%.2f" % slope if slope is not None else "–", count))
    page = "\n".join(lines) + "\n"
    if args.print:
        print(page, end="")
    else:
        with open(os.path.join(ROOT, "docs", "compile-time.md"), "w") as f:
            f.write(page)
        sys.stderr.write("docs/compile-time.md written\n")


if __name__ == "__main__":
    main()
