#!/usr/bin/env python3
"""The critical path of a cargo build, from its `--timings` report.

Cargo starts a unit when the last of its dependencies finishes (or, for a
dependency whose metadata suffices, emits it) and records which unit
unlocked which. Following the unlocks back from the unit that finished last
gives the chain of units no number of cores could have overlapped: an idle
machine with enough cores still takes the sum of their durations. With
fewer jobs than ready units (`-j2` on two cores), a unit may wait for a job
after its dependencies finish: its start then lies after its unlocker's end,
and the chain's CPU seconds say more than its wall span.

    cargo test --workspace --no-run --timings
    scripts/critical-path.py target/cargo-timings/cargo-timing.html

With the log of `scripts/build-cpu.sh` (one line per rustc process: user and
system CPU, wall, crate name, kind, package), each unit of the chain also shows its
CPU seconds, which do not depend on the machine's load as its wall seconds do:

    scripts/critical-path.py target/cargo-timings/cargo-timing.html /tmp/lagrangian-build-cpu.log
"""

import json
import re
import sys


def units(html_path):
    text = open(html_path, encoding="utf-8").read()
    found = re.search(r"UNIT_DATA\s*=\s*(\[.*?\]);\s*\n", text, re.S)
    if not found:
        sys.exit(f"{html_path}: no UNIT_DATA in this report")
    return json.loads(found.group(1))


def cpu_by_name(log_path):
    """CPU seconds per (package, crate name, is a test harness), and per (crate
    name, is a test harness) for logs without the package; None where a key is
    ambiguous."""
    cpu = {}
    for line in open(log_path, encoding="utf-8"):
        fields = line.split()
        if len(fields) not in (5, 6) or fields[3] == "?":
            continue
        try:
            seconds = float(fields[0]) + float(fields[1])
        except ValueError:
            continue
        is_test = "test," in fields[4]
        keys = [(fields[3], is_test)]
        if len(fields) == 6:
            keys.append((fields[5], fields[3], is_test))
        for key in keys:
            cpu[key] = None if key in cpu else seconds
    return cpu


def main():
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    data = units(sys.argv[1])
    cpu = cpu_by_name(sys.argv[2]) if len(sys.argv) == 3 else {}
    by_index = {u["i"]: u for u in data}
    unlocker = {}
    for u in data:
        # `unblocked_*` in the reports of newer cargo, `unlocked_*` before.
        unblocked = u.get("unblocked_units", u.get("unlocked_units", []))
        unblocked_rmeta = u.get("unblocked_rmeta_units", u.get("unlocked_rmeta_units", []))
        for j in unblocked + unblocked_rmeta:
            unlocker[j] = u["i"]
    last = max(data, key=lambda u: u["start"] + u["duration"])
    chain = [last]
    while chain[-1]["i"] in unlocker:
        chain.append(by_index[unlocker[chain[-1]["i"]]])
    chain.reverse()
    total_cpu = 0.0
    print(f"{'start s':>8} {'wall s':>8} {'CPU s':>8}  unit")
    for u in chain:
        # `target` reads ` NAME "KIND"`, with ` (test)` for a test harness
        # (empty for a package's library).
        target = u.get("target", "").strip()
        name = target.split()[0] if target else u["name"].replace("-", "_")
        is_test = '"test"' in target or "(test)" in target
        seconds = cpu.get((u["name"], name, is_test), cpu.get((name, is_test)))
        total_cpu += seconds or 0.0
        shown = f"{seconds:8.1f}" if seconds is not None else f"{'':>8}"
        print(f"{u['start']:8.1f} {u['duration']:8.1f} {shown}  {u['name']}{(' ' + target) if target else ''}")
    end = last["start"] + last["duration"]
    print(f"critical path: ends at {end:.1f} s wall; {len(chain)} units", end="")
    print(f", {total_cpu:.1f} s CPU in the units matched in the log" if cpu else "")


if __name__ == "__main__":
    main()
