#!/usr/bin/env bash
# The README's test command while another process keeps every core busy (tests/load.py): a test
# that waits on a sleep or a deadline instead of an event fails here first. Arguments go to pytest:
#   bash tests/under-load.sh                       # the whole suite
#   bash tests/under-load.sh -q tests/test_cli.py  # a part of it
# PYTHON names the interpreter (default: .venv/bin/python if there is one, else python3);
# LOAD_CORES the busy processes (default: one per core).
set -euo pipefail
cd "$(dirname "$0")/.."
python=${PYTHON:-}
if [ -z "$python" ]; then
    if [ -x .venv/bin/python ]; then python=.venv/bin/python; else python=python3; fi
fi
# The load stops by itself after an hour at most, or as soon as this script is gone.
"$python" tests/load.py --seconds 3600 ${LOAD_CORES:+--cores "$LOAD_CORES"} &
load=$!
trap 'kill "$load" 2> /dev/null || true; wait "$load" 2> /dev/null || true' EXIT
"$python" -m pytest -n auto "$@"
