#!/usr/bin/env bash
# Reproduce the benchmark figures and charts of docs/bench.md with one command, from the repository root:
#   bash benchmarks/run.sh
# It installs hconv (building its compiled engine) and the bench extra (matplotlib) into .venv,
# then runs the full benchmark
# (2M rows, 3 repeats, peak memory on 20M rows; about 5 minutes and 4 GB of temporary disk) and
# the stability sweeps. Run it on an otherwise idle machine: the targets are ratios within one run.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -x .venv/bin/python ] || python3 -m venv .venv
.venv/bin/pip install -q -e '.[bench]'
COLUMNS=170 .venv/bin/hconv bench --rows 2000000 --repeats 3 --memory-rows 20000000 \
    --out docs/speed-vs-accuracy.png --json docs/bench.json
COLUMNS=170 .venv/bin/hconv stability --out docs/stability.png > /dev/null
