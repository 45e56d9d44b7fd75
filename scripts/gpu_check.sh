#!/usr/bin/env bash
# The GPU check: the two JAX PINNs trained and queried on a GPU by the harness, rows into results/gpu/.
#
#   bash scripts/gpu_check.sh              # on a machine with a GPU: rows into results/gpu/ (a 450 s budget)
#   bash scripts/gpu_check.sh --cpu        # the same runs with JAX on the CPU (JAX_PLATFORMS=cpu), rows into
#                                          # .cache/gpu-check-cpu/ (never results/gpu/: that holds GPU rows only)
#   bash scripts/gpu_check.sh --quick      # tiny budgets on small cases (GPU_CHECK_QUICK=1): a test of the plan
#   bash scripts/gpu_check.sh --dry-run    # print the harness commands (one `harness run ...` a line), run nothing
#
# Steps: (a) carried wheels (.whl/, scripts/gpu_wheels.sh) installed into $GPU_CHECK_SITE and put on
# PYTHONPATH, for a machine without the project's .venv; (b) JAX's default backend must be a GPU
# (--cpu: the CPU), its device kind is written into each run's metadata.json ("accelerator"); (c) two
# `python -m harness run`s, each unit (build, fit, suites) in a process of its own, stopped at its
# share of the time budget with a row saying so; (d) one summary line. CI never runs it.
# Environment: PYTHON (default python3), GPU_CHECK_QUICK=1 (as --quick), GPU_CHECK_CPU=1 (as --cpu),
# GPU_CHECK_THREADS (--threads of the runs; default: every core), GPU_CHECK_SECONDS (the whole
# budget, default 450 s), GPU_CHECK_OUT (the results folder), GPU_CHECK_SITE (where wheels go),
# GPU_CHECK_WHEELS=0 (leave .whl/ alone: a Python that has the project's dependencies, e.g. .venv).
# Where $OUT is set (the device tool's folder of files that come back), the rows, metadata and the
# summary are copied there too: at most 8 files. Exit status: 0; 3 when JAX has no GPU (--cpu: no
# CPU backend); else the last run's that did not end well (1: a unit failed; 124: the first run was
# interrupted at its share of the budget).
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
cpu=${GPU_CHECK_CPU:-0}
quick=${GPU_CHECK_QUICK:-0}
dry=0
for arg in "$@"; do
    case $arg in
        --cpu) cpu=1 ;;
        --quick) quick=1 ;;
        --dry-run) dry=1 ;;
        -h|--help) sed -n '2,/^set /{/^#/s/^# \{0,1\}//p}' "$0"; exit 0 ;;
        *) echo "gpu_check.sh: unknown argument $arg (--cpu, --quick, --dry-run)" >&2; exit 2 ;;
    esac
done

