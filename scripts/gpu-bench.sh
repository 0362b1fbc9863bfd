#!/usr/bin/env bash
# Every figure of the GPU performance table (docs/performance.md), both back-ends, on this
# machine, in one run: meant for one short use of a machine with a hardware GPU.
#
#   scripts/gpu-bench.sh                 # builds the bench executables (not timed), runs them
#   scripts/gpu-bench.sh --bin-dir DIR   # runs prebuilt, stripped executables from DIR:
#                                        # distance tabulate fit nbrdf weighted appearance brdf-basis
#
# What it prints:
# * BRDF_it (`distance` bench): N = 100, 240, 1,000 on both back-ends (and whether the
#   matrices agree), N = 10,000 on the GPU (the CPU back-end's rate at N = 1,000 stands in
#   for it: its throughput does not depend on N), and every kernel shape at N = 240;
# * tabulation of 100 analytic materials x RGB to the host, and into a GPU texture;
# * NBRDF: tabulation of the 100 MERL networks to the host, BRDF_it and Gram (needs
#   ../shared/data/real/nbrdf/merl100);
# * fit: Gram passes and batched PGD, 100,000 x 10;
# * weighted fits: 10,000 NBRDF targets x 3 channels by a 12-material basis, per-target
#   weights (`weighted` bench; the CPU back-end on 300 targets);
# * FLIP: ours on one CPU thread and a batch of 64 pairs on the GPU against NVIDIA's C++
#   reference per 256 x 256 image (`appearance` bench);
# * `reproduce merl100 --no-acquisition` and `select --method greedy -k 12` end to end;
# * the PyTorch peer (../shared/bench/torch_peer.py) when python3 has torch and a GPU.
# Each part runs under a time limit, so that the whole stays within 5 minutes after the
# build on an H200. Set BENCH_SHARED to the shared folder (default ../shared).
set -uo pipefail
cd "$(dirname "$0")/.."
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
shared="${BENCH_SHARED:-../shared}"
bin=""
if [ "${1:-}" = "--bin-dir" ]; then
    bin="$2"
else
    cargo build --release --quiet
    cargo bench --no-run --bench distance --bench tabulate --bench fit --bench nbrdf --bench weighted --bench appearance >/dev/null 2>&1
    bin="$(mktemp -d)"
    for b in distance tabulate fit nbrdf weighted appearance; do
        cp "$(ls -t target/release/deps/$b-* | grep -v '\.d$' | head -1)" "$bin/$b"
    done
    cp target/release/brdf-basis "$bin/"
fi
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,clocks.max.sm --format=csv,noheader || true
lscpu | grep -E '^(Model name|CPU\(s\))' || true
"$bin/brdf-basis" info 2>&1 | head -20
start=$(date +%s)
part() {
    local limit=$1
    shift
    echo "== $* (limit ${limit} s)"
    local t0
    t0=$(date +%s%N)
    timeout "$limit" "$@" 2>&1
    local rc=$?
    [ $rc = 0 ] || echo "== stopped after ${limit} s or failed (exit $rc)"
    echo "== $(( ($(date +%s%N) - t0) / 1000000 )) ms"
}
part 90 env BENCH_SHAPES="${BENCH_SHAPES:-1}" BENCH_SHAPES_N="${BENCH_SHAPES_N:-240}" BENCH_N=100,240,1000 "$bin/distance"
[ "${BENCH_NO_10K:-}" = 1 ] || part 90 env BENCH_N=10000 BENCH_N_GPU_ONLY=0 BENCH_BACKENDS=gpu "$bin/distance"
part 60 env BRDF_BASIS_GPU_TRACE=1 "$bin/tabulate"
part 90 env BRDF_BASIS_PYTHON=/bin/false "$bin/nbrdf"
part 60 "$bin/fit"
part 90 env BENCH_T=10000 BENCH_T_CPU=300 "$bin/weighted"
part 60 "$bin/appearance"
if [ -d "$shared/data/real/nbrdf/merl100" ]; then
    out="$(mktemp -d)"
    for be in gpu cpu; do
        part 60 "$bin/brdf-basis" --backend $be reproduce "$shared/data/real/nbrdf/merl100" \
            --out "$out/r-$be" --no-acquisition --quiet
        part 30 "$bin/brdf-basis" --backend $be select "$shared/data/real/nbrdf/merl100" \
            --method greedy -k 12 --json "$out/s-$be.json" --quiet
    done
    cmp "$out/s-gpu.json" "$out/s-cpu.json" >/dev/null && echo "select: the same JSON on both back-ends" \
        || { echo "select: the JSON differs between back-ends:"; diff <(grep -v seconds "$out/s-gpu.json") <(grep -v seconds "$out/s-cpu.json") | head -20; }
fi
if [ "${BENCH_NO_PEER:-}" = 1 ]; then
    echo "== torch peer: skipped (BENCH_NO_PEER=1)"
elif python3 -c 'import torch; assert torch.cuda.is_available()' 2>/dev/null; then
    part 90 python3 "$shared/bench/torch_peer.py" "$shared"
else
    echo "== torch peer: no python3 with torch and a CUDA device here"
fi
echo "== total $(( $(date +%s) - start )) s"
