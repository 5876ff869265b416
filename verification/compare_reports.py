#!/usr/bin/env python3
"""Compare two directories of JSON reports numerically.

Usage: compare_reports.py OLD_DIR NEW_DIR [--rtol 1e-12] [--ignore-timing] [--skip REGEX ...]

Walks every *.json under OLD_DIR, loads the file of the same relative path under NEW_DIR and
compares the two trees: numbers within `rtol` (relative to the larger magnitude, with an
absolute floor of rtol * 1e-300), strings, booleans and nulls exactly, arrays by length and
element, objects by key set. With --ignore-timing, keys that hold wall-clock figures (names
containing "ms", "seconds", "wall", "time_s", "elapsed", "per_second", "date", "speedup") are
skipped; each --skip REGEX drops the differences whose "file: path" matches it (figures derived
from timings, such as the trade-off study's Pareto fronts, which are chosen by measured cost).
Prints one line per difference (path, old, new) and a summary; exits 1 if any.
"""
import json
import math
import os
import re
import sys

TIMING = ("_ms", "ms_", "seconds", "wall", "time_s", "elapsed", "per_second", "date", "speedup",
          "timing", "throughput", "cost_ratio", "_us", "duration")


def is_timing(key):
    k = key.lower()
    return k == "ms" or any(t in k for t in TIMING)


def compare(a, b, path, rtol, ignore_timing, out):
    if isinstance(a, bool) or isinstance(b, bool):
        if a != b:
            out.append((path, a, b))
        return
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        if a == b:
            return
        if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
            return
        scale = max(abs(a), abs(b))
        if abs(a - b) > rtol * scale:
            out.append((path, a, b))
        return
    if type(a) is not type(b):
        out.append((path, a, b))
        return
    if isinstance(a, dict):
        for k in sorted(set(a) | set(b)):
            if ignore_timing and is_timing(k):
                continue
            if k not in a or k not in b:
                out.append((f"{path}.{k}", a.get(k, "<missing>"), b.get(k, "<missing>")))
                continue
            compare(a[k], b[k], f"{path}.{k}", rtol, ignore_timing, out)
        return
    if isinstance(a, list):
        if len(a) != len(b):
            out.append((f"{path}[len]", len(a), len(b)))
            return
        for i, (x, y) in enumerate(zip(a, b)):
            compare(x, y, f"{path}[{i}]", rtol, ignore_timing, out)
        return
    if a != b:
        out.append((path, a, b))


def main():
    args = sys.argv[1:]
    rtol = 1e-12
    ignore_timing = False
    if "--rtol" in args:
        i = args.index("--rtol")
        rtol = float(args[i + 1])
        del args[i:i + 2]
    if "--ignore-timing" in args:
        args.remove("--ignore-timing")
        ignore_timing = True
    skips = []
    while "--skip" in args:
        i = args.index("--skip")
        skips.append(re.compile(args[i + 1]))
        del args[i:i + 2]
    if len(args) != 2:
        print(__doc__)
        sys.exit(2)
    old_dir, new_dir = args
    total = 0
    files = 0
    for root, _, names in os.walk(old_dir):
        for name in sorted(names):
            if not name.endswith(".json"):
                continue
            rel = os.path.relpath(os.path.join(root, name), old_dir)
            new_path = os.path.join(new_dir, rel)
            files += 1
            if not os.path.exists(new_path):
                print(f"{rel}: missing in {new_dir}")
                total += 1
                continue
            with open(os.path.join(old_dir, rel)) as f:
                a = json.load(f)
            with open(new_path) as f:
                b = json.load(f)
            out = []
            compare(a, b, "$", rtol, ignore_timing, out)
            out = [d for d in out if not any(r.search(f"{rel}: {d[0]}") for r in skips)]
            for p, x, y in out:
                xs, ys = json.dumps(x)[:80], json.dumps(y)[:80]
                print(f"{rel}: {p}: {xs} -> {ys}")
            total += len(out)
    print(f"{files} files compared, {total} differences (rtol {rtol})")
    sys.exit(1 if total else 0)


if __name__ == "__main__":
    main()
