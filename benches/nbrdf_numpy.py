"""Plain numpy evaluation of neural BRDFs (SPEC 9) on the full MERL grid: the baseline of
`cargo bench --bench nbrdf`.

    python benches/nbrdf_numpy.py DIR COUNT

Evaluates the first COUNT networks of DIR (NAME_fc1.npy ... NAME_b3.npy, names sorted) at
the 1,458,000 cell centres of SPEC 2 in float32 (matrix products per layer, as a numpy
user would write it), and prints one line per material `name sum` (the f64 sum of its
clamped RGB values over every cell, a check of the Rust tabulation), then
`seconds S` (evaluation time, inputs built once and not counted).
"""

import sys
import time
from pathlib import Path

import numpy as np


def grid_inputs():
    i = np.arange(90, dtype=np.float64)
    th = ((i + 0.5) / 90.0) ** 2 * np.pi / 2
    td = (np.arange(90, dtype=np.float64) + 0.5) * np.pi / 180
    pd = (np.arange(180, dtype=np.float64) + 0.5) * np.pi / 180
    TH, TD, PD = np.meshgrid(th, td, pd, indexing="ij")  # flat = k + 180 (j + 90 i)
    x = np.stack(
        [
            np.sin(TH),
            np.zeros_like(TH),
            np.cos(TH),
            np.sin(TD) * np.cos(PD),
            np.sin(TD) * np.sin(PD),
            np.cos(TD),
        ],
        axis=-1,
    ).reshape(-1, 6)
    return x.astype(np.float32)


def load(d, name):
    return [np.load(d / f"{name}_{p}.npy") for p in ("fc1", "b1", "fc2", "b2", "fc3", "b3")]


def forward(x, w):
    fc1, b1, fc2, b2, fc3, b3 = w
    a1 = np.maximum(x @ fc1 + b1, 0)
    a2 = np.maximum(a1 @ fc2 + b2, 0)
    return np.maximum(np.exp(a2 @ fc3 + b3) - 1, 0)


def main():
    d = Path(sys.argv[1])
    count = int(sys.argv[2])
    names = sorted({p.name[: -len("_fc1.npy")] for p in d.glob("*_fc1.npy")})[:count]
    nets = [load(d, n) for n in names]
    x = grid_inputs()
    sums = []
    t = time.perf_counter()
    for w in nets:
        sums.append(float(forward(x, w).sum(dtype=np.float64)))
    s = time.perf_counter() - t
    for n, v in zip(names, sums):
        print(n, repr(v))
    print("seconds", s)


if __name__ == "__main__":
    main()
