#!/usr/bin/env python3
"""The adaptive acquisition's error table (BENCHMARKS.md, "Adaptive acquisition").

For each sample of config/samples/ and each budget, `gonio plan compare` measures
config/plan-adaptive.toml on the simulated instrument against a uniform lattice and
a grid of the same number of points, and prints the errors as Markdown. Then, at one
budget, the methods a batch can choose by are compared.

    cargo build --release -p gonio-cli
    scripts/adaptive_table.py [--gonio target/release/gonio] [--budgets 300,600,1200]
"""

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
SAMPLES = [
    ("Lambertian ρ = 0.8", "lambert"),
    ("Lafortune n = 5", "lafortune-n5"),
    ("Lafortune n = 50", "lafortune-n50"),
    ("Lafortune n = 500", "lafortune-n500"),
    ("Ward α = 0.5", "ward-0.5"),
    ("Ward α = 0.15", "ward-0.15"),
    ("Ward α = 0.05", "ward-0.05"),
    ("Ward αx = 0.05, αy = 0.2", "ward-0.05x0.2"),
    ("GGX α = 0.5", "ggx-0.5"),
    ("GGX α = 0.2", "ggx-0.2"),
    ("GGX α = 0.05", "ggx-0.05"),
]


def compare(gonio, plan, sample, budget):
    """The three runs' JSON records for one sample and budget."""
    out = subprocess.run(
        [
            gonio,
            "plan",
            "compare",
            str(plan),
            "--instrument",
            str(ROOT / "config/instrument-sim.toml"),
            "--sample",
            str(ROOT / "config/samples" / f"{sample}.toml"),
            "--budget",
            str(budget),
            "--json",
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    return {r["plan"]: r for r in json.loads(out.stdout)["runs"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gonio", default=str(ROOT / "target/release/gonio"))
    ap.add_argument("--budgets", default="300,600,1200")
    ap.add_argument("--methods-budget", type=int, default=600)
    a = ap.parse_args()
    budgets = [int(b) for b in a.budgets.split(",")]
    plan = ROOT / "config/plan-adaptive.toml"
    print(
        "| sample | points | E adaptive | E lattice | E grid | lattice / adaptive | grid / adaptive |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, sample in SAMPLES:
        for b in budgets:
            r = compare(a.gonio, plan, sample, b)
            ad, la, gr = r["adaptive"], r["lattice"], r["grid"]
            print(
                f"| {name} | {ad['points']} / {la['points']} / {gr['points']} "
                f"| {ad['error']:.3g} | {la['error']:.3g} | {gr['error']:.3g} "
                f"| {la['error'] / ad['error']:.2f}× | {gr['error'] / ad['error']:.2f}× |"
            )
            sys.stdout.flush()
    print()
    methods = ["residual", "variation", "value"]
    print(
        f"| sample ({a.methods_budget} points) | "
        + " | ".join(f"E {m}" for m in methods)
        + " | E lattice |"
    )
    print("|---|" + "---|" * (len(methods) + 1))
    text = plan.read_text()
    with tempfile.TemporaryDirectory() as d:
        for name, sample in SAMPLES:
            errors = []
            lattice = None
            for m in methods:
                p = pathlib.Path(d) / f"plan-{m}.toml"
                p.write_text(
                    text.replace('# method = "residual"', f'method = "{m}"', 1)
                )
                r = compare(a.gonio, p, sample, a.methods_budget)
                errors.append(r["adaptive"]["error"])
                lattice = r["lattice"]["error"]
            print(
                f"| {name} | "
                + " | ".join(f"{e:.3g}" for e in errors)
                + f" | {lattice:.3g} |"
            )
            sys.stdout.flush()


if __name__ == "__main__":
    main()
