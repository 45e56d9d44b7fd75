#!/usr/bin/env bash
# The wheels that scripts/gpu_check.sh needs on the GPU machine and its image lacks, into .whl/
# (git-ignored; the device call carries it: carry [".whl"]). Run here, where pip reaches PyPI:
#
#   bash scripts/gpu_wheels.sh            # PYTHON (default python3) runs pip; it installs nothing
#
# The image (python 3.12, x86-64; its package list: the device notes' KINDS.md) has numpy, scipy,
# jax, numba, matplotlib, networkx, tabulate, tqdm, joblib, threadpoolctl, psutil, packaging,
# colorama, typing-inspect and mypy-extensions. What the two runs import beyond them (read off
# sys.modules of every process of `gpu_check.sh --cpu --quick`), at the versions this project's
# .venv tests with: pydantic (solvers/options.py) and pandapower (the cases' power flows), with
# their needs. pandas 2.3.3 (and pytz, tzdata, which pandas 2 needs) and typing-extensions 4.16.0
# are in the image at versions that may not be these: pandapower 3.5.6 asks for pandas ~= 2.3 and
# typing_extensions ~= 4.16, so these travel too and come first on the path. casadi (one
# classical adapter, not run) stays behind; openpyxl, xlsxwriter and wcwidth, optional imports, too.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}

WHEELS=(
    pydantic==2.14.4 pydantic-core==2.50.5 annotated-types==0.8.0 typing-inspection==0.4.5
    pandapower==3.5.6 pandera==0.35.0 typeguard==4.6.1 deepdiff==9.1.0 cachebox==5.2.3
    orderly-set==5.5.0 geojson==3.3.0
    pandas==2.3.3 pytz==2026.6 tzdata==2026.6 typing-extensions==4.16.0
)
rm -rf .whl
mkdir -p .whl
# pip matches a manylinux tag exactly: the tags the compiled ones (pandas, pydantic-core, cachebox) use
"$PYTHON" -m pip download --quiet --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_24_x86_64 \
    --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 --platform manylinux1_x86_64 \
    -d .whl "${WHEELS[@]}"
count=$(find .whl -type f -name '*.whl' | wc -l)
if [ "$count" -ne "${#WHEELS[@]}" ]; then
    echo "gpu_wheels.sh: $count wheels for ${#WHEELS[@]} names" >&2
    exit 1
fi
ls -1 .whl
echo "gpu_wheels.sh: $count wheels, $(du -sh .whl | cut -f1) in .whl/ (the device call carries at most 64 MiB in all)"
