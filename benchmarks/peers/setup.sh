#!/usr/bin/env bash
# The peers of benchmarks/bench_peers.py in throw-away virtual environments (not wbcbench's dependencies):
#   DIR/tsid:  C++ TSID 1.7.1 through its bindings (its wheel needs pinocchio 3.4 and that build's libraries)
#   DIR/placo: PlaCo 0.10.2 and pink 4.4 with daqp
# Usage: bash benchmarks/peers/setup.sh [DIR]   (default /tmp/wbcbench-peers)
set -euo pipefail
DIR="${1:-/tmp/wbcbench-peers}"
PY="${PY:-python3}"
mkdir -p "$DIR"
if [ ! -x "$DIR/tsid/bin/python" ]; then
    "$PY" -m venv "$DIR/tsid"
    "$DIR/tsid/bin/pip" install --quiet "tsid==1.7.1" "pin==3.4.0" "cmeel-urdfdom<5" "cmeel-tinyxml2<11"
fi
if [ ! -x "$DIR/placo/bin/python" ]; then
    "$PY" -m venv "$DIR/placo"
    "$DIR/placo/bin/pip" install --quiet "placo==0.10.2" "pin-pink==4.4.0" "daqp"
fi
"$DIR/tsid/bin/python" -c "import pinocchio; from tsid import tsid_pywrap" && echo "tsid ok: $DIR/tsid"
"$DIR/placo/bin/python" -c "import placo, pink, daqp" && echo "placo, pink ok: $DIR/placo"
