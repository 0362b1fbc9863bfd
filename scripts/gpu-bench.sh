#!/usr/bin/env bash
# The figures of the README's performance table (both back-ends) on this machine: BRDF_it
# at N = 100 and 1,000 on the full grid, tabulation (host readback and packed texture),
# fit end to end and the Gram pass, batched PGD (`cargo bench --bench distance|tabulate|
# fit`). Meant for a machine with a hardware GPU: the benches print the adapter they ran
# on; each runs under a time limit so that the whole script stays within 5 minutes after
# the build. Usage: scripts/gpu-bench.sh [--no-build]
set -euo pipefail
cd "$(dirname "$0")/.."
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
if [ "${1:-}" != "--no-build" ]; then
    # The build is not timed.
    cargo bench --no-run --bench distance --bench tabulate --bench fit >/dev/null 2>&1
fi
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version --format=csv,noheader || true
start=$(date +%s)
run() {
    local limit=$1 bench=$2
    echo "== cargo bench --bench $bench (limit ${limit} s)"
    if ! timeout "$limit" cargo bench --bench "$bench" 2>&1 | grep -vE '^\s*(Compiling|Finished|Running)'; then
        echo "== $bench: stopped after ${limit} s or failed"
    fi
}
run 150 distance
run 60 tabulate
run 80 fit
echo "== total $(( $(date +%s) - start )) s"
