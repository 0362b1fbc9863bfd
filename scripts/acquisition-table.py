#!/usr/bin/env python3
"""The README's acquisition table from `cv --acquisition` JSON files.

    scripts/acquisition-table.py merl100=merl100.json Ngan=ngan.json

prints the Markdown table (one block of rows per collection: the dense limit, then every
plan and n), then per collection and n the best informed plan (`error` or `condition`,
by image error over the four lights) against `nielsen` and `random` on image error,
FLIP and ΔE_ITP. Noise-free rows only; the first selection method of each file.
"""

import json
import sys

HEADER = (
    "| collection | plan | n | rho (median) | max rho | log-RMSE | image error (45, 45) "
    "| image error, 4 lights | CIEDE2000, 4 lights | ΔE_ITP, 4 lights | FLIP, 4 lights |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|"
)
INFORMED = ("error", "condition")
METRICS = (("image error", "image_error"), ("FLIP", "flip"), ("ΔE_ITP", "delta_e_itp"))


def g(x):
    """Three significant digits, as the README prints them."""
    return f"{x:.3g}"


def rows(label, doc):
    results = [r for r in doc["results"] if r["noise"] == 0.0]
    if not results:
        sys.exit(f"{label}: no noise-free rows")
    method = results[0]["method"]
    results = [r for r in results if r["method"] == method]
    first = results[0]
    dense_rhos = [h["dense_rho"] for h in first["held_out"]]
    da = first["dense_appearance"]
    out = [
        f"| {label} | dense fit (the limit) | all | {g(first['mean_dense_rho'])} | "
        f"{g(max(dense_rhos))} | {g(first['mean_dense_log_rmse'])} | "
        f"{g(da['image_error_paper_light'])} | {g(da['image_error'])} | {g(da['ciede2000'])} | "
        f"{g(da['delta_e_itp'])} | {g(da['flip'])} |"
    ]
    for r in results:
        a = r["appearance"]
        out.append(
            f"| {label} | {r['plan']} | {r['n']} | {g(r['mean_rho'])} ({g(r['median_rho'])}) | "
            f"{g(r['max_rho'])} | {g(r['mean_log_rmse'])} | {g(a['image_error_paper_light'])} | "
            f"{g(a['image_error'])} | {g(a['ciede2000'])} | {g(a['delta_e_itp'])} | {g(a['flip'])} |"
        )
    return out, results


def comparisons(label, results):
    by = {(r["plan"], r["n"]): r for r in results}
    lines = []
    for n in sorted({r["n"] for r in results}):
        ours = [by[(p, n)] for p in INFORMED if (p, n) in by]
        if not ours:
            continue
        best = min(ours, key=lambda r: r["appearance"]["image_error"])
        parts = []
        for peer in ("nielsen", "random"):
            if (peer, n) not in by:
                continue
            pa, ba = by[(peer, n)]["appearance"], best["appearance"]
            ratios = " / ".join(f"{name} {pa[key] / ba[key]:.2f}x" for name, key in METRICS)
            parts.append(f"against `{peer}`: {ratios}")
        worst = max(by[(p, n)]["max_rho"] for p in INFORMED if (p, n) in by)
        lines.append(
            f"* {label}, n = {n}: best informed plan `{best['plan']}`; "
            + "; ".join(parts)
            + f"; max rho of the informed plans {worst:.3g}"
        )
    return lines


def main(args):
    if not args:
        sys.exit(__doc__)
    table, notes = [HEADER], []
    for arg in args:
        label, _, path = arg.partition("=")
        if not path:
            sys.exit(f"{arg}: expected LABEL=FILE.json")
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
        out, results = rows(label, doc)
        table.extend(out)
        notes.extend(comparisons(label, results))
    print("\n".join(table))
    print()
    print("\n".join(notes))


if __name__ == "__main__":
    main(sys.argv[1:])