if [ "$cpu" = 1 ]; then results=${GPU_CHECK_OUT:-.cache/gpu-check-cpu}; else results=${GPU_CHECK_OUT:-results/gpu}; fi
case $(realpath -m "$results")/ in
    "$PWD"/results/gpu/*) if [ "$cpu" = 1 ]; then echo "gpu_check.sh: --cpu writes no rows into results/gpu/" >&2; exit 2; fi ;;
esac
threads=${GPU_CHECK_THREADS:-$(nproc)}
budget=${GPU_CHECK_SECONDS:-450}

# The two runs. The full budgets are those of the CPU rows they compare with, so that a fit row
# differs in where it computed: reduced-pinn 60 Levenberg-Marquardt iterations a window as
# results/scaling-reduced-9241 (601 s of fit on 2 shared cores, 9 % of it the snapshots and the
# basis), within max_seconds=150 (snapshots and basis included; each window gets an equal share of
# what is left, and the fit message counts the iterations made); jax-pinn `marching` on ieee39 with
# make bench's budget for that case (60 iterations a window, harness.settings.DEFAULT: 74 s of fit
# on 2 cores in results/rows.jsonl), trained on the GPU, queried on the CPU as the adapter does.
if [ "$quick" = 1 ]; then
    reduced_case=case118; reduced_opts=(--option max_iterations=1 --option max_seconds=60)
    marching_case=wscc9; marching_opts=(--option max_iterations=2); size=(--quick)
else
    reduced_case=case9241pegase; reduced_opts=(--option max_iterations=60 --option max_seconds=150)
    marching_case=ieee39; marching_opts=(); size=()
fi
[ "$cpu" = 1 ] || marching_opts+=(--option device=gpu)
common=(--threads "$threads" --progress off --overwrite "${size[@]}")
reduced_out=$results/reduced-pinn-$reduced_case
marching_out=$results/jax-pinn-marching-$marching_case
reduced_cmd=(run --suite scaling --solver reduced-pinn --config default --case "$reduced_case"
             "${reduced_opts[@]}" "${common[@]}" --out "$reduced_out")
marching_cmd=(run --suite accuracy latency --solver jax-pinn --config marching --case "$marching_case"
              "${marching_opts[@]}" "${common[@]}" --out "$marching_out")

if [ "$dry" = 1 ]; then  # as run, with the units' largest time limits
    echo "harness ${marching_cmd[*]} --unit-seconds 240"
    echo "harness ${reduced_cmd[*]} --unit-seconds 300"
    exit 0
fi

start=$SECONDS
# (a) the wheels the image lacks (scripts/gpu_wheels.sh), installed outside the image's environment
path=$PWD  # the project from this checkout: it is not installed there
if [ "${GPU_CHECK_WHEELS:-1}" != 0 ] && compgen -G ".whl/*.whl" > /dev/null; then
    site=${GPU_CHECK_SITE:-/tmp/swingbench-site}
    "$PYTHON" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$site" .whl/*.whl
    path=$path:$site
fi
export PYTHONPATH="$path${PYTHONPATH:+:$PYTHONPATH}"

# (b) where JAX computes. Each unit is a process of its own beside the parent that planned it: no
# process takes 75 % of the GPU's memory up front.
export XLA_PYTHON_CLIENT_PREALLOCATE=false
if [ "$cpu" = 1 ]; then export JAX_PLATFORMS=cpu; want=cpu; else want=gpu; fi
mkdir -p "$results"
"$PYTHON" scripts/gpu_check_rows.py probe --want "$want" > "$results/accelerator.json"
echo "gpu_check: $(cat "$results/accelerator.json")"

# (c) the runs, jax-pinn first: its time is the less certain (a GPU compiles each window's
# functions), reduced-pinn's fit is bounded by max_seconds. Each unit (a process: the case built,
# the fit, the suites) is stopped at its share of the budget with a row saying so; `share CAP KEEP`:
# what is left but KEEP s, at most CAP, at least 30. jax-pinn's run (two units: the adapter's own
# queries, then its numba query path on the trained model) keeps 270 s for reduced-pinn's (the case
# built in the parent and in the unit, snapshots, basis, fit, the DOP853 reference, queries) and is
# interrupted as a whole (as Ctrl-C: the units done are kept) once only 260 s are left. A run's
# exit status 1 (a failed unit) does not stop the check. Each run's rows and metadata go to the
# device tool's $OUT as soon as it ends.
share() { local s=$((budget - (SECONDS - start) - $2)); [ "$s" -gt "$1" ] && s=$1; [ "$s" -lt 30 ] && s=30; echo $s; }
keep() {
    "$PYTHON" scripts/gpu_check_rows.py stamp "$1" "$results/accelerator.json"
    if [ -n "${OUT:-}" ]; then
        mkdir -p "$OUT/$(basename "$1")"
        cp "$1/rows.jsonl" "$1/metadata.json" "$OUT/$(basename "$1")/" 2>/dev/null || true
    fi
}
status=0
timeout -s INT -k 20 "$(share 600 260)" \
    "$PYTHON" -m harness "${marching_cmd[@]}" --unit-seconds "$(share 240 270)" > /dev/null || status=$?
keep "$marching_out"
"$PYTHON" -m harness "${reduced_cmd[@]}" --unit-seconds "$(share 300 45)" > /dev/null || status=$?
keep "$reduced_out"

# (d) the summary line
"$PYTHON" scripts/gpu_check_rows.py summary "$marching_out" "$reduced_out" --seconds $((SECONDS - start)) \
    | tee "$results/summary.txt"
[ -z "${OUT:-}" ] || cp "$results/summary.txt" "$results/accelerator.json" "$OUT/"
exit "$status"
